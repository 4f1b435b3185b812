//! `worker --connect URL`: the worker daemon. It registers with the coordinator, leases
//! one cell per slot, trains it with [`train_cell`] on a dedicated OS thread, and streams
//! epoch metrics, checkpoints (chunked, sha256) and the result back. Every delivery is
//! retried with backoff while the coordinator is away, so training never waits for the
//! network and nothing is lost; a re-leased cell resumes from the checkpoint its lease
//! names.

use crate::{Error, Result};
use gaitsweep_core::pb::{self, worker_service_client::WorkerServiceClient};
use gaitsweep_core::reason;
use gaitsweep_trainer::train::{
    train_cell, CellOutcome, CellRunConfig, EpochMetrics, TrainObserver,
};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::future::Future;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::Channel;
use tonic::{Code, Status};

#[cfg(test)]
mod tests;
mod transfer;
mod transport;

use transfer::{download, upload, UploadError};
use transport::{connect, is_unknown_worker, tls_refused, transient, Backoff, Coordinator, Retry};

/// Command-line arguments of the worker daemon.
#[derive(clap::Args, Debug, Clone)]
pub struct DaemonArgs {
    /// Coordinator URL (http://HOST:PORT, or https:// with TLS).
    #[arg(long, env = "GAITSWEEP_URL")]
    pub connect: String,
    /// Cells to train concurrently.
    #[arg(long, default_value_t = 1)]
    pub slots: usize,
    /// Training device: cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Threads for libtorch and the simulation (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Access token of the coordinator.
    #[arg(long, env = "GAITSWEEP_TOKEN")]
    pub token: Option<String>,
    /// PEM CA certificate to trust for https:// URLs.
    #[arg(long)]
    pub tls_ca: Option<PathBuf>,
    /// Directory for checkpoints in progress (default: a directory under the system temp dir).
    #[arg(long)]
    pub work_dir: Option<PathBuf>,
    /// Longest wait between retries when the coordinator is unreachable, seconds.
    #[arg(long, default_value_t = 10.0)]
    pub max_backoff_seconds: f64,
}

/// Runs the daemon on its own tokio runtime until Ctrl-C.
pub fn run_blocking(args: DaemonArgs) -> Result<()> {
    if let Some(n) = args.threads {
        // The simulation's rayon pool reads this before its first use.
        std::env::set_var("RAYON_NUM_THREADS", n.to_string());
    }
    crate::cli::configure_threads(args.threads);
    let rt = tokio::runtime::Runtime::new().map_err(Error::io("start the tokio runtime"))?;
    rt.block_on(run(args))
}

/// Runs the daemon until Ctrl-C. Leases held at exit expire on the coordinator and are
/// resumed elsewhere from their last checkpoint.
pub async fn run(args: DaemonArgs) -> Result<()> {
    let device = crate::cli::parse_device(&args.device)?;
    let client = connect(&args)?;
    let retry = Retry {
        backoff: Backoff::new(Duration::from_secs_f64(args.max_backoff_seconds.max(0.1))),
        shutdown: Arc::new(AtomicBool::new(false)),
    };
    let work_dir = args.work_dir.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("gaitsweep-worker-{}", std::process::id()))
    });
    std::fs::create_dir_all(work_dir.join("cache"))
        .map_err(Error::io(format!("create {}", work_dir.display())))?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u32;
    let hostname = std::fs::read_to_string("/etc/hostname")
        .map(|s| s.trim().to_string())
        .unwrap_or_default();
    let reg = pb::RegisterRequest {
        hostname,
        cores,
        device: args.device.clone(),
        slots: args.slots as u32,
        version: env!("CARGO_PKG_VERSION").to_string(),
        cpu: crate::host::cpu_model(),
    };
    let reg_req = reg.clone();
    let reg = retry
        .call("register", None, || client.register(reg.clone()))
        .await
        .map_err(|s| match tls_refused(&s) {
            Some(tls) => Error::Config(format!("cannot connect to {}: {tls}", args.connect)),
            None => Error::Config(format!(
                "the coordinator refused registration: {}",
                s.message()
            )),
        })?;
    let shutdown = retry.shutdown.clone();
    let ctx = Arc::new(Ctx {
        client,
        worker_id: std::sync::RwLock::new(reg.worker_id.clone()),
        registration: reg_req,
        heartbeat: Duration::from_millis(reg.heartbeat_interval_ms.max(100) as u64),
        retry,
        device,
        work_dir,
        train: Arc::new(|cfg, observer| train_cell(cfg, observer)),
        robot_wait: ROBOT_WAIT,
    });
    tracing::info!(worker = %reg.worker_id, slots = args.slots, device = %args.device, url = %args.connect, "worker registered");
    let mut slots = tokio::task::JoinSet::new();
    for slot in 0..args.slots.max(1) as u32 {
        slots.spawn(slot_loop(ctx.clone(), slot));
    }
    tokio::select! {
        _ = gaitsweep_core::shutdown_signal() => {
            tracing::info!("stopping: each slot checkpoints its cell at the end of the epoch and uploads it");
            shutdown.store(true, Ordering::Relaxed);
            // Training threads use libtorch until they return; exiting before them would tear
            // libtorch down under their feet.
            let drained = tokio::time::timeout(SHUTDOWN_GRACE, async {
                while let Some(r) = slots.join_next().await {
                    if let Err(e) = r {
                        tracing::error!(error = %e, "slot task ended");
                    }
                }
            })
            .await;
            if drained.is_err() {
                tracing::warn!(seconds = SHUTDOWN_GRACE.as_secs(), "slots did not stop in time; their leases will expire");
            }
        }
        Some(r) = slots.join_next() => if let Err(e) = r { tracing::error!(error = %e, "slot task ended") },
    }
    Ok(())
}

