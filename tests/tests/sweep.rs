//! Real-process sweeps: two workers finish a 2x2 sweep; a worker killed mid-cell is
//! replaced and its cell resumes from its checkpoint; a coordinator killed mid-sweep is
//! restarted and the sweep completes without losing or duplicating a score (both also with
//! the coordinator's database on PostgreSQL); a worker whose
//! coordinator lost its database registers again; a worker stopped with SIGTERM gives its
//! cell back at once.

mod common;

use common::*;
use gaitsweep_core::pb;
use sqlx::Row;
use std::time::Duration;

const SWEEP_TIMEOUT: Duration = Duration::from_secs(600);
/// Epochs of the fault-test cells: long enough (about 0.1 s each) to be killed mid-cell.
const LONG_EPOCHS: u32 = 40;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_workers_finish_a_2x2_sweep() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(tmp.path(), "127.0.0.1:0", &[]).await;
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, tiny_spec(&[2.0, 8.0], &[-6.0, -3.0], 2)).await;
    assert_eq!(sweep.cells_total, 4);
    let w1 = start_worker(tmp.path(), &coord.url(), "a");
    let w2 = start_worker(tmp.path(), &coord.url(), "b");
    let done = wait_done(
        &coord,
        sweep.sweep_id,
        SWEEP_TIMEOUT,
        &[&coord.proc, &w1, &w2],
    )
    .await;
    assert_eq!(done.state, pb::SweepState::Done as i32);
    assert_eq!(done.cells_done, 4);

    let db = coord.db().await;
    let scores: Vec<(i64, f64, Option<String>)> = sqlx::query_as(
        "SELECT cell_id, score, final_checkpoint_sha256 FROM scores ORDER BY cell_id",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(scores.len(), 4, "one score per cell");
    let workers: i64 =
        sqlx::query_scalar("SELECT COUNT(DISTINCT worker_id) FROM attempts WHERE state = 'done'")
            .fetch_one(&db)
            .await
            .unwrap();
    assert_eq!(workers, 2, "both workers trained cells");
    // Which CPU trained each attempt is in SQL: the same cell and seed can end differently
    // on two CPUs.
    let cpus: Vec<String> = sqlx::query_scalar(
        "SELECT DISTINCT w.cpu FROM attempts a JOIN workers w ON w.id = a.worker_id",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(cpus.len(), 1, "one machine, one CPU model: {cpus:?}");
    assert!(!cpus[0].is_empty(), "workers.cpu is stored");
    if std::env::consts::ARCH == "x86_64" {
        assert!(cpus[0].contains(" (family "), "{cpus:?}");
    }
    for (cell, _, sha) in &scores {
        let sha = sha.as_ref().expect("final checkpoint stored");
        let (size, path): (i64, String) =
            sqlx::query_as("SELECT size, path FROM checkpoints WHERE sha256 = $1")
                .bind(sha)
                .fetch_one(&db)
                .await
                .unwrap();
        let file = coord.data.join(&path);
        assert_eq!(std::fs::metadata(&file).unwrap().len() as i64, size);
        assert_eq!(
            &sha256_file(&file),
            sha,
            "stored checkpoint content matches its hash"
        );
        let epochs: i64 = sqlx::query_scalar(
            "SELECT COUNT(DISTINCT epoch) FROM epoch_metrics WHERE cell_id = $1",
        )
        .bind(cell)
        .fetch_one(&db)
        .await
        .unwrap();
        assert_eq!(epochs, 2, "learning curve of cell {cell}");
    }
    // The load bench sends exactly the metric set a real worker reports per epoch.
    let names: Vec<String> = sqlx::query_scalar(
        "SELECT DISTINCT name FROM epoch_metrics WHERE name NOT LIKE 'eval/%' ORDER BY name",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(names, gaitsweep_coordinator::loadgen::TRAINER_METRICS);
    // Every report was committed; the coordinator says so.
    let status = c
        .get_status(pb::GetStatusRequest {})
        .await
        .unwrap()
        .into_inner();
    let rows: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM epoch_metrics")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(status.metric_reports_queued, 0);
    assert!(
        status.metric_rows_written >= rows as u64 && status.metric_reports_written >= 8,
        "{rows} rows stored; {status:?}"
    );
    // every stored checkpoint file hashes to its name
    for row in sqlx::query("SELECT sha256, path FROM checkpoints")
        .fetch_all(&db)
        .await
        .unwrap()
    {
        let (sha, path): (String, String) = (row.get(0), row.get(1));
        assert_eq!(sha256_file(&coord.data.join(path)), sha);
    }
    let best = scores
        .iter()
        .filter(|s| !s.1.is_nan())
        .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
        .unwrap();
    let promoted = c
        .get_promoted(pb::GetPromotedRequest {
            sweep_id: sweep.sweep_id,
            terrain: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(
        promoted.cell.unwrap().cell_id,
        best.0,
        "the best cell is promoted"
    );
    assert_eq!(done.best_cell_id, best.0);

    // the CLI shows the grid and fetches the best model
    let (ok, text) = show(&coord, sweep.sweep_id);
    assert!(
        ok && text.contains('*') && text.contains("fall rate"),
        "show output: {text}"
    );
    let model = tmp.path().join("best.safetensors");
    let out = std::process::Command::new(bin("coordinator"))
        .args([
            "fetch-best",
            "--connect",
            &coord.url(),
            &sweep.sweep_id.to_string(),
            "--out",
            model.to_str().unwrap(),
        ])
        .args(["--export", tmp.path().join("export").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "fetch-best: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(&sha256_file(&model), best.2.as_ref().unwrap());
    let exported = std::fs::read_dir(tmp.path().join("export"))
        .map(|d| d.count())
        .unwrap_or(0);
    assert!(exported > 0, "fetch-best --export wrote the exported actor");
    // The exported actor is the robot's (anymal on flat ground: legged_gym's 48 observations,
    // 12 joint actions): onnxruntime and torch run it on the same observations and agree
    // within 1e-5 (trainer/tests/checkpoint.rs compares both with the Rust policy).
    let script = "import sys, numpy as np, onnxruntime as ort, torch\n\
                  s = ort.InferenceSession(sys.argv[1], providers=['CPUExecutionProvider'])\n\
                  dim = s.get_inputs()[0].shape[1]\n\
                  obs = (np.random.default_rng(1).normal(size=(16, dim)) * 3).astype(np.float32)\n\
                  a = s.run(['actions'], {'obs': obs})[0]\n\
                  t = torch.jit.load(sys.argv[2])(torch.from_numpy(obs)).detach().numpy()\n\
                  print(dim, a.shape[0], a.shape[1], float(np.abs(a - t).max()))\n";
    let export = tmp.path().join("export");
    let out = std::process::Command::new(python())
        .args(["-c", script])
        .arg(export.join("policy.onnx"))
        .arg(export.join("policy.pt"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "onnxruntime or torch failed on the exported actor: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let got: Vec<f64> = text
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(&got[..3], &[48.0, 16.0, 12.0], "{text}");
    assert!(got[3] <= 1e-5, "onnxruntime and torch differ by {}", got[3]);

    // every metric of every cell as one TensorBoard log dir, read back by TensorBoard
    let tb = tmp.path().join("tb");
    let out = std::process::Command::new(bin("coordinator"))
        .args(["tensorboard", &sweep.sweep_id.to_string(), "--data-dir"])
        .arg(&coord.data)
        .arg("--out")
        .arg(&tb)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "coordinator tensorboard: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: i64 = sqlx::query_scalar(
        "SELECT COUNT(*) FROM epoch_metrics m JOIN cells c ON c.id = m.cell_id WHERE c.sweep_id = $1",
    )
    .bind(sweep.sweep_id)
    .fetch_one(&db)
    .await
    .unwrap();
    let count = r#"
import os, sys
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
runs = sorted(os.listdir(sys.argv[1])); n = 0
for r in runs:
    a = EventAccumulator(os.path.join(sys.argv[1], r), size_guidance={'scalars': 0}); a.Reload()
    n += sum(len(a.Scalars(t)) for t in a.Tags()['scalars'])
print(len(runs), n, runs[0])
"#;
    let read = std::process::Command::new(common::python())
        .args(["-c", count])
        .arg(&tb)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&read.stdout);
    let f: Vec<&str> = text.split_whitespace().collect();
    assert!(
        read.status.success() && f.len() == 3,
        "tensorboard read: {text} {}",
        String::from_utf8_lossy(&read.stderr)
    );
    assert_eq!(f[0], "4", "one run per cell");
    assert_eq!(f[1], rows.to_string(), "every stored metric is a scalar");
    assert!(
        f[2].starts_with("flat_w1=2.000_w2=-3.000_seed="),
        "run name {}",
        f[2]
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killed_worker_cell_resumes_on_another_worker() {
    killed_worker_cell_resumes(Db::Sqlite).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killed_worker_cell_resumes_on_another_worker_on_postgres() {
    killed_worker_cell_resumes(Db::Postgres).await
}

async fn killed_worker_cell_resumes(on: Db) {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let database = on.fresh().await;
    let coord = Coord::start_on(
        tmp.path(),
        "127.0.0.1:0",
        database.as_deref(),
        &["--lease-seconds", "2"],
    )
    .await;
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, tiny_spec(&[4.0], &[-5.0], LONG_EPOCHS)).await;
    let mut a = start_worker(tmp.path(), &coord.url(), "a");
    let db = coord.db().await;
    let epoch = wait_for_at_least(
        &db,
        "worker a to upload a checkpoint",
        SWEEP_TIMEOUT,
        "SELECT MAX(epoch) FROM cell_checkpoints",
        1,
    )
    .await;
    a.kill();
    let state: String = sqlx::query_scalar("SELECT state FROM cells")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(
        state, "running",
        "worker a was killed mid-cell (after checkpoint of epoch {epoch})"
    );
    let b = start_worker(tmp.path(), &coord.url(), "b");
    let done = wait_done(
        &coord,
        sweep.sweep_id,
        SWEEP_TIMEOUT,
        &[&coord.proc, &a, &b],
    )
    .await;
    assert_eq!(done.cells_done, 1);
    let attempts: Vec<(String, i64)> =
        sqlx::query_as("SELECT state, resumed_from_epoch FROM attempts ORDER BY id")
            .fetch_all(&db)
            .await
            .unwrap();
    assert_eq!(attempts.len(), 2, "{attempts:?}");
    assert_eq!(attempts[0].0, "expired");
    assert_eq!(attempts[1].0, "done");
    assert!(
        attempts[1].1 >= epoch,
        "second attempt resumed from epoch {} (checkpoint at {epoch})",
        attempts[1].1
    );
    assert!(b.log_text().contains("resume checkpoint downloaded"));
    let scores: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM scores")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(scores, 1);
    let epochs: i64 = sqlx::query_scalar("SELECT MAX(epoch) FROM epoch_metrics")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(
        epochs, LONG_EPOCHS as i64,
        "the epoch count continues across attempts"
    );
}

/// Fault-injection finding: a worker stopped with SIGTERM uploaded its checkpoint and
/// exited, but its cell stayed `running` until the lease expired and the stop counted as a
/// failed attempt (three preemptions failed a healthy cell). Now the worker gives the cell
/// back: it is queued at once, and with `--max-attempts 1` it still finishes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stopped_worker_gives_its_cell_back_at_once() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(
        tmp.path(),
        "127.0.0.1:0",
        &["--lease-seconds", "300", "--max-attempts", "1"],
    )
    .await;
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, tiny_spec(&[4.0], &[-5.0], LONG_EPOCHS)).await;
    let mut a = start_worker(tmp.path(), &coord.url(), "a");
    let db = coord.db().await;
    wait_for_at_least(
        &db,
        "worker a to upload a checkpoint",
        SWEEP_TIMEOUT,
        "SELECT MAX(epoch) FROM cell_checkpoints",
        1,
    )
    .await;
    a.stop("worker a to exit after SIGTERM").await;
    // Far sooner than the 300 s lease: the cell is back in the queue.
    let attempt: String = wait_for("the cell to be queued again", Duration::from_secs(10), || {
        let db = db.clone();
        async move {
            let row: (String, String) = sqlx::query_as(
                "SELECT c.state, a.state FROM cells c JOIN attempts a ON a.cell_id = c.id ORDER BY a.id LIMIT 1",
            )
            .fetch_one(&db)
            .await
            .ok()?;
            (row.0 == "queued").then_some(row.1)
        }
    })
    .await;
    assert_eq!(attempt, "released", "{}", tail(&a.log_text(), 20));
    let b = start_worker(tmp.path(), &coord.url(), "b");
    let done = wait_done(
        &coord,
        sweep.sweep_id,
        SWEEP_TIMEOUT,
        &[&coord.proc, &a, &b],
    )
    .await;
    assert_eq!(
        (done.cells_done, done.cells_failed),
        (1, 0),
        "a release is not a failed attempt"
    );
    let states: Vec<String> = sqlx::query_scalar("SELECT state FROM attempts ORDER BY id")
        .fetch_all(&db)
        .await
        .unwrap();
    assert_eq!(states, ["released", "done"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn coordinator_killed_and_restarted_mid_sweep_completes() {
    coordinator_killed_and_restarted(Db::Sqlite).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn coordinator_killed_and_restarted_mid_sweep_completes_on_postgres() {
    coordinator_killed_and_restarted(Db::Postgres).await
}

async fn coordinator_killed_and_restarted(on: Db) {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let database = on.fresh().await;
    let mut coord = Coord::start_on(tmp.path(), "127.0.0.1:0", database.as_deref(), &[]).await;
    let addr = coord.addr.clone();
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, tiny_spec(&[2.0], &[-6.0, -3.0], LONG_EPOCHS)).await;
    let w = start_worker(tmp.path(), &coord.url(), "a");
    let db = coord.db().await;
    wait_for_at_least(
        &db,
        "the first epoch metrics",
        SWEEP_TIMEOUT,
        "SELECT COUNT(*) FROM epoch_metrics",
        1,
    )
    .await;
    let done_before: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM scores")
        .fetch_one(&db)
        .await
        .unwrap();
    assert!(
        done_before < 2,
        "the sweep is still running when the coordinator dies"
    );
    db.close().await;
    coord.proc.kill();
    // the worker keeps training and retries; restart on the same address
    wait_for(
        "the worker to notice the coordinator is gone",
        Duration::from_secs(60),
        || {
            let text = w.log_text();
            async move { text.contains("retrying").then_some(()) }
        },
    )
    .await;
    let coord = Coord::start_on(tmp.path(), &addr, database.as_deref(), &[]).await;
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(done.cells_done, 2);
    let db = coord.db().await;
    let scores: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM scores")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(scores, 2, "no score lost or duplicated");
    let per_cell: i64 = sqlx::query_scalar(
        "SELECT MAX(n) FROM (SELECT COUNT(*) AS n FROM scores GROUP BY cell_id) AS per_cell",
    )
    .fetch_one(&db)
    .await
    .unwrap();
    assert_eq!(per_cell, 1);
    let metrics: i64 =
        sqlx::query_scalar("SELECT COUNT(DISTINCT cell_id || '/' || epoch) FROM epoch_metrics")
            .fetch_one(&db)
            .await
            .unwrap();
    assert_eq!(
        metrics,
        2 * LONG_EPOCHS as i64,
        "every epoch of both cells stored once"
    );
    // the report reads the same database (`--database` when it is PostgreSQL)
    let out = tmp.path().join("report");
    let mut cmd = std::process::Command::new(bin("coordinator"));
    cmd.args([
        "report",
        &sweep.sweep_id.to_string(),
        "--no-gif",
        "--data-dir",
    ])
    .arg(&coord.data)
    .arg("--out")
    .arg(&out);
    if let Some(d) = &database {
        cmd.args(["--database", d]);
    }
    let run = cmd.output().unwrap();
    assert!(
        run.status.success(),
        "coordinator report: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(
        html.contains("2 of 2 cells scored"),
        "report of the finished sweep"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn worker_registers_again_with_a_coordinator_that_lost_its_database() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    for d in ["old", "new"] {
        std::fs::create_dir_all(tmp.path().join(d)).unwrap();
    }
    let mut old = Coord::start(&tmp.path().join("old"), "127.0.0.1:0", &[]).await;
    let addr = old.addr.clone();
    let w = start_worker(tmp.path(), &old.url(), "a");
    wait_for("the worker to register", Duration::from_secs(60), || {
        let text = w.log_text();
        async move { text.contains("worker registered").then_some(()) }
    })
    .await;
    old.proc.kill();
    // A new coordinator on the same address with an empty database: the worker's id is
    // unknown there, so it must register again before it can lease.
    let coord = Coord::start(&tmp.path().join("new"), &addr, &[]).await;
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, tiny_spec(&[2.0], &[-6.0], 2)).await;
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(done.cells_done, 1, "{}", tail(&w.log_text(), 20));
    assert!(w.log_text().contains("registered again"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replicates_train_each_point_k_times_and_promote_the_best_mean() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(tmp.path(), "127.0.0.1:0", &[]).await;
    let mut c = coord.sweeps().await;
    let spec = format!("{}seeds = 2\n", tiny_spec(&[2.0, 8.0], &[-6.0], 2));
    let sweep = create(&mut c, spec).await;
    assert_eq!(sweep.cells_total, 4, "2 points x 2 replicates");
    let w = start_worker(tmp.path(), &coord.url(), "a");
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(
        (done.state, done.cells_done),
        (pb::SweepState::Done as i32, 4)
    );

    // SQL keeps every replicate's score; the promotion is the point with the best mean,
    // stored with that mean and represented by its best replicate.
    let db = coord.db().await;
    let reps: Vec<(i64, i64, i64, f64)> = sqlx::query_as(
        "SELECT c.w1_index, c.replicate, c.seed, s.score FROM cells c JOIN scores s ON s.cell_id = c.id \
         WHERE c.sweep_id = $1 ORDER BY c.w1_index, c.replicate",
    )
    .bind(sweep.sweep_id)
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(reps.len(), 4);
    assert_eq!(
        reps.iter().map(|r| (r.0, r.1)).collect::<Vec<_>>(),
        [(0, 0), (0, 1), (1, 0), (1, 1)]
    );
    assert_ne!(
        reps[0].2, reps[1].2,
        "replicates train with different seeds"
    );
    let mean = |w1: i64| reps.iter().filter(|r| r.0 == w1).map(|r| r.3).sum::<f64>() / 2.0;
    let best_w1 = if mean(0) >= mean(1) { 0 } else { 1 };
    let (cell_id, promoted): (i64, f64) = sqlx::query_as(
        "SELECT cell_id, score FROM promotions WHERE sweep_id = $1 AND terrain = '' ORDER BY id DESC LIMIT 1",
    )
    .bind(sweep.sweep_id)
    .fetch_one(&db)
    .await
    .unwrap();
    assert!(
        (promoted - mean(best_w1)).abs() < 1e-9,
        "promoted {promoted}, means {} {}",
        mean(0),
        mean(1)
    );
    let (w1_index, score): (i64, f64) = sqlx::query_as(
        "SELECT c.w1_index, s.score FROM cells c JOIN scores s ON s.cell_id = c.id WHERE c.id = $1",
    )
    .bind(cell_id)
    .fetch_one(&db)
    .await
    .unwrap();
    assert_eq!(w1_index, best_w1);
    let best_rep = reps
        .iter()
        .filter(|r| r.0 == best_w1)
        .map(|r| r.3)
        .fold(f64::MIN, f64::max);
    assert_eq!(score, best_rep, "the point's best replicate is its model");

    let (ok, text) = show(&coord, sweep.sweep_id);
    assert!(
        ok && text.contains('±') && text.contains("2 replicates"),
        "show output: {text}"
    );
}

/// `stop_unrewarded`: the heavy robot at w2 = -2 pays ~1,800 a step for torque, so every
/// step's reward is clipped to 0 and its cell stops at a quarter of its epochs, scored there
/// with its checkpoint; the rewarded cell beside it trains every epoch; the sweep finishes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cell_never_rewarded_stops_early_and_the_sweep_finishes() {
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(tmp.path(), "127.0.0.1:0", &["--http", "127.0.0.1:0"]).await;
    let mut c = coord.sweeps().await;
    let spec = "name = \"unrewarded\"\nrobot = \"heavy\"\nterrains = [\"flat\"]\n\
                w1 = { values = [12.0] }\nw2 = { values = [-20.0, -2.0] }\nagents_per_cell = 8\n\
                epochs = 8\ncheckpoint_every = 4\nseed = 3\nstop_unrewarded = 0.25\n\
                eval = { robots = 2, seconds = 1.0 }\n";
    let sweep = create(&mut c, spec.to_string()).await;
    let w = start_worker(tmp.path(), &coord.url(), "a");
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(
        (done.state, done.cells_done),
        (pb::SweepState::Done as i32, 2)
    );
    let db = coord.db().await;
    let rows: Vec<(f64, i64, i64, Option<String>, f64, i64)> = sqlx::query_as(
        "SELECT c.w2, c.epochs_done, s.epochs, s.final_checkpoint_sha256, \
         (SELECT MAX(value) FROM epoch_metrics m WHERE m.cell_id = c.id AND m.name = 'mean_step_reward'), \
         (SELECT COUNT(DISTINCT epoch) FROM epoch_metrics m WHERE m.cell_id = c.id) \
         FROM cells c JOIN scores s ON s.cell_id = c.id ORDER BY c.w2",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(rows.len(), 2, "{rows:?}");
    let (rewarded, unrewarded) = (&rows[0], &rows[1]);
    assert_eq!(
        (rewarded.0, rewarded.1, rewarded.2, rewarded.5),
        (-20.0, 8, 8, 8)
    );
    assert!(rewarded.4 > 0.0, "{rows:?}");
    assert_eq!(
        (unrewarded.0, unrewarded.1, unrewarded.2, unrewarded.5),
        (-2.0, 2, 2, 2),
        "stopped after 0.25 x 8 epochs"
    );
    assert_eq!(unrewarded.4, 0.0);
    let sha = unrewarded
        .3
        .as_ref()
        .expect("the stopped cell's checkpoint is stored");
    let epoch: i64 = sqlx::query_scalar("SELECT epoch FROM cell_checkpoints WHERE sha256 = $1")
        .bind(sha)
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(epoch, 2);

    // The live page's data marks the stopped cell, and only it, as never rewarded.
    let http = std::fs::read_to_string(coord.data.join("http.addr")).unwrap();
    let (status, body) = http_get(&http, &format!("/api/sweeps/{}", sweep.sweep_id), None);
    assert!(status.contains("200"), "{status}");
    let json: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let marks: Vec<(f64, bool)> = json["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["w2"].as_f64().unwrap(),
                c["never_rewarded"].as_bool().unwrap(),
            )
        })
        .collect();
    assert_eq!(marks, [(-20.0, false), (-2.0, true)]);
    // The sweep list's progress counts the stopped cell at the epochs it trained: full.
    let (status, body) = http_get(&http, "/api/sweeps", None);
    assert!(status.contains("200"), "{status}");
    let list: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let listed = &list["sweeps"][0];
    assert_eq!(
        (
            listed["epochs_done"].as_i64(),
            listed["epochs_total"].as_i64()
        ),
        (Some(10), Some(10)),
        "8 epochs and 2 of 8: {listed}"
    );
    // So does `coordinator show` (ListCells), with its legend.
    let (ok, text) = show(&coord, sweep.sweep_id);
    assert!(ok, "{text}");
    assert_eq!(
        text.matches('!').count(),
        2,
        "the w2 = -2 point marked, and the legend: {text}"
    );
    assert!(text.contains("! never rewarded"), "{text}");
}

/// `coordinator show` of a sweep: whether it succeeded, and what it printed.
fn show(coord: &Coord, sweep: i64) -> (bool, String) {
    let out = std::process::Command::new(bin("coordinator"))
        .args(["show", "--connect", &coord.url(), &sweep.to_string()])
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}
