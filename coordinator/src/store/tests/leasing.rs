//! Leasing, expiry and retries, idempotent reports, checkpoints, cancellation, and reports
//! a cell must refuse.

use super::*;

pub(super) async fn expired_cells_are_retried_then_failed() {
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

pub(super) async fn results_are_idempotent_and_promote_the_best() {
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

pub(super) async fn resume_points_at_the_latest_checkpoint_and_cancel_stops_all() {
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
pub(super) async fn a_retried_attempt_replaces_its_periodic_evaluations() {
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
pub(super) async fn a_failed_cell_stays_failed() {
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
pub(super) async fn released_attempts_requeue_at_once_and_do_not_count() {
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
pub(super) async fn reports_outside_the_cell_are_refused_and_change_nothing() {
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
