//! The store's conformance suite: leasing, expiry and retries, idempotent reports,
//! promotion, cancellation, successive halving, the evolutionary search and group commits,
//! each run on a real SQLite file and on a real PostgreSQL server (a database of its own per
//! test on the server `GAITSWEEP_TEST_PG` names; `scripts/test.sh` starts a throwaway one).
//! A test that needs one backend's internals (SQLite's page limit) runs on that one only.

use super::*;
use crate::Error;
use gaitsweep_core::{CellState, SweepState};
use gaitsweep_model::{LevelScore, TerrainKind};

fn spec(w1: usize, w2: usize, terrains: Vec<TerrainKind>) -> ResolvedSpec {
    ResolvedSpec {
        name: "t".into(),
        robot: "anymal".into(),
        terrains,
        difficulty: None,
        w1_values: (0..w1).map(|i| i as f64).collect(),
        w2_values: (0..w2).map(|i| -(i as f64)).collect(),
        agents_per_cell: 2,
        epochs: 3,
        checkpoint_every: 1,
        seed: 1,
        replicates: 1,
        ppo_overrides: Default::default(),
        eval: gaitsweep_model::EvalSettings {
            robots: 0,
            seconds: 0.0,
            levels: vec![],
            score: Default::default(),
            every: 0,
        },
        search: Default::default(),
        finalists: None,
        stop_unrewarded: None,
    }
}

fn score(s: f64) -> GaitScore {
    GaitScore {
        score: s,
        track: 0.5,
        effort: 0.1,
        tilt: 0.0,
        progress: 0.0,
        fall_rate: 0.0,
        mean_vel_error: 0.0,
        mean_abs_torque: 0.0,
        cost_of_transport: 0.0,
        robots: 2,
        ..Default::default()
    }
}

/// A score evaluated at levels 0 and 7 (the mean of the two).
fn score_at_levels(low: f64, high: f64) -> GaitScore {
    let at = |level, s: f64| LevelScore {
        level,
        score: GaitScore {
            fall_rate: if level == 7 { 0.5 } else { 0.0 },
            overspeed: 0.1,
            ..score(s)
        },
    };
    GaitScore::mean_of_levels(vec![at(0, low), at(7, high)])
}

async fn setup() -> (tempfile::TempDir, SqlStore, WorkerId) {
    setup_with_slots(2).await
}

/// A store in a temp dir with one registered worker of `slots` slots.
async fn setup_with_slots(slots: u32) -> (tempfile::TempDir, SqlStore, WorkerId) {
    let dir = tempfile::tempdir().unwrap();
    let backend = BACKEND.try_with(|b| *b).unwrap_or(Backend::Sqlite);
    let url = match backend {
        Backend::Sqlite => DatabaseUrl::Sqlite(dir.path().join("db.sqlite")),
        Backend::Postgres => DatabaseUrl::Postgres(pg::fresh_database().await),
    };
    let store = SqlStore::connect(&url).await.unwrap();
    assert_eq!(store.backend(), backend);
    let w = WorkerId("w1".into());
    let info = WorkerInfo {
        hostname: "h".into(),
        cores: 2,
        device: "cpu".into(),
        slots,
        version: "t".into(),
        cpu: "test cpu".into(),
    };
    store.register_worker(&w, &info, 0).await.unwrap();
    (dir, store, w)
}

