//! `loadbench`: many simulated workers (register, lease, heartbeat, report progress and a
//! result; no training) against a real coordinator process on loopback. Prints RPCs/s and
//! heartbeat latency percentiles, and checks that every result was stored.
//!
//! `loadbench --workers 1000 --seconds 30` starts `coordinator serve` from the same
//! directory as this binary with a temporary data dir; `--connect URL` uses a running one.

use anyhow::{bail, Context};
use clap::Parser;
use gaitsweep_core::pb::{
    self, sweep_service_client::SweepServiceClient, worker_service_client::WorkerServiceClient,
};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tonic::transport::{Channel, Endpoint};

#[derive(Parser)]
#[command(
    name = "loadbench",
    about = "load benchmark of the gaitsweep coordinator with simulated workers"
)]
struct Args {
    /// Simulated workers (each with its own connection).
    #[arg(long, default_value_t = 1000)]
    workers: usize,
    /// Length of the heartbeat phase, seconds.
    #[arg(long, default_value_t = 30)]
    seconds: u64,
    /// Heartbeat interval of every worker, milliseconds.
    #[arg(long, default_value_t = 1000)]
    heartbeat_ms: u64,
    /// Send a progress report every this many heartbeats.
    #[arg(long, default_value_t = 5)]
    progress_every: u64,
    /// Use a running coordinator instead of starting one.
    #[arg(long)]
    connect: Option<String>,
}

struct Stats {
    rpcs: AtomicU64,
    errors: AtomicU64,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let rt = tokio::runtime::Runtime::new()?;
    rt.block_on(run(args))
}

