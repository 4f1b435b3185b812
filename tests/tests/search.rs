//! Search strategies on real processes: a successive-halving (ASHA) sweep trains every cell
//! to its first rung, continues the best from its rung checkpoint to the end, stops the
//! rest, and records every rung evaluation and decision in SQL.

mod common;

use common::*;
use gaitsweep_core::pb;
use std::time::Duration;

const SWEEP_TIMEOUT: Duration = Duration::from_secs(600);

/// The cell promoted over all terrains, from SQL.
async fn promoted_cell(db: &sqlx::AnyPool, sweep: i64) -> i64 {
    sqlx::query_scalar(
        "SELECT cell_id FROM promotions WHERE sweep_id = $1 AND terrain = '' ORDER BY id DESC LIMIT 1",
    )
    .bind(sweep)
    .fetch_one(db)
    .await
    .unwrap()
}

/// `coordinator show SWEEP`'s output; panics if it fails.
fn show(coord: &Coord, sweep: i64) -> String {
    let out = std::process::Command::new(bin("coordinator"))
        .args(["show", "--connect", &coord.url(), &sweep.to_string()])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "show failed: {text}");
    text
}

/// `coordinator report SWEEP --no-gif` into `out`; its index.html. Panics if it fails.
fn report(coord: &Coord, sweep: i64, out: &std::path::Path) -> String {
    let run = std::process::Command::new(bin("coordinator"))
        .args(["report", &sweep.to_string(), "--no-gif", "--data-dir"])
        .arg(&coord.data)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "coordinator report: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    std::fs::read_to_string(out.join("index.html")).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn asha_continues_the_best_cell_from_its_rung_and_stops_the_rest() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(tmp.path(), "127.0.0.1:0", &[]).await;
    let mut c = coord.sweeps().await;
    let spec = "name = \"asha\"\nrobot = \"anymal\"\nterrains = [\"flat\"]\n\
                w1 = { values = [2.0, 5.0, 8.0] }\nw2 = { values = [-6.0] }\n\
                agents_per_cell = 4\nepochs = 3\ncheckpoint_every = 1\nseed = 3\n\
                eval = { robots = 2, seconds = 1.0, every = 2 }\n\
                [search]\nmethod = \"asha\"\nmin_epochs = 1\nreduction = 3\n";
    let sweep = create(&mut c, spec.to_string()).await;
    assert_eq!(sweep.cells_total, 3);
    let w = start_worker(tmp.path(), &coord.url(), "a");
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(
        (
            done.state,
            done.cells_done,
            done.cells_stopped,
            done.cells_paused
        ),
        (pb::SweepState::Done as i32, 1, 2, 0)
    );

    let db = coord.db().await;
    // Every cell was evaluated at rung 0 (epoch 1) from its own training.
    let rung0: Vec<(i64, f64, i64)> = sqlx::query_as(
        "SELECT e.cell_id, e.score, e.robots FROM evaluations e WHERE e.kind = 'rung' AND e.epoch = 1 ORDER BY e.cell_id",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(rung0.len(), 3);
    assert!(
        rung0.iter().all(|r| r.2 == 2),
        "rung evaluations use the spec's robots"
    );
    // The best of rung 0 (ties to the lower id) continued, the others stopped.
    let best = rung0
        .iter()
        .fold(None::<(i64, f64)>, |b, r| match b {
            Some((_, s)) if s >= r.1 => b,
            _ => Some((r.0, r.1)),
        })
        .unwrap()
        .0;
    let decisions: Vec<(i64, i64, i64, String)> = sqlx::query_as(
        "SELECT cell_id, rung, epoch, decision FROM rung_decisions ORDER BY cell_id",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(decisions.len(), 3, "{decisions:?}");
    for (cell, rung, epoch, d) in &decisions {
        assert_eq!((*rung, *epoch), (0, 1));
        assert_eq!(
            d,
            if *cell == best { "continue" } else { "stop" },
            "{decisions:?}"
        );
    }
    // The continued cell resumed from its rung checkpoint, logged a periodic evaluation at
    // epoch 2 and was scored at the full budget; stopped cells keep their rung epoch.
    let resumed: Vec<i64> = sqlx::query_scalar(
        "SELECT resumed_from_epoch FROM attempts WHERE cell_id = $1 AND state = 'done' ORDER BY id",
    )
    .bind(best)
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(resumed, vec![0, 1]);
    let periodic: Vec<i64> = sqlx::query_scalar(
        "SELECT epoch FROM evaluations WHERE kind = 'periodic' AND cell_id = $1",
    )
    .bind(best)
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(periodic, vec![2]);
    let cells: Vec<(i64, String, i64, Option<i64>)> = sqlx::query_as(
        "SELECT c.id, c.state, c.epochs_done, s.epochs FROM cells c LEFT JOIN scores s ON s.cell_id = c.id ORDER BY c.id",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    for (id, state, epochs_done, scored) in &cells {
        if *id == best {
            assert_eq!(
                (state.as_str(), *epochs_done, *scored),
                ("done", 3, Some(3))
            );
        } else {
            assert_eq!(
                (state.as_str(), *epochs_done, *scored),
                ("stopped", 1, None)
            );
        }
    }
    let promoted = promoted_cell(&db, sweep.sweep_id).await;
    assert_eq!(promoted, best);
    // Five of the grid's nine epochs were trained.
    let trained: i64 = sqlx::query_scalar("SELECT SUM(epochs_done) FROM cells")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(trained, 5);

    let text = show(&coord, sweep.sweep_id);
    // A stopped cell shows the rung it stopped at and the score it stopped with.
    for (_, score, _) in rung0.iter().filter(|r| r.0 != best) {
        let shown = format!("stopped@1: {score:.3}");
        assert!(
            text.contains(&shown),
            "{shown} missing from show output: {text}"
        );
    }
}

/// Item 6 of the search issue: a worker killed while a continued cell trains towards its
/// next rung and a coordinator restarted between two rungs lose nothing and take no
/// decision twice.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn asha_survives_a_killed_worker_and_a_restarted_coordinator_between_rungs() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let args = ["--lease-seconds", "2", "--http", "127.0.0.1:0"];
    let mut coord = Coord::start(tmp.path(), "127.0.0.1:0", &args).await;
    let addr = coord.addr.clone();
    let mut c = coord.sweeps().await;
    let spec = "name = \"asha-faults\"\nrobot = \"anymal\"\nterrains = [\"flat\"]\n\
                w1 = { values = [2.0, 5.0, 8.0] }\nw2 = { values = [-6.0] }\n\
                agents_per_cell = 4\nepochs = 40\ncheckpoint_every = 1\nseed = 3\n\
                eval = { robots = 2, seconds = 1.0 }\n\
                [search]\nmethod = \"asha\"\nmin_epochs = 10\nreduction = 3\n";
    let sweep = create(&mut c, spec.to_string()).await;
    let mut a = start_worker(tmp.path(), &coord.url(), "a");
    let db = coord.db().await;
    wait_for_at_least(
        &db,
        "the first rung decisions",
        SWEEP_TIMEOUT,
        "SELECT COUNT(*) FROM rung_decisions",
        3,
    )
    .await;
    a.kill();
    db.close().await;
    coord.proc.kill();
    let coord = Coord::start(tmp.path(), &addr, &args).await;
    let b = start_worker(tmp.path(), &coord.url(), "b");
    let done = wait_done(
        &coord,
        sweep.sweep_id,
        SWEEP_TIMEOUT,
        &[&coord.proc, &a, &b],
    )
    .await;
    assert_eq!(
        (done.state, done.cells_done, done.cells_stopped),
        (pb::SweepState::Done as i32, 1, 2)
    );
    let db = coord.db().await;
    // Rung 0 (epoch 10): three decisions; rung 1 (epoch 30): the only cell there goes on.
    let decisions: Vec<(i64, i64, String)> =
        sqlx::query_as("SELECT cell_id, rung, decision FROM rung_decisions ORDER BY rung, cell_id")
            .fetch_all(&db)
            .await
            .unwrap();
    assert_eq!(decisions.len(), 4, "{decisions:?}");
    assert_eq!(decisions.iter().filter(|d| d.2 == "continue").count(), 2);
    let best = decisions[3].0;
    assert_eq!((decisions[3].1, decisions[3].2.as_str()), (1, "continue"));
    let evals: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM evaluations WHERE kind = 'rung'")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(evals, 4, "three at rung 0, one at rung 1");
    let (epochs, scores): (i64, i64) =
        sqlx::query_as("SELECT MAX(epochs), COUNT(*) FROM scores WHERE cell_id = $1")
            .bind(best)
            .fetch_one(&db)
            .await
            .unwrap();
    assert_eq!((epochs, scores), (40, 1));
    // The continued cell's epochs were trained once each, across its attempts.
    let metrics: i64 =
        sqlx::query_scalar("SELECT COUNT(DISTINCT epoch) FROM epoch_metrics WHERE cell_id = $1")
            .bind(best)
            .fetch_one(&db)
            .await
            .unwrap();
    assert_eq!(metrics, 40);
}

/// An evolutionary sweep of `spec` on real processes, interrupted once: generation 0 trains
/// on a worker until generation 1 is queued, then that worker and the coordinator are killed
/// and a new coordinator on the same data dir finishes the sweep with a new worker. Returns
/// the temp dir, the live coordinator, the sweep as created and as finished.
async fn run_across_a_restart(spec: &str) -> (tempfile::TempDir, Coord, pb::Sweep, pb::Sweep) {
    let tmp = tempfile::tempdir().unwrap();
    let args = ["--lease-seconds", "2", "--http", "127.0.0.1:0"];
    let mut coord = Coord::start(tmp.path(), "127.0.0.1:0", &args).await;
    let addr = coord.addr.clone();
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, spec.to_string()).await;
    assert_eq!(sweep.cells_total, 2, "generation 0 only");
    let mut a = start_worker(tmp.path(), &coord.url(), "a");
    let db = coord.db().await;
    wait_for_at_least(
        &db,
        "generation 1 to be queued",
        SWEEP_TIMEOUT,
        "SELECT COUNT(*) FROM cells WHERE generation = 1",
        2,
    )
    .await;
    a.kill();
    db.close().await;
    coord.proc.kill();
    let coord = Coord::start(tmp.path(), &addr, &args).await;
    let b = start_worker(tmp.path(), &coord.url(), "b");
    let done = wait_done(
        &coord,
        sweep.sweep_id,
        SWEEP_TIMEOUT,
        &[&coord.proc, &a, &b],
    )
    .await;
    (tmp, coord, sweep, done)
}

/// The evolutionary search end to end: CMA-ES proposes each generation once the last one
/// has ended; a worker killed and the coordinator restarted between two generations lose
/// nothing and ask for no generation twice; the best candidate is promoted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cmaes_trains_generation_after_generation_across_a_restart() {
    let _g = heavy().await;
    let spec = "name = \"cmaes\"\nrobot = \"anymal\"\nterrains = [\"flat\"]\n\
                w1 = { min = 2.0, max = 12.0, count = 2 }\nw2 = { values = [-10.0, -2.0] }\n\
                agents_per_cell = 4\nepochs = 10\ncheckpoint_every = 1\nseed = 5\n\
                eval = { robots = 2, seconds = 1.0 }\n\
                [search]\nmethod = \"cmaes\"\npopulation = 2\nbudget_epochs = 60\n";
    let (_tmp, coord, sweep, done) = run_across_a_restart(spec).await;
    assert_eq!(
        (done.state, done.cells_total, done.cells_done),
        (pb::SweepState::Done as i32, 6, 6),
        "60 epochs pay for 3 generations of 2 candidates x 10 epochs"
    );
    let db = coord.db().await;
    // Candidates are stored by generation and number, never as grid indices.
    let cells: Vec<(i64, i64, i64, f64, f64, f64)> = sqlx::query_as(
        "SELECT c.id, c.generation, c.candidate, c.w1, c.w2, s.score FROM cells c JOIN scores s ON s.cell_id = c.id \
         WHERE c.w1_index IS NULL AND c.w2_index IS NULL ORDER BY c.generation, c.candidate",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    let keys: Vec<(i64, i64)> = cells.iter().map(|c| (c.1, c.2)).collect();
    assert_eq!(keys, vec![(0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (2, 1)]);
    for c in &cells {
        assert!(
            (2.0..=12.0).contains(&c.3) && (-10.0..=-2.0).contains(&c.4),
            "candidate outside the axes' ranges: {c:?}"
        );
    }
    let distinct: std::collections::BTreeSet<(u64, u64)> = cells
        .iter()
        .map(|c| (c.3.to_bits(), c.4.to_bits()))
        .collect();
    assert_eq!(
        distinct.len(),
        6,
        "every candidate is a new point: {cells:?}"
    );
    let best = cells
        .iter()
        .fold(None::<(i64, f64)>, |b, c| match b {
            Some((_, s)) if s >= c.5 => b,
            _ => Some((c.0, c.5)),
        })
        .unwrap()
        .0;
    let promoted = promoted_cell(&db, sweep.sweep_id).await;
    assert_eq!(promoted, best);
    let trained: i64 = sqlx::query_scalar("SELECT SUM(epochs_done) FROM cells")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(trained, 60);

    let text = show(&coord, sweep.sweep_id);
    assert!(text.contains("generation"), "show output: {text}");
    // `show` lists the candidates by generation and number and marks the promoted one.
    let (g, k) = cells
        .iter()
        .find(|c| c.0 == best)
        .map(|c| (c.1, c.2))
        .unwrap();
    let row = format!("{g:>10} {k:>9}");
    assert!(
        text.lines().any(|l| l.starts_with(&row) && l.contains('*')),
        "no marked row for generation {g} candidate {k}: {text}"
    );
    // The live API lays the candidates out by generation and number, never as grid points.
    let http = std::fs::read_to_string(coord.data.join("http.addr")).unwrap();
    let (status, body) = http_get(
        http.trim(),
        &format!("/api/sweeps/{}", sweep.sweep_id),
        None,
    );
    assert!(status.contains("200"), "{status}");
    let api: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(api["layout"], "candidates");
    let mut places: Vec<(i64, i64)> = api["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            assert!(c["w1_index"].is_null() && c["w2_index"].is_null(), "{c}");
            (
                c["generation"].as_i64().unwrap(),
                c["candidate"].as_i64().unwrap(),
            )
        })
        .collect();
    places.sort_unstable();
    assert_eq!(
        places,
        keys.iter().map(|&(g, k)| (g, k)).collect::<Vec<_>>()
    );
}

/// The genetic algorithm end to end, with successive halving inside each generation: each
/// generation trains grid points nobody trained before, halves them at the first rung and
/// breeds the next from the scores; a coordinator restarted between generations asks for
/// the same generation (no point twice, no rung decided twice); the budget ends the search
/// once the grid is spent; the best candidate trained to the end is promoted, and the
/// report draws the candidates.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn genetic_breeds_grid_points_generation_after_generation_across_a_restart() {
    let _g = heavy().await;
    let spec = "name = \"genetic\"\nrobot = \"anymal\"\nterrains = [\"flat\"]\n\
                w1 = { min = 2.0, max = 12.0, count = 2 }\nw2 = { values = [-10.0, -6.0, -2.0] }\n\
                agents_per_cell = 4\nepochs = 10\ncheckpoint_every = 1\nseed = 9\n\
                eval = { robots = 2, seconds = 1.0 }\n\
                [search]\nmethod = \"genetic\"\npopulation = 2\nmin_epochs = 5\nreduction = 2\nbudget_epochs = 45\n";
    let (tmp, coord, sweep, done) = run_across_a_restart(spec).await;
    assert_eq!(
        (done.state, done.cells_total),
        (pb::SweepState::Done as i32, 6),
        "3 generations of 2 grid points"
    );
    let db = coord.db().await;
    let cells: Vec<(i64, i64, i64, f64, f64, String, i64)> = sqlx::query_as(
        "SELECT id, generation, candidate, w1, w2, state, epochs_done FROM cells \
         WHERE w1_index IS NULL ORDER BY generation, candidate",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    let keys: Vec<(i64, i64)> = cells.iter().map(|c| (c.1, c.2)).collect();
    assert_eq!(keys, vec![(0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (2, 1)]);
    let points: std::collections::BTreeSet<(u64, u64)> = cells
        .iter()
        .map(|c| (c.3.to_bits(), c.4.to_bits()))
        .collect();
    let grid: std::collections::BTreeSet<(u64, u64)> = [2.0f64, 12.0]
        .iter()
        .flat_map(|&w1| [-10.0f64, -6.0, -2.0].map(|w2| (w1.to_bits(), w2.to_bits())))
        .collect();
    assert_eq!(points, grid, "every grid point trained once: {cells:?}");
    // Each generation: one candidate continued to the end, one stopped at the rung.
    let decisions: Vec<(i64, i64, String)> =
        sqlx::query_as("SELECT cell_id, rung, decision FROM rung_decisions ORDER BY cell_id")
            .fetch_all(&db)
            .await
            .unwrap();
    assert_eq!(decisions.len(), 6, "one decision per cell: {decisions:?}");
    assert!(decisions.iter().all(|d| d.1 == 0));
    for g in 0..3 {
        let states: Vec<&str> = cells
            .iter()
            .filter(|c| c.1 == g)
            .map(|c| c.5.as_str())
            .collect();
        let mut sorted = states.clone();
        sorted.sort();
        assert_eq!(sorted, vec!["done", "stopped"], "generation {g}: {cells:?}");
    }
    let trained: i64 = cells.iter().map(|c| c.6).sum();
    assert_eq!(trained, 45);
    let best: i64 = sqlx::query_scalar(
        "SELECT s.cell_id FROM scores s ORDER BY s.score DESC, s.cell_id LIMIT 1",
    )
    .fetch_one(&db)
    .await
    .unwrap();
    assert_eq!(promoted_cell(&db, sweep.sweep_id).await, best);

    let text = show(&coord, sweep.sweep_id);
    assert!(
        text.contains("evolutionary search (genetic algorithm)"),
        "show output: {text}"
    );
    let out = tmp.path().join("report");
    let html = report(&coord, sweep.sweep_id, &out);
    assert!(
        html.contains("genetic algorithm"),
        "report: {}",
        tail(&html, 2000)
    );
    assert!(out.join("candidates_flat.png").exists());
}

/// Issue 41 item 4 on real processes: a random search trains the grid points its seed
/// draws (the draw search-bench replays), and nothing else, to the end; the best of them
/// is promoted; `show` and the report lay it out as a grid with the undrawn points empty.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn random_search_trains_the_points_its_seed_draws_and_promotes_the_best() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(tmp.path(), "127.0.0.1:0", &[]).await;
    let mut c = coord.sweeps().await;
    // 3 x 2 points of 2 epochs: a budget of 4 epochs draws 2 points.
    let spec = "name = \"random\"\nrobot = \"anymal\"\nterrains = [\"flat\"]\n\
                w1 = { values = [2.0, 5.0, 8.0] }\nw2 = { values = [-6.0, -4.0] }\n\
                agents_per_cell = 4\nepochs = 2\ncheckpoint_every = 1\nseed = 11\n\
                eval = { robots = 2, seconds = 1.0 }\n\
                [search]\nmethod = \"random\"\nbudget_epochs = 4\n";
    let sweep = create(&mut c, spec.to_string()).await;
    assert_eq!(sweep.cells_total, 2);
    let w = start_worker(tmp.path(), &coord.url(), "a");
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(
        (done.state, done.cells_done),
        (pb::SweepState::Done as i32, 2)
    );

    let db = coord.db().await;
    let cells: Vec<(i64, i64, i64, i64, f64)> = sqlx::query_as(
        "SELECT c.id, c.w1_index, c.w2_index, c.epochs_done, s.score FROM cells c \
         JOIN scores s ON s.cell_id = c.id ORDER BY c.w1_index, c.w2_index",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    let mut drawn = gaitsweep_search::random::random_points(3, 2, 2, 11);
    drawn.sort_unstable();
    let points: Vec<(usize, usize)> = cells.iter().map(|c| (c.1 as usize, c.2 as usize)).collect();
    assert_eq!(points, drawn, "the seed's draw, each point once");
    assert!(
        cells.iter().all(|c| c.3 == 2),
        "trained to the end: {cells:?}"
    );
    let best = cells
        .iter()
        .fold(None::<(i64, f64)>, |b, c| match b {
            Some((_, s)) if s >= c.4 => b,
            _ => Some((c.0, c.4)),
        })
        .unwrap()
        .0;
    assert_eq!(promoted_cell(&db, sweep.sweep_id).await, best);

    let text = show(&coord, sweep.sweep_id);
    assert!(
        text.contains("w1 \\ w2") && !text.contains("evolutionary search"),
        "a grid: {text}"
    );
    let out = tmp.path().join("report");
    let html = report(&coord, sweep.sweep_id, &out);
    assert!(
        html.contains("random search: 2 of the grid's 6 points drawn at random"),
        "report: {}",
        tail(&html, 2000)
    );
    assert!(out.join("score_flat.png").exists());
}

/// Item 5 of the search issue on real processes: a full grid recorded with `eval.every`
/// exports as a search-bench recording, and the bench replays it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorded_grid_replays_in_the_search_bench() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(tmp.path(), "127.0.0.1:0", &[]).await;
    let mut c = coord.sweeps().await;
    let spec = "name = \"record\"\nrobot = \"anymal\"\nterrains = [\"flat\"]\n\
                w1 = { values = [2.0, 8.0] }\nw2 = { values = [-6.0, -2.0] }\n\
                agents_per_cell = 4\nepochs = 3\ncheckpoint_every = 1\nseed = 3\nseeds = 2\n\
                eval = { robots = 2, seconds = 1.0, every = 1 }\n";
    let sweep = create(&mut c, spec.to_string()).await;
    let w = start_worker(tmp.path(), &coord.url(), "a");
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(done.cells_done, 8);
    let data_dir = coord.data.clone();
    let out = std::process::Command::new(bin("search-bench"))
        .args(["export", "--data-dir"])
        .arg(&data_dir)
        .args(["--sweep", &sweep.sweep_id.to_string()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rec: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(rec["points"].as_array().unwrap().len(), 4);
    let run0 = &rec["points"][0]["runs"][0];
    assert_eq!(rec["points"][0]["runs"].as_array().unwrap().len(), 2);
    assert!(
        run0["evals"]["1"].is_number() && run0["evals"]["2"].is_number(),
        "{run0}"
    );
    // How each run walked, beside its score: flat ground is evaluated at level 0 only, so
    // the level's falls are the run's.
    let gait = &run0["gait"];
    let falls = gait["fall_rate"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&falls), "{gait}");
    assert!(gait["mean_vel_error"].as_f64().unwrap() >= 0.0, "{gait}");
    assert!(gait["overspeed"].as_f64().unwrap() >= 0.0, "{gait}");
    let levels = gait["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 1, "{gait}");
    assert_eq!(levels[0]["level"].as_u64(), Some(0));
    assert!((levels[0]["fall_rate"].as_f64().unwrap() - falls).abs() < 1e-12);
    assert!((levels[0]["score"].as_f64().unwrap() - run0["score"].as_f64().unwrap()).abs() < 1e-12);
    let file = tmp.path().join("grid.json");
    std::fs::write(&file, &out.stdout).unwrap();
    let out = std::process::Command::new(bin("search-bench"))
        .args(["run", "--data"])
        .arg(&file)
        .args([
            "--replays",
            "20",
            "--reduction",
            "2",
            "--population",
            "2",
            "--budget-fraction",
            "1",
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("asha rungs [1, 2, 3]") && text.contains("cma-es pop 2"),
        "{text}"
    );
}