/// Trains one cell, reporting to the observer: [`train_cell`] in production.
type TrainFn =
    Arc<dyn Fn(&CellRunConfig, &mut dyn TrainObserver) -> Result<CellOutcome> + Send + Sync>;

/// What every slot of the daemon shares.
struct Ctx<C> {
    client: C,
    /// Replaced when the coordinator no longer knows this worker (e.g. its database was
    /// recreated) and the worker registers again.
    worker_id: std::sync::RwLock<String>,
    registration: pb::RegisterRequest,
    heartbeat: Duration,
    /// Backoff, and the flag set when the process is asked to stop: training threads then
    /// end their current epoch, write and upload a checkpoint, and no new cell is leased.
    retry: Retry,
    device: tch::Device,
    work_dir: PathBuf,
    train: TrainFn,
    /// How long a slot waits before leasing again after a cell whose robot this machine
    /// cannot load (first wait, longest wait; doubling in between).
    robot_wait: (Duration, Duration),
}

/// How long a stopping worker waits for its slots to checkpoint and upload.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(60);

/// The waits of a slot whose machine cannot load a leased cell's robot: 30 s, doubling to
/// 15 min, so that a broken machine neither drains the queue nor gives up for good.
const ROBOT_WAIT: (Duration, Duration) = (Duration::from_secs(30), Duration::from_secs(900));

