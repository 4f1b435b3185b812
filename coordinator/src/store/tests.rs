//! Storage tests on a real SQLite file: leasing, expiry and retries, idempotent reports,
//! promotion, cancellation.

use super::*;
use crate::Error;
use gaitsweep_core::{CellState, SweepState};
use gaitsweep_sim::TerrainKind;

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
        ppo_overrides: Default::default(),
        eval_robots: 0,
        eval_seconds: 0.0,
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
    }
}

async fn setup() -> (tempfile::TempDir, SqliteStore, WorkerId) {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("db.sqlite"))
        .await
        .unwrap();
    let w = WorkerId("w1".into());
    let info = WorkerInfo {
        hostname: "h".into(),
        cores: 2,
        device: "cpu".into(),
        slots: 1,
        version: "t".into(),
    };
    store.register_worker(&w, &info, 0).await.unwrap();
    (dir, store, w)
}

#[tokio::test]
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

#[tokio::test]
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

#[tokio::test]
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
