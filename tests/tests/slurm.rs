//! Workers on Slurm, end to end: a one-node cluster of Debian's Slurm
//! (`scripts/slurm-cluster.sh`) runs `deploy/slurm/gaitsweep-workers.sbatch` as a user
//! submits it, against a real coordinator. The first job is cancelled with a plain
//! `scancel` mid-cell: its worker gives the cell back (`released`, not a failure, with
//! `--max-attempts 1`) and the job ends cleanly; a second job resumes the cell from its
//! checkpoint and finishes the sweep: every cell scored once, every epoch stored once.
//! The second job is then stopped with `scancel --signal=TERM` and completes.
//!
//! The cluster needs root and apt-get (the script installs slurm-wlm and munge when they
//! are missing). Where that cannot work, the test fails; `GAITSWEEP_SKIP_SLURM=1` skips it.

mod common;

use common::*;
use gaitsweep_core::pb;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

const SWEEP_TIMEOUT: Duration = Duration::from_secs(600);
/// The sweep of the README's "Running a sweep on a Slurm cluster": two cells of 600 short
/// epochs (about 30 ms each on one thread), long enough to cancel a job mid-cell by hand.
const SPEC: &str = r#"name = "slurm-demo"
robot = "anymal"
terrains = ["flat"]
w1 = { values = [2.0, 8.0] }
w2 = { values = [-5.0] }
agents_per_cell = 4
epochs = 600
checkpoint_every = 20
seed = 3
eval = { robots = 2, seconds = 1.0 }
"#;
const EPOCHS: i64 = 600;
/// Slurm client commands wait forever for a slurmctld that is gone: bounded by `timeout`.
const SLURM_CMD_TIMEOUT: &str = "30";

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// A one-node Slurm cluster with all its files in a temp dir, stopped when dropped.
struct Cluster {
    dir: tempfile::TempDir,
    conf: String,
    /// Job output files to print if the test fails.
    outputs: Vec<PathBuf>,
}

