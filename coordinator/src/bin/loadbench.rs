//! `loadbench`: simulated workers that send a real coordinator process what real worker
//! daemons send, at the real rate, on loopback. Each simulated worker (one slot, its own
//! connection) registers, leases a cell, heartbeats at the interval the coordinator asks
//! for, reports the trainer's full metric set after every epoch (with the evaluation's
//! metrics every `--eval-every` epochs), uploads a checkpoint of the real size every
//! `--checkpoint-every` epochs and reports a result when the phase ends. Epochs the
//! coordinator has not acknowledged yet are batched into the next report, as the worker
//! daemon does. Prints RPCs/s, metric rows/s stored, latency percentiles, coordinator CPU
//! and memory, database growth and lost leases; fails unless every metric and result
//! acknowledged was stored and no lease was lost.
//!
//! `loadbench --workers 1000 --seconds 60` starts `coordinator serve` from the same
//! directory as this binary with a temporary data dir (`--postgres URL`: its database on
//! that PostgreSQL server); `--connect URL` uses a running one (then the coordinator's
//! CPU, memory and database are not measured). The coordinator's CPU and memory are its
//! own process's: a PostgreSQL server's are not included.

use anyhow::{bail, Context};
use clap::Parser;
use gaitsweep_coordinator::loadgen::{
    database_bytes, epoch_values, eval_metric_names, quantile, ProcUsage, TRAINER_METRICS,
};
use gaitsweep_core::client::upload_messages;
use gaitsweep_core::pb::{
    self, sweep_service_client::SweepServiceClient, worker_service_client::WorkerServiceClient,
};
use sha2::{Digest, Sha256};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;
use tonic::transport::{Channel, Endpoint};

#[derive(Parser, Clone)]
#[command(
    name = "loadbench",
    about = "load benchmark of the gaitsweep coordinator with simulated workers at the real rate"
)]
struct Args {
    /// Simulated workers, one training slot each, each on its own connection.
    #[arg(long, default_value_t = 1000)]
    workers: usize,
    /// Length of the training phase, seconds.
    #[arg(long, default_value_t = 60)]
    seconds: u64,
    /// Milliseconds per training epoch (default: a demo cell measured on the 2-core AMD
    /// EPYC, 128 robots, one libtorch thread: 0.75 s).
    #[arg(long, default_value_t = 750)]
    epoch_ms: u64,
    /// Evaluate (send the eval/* metrics) every this many epochs (the demo's 100).
    #[arg(long, default_value_t = 100)]
    eval_every: u32,
    /// Upload a checkpoint every this many epochs (the demo's 100).
    #[arg(long, default_value_t = 100)]
    checkpoint_every: u32,
    /// Checkpoint size in bytes (the anymal preset's safetensors file: 414 KB).
    #[arg(long, default_value_t = 414_400)]
    checkpoint_bytes: usize,
    /// Heartbeat interval in milliseconds (default: what the coordinator asks for).
    #[arg(long)]
    heartbeat_ms: Option<u64>,
    /// Use a running coordinator instead of starting one.
    #[arg(long)]
    connect: Option<String>,
    /// Keep the coordinator's database on this PostgreSQL server (a URL of any database on
    /// it, e.g. scripts/pg-cluster.sh's): the bench creates a fresh database there and
    /// starts the coordinator with `--database`. Default: SQLite in the temporary data dir.
    #[arg(long)]
    postgres: Option<String>,
    /// Extra arguments for the coordinator this bench starts (e.g. "--lease-seconds 60").
    #[arg(long, allow_hyphen_values = true)]
    serve_args: Option<String>,
}

/// Latencies (milliseconds) and counters shared by every simulated worker.
#[derive(Default)]
struct Stats {
    rpcs: AtomicU64,
    rows_acked: AtomicU64,
    epochs_sent: AtomicU64,
    reports: AtomicU64,
    batched_reports: AtomicU64,
    lost_leases: AtomicU64,
    heartbeat: Mutex<Vec<f64>>,
    progress: Mutex<Vec<f64>>,
    upload: Mutex<Vec<f64>>,
    result: Mutex<Vec<f64>>,
}