impl<C: Coordinator> Ctx<C> {
    fn worker_id(&self) -> String {
        self.worker_id
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Registers again after the coordinator answered that `stale` is not registered; a
    /// slot that finds another slot already did so keeps the new id.
    async fn register_again(&self, stale: &str) {
        if self.worker_id() != stale {
            return;
        }
        let resp = self
            .retry
            .call("register", None, || {
                self.client.register(self.registration.clone())
            })
            .await;
        match resp {
            Ok(reg) => {
                let mut id = self.worker_id.write().unwrap_or_else(|e| e.into_inner());
                if *id == stale {
                    tracing::warn!(old = %stale, worker = %reg.worker_id, "the coordinator no longer knew this worker; registered again");
                    *id = reg.worker_id;
                }
            }
            Err(s) => {
                tracing::error!(code = ?s.code(), error = %s.message(), "cannot register again")
            }
        }
    }
}

async fn slot_loop<C: Coordinator>(ctx: Arc<Ctx<C>>, slot: u32) {
    let mut robot_wait = ctx.robot_wait.0;
    while !ctx.retry.stopping() {
        let worker_id = ctx.worker_id();
        let req = pb::LeaseRequest {
            worker_id: worker_id.clone(),
            slot,
        };
        let resp = ctx
            .retry
            .call("lease", None, || ctx.client.lease(req.clone()))
            .await;
        match resp {
            Ok(pb::LeaseResponse {
                lease: Some(lease), ..
            }) => {
                let id = lease.lease_id;
                // A robot this machine cannot load (its robot files missing or broken) is
                // the machine's fault, not the cell's: counted as the cell's failure, it
                // would fail every cell of the sweep within seconds, one lease after another.
                if let Some(problem) = robot_problem(&lease).await {
                    tracing::error!(slot, lease = id, error = %problem, wait_s = robot_wait.as_secs(),
                        "this machine cannot load the cell's robot: giving the cell back (not counted against it) and waiting before leasing again; point GAITSWEEP_ROBOTS at the robots/ directory");
                    give_back(
                        &ctx,
                        id,
                        &format!("worker cannot load the robot: {problem}"),
                    )
                    .await;
                    tokio::time::sleep(robot_wait).await;
                    robot_wait = (robot_wait * 2).min(ctx.robot_wait.1);
                    continue;
                }
                robot_wait = ctx.robot_wait.0;
                if let Err(e) = run_lease(&ctx, slot, lease).await {
                    tracing::error!(slot, lease = id, error = %e, "lease ended with an error");
                }
            }
            Ok(r) => {
                tokio::time::sleep(Duration::from_millis(
                    r.retry_after_ms.clamp(100, 10_000) as u64
                ))
                .await
            }
            Err(s) if is_unknown_worker(&s) => ctx.register_again(&worker_id).await,
            Err(s) => {
                tracing::error!(slot, code = ?s.code(), error = %s.message(), "cannot lease cells, retrying in 5 s");
                tokio::time::sleep(Duration::from_secs(5)).await;
            }
        }
    }
}

/// Why this machine cannot train a leased cell's robot, if it cannot: its preset and URDF
/// are read as training reads them.
async fn robot_problem(lease: &pb::Lease) -> Option<String> {
    let robot = lease.task.as_ref()?.robot.clone();
    let loaded = tokio::task::spawn_blocking(move || gaitsweep_sim::Preset::load(&robot)).await;
    match loaded {
        Ok(Ok(_)) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(e) => Some(format!("loading the robot panicked: {e}")),
    }
}

/// Gives a leased cell back to the coordinator: it is queued again at once, and the
/// attempt is not counted as a failure.
async fn give_back<C: Coordinator>(ctx: &Ctx<C>, lease: i64, reason: &str) -> bool {
    let req = pb::ReleaseLeaseRequest {
        lease_id: lease,
        reason: reason.into(),
    };
    match ctx
        .retry
        .call("release_lease", None, || {
            ctx.client.release_lease(req.clone())
        })
        .await
    {
        Ok(r) => r.requeued,
        Err(s) => {
            tracing::warn!(lease, code = ?s.code(), error = %s.message(), "could not give the cell back, its lease will expire");
            false
        }
    }
}

/// What the training thread tells the async side, in order.
enum Event {
    Epoch(EpochMetrics),
    Checkpoint(u32, PathBuf),
    Done(Result<CellOutcome>),
}

struct Bridge {
    tx: mpsc::UnboundedSender<Event>,
    stop: Arc<AtomicBool>,
    shutdown: Arc<AtomicBool>,
}

impl TrainObserver for Bridge {
    fn on_epoch(&mut self, m: &EpochMetrics) {
        let _ = self.tx.send(Event::Epoch(m.clone()));
    }
    fn on_checkpoint(&mut self, epoch: u32, path: &Path) {
        let _ = self.tx.send(Event::Checkpoint(epoch, path.to_path_buf()));
    }
    fn should_stop(&self) -> bool {
        self.stop.load(Ordering::Relaxed) || self.shutdown.load(Ordering::Relaxed)
    }
}

async fn run_lease<C: Coordinator>(ctx: &Ctx<C>, slot: u32, lease: pb::Lease) -> Result<()> {
    let id = lease.lease_id;
    let task = lease
        .task
        .clone()
        .ok_or_else(|| Error::Config("lease without a task".into()))?;
    let cell = task.cell.clone().unwrap_or_default();
    let terrain = cell
        .terrain
        .parse()
        .map_err(|_| Error::Config(format!("unknown terrain {:?} in lease", cell.terrain)))?;
    let dir = ctx.work_dir.join(format!("lease-{id}"));
    let stop = Arc::new(AtomicBool::new(false));
    let resume_from = match &lease.resume_from {
        Some(ck) => Some(download(ctx, ck, &stop).await?),
        None => None,
    };
    tracing::info!(slot, lease = id, cell = cell.cell_id, w1 = cell.w1, w2 = cell.w2, terrain = %cell.terrain,
        epochs = task.epochs, resume_epoch = lease.resume_from.as_ref().map(|c| c.epoch), "training cell");
    let cfg = CellRunConfig {
        robot: task.robot.clone(),
        terrain,
        difficulty: task.difficulty.map(|d| d.min(9) as u8),
        w1: cell.w1,
        w2: cell.w2,
        agents: task.agents as usize,
        epochs: task.epochs,
        budget_epochs: task.budget_epochs,
        seed: cell.seed,
        device: ctx.device,
        checkpoint_every: task.checkpoint_every,
        out_dir: dir.clone(),
        resume_from,
        ppo_overrides: task.ppo_overrides.clone(),
        eval: gaitsweep_core::convert::task_eval(&task, terrain).map_err(Error::Config)?,
        stop_unrewarded_after: task.stop_unrewarded_after,
    };
    let (tx, mut rx) = mpsc::unbounded_channel();
    let bridge_tx = tx.clone();
    let thread_stop = stop.clone();
    let (train, shutdown) = (ctx.train.clone(), ctx.retry.shutdown.clone());
    // Training never runs on the async runtime: heartbeats must not wait for an epoch.
    std::thread::Builder::new()
        .name(format!("train-slot-{slot}"))
        .spawn(move || {
            let mut bridge = Bridge {
                tx: bridge_tx,
                stop: thread_stop,
                shutdown,
            };
            let out = train(&cfg, &mut bridge);
            let _ = bridge.tx.send(Event::Done(out));
        })
        .map_err(Error::io("spawn the training thread"))?;
    drop(tx);

    let beat = tokio::spawn(heartbeat_loop(
        ctx.client.clone(),
        ctx.worker_id(),
        id,
        ctx.heartbeat,
        stop.clone(),
    ));
    let result = deliver(ctx, id, task.epochs, &mut rx, &stop).await;
    beat.abort();
    if result.is_ok() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    result
}

/// Renews the lease; sets `stop` when the coordinator says the lease is lost or cancelled.
async fn heartbeat_loop<C: Coordinator>(
    client: C,
    worker_id: String,
    lease: i64,
    every: Duration,
    stop: Arc<AtomicBool>,
) {
    let mut tick = tokio::time::interval(every);
    loop {
        tick.tick().await;
        let req = pb::HeartbeatRequest {
            worker_id: worker_id.clone(),
            lease_ids: vec![lease],
        };
        match client.heartbeat(req).await {
            Ok(r) => {
                let status = r
                    .leases
                    .first()
                    .map(|l| l.status())
                    .unwrap_or(pb::LeaseStatus::Lost);
                if status != pb::LeaseStatus::Active {
                    tracing::warn!(lease, status = ?status, "coordinator withdrew the lease, stopping the cell");
                    stop.store(true, Ordering::Relaxed);
                    return;
                }
            }
            Err(s) => {
                tracing::debug!(lease, code = ?s.code(), "heartbeat failed, training continues")
            }
        }
    }
}

/// Delivers the training thread's events in order until it is done.
async fn deliver<C: Coordinator>(
    ctx: &Ctx<C>,
    lease: i64,
    epochs: u32,
    rx: &mut mpsc::UnboundedReceiver<Event>,
    stop: &AtomicBool,
) -> Result<()> {
    let mut uploaded: HashMap<PathBuf, (String, u64)> = HashMap::new();
    let mut closed = false; // the coordinator refused further reports for this lease
    let closed_by = |s: &Status| {
        tracing::warn!(lease, code = ?s.code(), error = %s.message(), "coordinator refused a report, stopping the cell");
        stop.store(true, Ordering::Relaxed);
    };
    let mut next: Option<Event> = None;
    loop {
        let ev = match next.take() {
            Some(ev) => ev,
            None => match rx.recv().await {
                Some(ev) => ev,
                None => break,
            },
        };
        match ev {
            Event::Epoch(m) => {
                // Backpressure: epochs that finished while the last report was on its way
                // go in one report, so a coordinator that falls behind gets fewer, larger
                // reports instead of a growing queue of calls that time out.
                let mut batch = vec![m];
                while let Ok(ev) = rx.try_recv() {
                    match ev {
                        Event::Epoch(m) => batch.push(m),
                        other => {
                            next = Some(other);
                            break;
                        }
                    }
                }
                for m in &batch {
                    tracing::info!(
                        lease,
                        epoch = m.epoch,
                        epochs,
                        mean_return = m.values.get("mean_return").copied(),
                        "epoch"
                    );
                }
                if closed {
                    continue;
                }
                if batch.len() > 1 {
                    tracing::debug!(
                        lease,
                        epochs = batch.len(),
                        "reporting a backlog of epochs in one call"
                    );
                }
                let req = pb::ReportProgressRequest {
                    lease_id: lease,
                    epochs: batch
                        .into_iter()
                        .map(|m| pb::EpochMetrics {
                            epoch: m.epoch,
                            values: m.values,
                        })
                        .collect(),
                };
                if let Err(s) = ctx
                    .retry
                    .call("report_progress", None, || {
                        ctx.client.report_progress(req.clone())
                    })
                    .await
                {
                    closed = true;
                    closed_by(&s);
                }
            }
            Event::Checkpoint(epoch, path) => {
                if closed {
                    continue;
                }
                match upload(ctx, lease, epoch, &path).await {
                    Ok(v) => {
                        uploaded.insert(path, v);
                    }
                    Err(UploadError::Refused(s)) => {
                        closed = true;
                        closed_by(&s);
                    }
                    Err(UploadError::Local(e)) => {
                        tracing::warn!(lease, epoch, error = %e, "could not read a checkpoint, skipping it")
                    }
                }
            }
            Event::Done(Ok(out)) => {
                if closed {
                    return Ok(());
                }
                let sha = match uploaded.get(&out.final_checkpoint) {
                    Some((sha, _)) => Some(sha.clone()),
                    None => match upload(ctx, lease, out.epochs, &out.final_checkpoint).await {
                        Ok((sha, _)) => Some(sha),
                        Err(UploadError::Refused(s)) => {
                            closed_by(&s);
                            return Ok(());
                        }
                        Err(UploadError::Local(e)) => {
                            tracing::warn!(lease, error = %e, "final checkpoint unreadable, reporting the score without it");
                            None
                        }
                    },
                };
                let req = pb::ReportResultRequest {
                    lease_id: lease,
                    score: Some((&out.score).into()),
                    epochs: out.epochs,
                    final_checkpoint_sha256: sha.unwrap_or_default(),
                };
                match ctx
                    .retry
                    .call("report_result", None, || {
                        ctx.client.report_result(req.clone())
                    })
                    .await
                {
                    Ok(r) => tracing::info!(
                        lease,
                        score = out.score.score,
                        duplicate = r.duplicate,
                        "cell done, result delivered"
                    ),
                    Err(s) => {
                        tracing::warn!(lease, code = ?s.code(), error = %s.message(), "result refused")
                    }
                }
                return Ok(());
            }
            Event::Done(Err(e)) => {
                if stop.load(Ordering::Relaxed) {
                    tracing::info!(lease, "cell stopped: the coordinator withdrew the lease");
                    return Ok(());
                }
                if ctx.retry.stopping() {
                    // Give the cell back at once: it is queued again without waiting for the
                    // lease to expire, and a stop is not counted as a failed attempt.
                    let requeued = give_back(ctx, lease, "worker stopping").await;
                    tracing::info!(
                        lease,
                        requeued,
                        "cell stopped and given back; it resumes from its uploaded checkpoint"
                    );
                    return Ok(());
                }
                tracing::error!(lease, error = %e, "training failed");
                let req = pb::FailCellRequest {
                    lease_id: lease,
                    error: e.to_string(),
                };
                let _ = ctx
                    .retry
                    .call("fail_cell", None, || ctx.client.fail_cell(req.clone()))
                    .await;
                return Err(e);
            }
        }
    }
    Err(Error::Config(
        "the training thread ended without a result".into(),
    ))
}
