//! The store's conformance suite: leasing, expiry and retries, idempotent reports,
//! promotion, cancellation, successive halving, the evolutionary search and group commits,
//! each run on a real SQLite file and on a real PostgreSQL server (a database of its own per
//! test on the server `GAITSWEEP_TEST_PG` names; `scripts/test.sh` starts a throwaway one).
//! A test that needs one backend's internals (SQLite's page limit) runs on that one only.

mod leasing;
mod search;
mod storage;

use super::*;
use crate::Error;
use gaitsweep_core::{CellState, SweepState};
use gaitsweep_model::{LevelScore, TerrainKind};
use leasing::*;
use search::*;
use storage::*;

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

tokio::task_local! {
    /// The backend `setup` opens (SQLite unless a conformance test says otherwise).
    static BACKEND: Backend;
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
    a_point_never_rewarded_is_no_finalist,
    finalists_on_two_terrains_feed_the_promotion_across_them,
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
    attempt_spans_count_each_leases_epochs,
);