impl Stats {
    fn time(&self, which: &Mutex<Vec<f64>>, t: Instant) {
        self.rpcs.fetch_add(1, Ordering::Relaxed);
        which
            .lock()
            .expect("stats lock")
            .push(t.elapsed().as_secs_f64() * 1e3);
    }
}

fn main() -> std::process::ExitCode {
    gaitsweep_core::error::exit(start())
}

fn start() -> anyhow::Result<()> {
    let args = Args::parse();
    let rt = tokio::runtime::Runtime::new()?;
    rt.block_on(run(args))
}

/// The coordinator this bench started: its process, data dir and its PostgreSQL database
/// (`None`: the data dir's SQLite file).
struct Server {
    child: KillOnDrop,
    dir: TempDir,
    postgres: Option<String>,
}

impl Server {
    /// Where the database is, for the output.
    fn db_name(&self) -> String {
        match &self.postgres {
            Some(u) => gaitsweep_coordinator::store::DatabaseUrl::Postgres(u.clone()).redacted(),
            None => self.db_file().display().to_string(),
        }
    }

    fn db_file(&self) -> PathBuf {
        self.dir.0.join("gaitsweep.sqlite")
    }

    /// The database's size in bytes (SQLite: the file and its WAL).
    async fn db_bytes(&self) -> anyhow::Result<u64> {
        match &self.postgres {
            None => Ok(database_bytes(&self.db_file())),
            Some(_) => {
                let db = self.open().await?;
                let n: i64 = sqlx::query_scalar("SELECT pg_database_size(current_database())")
                    .fetch_one(&db)
                    .await?;
                db.close().await;
                Ok(n as u64)
            }
        }
    }

    async fn open(&self) -> anyhow::Result<sqlx::AnyPool> {
        gaitsweep_coordinator::store::reader::open(&self.dir.0, self.postgres.as_deref())
            .await
            .map_err(Into::into)
    }
}