async fn run(args: Args) -> anyhow::Result<()> {
    let mut server = None;
    let _tmp_guard;
    let url = match &args.connect {
        Some(u) => u.clone(),
        None => {
            let exe = std::env::current_exe()?;
            let bin = exe.with_file_name("coordinator");
            if !bin.is_file() {
                bail!(
                    "{} is missing: build it with `cargo build --release -p gaitsweep-coordinator`",
                    bin.display()
                );
            }
            let dir =
                std::env::temp_dir().join(format!("gaitsweep-loadbench-{}", std::process::id()));
            std::fs::create_dir_all(&dir)?;
            _tmp_guard = TempDir(dir.clone());
            let child = Command::new(&bin)
                .args(["serve", "--listen", "127.0.0.1:0", "--data-dir"])
                .arg(&dir)
                .args(["--lease-seconds", "60"])
                .env("RUST_LOG", "warn")
                .stdout(Stdio::null())
                .stderr(Stdio::inherit())
                .spawn()
                .context("start the coordinator")?;
            server = Some(KillOnDrop(child));
            let addr_file = dir.join("coordinator.addr");
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
            format!("http://{addr}")
        }
    };
    let n = args.workers;
    let mut sweeps = SweepServiceClient::new(Endpoint::from_shared(url.clone())?.connect().await?);
    let cols = 40usize.min(n.max(1));
    let rows = n.div_ceil(cols);
    let spec = pb::SweepSpec {
        name: "loadbench".into(),
        robot: "anymal".into(),
        terrains: vec!["flat".into()],
        w1: Some(pb::Axis {
            kind: Some(pb::axis::Kind::Range(pb::Range {
                min: 2.0,
                max: 12.0,
                count: rows as u32,
            })),
        }),
        w2: Some(pb::Axis {
            kind: Some(pb::axis::Kind::Range(pb::Range {
                min: -10.0,
                max: -2.0,
                count: cols as u32,
            })),
        }),
        agents_per_cell: 1,
        epochs: 1,
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

    // connect every worker first, then start them together
    let mut channels = Vec::with_capacity(n);
    for _ in 0..n {
        channels.push(
            Endpoint::from_shared(url.clone())?
                .tcp_nodelay(true)
                .connect()
                .await?,
        );
    }
    let stats = Arc::new(Stats {
        rpcs: AtomicU64::new(0),
        errors: AtomicU64::new(0),
    });
    let t0 = Instant::now();
    let phase = Duration::from_secs(args.seconds);
    let mut tasks = tokio::task::JoinSet::new();
    for (i, ch) in channels.into_iter().enumerate() {
        let stats = stats.clone();
        let a = (args.heartbeat_ms, args.progress_every);
        tasks.spawn(async move { worker(i, ch, a.0, a.1, phase, stats).await });
    }
    let mut lat: Vec<u32> = Vec::new();
    let mut reported = 0;
    while let Some(r) = tasks.join_next().await {
        match r? {
            Ok((l, ok)) => {
                lat.extend(l);
                reported += ok as usize;
            }
            Err(e) => {
                stats.errors.fetch_add(1, Ordering::Relaxed);
                eprintln!("worker failed: {e:#}");
            }
        }
    }
    let wall = t0.elapsed().as_secs_f64();
    lat.sort_unstable();
    let pct = |p: f64| {
        lat.get(((lat.len() as f64 * p) as usize).min(lat.len().saturating_sub(1)))
            .copied()
            .unwrap_or(0) as f64
            / 1000.0
    };
    let s = sweeps
        .get_sweep(pb::GetSweepRequest {
            sweep_id: sweep.sweep_id,
        })
        .await?
        .into_inner();
    let rpcs = stats.rpcs.load(Ordering::Relaxed);
    println!("workers                 {n}");
    println!(
        "wall time               {wall:.1} s (heartbeat phase {} s)",
        args.seconds
    );
    println!(
        "rpcs                    {rpcs} ({:.0} rpc/s)",
        rpcs as f64 / wall
    );
    println!("heartbeats              {}", lat.len());
    println!("heartbeat latency p50   {:.2} ms", pct(0.50));
    println!("heartbeat latency p99   {:.2} ms", pct(0.99));
    println!(
        "heartbeat latency max   {:.2} ms",
        lat.last().copied().unwrap_or(0) as f64 / 1000.0
    );
    println!(
        "errors                  {}",
        stats.errors.load(Ordering::Relaxed)
    );
    println!("results reported        {reported}");
    println!(
        "results stored          {} of {} cells",
        s.cells_done, s.cells_total
    );
    drop(server);
    if s.cells_done as usize != reported || reported != n {
        bail!(
            "not every report was stored: {reported} reported, {} stored, {n} workers",
            s.cells_done
        );
    }
    Ok(())
}

/// One simulated worker: register, lease, heartbeat (with progress) for the phase, report.
async fn worker(
    i: usize,
    ch: Channel,
    every_ms: u64,
    progress_every: u64,
    phase: Duration,
    stats: Arc<Stats>,
) -> anyhow::Result<(Vec<u32>, bool)> {
    let mut c = WorkerServiceClient::new(ch);
    let count = |s: &Stats| s.rpcs.fetch_add(1, Ordering::Relaxed);
    let reg = c
        .register(pb::RegisterRequest {
            hostname: format!("sim-{i}"),
            cores: 1,
            device: "cpu".into(),
            slots: 1,
            version: "loadbench".into(),
        })
        .await?
        .into_inner();
    count(&stats);
    let lease = c
        .lease(pb::LeaseRequest {
            worker_id: reg.worker_id.clone(),
            slot: 0,
        })
        .await?
        .into_inner();
    count(&stats);
    let lease = lease.lease.context("no cell left to lease")?;
    let start = Instant::now();
    // spread the workers' ticks over the interval
    tokio::time::sleep(Duration::from_millis(
        every_ms * i as u64 / 1000 % every_ms.max(1),
    ))
    .await;
    let mut tick = tokio::time::interval(Duration::from_millis(every_ms));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut lat = Vec::new();
    let mut beats = 0u64;
    while start.elapsed() < phase {
        tick.tick().await;
        let t = Instant::now();
        let r = c
            .heartbeat(pb::HeartbeatRequest {
                worker_id: reg.worker_id.clone(),
                lease_ids: vec![lease.lease_id],
            })
            .await;
        lat.push(t.elapsed().as_micros() as u32);
        count(&stats);
        match r {
            Ok(r)
                if r.get_ref().leases.first().map(|l| l.status())
                    == Some(pb::LeaseStatus::Active) => {}
            Ok(_) => bail!("worker {i} lost its lease"),
            Err(e) => bail!("heartbeat of worker {i} failed: {e}"),
        }
        beats += 1;
        if beats % progress_every.max(1) == 0 {
            let values = [("mean_reward".to_string(), beats as f64)]
                .into_iter()
                .collect();
            c.report_progress(pb::ReportProgressRequest {
                lease_id: lease.lease_id,
                epochs: vec![pb::EpochMetrics {
                    epoch: beats as u32,
                    values,
                }],
            })
            .await?;
            count(&stats);
        }
    }
    let score = pb::GaitScore {
        score: (i % 97) as f64 / 97.0,
        track: 0.5,
        effort: 0.1,
        tilt: 0.05,
        progress: 1.0,
        robots: 1,
        ..Default::default()
    };
    let r = c
        .report_result(pb::ReportResultRequest {
            lease_id: lease.lease_id,
            score: Some(score),
            epochs: 1,
            final_checkpoint_sha256: String::new(),
        })
        .await?
        .into_inner();
    count(&stats);
    Ok((lat, !r.duplicate))
}

struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

struct TempDir(std::path::PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