async fn expired_cells_are_retried_then_failed() {
    let (_d, store, w) = setup().await;
    let sweep = store
        .create_sweep(&spec(1, 1, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    for attempt in 1..=2 {
        let g = store.lease_next(&w, 0, 10).await.unwrap().expect("lease");
        assert_eq!(g.cell.attempts, attempt);
        assert!(
            store.lease_next(&w, 1, 10).await.unwrap().is_none(),
            "one lease per cell"
        );
        let out = store
            .end_attempt(g.lease, AttemptEnd::Expired, "gone", 2, 20)
            .await
            .unwrap();
        let again = store
            .end_attempt(g.lease, AttemptEnd::Expired, "gone", 2, 20)
            .await
            .unwrap();
        assert_eq!(
            out.cell.state, again.cell.state,
            "ending twice changes nothing"
        );
        if attempt == 2 {
            assert_eq!(out.cell.state, CellState::Failed);
            assert_eq!(out.cell.last_error.as_deref(), Some("gone"));
            assert_eq!(out.finished.unwrap().state, SweepState::Done);
        } else {
            assert_eq!(out.cell.state, CellState::Queued);
        }
    }
    assert_eq!(store.sweep(sweep.id).await.unwrap().cells_failed, 1);
}

async fn results_are_idempotent_and_promote_the_best() {
    let (_d, store, w) = setup().await;
    let sweep = store
        .create_sweep(&spec(2, 1, vec![TerrainKind::Flat, TerrainKind::Rough]), 0)
        .await
        .unwrap();
    let mut scores = vec![0.2, 0.9, 0.5, 0.7].into_iter();
    let mut promoted = 0;
    while let Some(g) = store.lease_next(&w, 0, 1).await.unwrap() {
        let s = scores.next().unwrap();
        let ck = CheckpointRecord {
            sha256: format!("{:064x}", g.lease.0),
            size: 10,
            epoch: 3,
        };
        store.record_checkpoint(g.lease, &ck, "x", 2).await.unwrap();
        store.record_checkpoint(g.lease, &ck, "x", 2).await.unwrap();
        let (rows, ..) = store
            .record_progress(g.lease, &[(1, [("a".to_string(), 1.0)].into())])
            .await
            .unwrap();
        assert_eq!(rows, 1);
        let out = store
            .report_result(g.lease, &score(s), 3, Some(&ck.sha256), 3)
            .await
            .unwrap();
        assert!(!out.duplicate);
        promoted += out.promotions.len();
        let dup = store
            .report_result(g.lease, &score(s), 3, Some(&ck.sha256), 4)
            .await
            .unwrap();
        assert!(dup.duplicate && dup.promotions.is_empty());
        assert!(matches!(
            store.record_progress(g.lease, &[]).await,
            Err(Error::CellClosed { .. })
        ));
    }
    assert!(promoted >= 3, "first cell overall + each terrain's first");
    let rec = store.sweep(sweep.id).await.unwrap();
    assert_eq!((rec.cells_done, rec.state), (4, SweepState::Done));
    let best = store.promoted(sweep.id, None).await.unwrap();
    assert_eq!(best.cell.score.unwrap().score, 0.9);
    assert!(best.checkpoint.is_some());
    assert_eq!(
        store
            .promoted(sweep.id, Some("rough"))
            .await
            .unwrap()
            .cell
            .score
            .unwrap()
            .score,
        0.7
    );
    assert_eq!(rec.best_cell, Some(best.cell.id));
}

async fn resume_points_at_the_latest_checkpoint_and_cancel_stops_all() {
    let (_d, store, w) = setup().await;
    let sweep = store
        .create_sweep(&spec(1, 2, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    let g = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
    for e in [1, 2] {
        let ck = CheckpointRecord {
            sha256: format!("{e:064x}"),
            size: 1,
            epoch: e,
        };
        store.record_checkpoint(g.lease, &ck, "x", 1).await.unwrap();
    }
    store
        .end_attempt(g.lease, AttemptEnd::Failed, "boom", 3, 2)
        .await
        .unwrap();
    let g2 = store.lease_next(&w, 0, 3).await.unwrap().unwrap();
    assert_eq!(g2.cell.id, g.cell.id, "the retried cell comes first");
    assert_eq!(g2.resume.unwrap().epoch, 2);
    assert_eq!(store.running_leases().await.unwrap().len(), 1);
    let (rec, leases) = store.cancel_sweep(sweep.id, 4).await.unwrap();
    assert_eq!(rec.state, SweepState::Cancelled);
    assert_eq!(leases, vec![g2.lease]);
    assert!(store.lease_next(&w, 0, 5).await.unwrap().is_none());
    assert!(matches!(
        store.report_result(g2.lease, &score(1.0), 3, None, 6).await,
        Err(Error::CellClosed { .. })
    ));
    assert!(matches!(
        store.sweep(SweepId(99)).await,
        Err(Error::UnknownSweep(_))
    ));
}

/// A cell retried after its attempt failed trains the epochs after its checkpoint again: its
/// periodic evaluation there replaces the failed attempt's (as the metrics do), and a late
/// report of the failed attempt cannot bring the old one back.
async fn a_retried_attempt_replaces_its_periodic_evaluations() {
    let (_d, store, w) = setup().await;
    let mut s = spec(1, 1, vec![TerrainKind::Flat]);
    s.eval.every = 1;
    store.create_sweep(&s, 0).await.unwrap();
    let eval = |score: f64| {
        metrics(&[
            ("mean_return", 1.0),
            ("eval/score", score),
            ("eval/fall_rate", 0.5),
        ])
    };
    let g = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
    store
        .record_progress(g.lease, &[(1, eval(0.2)), (2, eval(0.3))])
        .await
        .unwrap();
    store
        .end_attempt(g.lease, AttemptEnd::Failed, "killed", 3, 2)
        .await
        .unwrap();
    let g2 = store.lease_next(&w, 0, 3).await.unwrap().unwrap();
    assert_eq!(g2.cell.id, g.cell.id);
    store
        .record_progress(g2.lease, &[(2, eval(0.7))])
        .await
        .unwrap();
    let rows: Vec<(i64, f64, i64)> = sqlx::query_as(
        "SELECT epoch, score, attempt_id FROM evaluations WHERE cell_id = $1 ORDER BY epoch",
    )
    .bind(g.cell.id.0)
    .fetch_all(store.reader())
    .await
    .unwrap();
    assert_eq!(
        rows,
        vec![(1, 0.2, g.lease.0), (2, 0.7, g2.lease.0)],
        "epoch 1 from the first attempt, epoch 2 from the retry"
    );
    let metric: f64 = sqlx::query_scalar(
        "SELECT value FROM epoch_metrics WHERE cell_id = $1 AND epoch = 2 AND name = 'eval/score'",
    )
    .bind(g.cell.id.0)
    .fetch_one(store.reader())
    .await
    .unwrap();
    assert_eq!(metric, 0.7, "the metric and the evaluation agree");
    // Refused or not, a report of the ended attempt leaves the retry's evaluation standing.
    let _ = store.record_progress(g.lease, &[(2, eval(0.1))]).await;
    let kept: f64 =
        sqlx::query_scalar("SELECT score FROM evaluations WHERE cell_id = $1 AND epoch = 2")
            .bind(g.cell.id.0)
            .fetch_one(store.reader())
            .await
            .unwrap();
    assert_eq!(kept, 0.7);
}

/// A full disk (here: SQLite's page limit) fails the writes that meet it; once space is
/// back, writes succeed again without a restart.
#[tokio::test]
async fn the_writer_recovers_after_the_disk_was_full() {
    let (_dir, store, _w) = setup().await;
    let pages: i64 = sqlx::query_scalar("PRAGMA page_count")
        .fetch_one(store.writer())
        .await
        .unwrap();
    sqlx::query(&format!("PRAGMA max_page_count = {}", pages + 4))
        .execute(store.writer())
        .await
        .unwrap();
    let mut full = None;
    for _ in 0..200 {
        if let Err(e) = store
            .create_sweep(&spec(30, 30, vec![TerrainKind::Flat]), 1)
            .await
        {
            full = Some(e.to_string());
            break;
        }
    }
    let full = full.expect("the page limit was never reached");
    assert!(full.contains("full"), "{full}");
    // Space is back (the limit lifted): every later write must work.
    let _ = sqlx::query("PRAGMA max_page_count = 1073741823")
        .execute(store.writer())
        .await;
    for _ in 0..3 {
        store
            .create_sweep(&spec(2, 2, vec![TerrainKind::Flat]), 2)
            .await
            .expect("a write after the disk had space again");
    }
}

/// Fault-injection finding: a result on the lease of a cell that had failed for good
/// turned it `done`.
async fn a_failed_cell_stays_failed() {
    let (_d, store, w) = setup().await;
    store
        .create_sweep(&spec(1, 1, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    let mut first = None;
    for _ in 0..3 {
        let g = store.lease_next(&w, 0, 1).await.unwrap().expect("lease");
        first.get_or_insert(g.lease);
        store
            .end_attempt(g.lease, AttemptEnd::Failed, "boom", 3, 2)
            .await
            .unwrap();
    }
    let first = first.unwrap();
    assert!(matches!(
        store.report_result(first, &score(0.5), 3, None, 3).await,
        Err(Error::CellClosed { .. })
    ));
    assert!(matches!(
        store
            .record_progress(first, &[(1, [("a".to_string(), 1.0)].into())])
            .await,
        Err(Error::CellClosed { .. })
    ));
    let cells = store.cells(SweepId(1)).await.unwrap();
    assert_eq!(cells[0].state, CellState::Failed);
    assert!(cells[0].score.is_none());
    let state: String = sqlx::query_scalar("SELECT state FROM attempts WHERE id = $1")
        .bind(first.0)
        .fetch_one(store.writer())
        .await
        .unwrap();
    assert_eq!(state, "failed");
}

/// Fault-injection finding: a stopping worker's cell waited for its lease to expire and
/// the stop counted towards the attempt limit.
async fn released_attempts_requeue_at_once_and_do_not_count() {
    let (_d, store, w) = setup().await;
    store
        .create_sweep(&spec(1, 1, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    for i in 0..5 {
        let g = store.lease_next(&w, 0, i).await.unwrap().expect("lease");
        let out = store
            .end_attempt(
                g.lease,
                AttemptEnd::Released,
                "released: worker stopping",
                2,
                i,
            )
            .await
            .unwrap();
        assert_eq!(out.cell.state, CellState::Queued, "release {i}");
        assert!(out.finished.is_none());
    }
    // Failures still count: two more and the cell fails.
    for i in 0..2 {
        let g = store.lease_next(&w, 0, 10).await.unwrap().expect("lease");
        let out = store
            .end_attempt(g.lease, AttemptEnd::Expired, "gone", 2, 11)
            .await
            .unwrap();
        assert_eq!(
            out.cell.state,
            if i == 0 {
                CellState::Queued
            } else {
                CellState::Failed
            }
        );
    }
    let released: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM attempts WHERE state = 'released'")
            .fetch_one(store.writer())
            .await
            .unwrap();
    assert_eq!(released, 5);
}

/// Fault-injection findings: out-of-range epochs, non-finite scores and metrics, slot
/// numbers the worker never registered, terrains a sweep does not have.
async fn reports_outside_the_cell_are_refused_and_change_nothing() {
    let (_d, store, w) = setup().await;
    let sweep = store
        .create_sweep(&spec(1, 1, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    assert!(matches!(
        store.lease_next(&w, 4_000_000_000, 1).await,
        Err(Error::BadRequest(m)) if m.contains("slot 4000000000")
    ));
    let g = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
    let m = |v: f64| -> BTreeMap<String, f64> { [("kl".to_string(), v)].into() };
    for (epoch, v) in [
        (u32::MAX, 1.0),
        (0, 1.0),
        (4, 1.0),
        (1, f64::NAN),
        (1, f64::INFINITY),
    ] {
        assert!(
            matches!(
                store.record_progress(g.lease, &[(epoch, m(v))]).await,
                Err(Error::BadRequest(_))
            ),
            "epoch {epoch} value {v}"
        );
    }
    assert_eq!(store.cells(sweep.id).await.unwrap()[0].epochs_done, 0);
    let ck = CheckpointRecord {
        sha256: format!("{:064x}", 7),
        size: 1,
        epoch: 99,
    };
    assert!(matches!(
        store.record_checkpoint(g.lease, &ck, "x", 1).await,
        Err(Error::BadRequest(_))
    ));
    for bad in [f64::INFINITY, f64::NAN] {
        let mut s = score(0.5);
        s.score = bad;
        assert!(matches!(
            store.report_result(g.lease, &s, 3, None, 2).await,
            Err(Error::BadRequest(_))
        ));
        let mut s = score(0.5);
        s.fall_rate = bad;
        assert!(matches!(
            store.report_result(g.lease, &s, 3, None, 2).await,
            Err(Error::BadRequest(_))
        ));
    }
    assert!(matches!(
        store.report_result(g.lease, &score(0.5), 4, None, 2).await,
        Err(Error::BadRequest(_))
    ));
    let cell = &store.cells(sweep.id).await.unwrap()[0];
    assert_eq!(
        (cell.state, cell.score.is_none()),
        (CellState::Running, true)
    );
    store
        .report_result(g.lease, &score(0.5), 3, None, 2)
        .await
        .unwrap();
    assert!(matches!(
        store.promoted(sweep.id, Some("nosuch")).await,
        Err(Error::BadRequest(m)) if m.contains("its terrains are flat")
    ));
    assert!(store.promoted(sweep.id, Some("flat")).await.is_ok());
}

async fn replicates_promote_a_point_by_their_mean_once_all_are_done() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 1, vec![TerrainKind::Flat]);
    s.replicates = 2;
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    assert_eq!(sweep.cells_total, 4);
    let cells = store.cells(sweep.id).await.unwrap();
    let seeds: std::collections::BTreeSet<u64> = cells.iter().map(|c| c.seed).collect();
    assert_eq!(seeds.len(), 4, "every replicate has its own seed");
    // Point w1 = 0: 0.9 and 0.1 (mean 0.5); point w1 = 1: 0.6 and 0.6 (mean 0.6).
    let value = |w1: u32, r: u32| [[0.9, 0.1], [0.6, 0.6]][w1 as usize][r as usize];
    let mut reported = [0; 2];
    while let Some(g) = store.lease_next(&w, 0, 1).await.unwrap() {
        let c = g.cell.clone();
        let out = store
            .report_result(
                g.lease,
                &score(value(c.place.pair().0, c.replicate)),
                3,
                None,
                3,
            )
            .await
            .unwrap();
        reported[c.place.pair().0 as usize] += 1;
        if reported[c.place.pair().0 as usize] < 2 {
            assert!(
                out.promotions.is_empty(),
                "promoted before its other replicate reported"
            );
        } else if reported.iter().sum::<i32>() == 2 {
            assert!(
                !out.promotions.is_empty(),
                "the first complete point is promoted"
            );
        }
        for p in &out.promotions {
            assert_eq!(p.cell.place.pair().0, c.place.pair().0);
            // Point 0's best is its 0.9; point 1's replicates tie and the lower id wins.
            assert_eq!(
                p.cell.replicate, 0,
                "the point's best replicate stands for it"
            );
        }
    }
    let best = store.promoted(sweep.id, None).await.unwrap();
    assert_eq!(
        best.cell.place.pair().0,
        1,
        "mean 0.6 beats mean 0.5 despite the single 0.9"
    );
    assert_eq!(best.cell.replicate, 0, "ties go to the lower id");
    let rec = store.sweep(sweep.id).await.unwrap();
    assert_eq!(rec.best_cell, Some(best.cell.id));
}

async fn finalists_get_more_seeds_and_the_best_mean_is_promoted() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 2, vec![TerrainKind::Flat]);
    s.finalists = Some(gaitsweep_core::finalists::Finalists { top: 2, seeds: 3 });
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    assert_eq!(sweep.cells_total, 4, "the first pass is one seed per point");
    // First pass: (0,0) 0.9 and (0,1) 0.8 are the finalists; their further seeds score
    // 0.3, 0.3 (mean 0.5) and 0.7, 0.6 (mean 0.7).
    let value = |c: &CellRecord| match (c.place.pair().0, c.place.pair().1, c.replicate) {
        (0, 0, 0) => 0.9,
        (0, 0, _) => 0.3,
        (0, 1, 0) => 0.8,
        (0, 1, 1) => 0.7,
        (0, 1, _) => 0.6,
        (1, 0, _) => 0.1,
        _ => 0.2,
    };
    for _ in 0..4 {
        let g = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
        let out = store
            .report_result(g.lease, &score(value(&g.cell)), 3, None, 1)
            .await
            .unwrap();
        assert!(out.finished.is_none(), "the finalists are still to train");
    }
    let cells = store.cells(sweep.id).await.unwrap();
    assert_eq!(cells.len(), 8);
    let mut replicated = s.clone();
    replicated.finalists = None;
    replicated.replicates = 3;
    let twins = replicated.cells();
    for c in cells.iter().filter(|c| c.replicate > 0) {
        assert_eq!(c.place.pair().0, 0, "only the top 2 points get more seeds");
        let twin = twins
            .iter()
            .find(|t| (t.place, t.replicate) == (c.place, c.replicate))
            .unwrap();
        assert_eq!(
            c.seed, twin.seed,
            "a finalist trains as a replicated grid would"
        );
    }
    let mut finished = None;
    while let Some(g) = store.lease_next(&w, 0, 2).await.unwrap() {
        let out = store
            .report_result(g.lease, &score(value(&g.cell)), 3, None, 2)
            .await
            .unwrap();
        assert!(
            out.promotions.is_empty(),
            "finalists are promoted together at the end"
        );
        finished = finished.or(out.finished);
    }
    assert_eq!(finished.unwrap().state, SweepState::Done);
    let best = store.promoted(sweep.id, None).await.unwrap();
    assert_eq!(
        (
            best.cell.place.pair().0,
            best.cell.place.pair().1,
            best.cell.replicate
        ),
        (0, 1, 0),
        "mean 0.7 beats the lucky single 0.9 (mean 0.5); its best seed stands for it"
    );
    let (mean, ci95): (f64, Option<f64>) = sqlx::query_as(
        "SELECT score, ci95 FROM promotions WHERE sweep_id = $1 AND terrain = '' ORDER BY id DESC LIMIT 1",
    )
    .bind(sweep.id.0)
    .fetch_one(store.reader())
    .await
    .unwrap();
    assert!((mean - 0.7).abs() < 1e-9);
    assert!(ci95.unwrap() > 0.0);
    let on_flat = store.promoted(sweep.id, Some("flat")).await.unwrap();
    assert_eq!(on_flat.cell.id, best.cell.id);
}

/// Uploads a leased cell's checkpoint at the epoch it trains to and reports `s` there.
async fn report_at_target(
    store: &SqlStore,
    g: &super::LeaseGrant,
    s: f64,
    now: i64,
) -> super::ResultOutcome {
    let target = g.cell.target_epochs;
    let ck = CheckpointRecord {
        sha256: format!("{:064x}", g.lease.0),
        size: 10,
        epoch: target,
    };
    store
        .record_checkpoint(g.lease, &ck, "x", now)
        .await
        .unwrap();
    store
        .report_result(g.lease, &score(s), target, Some(&ck.sha256), now)
        .await
        .unwrap()
}

/// Leases the next cell and reports `s` at the epoch it trains to.
async fn train_to_target(
    store: &SqlStore,
    w: &WorkerId,
    s: f64,
    now: i64,
) -> Option<(super::LeaseGrant, super::ResultOutcome)> {
    let g = store.lease_next(w, 0, now).await.unwrap()?;
    let out = report_at_target(store, &g, s, now).await;
    Some((g, out))
}

async fn successive_halving_continues_the_top_third_and_stops_the_rest() {
    let (_d, store, w) = setup().await;
    let mut s = spec(6, 1, vec![TerrainKind::Flat]);
    s.epochs = 9;
    s.search = gaitsweep_core::Search::Asha {
        min_epochs: 1,
        reduction: 3,
    };
    assert_eq!(s.rungs(), vec![1, 3, 9]);
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    // Rung 0 (epoch 1): six cells arrive with these scores, in cell order.
    let rung0 = [0.1, 0.6, 0.3, 0.9, 0.2, 0.5];
    let mut grants = Vec::new();
    while let Some(g) = store.lease_next(&w, 0, 5).await.unwrap() {
        grants.push(g);
    }
    assert_eq!(grants.len(), 6);
    let mut decided = Vec::new();
    for (i, (sc, g)) in rung0.iter().zip(&grants).enumerate() {
        let out = report_at_target(&store, g, *sc, 10 + i as i64).await;
        assert_eq!(
            g.cell.target_epochs, 1,
            "every cell trains to the first rung"
        );
        assert!(out.promotions.is_empty(), "a rung result promotes nothing");
        decided.extend(out.decisions.iter().map(|d| (d.cell.id, d.continued)));
        // A retried report of the same rung changes nothing.
        let dup = store
            .report_result(g.lease, &score(*sc), 1, None, 99)
            .await
            .unwrap();
        assert!(dup.duplicate && dup.decisions.is_empty());
    }
    // ASHA continues a cell as soon as it is in the top floor(n/3): the second leased
    // (0.6) at n = 3; at n = 6 the top two are 0.9 and 0.6; the rung is then closed and the
    // rest stop. (A halving sweep's cells are leased in a seeded random order of the grid,
    // by id: `id(i)` is the i-th leased.)
    let id = |i: usize| grants[i].cell.id;
    assert!(grants.windows(2).all(|g| g[0].cell.id < g[1].cell.id));
    let cont: Vec<CellId> = decided.iter().filter(|d| d.1).map(|d| d.0).collect();
    assert_eq!(cont, vec![id(1), id(3)]);
    let stopped = decided.iter().filter(|d| !d.1).count();
    assert_eq!(stopped, 4);
    let cells = store.cells(sweep.id).await.unwrap();
    let state = |i: usize| cells.iter().find(|c| c.id == id(i)).unwrap().state;
    assert_eq!(
        (0..6).map(state).collect::<Vec<_>>(),
        [
            CellState::Stopped,
            CellState::Queued,
            CellState::Stopped,
            CellState::Queued,
            CellState::Stopped,
            CellState::Stopped
        ]
    );
    // Continued cells resume from their rung checkpoint towards rung 1 (epoch 3); at rung 1
    // two cells, floor(2/3) = 0, the closed rung still continues its best to the end.
    let (g, out) = train_to_target(&store, &w, 0.4, 20).await.unwrap();
    assert_eq!(
        (g.cell.target_epochs, g.resume.as_ref().map(|r| r.epoch)),
        (3, Some(1))
    );
    assert!(out.decisions.is_empty(), "rung 1 is still open");
    let (_, out) = train_to_target(&store, &w, 0.8, 21).await.unwrap();
    let d: Vec<(CellId, bool)> = out
        .decisions
        .iter()
        .map(|d| (d.cell.id, d.continued))
        .collect();
    assert_eq!(d.len(), 2);
    assert!(
        d.contains(&(id(3), true)) && d.contains(&(id(1), false)),
        "{d:?}"
    );
    // The last cell trains to the full budget, is scored and promoted; the sweep ends.
    let (g, out) = train_to_target(&store, &w, 0.7, 22).await.unwrap();
    assert_eq!(g.cell.id, id(3));
    assert_eq!(g.cell.target_epochs, 9);
    assert_eq!(out.cell.state, CellState::Done);
    assert_eq!(out.promotions[0].cell.id, id(3));
    let done = out.finished.expect("sweep finished");
    assert_eq!(
        (done.cells_done, done.cells_stopped, done.cells_paused),
        (1, 5, 0)
    );
    assert!(store.lease_next(&w, 0, 30).await.unwrap().is_none());

    // SQL: one rung row per (cell, rung) reached, one decision per (cell, rung).
    let db = store.writer();
    let evals: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM evaluations WHERE kind = 'rung'")
        .fetch_one(db)
        .await
        .unwrap();
    let decisions: Vec<(i64, i64, String)> =
        sqlx::query_as("SELECT cell_id, rung, decision FROM rung_decisions ORDER BY rung, cell_id")
            .fetch_all(db)
            .await
            .unwrap();
    assert_eq!(evals, 8);
    assert_eq!(decisions.len(), 8);
    assert_eq!(
        decisions.iter().filter(|d| d.2 == "continue").count(),
        3,
        "two past rung 0, one past rung 1"
    );
}

async fn a_cell_failing_for_good_closes_the_rung_it_never_reached() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 1, vec![TerrainKind::Flat]);
    s.epochs = 4;
    s.search = gaitsweep_core::Search::Asha {
        min_epochs: 2,
        reduction: 3,
    };
    store.create_sweep(&s, 0).await.unwrap();
    let (_, out) = train_to_target(&store, &w, 0.5, 1).await.unwrap();
    assert_eq!(out.cell.state, CellState::Paused);
    assert!(
        out.decisions.is_empty(),
        "the other cell may still reach the rung"
    );
    let g = store.lease_next(&w, 0, 2).await.unwrap().unwrap();
    let end = store
        .end_attempt(g.lease, AttemptEnd::Failed, "nan", 1, 3)
        .await
        .unwrap();
    assert_eq!(end.cell.state, CellState::Failed);
    assert_eq!(end.decisions.len(), 1);
    assert!(end.decisions[0].continued, "the rung's only cell goes on");
    let g = store.lease_next(&w, 0, 4).await.unwrap().unwrap();
    assert_eq!(g.cell.target_epochs, 4);
}

async fn the_evolutionary_search_queues_a_generation_when_the_last_one_ends() {
    let (_d, store, w) = setup().await;
    let mut s = spec(3, 3, vec![TerrainKind::Flat]);
    s.replicates = 2;
    s.search = gaitsweep_core::Search::Cmaes {
        population: 3,
        sigma: 0.3,
        generations: 2,
        min_epochs: 0,
        reduction: 0,
    };
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    let gen0 = store.cells(sweep.id).await.unwrap();
    assert_eq!(gen0.len(), 6, "3 candidates x 2 replicates");
    for c in &gen0 {
        assert_eq!((c.place.generation().unwrap().0, c.target_epochs), (0, 3));
        assert!(
            (0.0..=2.0).contains(&c.w1) && (-2.0..=0.0).contains(&c.w2),
            "{c:?}"
        );
    }
    // A candidate's replicates share its (w1, w2), and their seeds differ.
    assert_eq!((gen0[0].w1, gen0[0].w2), (gen0[1].w1, gen0[1].w2));
    assert_ne!(gen0[0].seed, gen0[1].seed);

    // Generation 0: score = w1 (the best candidate has the largest w1); one cell fails
    // for good, and its candidate still has its other replicate's score.
    let mut now = 1;
    for n in 0..6 {
        let g = store.lease_next(&w, 0, now).await.unwrap().unwrap();
        assert_eq!(g.cell.place.generation().unwrap().0, 0);
        now += 1;
        if n == 1 {
            let end = store
                .end_attempt(g.lease, AttemptEnd::Failed, "nan", 1, now)
                .await
                .unwrap();
            assert_eq!(end.cell.state, CellState::Failed);
            continue;
        }
        let out = report_at_target(&store, &g, g.cell.w1, now).await;
        assert!(out.finished.is_none(), "one more generation to go");
        let queued = store.cells(sweep.id).await.unwrap().len();
        assert_eq!(
            queued,
            if n < 5 { 6 } else { 12 },
            "generation 1 waits for all of 0"
        );
    }
    let cells = store.cells(sweep.id).await.unwrap();
    let gen1: Vec<_> = cells
        .iter()
        .filter(|c| c.place.generation().unwrap().0 == 1)
        .collect();
    assert_eq!(gen1.len(), 6);
    assert!(gen1.iter().all(|c| c.state == CellState::Queued));

    // Generation 1 ends the budget: the sweep finishes, the best candidate mean promoted.
    let mut finished = None;
    while let Some(g) = store.lease_next(&w, 0, now).await.unwrap() {
        now += 1;
        let out = report_at_target(&store, &g, g.cell.w1, now).await;
        finished = finished.or(out.finished);
    }
    let done = finished.expect("the budget's two generations end the sweep");
    assert_eq!(done.state, SweepState::Done);
    assert_eq!(store.cells(sweep.id).await.unwrap().len(), 12);
    let best = store.promoted(sweep.id, None).await.unwrap();
    let max_w1 = store
        .cells(sweep.id)
        .await
        .unwrap()
        .iter()
        .filter(|c| c.state == CellState::Done)
        .map(|c| c.w1)
        .fold(f64::MIN, f64::max);
    assert_eq!(best.cell.w1, max_w1);
}

async fn cmaes_halves_inside_each_generation() {
    let (_d, store, w) = setup().await;
    let mut s = spec(3, 3, vec![TerrainKind::Flat]);
    s.epochs = 9;
    s.search = gaitsweep_core::Search::Cmaes {
        population: 3,
        sigma: 0.3,
        generations: 2,
        min_epochs: 1,
        reduction: 3,
    };
    assert_eq!(s.rungs(), vec![1, 3, 9]);
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    let mut now = 1;
    // Generation 0 at rung 0: the best of three (score = w1) goes on, the others stop.
    let mut decided = Vec::new();
    for _ in 0..3 {
        let (g, out) = train_to_target(&store, &w, 0.0, now).await.unwrap();
        assert_eq!(
            (g.cell.place.generation().unwrap().0, g.cell.target_epochs),
            (0, 1)
        );
        decided.extend(out.decisions);
        now += 1;
    }
    assert_eq!(decided.len(), 3);
    assert_eq!(decided.iter().filter(|d| d.continued).count(), 1);
    // It trains on through rung 1 to the end; then generation 1 is queued at rung 0.
    let (g, out) = train_to_target(&store, &w, 0.5, now).await.unwrap();
    assert_eq!(g.cell.target_epochs, 3);
    assert_eq!(out.decisions.len(), 1, "alone at rung 1, it goes on");
    assert_eq!(
        store.cells(sweep.id).await.unwrap().len(),
        3,
        "generation 0 is still open"
    );
    let (g, out) = train_to_target(&store, &w, 0.7, now + 1).await.unwrap();
    assert_eq!((g.cell.target_epochs, out.cell.state), (9, CellState::Done));
    assert_eq!(out.promotions.len(), 2, "overall and on its terrain");
    let cells = store.cells(sweep.id).await.unwrap();
    assert_eq!(cells.len(), 6);
    assert!(cells[3..]
        .iter()
        .all(|c| c.place.generation().unwrap().0 == 1
            && c.state == CellState::Queued
            && c.target_epochs == 1));
    // Generation 1 repeats it; the budget's two generations end the sweep.
    let mut finished = None;
    while let Some((_, out)) = train_to_target(&store, &w, 0.1, now + 10).await {
        now += 1;
        finished = finished.or(out.finished);
    }
    let done = finished.expect("the sweep ends after generation 1");
    assert_eq!((done.cells_done, done.cells_stopped), (2, 4));
    let trained: i64 = sqlx::query_scalar("SELECT CAST(SUM(epochs_done) AS BIGINT) FROM cells")
        .fetch_one(store.writer())
        .await
        .unwrap();
    assert_eq!(
        trained,
        2 * (3 + 2 + 6),
        "each generation: 3x1 + 1x2 + 1x6 epochs"
    );
}

/// Many concurrent reports are committed together, each gets its own answer: a bad
/// value or a closed cell is refused alone and the rest of its batch is stored.
async fn concurrent_reports_share_commits_and_a_bad_one_fails_alone() {
    let (_dir, store, w) = setup_with_slots(8).await;
    store
        .create_sweep(&spec(2, 4, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    let mut leases: Vec<LeaseId> = Vec::new();
    for slot in 0..8 {
        leases.push(store.lease_next(&w, slot, 1).await.unwrap().unwrap().lease);
    }
    // The first cell is finished: its later reports are refused.
    let done = score(0.5);
    store
        .report_result(leases[0], &done, 3, None, 2)
        .await
        .unwrap();
    let before = store.write_stats();
    let report = |lease: LeaseId, k: usize| {
        let store = store.clone();
        async move {
            let value = if k == 13 { f64::NAN } else { k as f64 };
            let m: BTreeMap<String, f64> = [(format!("m{k}"), value), ("x".into(), 1.0)].into();
            store
                .record_progress(lease, &[((k % 3) as u32 + 1, m)])
                .await
        }
    };
    let calls: Vec<_> = (0..160).map(|k| report(leases[k % 8], k)).collect();
    let answers = futures::future::join_all(calls).await;
    let mut stored = 0;
    for (k, a) in answers.iter().enumerate() {
        match (k % 8, k) {
            (0, _) => assert!(matches!(a, Err(Error::CellClosed { .. })), "{k}: {a:?}"),
            (_, 13) => assert!(matches!(a, Err(Error::BadRequest(_))), "{k}: {a:?}"),
            _ => {
                assert_eq!(a.as_ref().unwrap().0, 2, "{k}");
                stored += 1;
            }
        }
    }
    let after = store.write_stats();
    assert_eq!(after.reports - before.reports, stored);
    assert!(
        after.batches - before.batches < 160 / 4,
        "reports waiting together are committed together: {before:?} -> {after:?}"
    );
    assert_eq!(after.queued, 0);
    let names: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM epoch_metrics WHERE name LIKE 'm%'")
        .fetch_one(store.reader())
        .await
        .unwrap();
    assert_eq!(names as u64, stored, "every accepted report's rows, once");
    let epochs_done: Vec<i64> = sqlx::query_scalar("SELECT epochs_done FROM cells ORDER BY id")
        .fetch_all(store.reader())
        .await
        .unwrap();
    assert_eq!(epochs_done[1..], [3; 7], "{epochs_done:?}");
}

/// Every SQL example of README's "Results in SQL" runs on the backend and returns rows,
/// on a grid sweep with replicates, metrics, evaluations, checkpoints and promotions.
async fn each_level_of_an_evaluation_is_stored() {
    let (_d, store, w) = setup().await;
    let mut sp = spec(1, 1, vec![TerrainKind::Rough]);
    sp.eval.every = 1;
    let sweep = store.create_sweep(&sp, 0).await.unwrap();
    let g = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
    // A periodic evaluation arrives as metrics, the final one as the result.
    let periodic = score_at_levels(0.2, 0.0).eval_metrics();
    store
        .record_progress(g.lease, &[(1, periodic)])
        .await
        .unwrap();
    let s = score_at_levels(0.9, 0.3);
    store.report_result(g.lease, &s, 3, None, 2).await.unwrap();
    let cells = store.cells(sweep.id).await.unwrap();
    let got = cells[0].score.clone().unwrap();
    assert!((got.score - 0.6).abs() < 1e-12);
    assert_eq!(got.levels.len(), 2, "{got:?}");
    assert_eq!(
        (got.levels[1].level, got.levels[1].score.fall_rate),
        (7, 0.5)
    );
    assert!((got.overspeed - 0.1).abs() < 1e-12);
    let rows: Vec<(i64, i64, f64)> =
        sqlx::query_as("SELECT epoch, level, score FROM level_scores ORDER BY epoch, level")
            .fetch_all(store.reader())
            .await
            .unwrap();
    assert_eq!(
        rows,
        vec![(1, 0, 0.2), (1, 7, 0.0), (3, 0, 0.9), (3, 7, 0.3)]
    );
    // A level outside 0-9 or a non-finite level score is refused, naming it.
    let mut bad = score_at_levels(0.9, 0.3);
    bad.levels[1].score.track = f64::NAN;
    let g2 = store.create_sweep(&sp, 0).await.unwrap();
    let lease = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
    assert_eq!(lease.cell.sweep_id, g2.id);
    let e = store
        .report_result(lease.lease, &bad, 3, None, 2)
        .await
        .unwrap_err();
    assert!(e.to_string().contains("levels[7].track"), "{e}");
}

async fn the_readme_queries_run() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 2, vec![TerrainKind::Flat]);
    s.w2_values = vec![-6.0, -3.0];
    s.replicates = 2;
    s.eval.every = 1;
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    assert_eq!(sweep.id.0, 1, "the README's examples query sweep 1");
    let mut k = 0.0;
    while let Some(g) = store.lease_next(&w, 0, 1).await.unwrap() {
        k += 0.1;
        let values = metrics(&[
            ("mean_step_reward", k),
            ("mean_return", 10.0 * k),
            ("eval/score", k),
            ("eval/fall_rate", 0.0),
        ]);
        store
            .record_progress(g.lease, &[(1, values.clone()), (2, values)])
            .await
            .unwrap();
        report_at_target(&store, &g, k, 2).await;
    }
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md")).unwrap();
    let section = readme
        .split("## Results in SQL:")
        .nth(1)
        .and_then(|r| r.split("\n## ").next())
        .expect("README has its SQL section");
    let mut statements = 0;
    for block in section.split("```sql").skip(1) {
        let block = block.split("```").next().unwrap();
        for sql in block.split(';').map(str::trim).filter(|q| !q.is_empty()) {
            let rows = sqlx::query(sql)
                .fetch_all(store.reader())
                .await
                .unwrap_or_else(|e| panic!("{e} in README query:\n{sql}"));
            // Sweep 1 is a grid: successive halving's decisions are empty there.
            assert!(
                !rows.is_empty() || sql.contains("rung_decisions"),
                "no rows from README query:\n{sql}"
            );
            statements += 1;
        }
    }
    assert!(statements >= 10, "{statements} README queries found");
}

/// A database of its own on the PostgreSQL server of the tests.
mod pg {
    pub async fn fresh_database() -> String {
        let server = std::env::var("GAITSWEEP_TEST_PG").expect(
            "the PostgreSQL conformance tests need a server: run scripts/test.sh (it starts a \
             throwaway one) or set GAITSWEEP_TEST_PG=postgres://user@host:port/postgres",
        );
        let name = super::backend::unique_database_name("gs_store");
        super::backend::create_postgres_database(&server, &name)
            .await
            .unwrap()
    }
}

/// A database written before `generation` and `candidate` existed: an evolutionary
/// sweep's candidates (stored then as `w1_index` = generation, `w2_index` = number) move
/// to their own columns, a grid's cells keep theirs, and both read back as their place.
async fn old_candidates_move_to_their_own_columns() {
    use gaitsweep_core::Place;
    use sqlx::{Connection, Executor};
    let dir = tempfile::tempdir().unwrap();
    let backend = BACKEND.try_with(|b| *b).unwrap_or(Backend::Sqlite);
    let (url, migrator) = match backend {
        Backend::Sqlite => (
            DatabaseUrl::Sqlite(dir.path().join("db.sqlite")),
            &super::sql::MIGRATOR,
        ),
        Backend::Postgres => (
            DatabaseUrl::Postgres(pg::fresh_database().await),
            &super::sql::PG_MIGRATOR,
        ),
    };
    let before = sqlx::migrate::Migrator {
        migrations: migrator
            .iter()
            .filter(|m| m.version < 20261204000000)
            .cloned()
            .collect::<Vec<_>>()
            .into(),
        ..sqlx::migrate::Migrator::DEFAULT
    };
    sqlx::any::install_default_drivers();
    let conn_url = match &url {
        DatabaseUrl::Sqlite(p) => format!("sqlite://{}?mode=rwc", p.display()),
        DatabaseUrl::Postgres(u) => u.clone(),
    };
    let mut conn = sqlx::AnyConnection::connect(&conn_url).await.unwrap();
    if backend == Backend::Sqlite {
        conn.execute("PRAGMA foreign_keys = OFF").await.unwrap();
    }
    before.run(&mut conn).await.unwrap();
    let mut grid = spec(2, 2, vec![TerrainKind::Flat]);
    grid.name = "grid".into();
    let mut cmaes = grid.clone();
    cmaes.name = "cmaes".into();
    cmaes.search = gaitsweep_core::Search::Cmaes {
        population: 2,
        sigma: 0.3,
        generations: 2,
        min_epochs: 0,
        reduction: 0,
    };
    for (id, s) in [(1i64, &grid), (2, &cmaes)] {
        sqlx::query(
            "INSERT INTO sweeps (id, name, robot, spec_json, state, created_unix_ms) \
             VALUES ($1, $2, 'anymal', $3, 'running', 0)",
        )
        .bind(id)
        .bind(&s.name)
        .bind(serde_json::to_string(s).unwrap())
        .execute(&mut conn)
        .await
        .unwrap();
        for (i, j) in [(0i64, 1i64), (1, 0)] {
            sqlx::query(
                "INSERT INTO cells (sweep_id, terrain_index, terrain, w1_index, w2_index, w1, w2, \
                 seed, state, target_epochs) VALUES ($1, 0, 'flat', $2, $3, 1.5, -3.0, 7, 'queued', 3)",
            )
            .bind(id)
            .bind(i)
            .bind(j)
            .execute(&mut conn)
            .await
            .unwrap();
        }
    }
    conn.close().await.unwrap();

    let store = SqlStore::connect(&url).await.unwrap();
    let places = |cells: Vec<gaitsweep_core::records::CellRecord>| {
        cells.into_iter().map(|c| c.place).collect::<Vec<_>>()
    };
    assert_eq!(
        places(store.cells(SweepId(1)).await.unwrap()),
        vec![Place::point(0, 1), Place::point(1, 0)]
    );
    let mut moved = places(store.cells(SweepId(2)).await.unwrap());
    moved.sort();
    assert_eq!(moved, vec![Place::candidate(0, 1), Place::candidate(1, 0)]);
    // The columns say one place each: a row with both pairs, or neither, is refused.
    for (a, b, g, k) in [
        (Some(0i64), Some(0i64), Some(2i64), Some(0i64)),
        (None, None, None, None),
    ] {
        let refused = sqlx::query(
            "INSERT INTO cells (sweep_id, terrain_index, terrain, w1_index, w2_index, generation, \
             candidate, w1, w2, seed, state, target_epochs) \
             VALUES (2, 0, 'flat', $1, $2, $3, $4, 1.0, -1.0, 1, 'queued', 3)",
        )
        .bind(a)
        .bind(b)
        .bind(g)
        .bind(k)
        .execute(store.writer())
        .await;
        assert!(
            refused.is_err(),
            "a cell at {a:?} {b:?} {g:?} {k:?} was stored"
        );
    }
}

tokio::task_local! {
    /// The backend `setup` opens (SQLite unless a conformance test says otherwise).
    static BACKEND: Backend;
}

async fn never_rewarded_cells_are_the_done_ones_with_zero_reward() {
    let (_d, store, w) = setup().await;
    let sweep = store
        .create_sweep(&spec(3, 1, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    // Cell 1: 0 at every epoch, done. Cell 2: rewarded once, done. Cell 3: 0 so far, running.
    let first = store.cells(sweep.id).await.unwrap()[0].id;
    for (k, rewards) in [[0.0, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.0]]
        .iter()
        .enumerate()
    {
        let g = store.lease_next(&w, 0, 1).await.unwrap().expect("lease");
        assert_eq!(g.cell.id.0, first.0 + k as i64, "cells are leased in order");
        let epochs: Vec<(u32, BTreeMap<String, f64>)> = rewards
            .iter()
            .enumerate()
            .map(|(e, r)| (e as u32 + 1, [("mean_step_reward".to_string(), *r)].into()))
            .collect();
        store.record_progress(g.lease, &epochs).await.unwrap();
        if k < 2 {
            store
                .report_result(g.lease, &score(0.5), 3, None, 2)
                .await
                .unwrap();
        }
    }
    assert_eq!(
        store.never_rewarded(sweep.id).await.unwrap(),
        vec![first],
        "the running cell is not judged yet, the rewarded one never"
    );
}

/// A run resumed from a checkpoint does not replay its epochs bit for bit: an attempt killed
/// after its first reward can be followed by one that stays unrewarded and stops early. The
/// cell's rows are then the run that finished, not the killed attempt's later epochs.
async fn a_cell_stopped_early_keeps_no_rows_of_a_killed_attempts_later_epochs() {
    let (_d, store, w) = setup().await;
    let mut s = spec(1, 1, vec![TerrainKind::Flat]);
    s.eval.every = 1;
    store.create_sweep(&s, 0).await.unwrap();
    // Each evaluation with its level 3 (`level_scores`).
    let epoch = |reward: f64, score: f64| {
        metrics(&[
            ("mean_step_reward", reward),
            ("eval/score", score),
            ("eval/fall_rate", 0.5),
            ("eval/level/3/score", score),
            ("eval/level/3/fall_rate", 0.5),
        ])
    };
    let g = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
    store
        .record_progress(
            g.lease,
            &[
                (1, epoch(0.0, 0.1)),
                (2, epoch(0.0, 0.1)),
                (3, epoch(0.2, 0.4)),
            ],
        )
        .await
        .unwrap();
    store
        .end_attempt(g.lease, AttemptEnd::Failed, "killed", 3, 2)
        .await
        .unwrap();
    let g2 = store.lease_next(&w, 0, 3).await.unwrap().unwrap();
    assert_eq!(g2.cell.id, g.cell.id);
    store
        .record_progress(g2.lease, &[(1, epoch(0.0, 0.1)), (2, epoch(0.0, 0.2))])
        .await
        .unwrap();
    let count = |sql: &'static str| {
        let store = &store;
        async move {
            let n: i64 = sqlx::query_scalar(sql)
                .bind(g.cell.id.0)
                .fetch_one(store.reader())
                .await
                .unwrap();
            n
        }
    };
    const METRICS: &str = "SELECT COUNT(*) FROM epoch_metrics WHERE cell_id = $1 AND epoch > 2";
    const EVALS: &str = "SELECT COUNT(*) FROM evaluations WHERE cell_id = $1 AND epoch > 2";
    const LEVELS: &str = "SELECT COUNT(*) FROM level_scores WHERE cell_id = $1 AND epoch > 2";
    assert!(
        count(METRICS).await > 0,
        "the killed attempt's epoch 3 is there while the cell runs"
    );
    assert_eq!((count(EVALS).await, count(LEVELS).await), (1, 1));
    // Stopped as never rewarded at epoch 2 of 3.
    let out = store
        .report_result(g2.lease, &score(0.5), 2, None, 4)
        .await
        .unwrap();
    assert_eq!(
        out.cell.epochs_done, 2,
        "a done cell has trained the epochs it was scored at"
    );
    assert_eq!(
        count(METRICS).await,
        0,
        "no metric past the epoch the result was trained to"
    );
    assert_eq!(count(EVALS).await, 0, "no evaluation past it either");
    assert_eq!(count(LEVELS).await, 0, "nor its levels");
    assert_eq!(
        count("SELECT COUNT(*) FROM evaluations WHERE cell_id = $1").await,
        2,
        "the finished run's own evaluations stay"
    );
    assert_eq!(
        store.never_rewarded(out.cell.sweep_id).await.unwrap(),
        vec![g.cell.id],
        "the run that finished was never rewarded"
    );
}

/// Named metric values, as a worker reports one epoch's.
fn metrics(values: &[(&str, f64)]) -> BTreeMap<String, f64> {
    values.iter().map(|&(n, v)| (n.to_string(), v)).collect()
}

/// Runs every listed test on SQLite and on PostgreSQL (`sqlite::NAME`, `postgres::NAME`).
macro_rules! conformance {
    ($($name:ident),* $(,)?) => {
        mod sqlite {
            $(
                #[tokio::test]
                async fn $name() {
                    super::BACKEND.scope(super::Backend::Sqlite, super::$name()).await
                }
            )*
        }
        mod postgres {
            $(
                #[tokio::test]
                async fn $name() {
                    super::BACKEND.scope(super::Backend::Postgres, super::$name()).await
                }
            )*
        }
    };
}

conformance!(
    expired_cells_are_retried_then_failed,
    results_are_idempotent_and_promote_the_best,
    resume_points_at_the_latest_checkpoint_and_cancel_stops_all,
    a_retried_attempt_replaces_its_periodic_evaluations,
    a_failed_cell_stays_failed,
    released_attempts_requeue_at_once_and_do_not_count,
    reports_outside_the_cell_are_refused_and_change_nothing,
    replicates_promote_a_point_by_their_mean_once_all_are_done,
    finalists_get_more_seeds_and_the_best_mean_is_promoted,
    successive_halving_continues_the_top_third_and_stops_the_rest,
    a_cell_failing_for_good_closes_the_rung_it_never_reached,
    the_evolutionary_search_queues_a_generation_when_the_last_one_ends,
    cmaes_halves_inside_each_generation,
    concurrent_reports_share_commits_and_a_bad_one_fails_alone,
    each_level_of_an_evaluation_is_stored,
    the_readme_queries_run,
    old_candidates_move_to_their_own_columns,
    never_rewarded_cells_are_the_done_ones_with_zero_reward,
    a_cell_stopped_early_keeps_no_rows_of_a_killed_attempts_later_epochs,
);