async fn start_server(args: &Args) -> anyhow::Result<(Server, String)> {
    let exe = std::env::current_exe()?;
    let bin = exe.with_file_name("coordinator");
    if !bin.is_file() {
        bail!(
            "{} is missing: build it with `cargo build --release -p gaitsweep-coordinator`",
            bin.display()
        );
    }
    let dir = std::env::temp_dir().join(format!("gaitsweep-loadbench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let dir = TempDir(dir);
    let postgres = match &args.postgres {
        Some(server) => Some(
            gaitsweep_coordinator::store::backend::create_postgres_database(
                server,
                &gaitsweep_coordinator::store::backend::unique_database_name("gs_loadbench"),
            )
            .await
            .context("create the bench's database on --postgres")?,
        ),
        None => None,
    };
    let mut extra: Vec<String> = args
        .serve_args
        .as_deref()
        .unwrap_or("")
        .split_whitespace()
        .map(String::from)
        .collect();
    if let Some(u) = &postgres {
        extra.extend(["--database".to_string(), u.clone()]);
    }
    let child = Command::new(&bin)
        .args(["serve", "--listen", "127.0.0.1:0", "--data-dir"])
        .arg(&dir.0)
        .args(&extra)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .context("start the coordinator")?;
    let child = KillOnDrop(child);
    let addr_file = dir.0.join("coordinator.addr");
    let start = Instant::now();
    let addr = loop {
        if let Ok(a) = std::fs::read_to_string(&addr_file) {
            if !a.is_empty() {
                break a;
            }
        }
        if start.elapsed() > Duration::from_secs(30) {
            bail!("the coordinator did not start within 30 s");
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    Ok((
        Server {
            child,
            dir,
            postgres,
        },
        format!("http://{addr}"),
    ))
}

fn range(min: f64, max: f64, count: usize) -> Option<pb::Axis> {
    Some(pb::Axis {
        kind: Some(pb::axis::Kind::Range(pb::Range {
            min,
            max,
            count: count as u32,
        })),
    })
}

async fn run(args: Args) -> anyhow::Result<()> {
    let (server, url) = match &args.connect {
        Some(u) => (None, u.clone()),
        None => {
            let (s, u) = start_server(&args).await?;
            (Some(s), u)
        }
    };
    let n = args.workers;
    let mut sweeps = SweepServiceClient::new(Endpoint::from_shared(url.clone())?.connect().await?);
    let cols = 40usize.min(n.max(1));
    let rows = n.div_ceil(cols);
    // Enough epochs that no cell ends inside the phase: results come when it ends.
    let epochs = (args.seconds * 1000 / args.epoch_ms.max(1)) as u32
        + args.checkpoint_every.max(args.eval_every)
        + 100;
    let spec = pb::SweepSpec {
        name: "loadbench".into(),
        robot: "anymal".into(),
        terrains: vec!["flat".into()],
        w1: range(2.0, 12.0, rows),
        w2: range(-10.0, -2.0, cols),
        agents_per_cell: 128,
        epochs,
        checkpoint_every: Some(args.checkpoint_every),
        eval_every: args.eval_every,
        ..Default::default()
    };
    let sweep = sweeps
        .create_sweep(pb::CreateSweepRequest {
            spec: Some(pb::create_sweep_request::Spec::Structured(spec)),
        })
        .await?
        .into_inner();
    println!(
        "sweep {} with {} cells; connecting {n} workers to {url}",
        sweep.sweep_id, sweep.cells_total
    );
    let mut channels = Vec::with_capacity(n);
    for _ in 0..n {
        channels.push(
            Endpoint::from_shared(url.clone())?
                .tcp_nodelay(true)
                .connect()
                .await?,
        );
    }
    let stats = Arc::new(Stats::default());
    let pid = server.as_ref().map(|s| s.child.0.id());
    let usage0 = pid.map(ProcUsage::of).unwrap_or_default();
    let db0 = match &server {
        Some(s) => s.db_bytes().await?,
        None => 0,
    };
    let t0 = Instant::now();
    let mut tasks = tokio::task::JoinSet::new();
    for (i, ch) in channels.into_iter().enumerate() {
        let (stats, args) = (stats.clone(), args.clone());
        tasks.spawn(async move { worker(i, n, ch, &args, &stats).await });
    }
    // The coordinator's own view of its write queue, once a second (older coordinators
    // without GetStatus: nothing).
    let watch = {
        let mut c = sweeps.clone();
        let until = t0 + Duration::from_secs(args.seconds);
        tokio::spawn(async move {
            let (mut queued, mut lag) = (0u64, 0f64);
            let mut seen = false;
            while Instant::now() < until {
                tokio::time::sleep(Duration::from_secs(1)).await;
                if let Ok(s) = c.get_status(pb::GetStatusRequest {}).await {
                    let s = s.into_inner();
                    seen = true;
                    queued = queued.max(s.metric_reports_queued);
                    lag = lag.max(s.metric_write_lag_ms);
                }
            }
            seen.then_some((queued, lag))
        })
    };
    let mut reported = 0u64;
    let mut failed = 0u64;
    while let Some(r) = tasks.join_next().await {
        match r? {
            Ok(ok) => reported += ok as u64,
            Err(e) => {
                failed += 1;
                if failed <= 5 {
                    eprintln!("worker failed: {e:#}");
                }
            }
        }
    }
    let wall = t0.elapsed().as_secs_f64();
    // Rates are over the training phase, when the traffic flows.
    let phase_s = args.seconds as f64;
    let usage1 = pid.map(ProcUsage::of).unwrap_or_default();
    let s = sweeps
        .get_sweep(pb::GetSweepRequest {
            sweep_id: sweep.sweep_id,
        })
        .await?
        .into_inner();
    let stored = match &server {
        Some(srv) => Some(stored_counts(&srv.open().await?).await?),
        None => None,
    };
    let db1 = match &server {
        Some(s) => s.db_bytes().await?,
        None => 0,
    };

    let ld = |m: &Mutex<Vec<f64>>| {
        let mut v = m.lock().expect("stats lock").clone();
        v.sort_by(f64::total_cmp);
        v
    };
    let line = |name: &str, v: &[f64]| {
        println!(
            "{name:<24}{:>8} calls  p50 {:>8.2} ms  p99 {:>8.2} ms  max {:>8.2} ms",
            v.len(),
            quantile(v, 0.5),
            quantile(v, 0.99),
            v.last().copied().unwrap_or(0.0)
        );
    };
    let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
    let rpcs = get(&stats.rpcs);
    let rows_acked = get(&stats.rows_acked);
    println!("workers (slots)         {n}");
    println!(
        "rate                    1 epoch / {} ms each, {} metrics per epoch (+{} every {} epochs), a {} KB checkpoint every {} epochs",
        args.epoch_ms,
        TRAINER_METRICS.len(),
        eval_metric_names().len(),
        args.eval_every,
        args.checkpoint_bytes / 1000,
        args.checkpoint_every
    );
    println!(
        "wall time               {wall:.1} s (phase {} s)",
        args.seconds
    );
    println!(
        "rpcs                    {rpcs} ({:.0} rpc/s)",
        rpcs as f64 / phase_s
    );
    println!(
        "epochs reported         {} in {} reports ({} carried more than one epoch)",
        get(&stats.epochs_sent),
        get(&stats.reports),
        get(&stats.batched_reports)
    );
    println!(
        "metric rows acked       {rows_acked} ({:.0} rows/s)",
        rows_acked as f64 / phase_s
    );
    line("heartbeat", &ld(&stats.heartbeat));
    line("report progress", &ld(&stats.progress));
    line("upload checkpoint", &ld(&stats.upload));
    line("report result", &ld(&stats.result));
    match watch.await? {
        Some((q, lag)) => println!(
            "coordinator write queue max {q} reports waiting, max lag {lag:.1} ms (GetStatus, 1/s)"
        ),
        None => println!("coordinator write queue n/a (no GetStatus)"),
    }
    println!("lost leases             {}", get(&stats.lost_leases));
    println!("failed workers          {failed}");
    println!(
        "results                 {reported} reported, {} of {} cells done",
        s.cells_done, s.cells_total
    );
    if let (Some(srv), Some((rows_stored, expired))) = (&server, stored) {
        println!(
            "metric rows stored      {rows_stored} ({:.0} rows/s)",
            rows_stored as f64 / phase_s
        );
        println!("expired attempts        {expired}");
        println!(
            "coordinator cpu         {:.1} s in {wall:.1} s ({:.0}% of one core)",
            usage1.cpu_s - usage0.cpu_s,
            100.0 * (usage1.cpu_s - usage0.cpu_s) / wall
        );
        println!(
            "coordinator memory      rss {:.0} MiB, peak {:.0} MiB",
            usage1.rss_mib, usage1.peak_rss_mib
        );
        let growth = db1.saturating_sub(db0) as f64;
        println!(
            "database growth         {:.1} MB in the phase, {:.2} GB per hour ({})",
            growth / 1e6,
            growth / phase_s * 3600.0 / 1e9,
            srv.db_name()
        );
        if rows_stored != rows_acked || expired > 0 {
            bail!("{rows_acked} metric rows acknowledged but {rows_stored} stored, {expired} attempts expired");
        }
    }
    if get(&stats.lost_leases) > 0 || failed > 0 || reported != n as u64 {
        bail!(
            "{} leases lost, {failed} workers failed, {reported} of {n} results reported",
            get(&stats.lost_leases)
        );
    }
    Ok(())
}

/// Metric rows and expired attempts in the bench's database.
async fn stored_counts(db: &sqlx::AnyPool) -> anyhow::Result<(u64, u64)> {
    let rows: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM epoch_metrics")
        .fetch_one(db)
        .await?;
    let expired: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM attempts WHERE state = 'expired'")
        .fetch_one(db)
        .await?;
    Ok((rows as u64, expired as u64))
}

/// One simulated worker slot; true once its result was stored.
async fn worker(
    i: usize,
    n: usize,
    ch: Channel,
    args: &Args,
    stats: &Arc<Stats>,
) -> anyhow::Result<bool> {
    let mut c = WorkerServiceClient::new(ch);
    let reg = c
        .register(pb::RegisterRequest {
            hostname: format!("sim-{i}"),
            cores: 1,
            device: "cpu".into(),
            slots: 1,
            version: "loadbench".into(),
            cpu: String::new(),
        })
        .await?
        .into_inner();
    stats.rpcs.fetch_add(1, Ordering::Relaxed);
    let lease = c
        .lease(pb::LeaseRequest {
            worker_id: reg.worker_id.clone(),
            slot: 0,
        })
        .await?
        .into_inner()
        .lease
        .context("no cell left to lease")?;
    stats.rpcs.fetch_add(1, Ordering::Relaxed);
    let phase = Duration::from_secs(args.seconds);
    let start = Instant::now();
    let beat_every = args
        .heartbeat_ms
        .unwrap_or(reg.heartbeat_interval_ms as u64)
        .max(1);
    // As the daemon does, heartbeats go on until the result is acknowledged: a worker
    // still delivering its backlog after training keeps its lease.
    let result_sent = Arc::new(AtomicBool::new(false));
    let beats = tokio::spawn(heartbeats(
        c.clone(),
        reg.worker_id.clone(),
        lease.lease_id,
        Duration::from_millis(beat_every * i as u64 / n as u64),
        Duration::from_millis(beat_every),
        result_sent.clone(),
        stats.clone(),
    ));
    // The training clock: epochs come at the real rate whether or not the coordinator
    // keeps up; the sender below batches what it has not delivered yet.
    let (tx, mut rx) = mpsc::unbounded_channel::<u32>();
    let epoch_ms = args.epoch_ms.max(1);
    // Real workers are at every stage of their cells: worker i starts its cell at an
    // epoch spread over one checkpoint interval, so uploads and evaluations come at a
    // steady rate rather than all at once.
    let first_epoch =
        (i as u64 * u64::from(args.checkpoint_every.max(args.eval_every)) / n as u64) as u32;
    let clock = tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(epoch_ms * i as u64 / n as u64)).await;
        let mut tick = tokio::time::interval(Duration::from_millis(epoch_ms));
        let mut epoch = first_epoch;
        while start.elapsed() < phase {
            tick.tick().await;
            epoch += 1;
            if tx.send(epoch).is_err() {
                break;
            }
        }
    });
    let mut last = 0u32;
    let mut ckpt = None;
    while let Some(first) = rx.recv().await {
        let mut batch = vec![first];
        while let Ok(e) = rx.try_recv() {
            batch.push(e);
        }
        last = *batch.last().expect("one epoch");
        let req = pb::ReportProgressRequest {
            lease_id: lease.lease_id,
            epochs: batch
                .iter()
                .map(|&e| pb::EpochMetrics {
                    epoch: e,
                    values: epoch_values(i, e, e % args.eval_every.max(1) == 0),
                })
                .collect(),
        };
        let rows: usize = req.epochs.iter().map(|e| e.values.len()).sum();
        let t = Instant::now();
        c.report_progress(req)
            .await
            .with_context(|| format!("progress of worker {i} at epoch {last}"))?;
        stats.time(&stats.progress, t);
        stats.rows_acked.fetch_add(rows as u64, Ordering::Relaxed);
        stats.reports.fetch_add(1, Ordering::Relaxed);
        stats
            .epochs_sent
            .fetch_add(batch.len() as u64, Ordering::Relaxed);
        if batch.len() > 1 {
            stats.batched_reports.fetch_add(1, Ordering::Relaxed);
        }
        if let Some(&e) = batch
            .iter()
            .rev()
            .find(|&&e| e % args.checkpoint_every.max(1) == 0)
        {
            ckpt = Some(upload(&mut c, lease.lease_id, e, i, args.checkpoint_bytes, stats).await?);
        }
    }
    clock.await?;
    if beats.is_finished() {
        beats.await??;
        bail!("heartbeats of worker {i} ended before its result");
    }
    result_sent.store(true, Ordering::Relaxed);
    let t = Instant::now();
    let r = c
        .report_result(pb::ReportResultRequest {
            lease_id: lease.lease_id,
            score: Some(pb::GaitScore {
                score: (i % 97) as f64 / 97.0,
                track: 0.5,
                effort: 0.1,
                tilt: 0.05,
                progress: 1.0,
                robots: 32,
                ..Default::default()
            }),
            epochs: last,
            final_checkpoint_sha256: ckpt.unwrap_or_default(),
        })
        .await
        .with_context(|| format!("result of worker {i}"))?
        .into_inner();
    stats.time(&stats.result, t);
    beats.abort();
    Ok(!r.duplicate)
}

/// Heartbeats of one worker until it is aborted after the result; counts leases the
/// coordinator lost (a lease that is no longer active once the result is on its way is not
/// lost: the result ended it).
async fn heartbeats(
    mut c: WorkerServiceClient<Channel>,
    worker_id: String,
    lease: i64,
    offset: Duration,
    every: Duration,
    result_sent: Arc<AtomicBool>,
    stats: Arc<Stats>,
) -> anyhow::Result<()> {
    tokio::time::sleep(offset).await;
    let mut tick = tokio::time::interval(every);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tick.tick().await;
        let t = Instant::now();
        let r = c
            .heartbeat(pb::HeartbeatRequest {
                worker_id: worker_id.clone(),
                lease_ids: vec![lease],
            })
            .await
            .context("heartbeat")?;
        stats.time(&stats.heartbeat, t);
        if r.get_ref().leases.first().map(|l| l.status()) != Some(pb::LeaseStatus::Active) {
            if result_sent.load(Ordering::Relaxed) {
                return Ok(());
            }
            stats.lost_leases.fetch_add(1, Ordering::Relaxed);
            bail!("lease {lease} lost");
        }
    }
}

/// Uploads a checkpoint-sized file of distinct bytes; returns its sha256.
async fn upload(
    c: &mut WorkerServiceClient<Channel>,
    lease: i64,
    epoch: u32,
    worker: usize,
    size: usize,
    stats: &Stats,
) -> anyhow::Result<String> {
    let mut bytes = vec![0u8; size];
    let tag = format!("{worker}/{epoch}");
    for (k, b) in bytes.iter_mut().enumerate() {
        *b = (k as u8).wrapping_mul(31);
    }
    bytes[..tag.len().min(size)].copy_from_slice(&tag.as_bytes()[..tag.len().min(size)]);
    let sha = hex::encode(Sha256::digest(&bytes));
    let header = pb::UploadHeader {
        lease_id: lease,
        epoch,
        sha256: sha.clone(),
        size: size as u64,
    };
    let t = Instant::now();
    c.upload_checkpoint(tokio_stream::iter(upload_messages(header, &bytes)))
        .await
        .with_context(|| format!("checkpoint upload of worker {worker} at epoch {epoch}"))?;
    stats.time(&stats.upload, t);
    Ok(sha)
}

struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
