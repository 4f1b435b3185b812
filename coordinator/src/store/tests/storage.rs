//! Group commits, per-level evaluations, the README's queries, old databases' migrations,
//! never-rewarded cells and what an early stop keeps.

use super::*;

/// Many concurrent reports are committed together, each gets its own answer: a bad
/// value or a closed cell is refused alone and the rest of its batch is stored.
pub(super) async fn concurrent_reports_share_commits_and_a_bad_one_fails_alone() {
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
pub(super) async fn each_level_of_an_evaluation_is_stored() {
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

pub(super) async fn the_readme_queries_run() {
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

/// A database written before `generation` and `candidate` existed: an evolutionary
/// sweep's candidates (stored then as `w1_index` = generation, `w2_index` = number) move
/// to their own columns, a grid's cells keep theirs, and both read back as their place.
pub(super) async fn old_candidates_move_to_their_own_columns() {
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

pub(super) async fn never_rewarded_cells_are_the_done_ones_with_zero_reward() {
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
pub(super) async fn a_cell_stopped_early_keeps_no_rows_of_a_killed_attempts_later_epochs() {
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

/// The live page's speed reads each attempt's wall time and the epochs it trained: a done
/// one to its last reported epoch, a released one too, a running one to its cell's epoch.
pub(super) async fn attempt_spans_count_each_leases_epochs() {
    let (_d, store, w) = setup().await;
    let sweep = store
        .create_sweep(&spec(2, 1, vec![TerrainKind::Flat]), 0)
        .await
        .unwrap();
    let reward = |e: u32| (e, metrics(&[("mean_step_reward", 0.1)]));
    // Cell 1: leased at 1,000, 2 epochs and a checkpoint, released at 3,000; leased again
    // at 4,000, resumed at epoch 2, its third epoch, done at 6,000. Cell 2: leased at 7,000, 2 epochs so far.
    let g = store.lease_next(&w, 0, 1_000).await.unwrap().unwrap();
    store
        .record_progress(g.lease, &[reward(1), reward(2)])
        .await
        .unwrap();
    let ck = CheckpointRecord {
        sha256: "a".repeat(64),
        size: 10,
        epoch: 2,
    };
    store
        .record_checkpoint(g.lease, &ck, "x", 2_500)
        .await
        .unwrap();
    store
        .end_attempt(
            g.lease,
            AttemptEnd::Released,
            "released: worker stopping",
            2,
            3_000,
        )
        .await
        .unwrap();
    let g = store.lease_next(&w, 0, 4_000).await.unwrap().unwrap();
    assert_eq!(
        g.resume.as_ref().map(|c| c.epoch),
        Some(2),
        "resumed from its checkpoint"
    );
    store.record_progress(g.lease, &[reward(3)]).await.unwrap();
    report_at_target(&store, &g, 0.5, 6_000).await;
    let g = store.lease_next(&w, 0, 7_000).await.unwrap().unwrap();
    store
        .record_progress(g.lease, &[reward(1), reward(2)])
        .await
        .unwrap();
    let span = |started_ms, ended_ms, epochs| queries::AttemptSpan {
        started_ms,
        ended_ms,
        epochs,
    };
    assert_eq!(
        queries::attempt_spans(store.reader(), sweep.id, 0)
            .await
            .unwrap(),
        [
            span(1_000, Some(3_000), 2),
            span(4_000, Some(6_000), 1),
            span(7_000, None, 2)
        ]
    );
    assert_eq!(
        queries::attempt_spans(store.reader(), sweep.id, 5_000)
            .await
            .unwrap(),
        [span(4_000, Some(6_000), 1), span(7_000, None, 2)],
        "attempts ended before the window are left out"
    );
}