impl Cluster {
    /// Starts the cluster, or `None` when `GAITSWEEP_SKIP_SLURM=1`.
    fn start() -> Option<Cluster> {
        if std::env::var("GAITSWEEP_SKIP_SLURM").as_deref() == Ok("1") {
            eprintln!("GAITSWEEP_SKIP_SLURM=1: the Slurm end-to-end test is skipped");
            return None;
        }
        let dir = tempfile::Builder::new()
            .prefix("gaitsweep-slurm")
            .tempdir()
            .expect("temp dir for the cluster");
        let out = Command::new(repo_root().join("scripts/slurm-cluster.sh"))
            .arg("start")
            .arg(dir.path())
            .output()
            .expect("run scripts/slurm-cluster.sh");
        let conf = String::from_utf8_lossy(&out.stdout).trim().to_string();
        let cluster = Cluster {
            dir,
            conf,
            outputs: Vec::new(),
        };
        assert!(
            out.status.success() && !cluster.conf.is_empty(),
            "cannot start a one-node Slurm cluster with scripts/slurm-cluster.sh (it needs root \
             and apt-get for slurm-wlm and munge; GAITSWEEP_SKIP_SLURM=1 skips this test): {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Some(cluster)
    }

    /// A Slurm client command for this cluster, bounded by `timeout`.
    fn command(&self, program: &str) -> Command {
        let mut cmd = Command::new("timeout");
        cmd.arg(SLURM_CMD_TIMEOUT)
            .arg(program)
            .env("SLURM_CONF", &self.conf);
        cmd
    }

    fn run(&self, program: &str, args: &[&str]) -> Output {
        let out = self
            .command(program)
            .args(args)
            .output()
            .unwrap_or_else(|e| panic!("run {program}: {e}"));
        assert!(
            out.status.success(),
            "{program} {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }

    /// The job's state as `scontrol show job` says (RUNNING, CANCELLED, COMPLETED, ...).
    fn job_state(&self, job: &str) -> Option<String> {
        let out = self
            .command("scontrol")
            .args(["show", "job", job])
            .output()
            .ok()?;
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        text.split_whitespace()
            .find_map(|w| w.strip_prefix("JobState="))
            .map(str::to_string)
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        if std::thread::panicking() {
            for f in &self.outputs {
                let text = std::fs::read_to_string(f).unwrap_or_default();
                eprintln!("---- {}\n{}", f.display(), tail(&text, 40));
            }
            let log = self.dir.path().join("log/slurmctld.log");
            let text = std::fs::read_to_string(&log).unwrap_or_default();
            eprintln!("---- {}\n{}", log.display(), tail(&text, 20));
        }
        let _ = Command::new(repo_root().join("scripts/slurm-cluster.sh"))
            .arg("stop")
            .arg(self.dir.path())
            .status();
    }
}

/// `sbatch` of the deploy script as the README runs it, sized for one CPU of this machine;
/// returns the job id and its output file.
fn submit(cluster: &Cluster, home: &Path, url: &str, submit_dir: &Path) -> (String, PathBuf) {
    let out = cluster
        .command("sbatch")
        .args([
            "--parsable",
            "--nodes=1",
            "--cpus-per-task=1",
            "--time=15:00",
        ])
        .arg(repo_root().join("deploy/slurm/gaitsweep-workers.sbatch"))
        .current_dir(submit_dir)
        .env("GAITSWEEP_URL", url)
        .env("GAITSWEEP_HOME", home)
        .env_remove("GAITSWEEP_TOKEN")
        .env("GAITSWEEP_TOKEN_FILE", home.join("no-token"))
        .env("RUST_LOG", "info")
        // The job's node-local scratch (the script's work dir) inside this test's temp dir:
        // job ids restart at 1 on every new cluster, and a cached checkpoint of an earlier
        // run in /tmp/gaitsweep-worker-2 would spare the resumed cell its download.
        .env("TMPDIR", submit_dir)
        .output()
        .expect("run sbatch");
    assert!(
        out.status.success(),
        "sbatch: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let job = String::from_utf8_lossy(&out.stdout)
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string();
    assert!(
        !job.is_empty() && job.chars().all(|c| c.is_ascii_digit()),
        "sbatch --parsable printed {:?}",
        String::from_utf8_lossy(&out.stdout)
    );
    // The script's own --output, in the directory sbatch ran in.
    let output = submit_dir.join(format!("gaitsweep-workers-{job}.out"));
    (job, output)
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_default()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sbatch_workers_give_cells_back_on_scancel_and_the_sweep_completes() {
    let _g = heavy().await;
    let Some(mut cluster) = Cluster::start() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    // GAITSWEEP_HOME as the deploy README installs it: bin/worker and robots/.
    let home = tmp.path().join("gaitsweep");
    std::fs::create_dir_all(home.join("bin")).unwrap();
    std::os::unix::fs::symlink(bin("worker"), home.join("bin/worker")).unwrap();
    std::os::unix::fs::symlink(repo_root().join("robots"), home.join("robots")).unwrap();
    let jobs_dir = tmp.path().join("jobs");
    std::fs::create_dir_all(&jobs_dir).unwrap();

    // A long lease: the cell comes back because the worker gives it, not because it expired;
    // one attempt per cell: a release is not counted as a failure.
    let coord = Coord::start(
        tmp.path(),
        "127.0.0.1:0",
        &["--lease-seconds", "300", "--max-attempts", "1"],
    )
    .await;
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, SPEC.to_string()).await;
    assert_eq!(sweep.cells_total, 2);
    let db = coord.db().await;

    let (job1, out1) = submit(&cluster, &home, &coord.url(), &jobs_dir);
    cluster.outputs.push(out1.clone());
    let (cell, epoch): (i64, i64) = wait_for(
        "job 1's worker to upload a checkpoint of its running cell past epoch 0",
        SWEEP_TIMEOUT,
        || {
            let db = db.clone();
            async move {
                let row: (i64, i64) = sqlx::query_as(
                    "SELECT cc.cell_id, MAX(cc.epoch) FROM cell_checkpoints cc JOIN cells c ON c.id = cc.cell_id \
                     WHERE c.state = 'running' AND cc.epoch >= 1 GROUP BY cc.cell_id",
                )
                .fetch_one(&db)
                .await
                .ok()?;
                Some(row)
            }
        },
    )
    .await;
    let cell_state: String = sqlx::query_scalar("SELECT state FROM cells WHERE id = $1")
        .bind(cell)
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(
        cell_state, "running",
        "job {job1} is cancelled mid-cell (after the checkpoint of epoch {epoch})"
    );
    cluster.run("scancel", &[job1.as_str()]);
    // Far sooner than the 300 s lease: the worker gave the cell back.
    let attempt: String = wait_for(
        "the cancelled job's cell to be queued again",
        Duration::from_secs(60),
        || {
            let db = db.clone();
            async move {
                let row: (String, String) = sqlx::query_as(
                    "SELECT c.state, a.state FROM cells c JOIN attempts a ON a.cell_id = c.id \
                     WHERE c.id = $1 ORDER BY a.id LIMIT 1",
                )
                .bind(cell)
                .fetch_one(&db)
                .await
                .ok()?;
                (row.0 == "queued").then_some(row.1)
            }
        },
    )
    .await;
    assert_eq!(attempt, "released", "{}", tail(&read(&out1), 20));
    let state = wait_for(
        "job 1 to end after scancel",
        Duration::from_secs(60),
        || {
            let s = cluster.job_state(&job1);
            async move { s.filter(|s| !matches!(s.as_str(), "RUNNING" | "COMPLETING")) }
        },
    )
    .await;
    assert_eq!(state, "CANCELLED");
    let text = wait_for(
        "job 1's script to report how its workers ended",
        Duration::from_secs(30),
        || {
            let text = read(&out1);
            async move { text.contains("gaitsweep: workers stopped").then_some(text) }
        },
    )
    .await;
    assert!(
        text.contains("cell stopped and given back")
            && text.contains("gaitsweep: workers stopped (srun exit status 0)"),
        "the worker of job {job1} got SIGTERM, gave its cell back and exited cleanly:\n{}",
        tail(&text, 30)
    );

    let (job2, out2) = submit(&cluster, &home, &coord.url(), &jobs_dir);
    cluster.outputs.push(out2.clone());
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc]).await;
    assert_eq!(done.state, pb::SweepState::Done as i32);
    assert_eq!(
        (done.cells_done, done.cells_failed),
        (2, 0),
        "a cancelled job is not a failed attempt"
    );

    // Every cell scored exactly once.
    let scores: Vec<(i64, i64)> =
        sqlx::query_as("SELECT cell_id, COUNT(*) FROM scores GROUP BY cell_id ORDER BY cell_id")
            .fetch_all(&db)
            .await
            .unwrap();
    assert_eq!(scores.len(), 2, "{scores:?}");
    assert!(scores.iter().all(|s| s.1 == 1), "{scores:?}");
    // The cancelled cell: released by job 1's worker, resumed from its checkpoint by job 2's.
    let attempts: Vec<(String, i64, String)> = sqlx::query_as(
        "SELECT state, resumed_from_epoch, worker_id FROM attempts WHERE cell_id = $1 ORDER BY id",
    )
    .bind(cell)
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(attempts.len(), 2, "{attempts:?}");
    assert_eq!(
        (attempts[0].0.as_str(), attempts[1].0.as_str()),
        ("released", "done")
    );
    assert!(
        attempts[1].1 >= epoch && attempts[1].1 > 0,
        "the cell resumed from epoch {} (checkpoint of epoch {epoch} before scancel)",
        attempts[1].1
    );
    assert_ne!(attempts[0].2, attempts[1].2, "job 2's worker resumed it");
    let other: Vec<String> =
        sqlx::query_scalar("SELECT state FROM attempts WHERE cell_id <> $1 ORDER BY id")
            .bind(cell)
            .fetch_all(&db)
            .await
            .unwrap();
    assert_eq!(other, ["done"], "the other cell trained once, by job 2");
    let text2 = read(&out2);
    assert!(
        text2.contains("resume checkpoint downloaded"),
        "{}",
        tail(&text2, 30)
    );
    // Nothing lost: every epoch of both cells stored once, across the two jobs.
    let per_cell: Vec<i64> = sqlx::query_scalar(
        "SELECT COUNT(DISTINCT epoch) FROM epoch_metrics GROUP BY cell_id ORDER BY cell_id",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(per_cell, [EPOCHS, EPOCHS]);
    // The checkpoint the cell resumed from is stored and intact.
    let (sha, path): (String, String) = sqlx::query_as(
        "SELECT k.sha256, k.path FROM cell_checkpoints cc JOIN checkpoints k ON k.sha256 = cc.sha256 \
         WHERE cc.cell_id = $1 AND cc.epoch = $2",
    )
    .bind(cell)
    .bind(attempts[1].1)
    .fetch_one(&db)
    .await
    .unwrap();
    assert_eq!(sha256_file(&coord.data.join(path)), sha);

    // `coordinator show`, as the README's Slurm section ends.
    let show = Command::new(bin("coordinator"))
        .args([
            "show",
            "--connect",
            &coord.url(),
            &sweep.sweep_id.to_string(),
        ])
        .output()
        .unwrap();
    let shown = String::from_utf8_lossy(&show.stdout);
    assert!(
        show.status.success() && shown.contains('*'),
        "coordinator show: {shown}"
    );

    // The idle workers of job 2 stop on a bare signal and the job completes by itself.
    cluster.run("scancel", &["--signal=TERM", job2.as_str()]);
    let state = wait_for(
        "job 2 to complete after scancel --signal=TERM",
        Duration::from_secs(60),
        || {
            let s = cluster.job_state(&job2);
            async move { s.filter(|s| !matches!(s.as_str(), "RUNNING" | "COMPLETING")) }
        },
    )
    .await;
    assert_eq!(state, "COMPLETED", "{}", tail(&read(&out2), 20));
    let scratch = jobs_dir.join(format!("gaitsweep-worker-{job2}"));
    assert!(
        !scratch.exists(),
        "job 2 removed its scratch {} when its workers stopped",
        scratch.display()
    );
    let states: Vec<String> = sqlx::query_scalar("SELECT state FROM attempts ORDER BY id")
        .fetch_all(&db)
        .await
        .unwrap();
    assert_eq!(states.len(), 3, "no attempt after the sweep: {states:?}");
}
