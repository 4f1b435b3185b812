//! The daemon's loops against an in-memory coordinator: what is sent, in which order,
//! what is retried and what stops a cell, without a server or a trainer.

use super::*;
use gaitsweep_trainer::Error as TrainError;
use std::collections::VecDeque;
use std::sync::Mutex;

/// Records every call the daemon makes; answers from a script.
#[derive(Clone, Default)]
struct Recorder(Arc<Mutex<Script>>);

#[derive(Default)]
struct Script {
    /// Successful calls, e.g. `progress 3`, `upload 2 <sha>`, `result 4 <sha>`.
    calls: Vec<String>,
    /// Every attempt, successful or not, by call name.
    attempts: HashMap<&'static str, u32>,
    /// Errors to answer before succeeding, by call name.
    errors: HashMap<&'static str, VecDeque<Status>>,
    /// Answers to `lease`, in order; when empty the worker is told to stop.
    leases: VecDeque<pb::LeaseResponse>,
    /// Ids handed out by `register`, in order.
    ids: VecDeque<String>,
    /// Status answered to heartbeats.
    heartbeat: Option<pb::LeaseStatus>,
    /// Set when the lease script runs out (the test's end).
    stop_when_out_of_leases: Option<Arc<AtomicBool>>,
}

impl Recorder {
    fn answer<T>(
        &self,
        call: &'static str,
        record: String,
        ok: T,
    ) -> std::result::Result<T, Status> {
        let mut s = self.0.lock().unwrap();
        *s.attempts.entry(call).or_default() += 1;
        if let Some(e) = s.errors.get_mut(call).and_then(VecDeque::pop_front) {
            return Err(e);
        }
        s.calls.push(record);
        Ok(ok)
    }

    fn fail(&self, call: &'static str, errors: impl IntoIterator<Item = Status>) {
        self.0
            .lock()
            .unwrap()
            .errors
            .entry(call)
            .or_default()
            .extend(errors);
    }

    fn calls(&self) -> Vec<String> {
        self.0.lock().unwrap().calls.clone()
    }

    fn attempts(&self, call: &str) -> u32 {
        self.0
            .lock()
            .unwrap()
            .attempts
            .get(call)
            .copied()
            .unwrap_or(0)
    }
}

impl Coordinator for Recorder {
    async fn register(
        &self,
        _: pb::RegisterRequest,
    ) -> std::result::Result<pb::RegisterResponse, Status> {
        let id = self.0.lock().unwrap().ids.pop_front().unwrap_or_default();
        self.answer(
            "register",
            format!("register {id}"),
            pb::RegisterResponse {
                worker_id: id,
                heartbeat_interval_ms: 100,
            },
        )
    }
    async fn lease(&self, r: pb::LeaseRequest) -> std::result::Result<pb::LeaseResponse, Status> {
        if self
            .0
            .lock()
            .unwrap()
            .errors
            .get("lease")
            .is_some_and(|e| !e.is_empty())
        {
            return self.answer("lease", String::new(), pb::LeaseResponse::default());
        }
        let next = {
            let mut s = self.0.lock().unwrap();
            let next = s.leases.pop_front();
            if next.is_none() {
                if let Some(stop) = &s.stop_when_out_of_leases {
                    stop.store(true, Ordering::Relaxed);
                }
            }
            next
        };
        self.answer(
            "lease",
            format!("lease {}", r.worker_id),
            next.unwrap_or(pb::LeaseResponse {
                lease: None,
                retry_after_ms: 100,
            }),
        )
    }
    async fn heartbeat(
        &self,
        r: pb::HeartbeatRequest,
    ) -> std::result::Result<pb::HeartbeatResponse, Status> {
        let status = self
            .0
            .lock()
            .unwrap()
            .heartbeat
            .unwrap_or(pb::LeaseStatus::Active);
        self.answer(
            "heartbeat",
            "heartbeat".into(),
            pb::HeartbeatResponse {
                leases: r
                    .lease_ids
                    .iter()
                    .map(|&lease_id| pb::LeaseState {
                        lease_id,
                        status: status.into(),
                        deadline_unix_ms: 0,
                    })
                    .collect(),
            },
        )
    }
    async fn report_progress(
        &self,
        r: pb::ReportProgressRequest,
    ) -> std::result::Result<pb::ReportProgressResponse, Status> {
        let epochs: Vec<String> = r.epochs.iter().map(|e| e.epoch.to_string()).collect();
        self.answer(
            "report_progress",
            format!("progress {}", epochs.join(",")),
            pb::ReportProgressResponse {
                stored: r.epochs.len() as u32,
            },
        )
    }
    async fn upload_checkpoint(
        &self,
        msgs: Vec<pb::UploadCheckpointRequest>,
    ) -> std::result::Result<pb::UploadCheckpointResponse, Status> {
        use pb::upload_checkpoint_request::Part;
        let Some(Part::Header(h)) = msgs.first().and_then(|m| m.part.clone()) else {
            return Err(Status::invalid_argument(
                "the first message must be the header",
            ));
        };
        let bytes: Vec<u8> = msgs[1..]
            .iter()
            .flat_map(|m| match &m.part {
                Some(Part::Chunk(c)) => c.data.clone(),
                _ => Vec::new(),
            })
            .collect();
        assert_eq!(
            hex::encode(Sha256::digest(&bytes)),
            h.sha256,
            "upload is the file"
        );
        self.answer(
            "upload_checkpoint",
            format!("upload {} {}", h.epoch, &h.sha256[..8]),
            pb::UploadCheckpointResponse::default(),
        )
    }
    async fn download_checkpoint(
        &self,
        sha256: String,
        _: u64,
    ) -> std::result::Result<Vec<u8>, gaitsweep_core::client::DownloadError> {
        Err(gaitsweep_core::client::DownloadError::Call(
            Status::not_found(format!("no checkpoint {sha256}")),
        ))
    }
    async fn report_result(
        &self,
        r: pb::ReportResultRequest,
    ) -> std::result::Result<pb::ReportResultResponse, Status> {
        let sha = r
            .final_checkpoint_sha256
            .get(..8)
            .unwrap_or("none")
            .to_string();
        self.answer(
            "report_result",
            format!("result {} {sha}", r.epochs),
            pb::ReportResultResponse { duplicate: false },
        )
    }
    async fn fail_cell(
        &self,
        r: pb::FailCellRequest,
    ) -> std::result::Result<pb::FailCellResponse, Status> {
        self.answer(
            "fail_cell",
            format!("fail {}", r.error),
            pb::FailCellResponse::default(),
        )
    }
    async fn release_lease(
        &self,
        r: pb::ReleaseLeaseRequest,
    ) -> std::result::Result<pb::ReleaseLeaseResponse, Status> {
        self.answer(
            "release_lease",
            format!("release {}", r.reason),
            pb::ReleaseLeaseResponse { requeued: true },
        )
    }
}

/// A trainer that writes a small checkpoint file every `checkpoint_every` epochs, fast.
fn scripted_trainer() -> TrainFn {
    Arc::new(|cfg: &CellRunConfig, obs: &mut dyn TrainObserver| {
        std::fs::create_dir_all(&cfg.out_dir).map_err(TrainError::io("create the out dir"))?;
        let mut last = None;
        for epoch in 1..=cfg.epochs {
            if obs.should_stop() {
                return Err(TrainError::Config("stopped".into()));
            }
            obs.on_epoch(&EpochMetrics {
                epoch,
                values: [("mean_return".to_string(), f64::from(epoch))].into(),
            });
            if epoch % cfg.checkpoint_every == 0 || epoch == cfg.epochs {
                let path = cfg.out_dir.join(format!("ckpt-{epoch}.safetensors"));
                std::fs::write(&path, format!("weights at epoch {epoch}"))
                    .map_err(TrainError::io("write a checkpoint"))?;
                obs.on_checkpoint(epoch, &path);
                last = Some(path);
            }
        }
        Ok(CellOutcome {
            score: Default::default(),
            final_checkpoint: last.expect("at least one epoch"),
            epochs: cfg.epochs,
            stopped_unrewarded: false,
        })
    })
}

fn ctx(client: Recorder, work_dir: &Path) -> Arc<Ctx<Recorder>> {
    Arc::new(Ctx {
        client,
        worker_id: std::sync::RwLock::new("w1".into()),
        registration: pb::RegisterRequest::default(),
        heartbeat: Duration::from_millis(20),
        retry: Retry {
            backoff: Backoff::starting_at(Duration::from_millis(1), Duration::from_millis(5)),
            shutdown: Arc::new(AtomicBool::new(false)),
        },
        device: tch::Device::Cpu,
        work_dir: work_dir.to_path_buf(),
        train: scripted_trainer(),
        robot_wait: (Duration::from_millis(50), Duration::from_millis(200)),
    })
}

fn file(dir: &Path, name: &str) -> (PathBuf, String) {
    let p = dir.join(name);
    std::fs::write(&p, name).unwrap();
    let sha = hex::encode(Sha256::digest(name.as_bytes()));
    (p, sha[..8].to_string())
}

fn epoch(e: u32) -> Event {
    Event::Epoch(EpochMetrics {
        epoch: e,
        values: Default::default(),
    })
}

fn done(path: &Path, epochs: u32) -> Event {
    Event::Done(Ok(CellOutcome {
        score: Default::default(),
        final_checkpoint: path.to_path_buf(),
        epochs,
        stopped_unrewarded: false,
    }))
}

async fn run_deliver(ctx: &Ctx<Recorder>, events: Vec<Event>, stop: &AtomicBool) -> Result<()> {
    let (tx, mut rx) = mpsc::unbounded_channel();
    for e in events {
        tx.send(e).unwrap();
    }
    drop(tx);
    deliver(ctx, 7, 3, &mut rx, stop).await
}

#[tokio::test]
async fn events_are_delivered_in_order_and_the_final_checkpoint_is_uploaded_once() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::default();
    let ctx = ctx(rec.clone(), dir.path());
    let (c1, s1) = file(dir.path(), "c1");
    let (c3, s3) = file(dir.path(), "c3");
    let events = vec![
        epoch(1),
        Event::Checkpoint(1, c1),
        epoch(2),
        epoch(3),
        Event::Checkpoint(3, c3.clone()),
        done(&c3, 3),
    ];
    run_deliver(&ctx, events, &AtomicBool::new(false))
        .await
        .unwrap();
    assert_eq!(
        rec.calls(),
        [
            "progress 1".to_string(),
            format!("upload 1 {s1}"),
            // Epochs queued while the upload was on its way go in one report.
            "progress 2,3".into(),
            format!("upload 3 {s3}"),
            format!("result 3 {s3}"),
        ]
    );
}

/// Backpressure: epochs that pile up while the coordinator is slow (here: away and
/// retried) go in one report, in order, each exactly once, and a checkpoint still comes
/// after the epochs before it.
#[tokio::test]
async fn a_backlog_of_epochs_is_reported_in_one_call_and_nothing_twice() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::default();
    rec.fail(
        "report_progress",
        [Status::unavailable("busy"), Status::unavailable("busy")],
    );
    let ctx = ctx(rec.clone(), dir.path());
    let (c5, s5) = file(dir.path(), "c5");
    let (c7, s7) = file(dir.path(), "c7");
    let mut events: Vec<Event> = (1..=5).map(epoch).collect();
    events.push(Event::Checkpoint(5, c5));
    events.extend((6..=7).map(epoch));
    events.push(Event::Checkpoint(7, c7.clone()));
    events.push(done(&c7, 7));
    run_deliver(&ctx, events, &AtomicBool::new(false))
        .await
        .unwrap();
    assert_eq!(
        rec.calls(),
        [
            "progress 1,2,3,4,5".to_string(),
            format!("upload 5 {s5}"),
            "progress 6,7".into(),
            format!("upload 7 {s7}"),
            format!("result 7 {s7}"),
        ]
    );
    assert_eq!(rec.attempts("report_progress"), 4);
}

#[tokio::test]
async fn a_coordinator_that_is_away_or_full_is_retried_and_nothing_is_lost() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::default();
    rec.fail(
        "report_progress",
        [
            Status::unavailable("connection refused"),
            Status::unavailable("connection refused"),
        ],
    );
    rec.fail(
        "upload_checkpoint",
        [reason::with(
            Status::resource_exhausted("disk full"),
            reason::DISK_FULL,
        )],
    );
    rec.fail("report_result", [Status::deadline_exceeded("slow")]);
    let ctx = ctx(rec.clone(), dir.path());
    let (c2, s2) = file(dir.path(), "c2");
    let events = vec![
        epoch(1),
        epoch(2),
        Event::Checkpoint(2, c2.clone()),
        done(&c2, 2),
    ];
    run_deliver(&ctx, events, &AtomicBool::new(false))
        .await
        .unwrap();
    assert_eq!(
        rec.calls(),
        [
            "progress 1,2".to_string(),
            format!("upload 2 {s2}"),
            format!("result 2 {s2}"),
        ]
    );
    assert_eq!(rec.attempts("report_progress"), 3);
    assert_eq!(rec.attempts("upload_checkpoint"), 2);
    assert_eq!(rec.attempts("report_result"), 2);
}

#[tokio::test]
async fn a_refused_report_stops_the_cell_and_nothing_more_is_sent() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::default();
    rec.fail(
        "report_progress",
        [Status::failed_precondition("cell closed")],
    );
    let ctx = ctx(rec.clone(), dir.path());
    let (c2, _) = file(dir.path(), "c2");
    let stop = AtomicBool::new(false);
    let events = vec![
        epoch(1),
        epoch(2),
        Event::Checkpoint(2, c2.clone()),
        done(&c2, 2),
    ];
    run_deliver(&ctx, events, &stop).await.unwrap();
    assert!(
        stop.load(Ordering::Relaxed),
        "the training thread is told to stop"
    );
    assert!(
        rec.calls().is_empty(),
        "sent after the refusal: {:?}",
        rec.calls()
    );
    assert_eq!(
        rec.attempts("report_progress"),
        1,
        "a refusal is not retried"
    );
}

#[tokio::test]
async fn failed_training_fails_the_cell_and_a_stopping_worker_gives_it_back() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::default();
    let ctx = ctx(rec.clone(), dir.path());
    let failed = vec![
        epoch(1),
        Event::Done(Err(TrainError::NonFinite {
            cell: "(w1=2, w2=-6)".into(),
            epoch: 1,
            quantity: "loss".into(),
        })),
    ];
    assert!(run_deliver(&ctx, failed, &AtomicBool::new(false))
        .await
        .is_err());
    let calls = rec.calls();
    assert_eq!(calls.len(), 2, "{calls:?}");
    assert!(
        calls[1].starts_with("fail ") && calls[1].contains("loss"),
        "{calls:?}"
    );

    let rec = Recorder::default();
    let ctx = self::ctx(rec.clone(), dir.path());
    ctx.retry.shutdown.store(true, Ordering::Relaxed);
    let stopped = vec![Event::Done(Err(TrainError::Stopped {
        epoch: 1,
        checkpoint: dir.path().join("c1"),
    }))];
    run_deliver(&ctx, stopped, &AtomicBool::new(false))
        .await
        .unwrap();
    assert_eq!(rec.calls(), ["release worker stopping"]);
}

#[tokio::test]
async fn a_lost_lease_stops_the_cell_a_missed_heartbeat_does_not() {
    let rec = Recorder::default();
    rec.fail(
        "heartbeat",
        [Status::unavailable("away"), Status::unavailable("away")],
    );
    let stop = Arc::new(AtomicBool::new(false));
    let beat = tokio::spawn(heartbeat_loop(
        rec.clone(),
        "w1".into(),
        7,
        Duration::from_millis(5),
        stop.clone(),
    ));
    wait_for(|| rec.calls().len() >= 3).await;
    assert!(
        !stop.load(Ordering::Relaxed),
        "failed heartbeats do not stop training"
    );
    rec.0.lock().unwrap().heartbeat = Some(pb::LeaseStatus::Lost);
    tokio::time::timeout(Duration::from_secs(10), beat)
        .await
        .expect("the heartbeat loop ends when the lease is lost")
        .unwrap();
    assert!(stop.load(Ordering::Relaxed));
}

#[tokio::test]
async fn a_slot_registers_again_when_unknown_then_trains_and_delivers_a_cell() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::default();
    rec.fail(
        "lease",
        [reason::with(
            Status::failed_precondition("worker w1 is not registered"),
            reason::UNKNOWN_WORKER,
        )],
    );
    let ctx = ctx(rec.clone(), dir.path());
    {
        let mut s = rec.0.lock().unwrap();
        s.ids.push_back("w2".into());
        s.stop_when_out_of_leases = Some(ctx.retry.shutdown.clone());
        s.leases.push_back(pb::LeaseResponse {
            lease: Some(pb::Lease {
                lease_id: 7,
                task: Some(pb::CellTask {
                    cell: Some(pb::Cell {
                        cell_id: 1,
                        terrain: "flat".into(),
                        w1: 2.0,
                        w2: -6.0,
                        ..Default::default()
                    }),
                    robot: "anymal".into(),
                    agents: 4,
                    epochs: 4,
                    checkpoint_every: 2,
                    ..Default::default()
                }),
                deadline_unix_ms: 0,
                resume_from: None,
            }),
            retry_after_ms: 0,
        });
    }
    tokio::time::timeout(Duration::from_secs(30), slot_loop(ctx.clone(), 0))
        .await
        .expect("the slot stops once the worker is stopping");
    let calls = short_calls(&rec.calls());
    assert_eq!(
        calls,
        [
            "register w2",
            "lease w2",
            "progress 1",
            "progress 2",
            "upload 2",
            "progress 3",
            "progress 4",
            "upload 4",
            "result 4",
            "lease w2",
        ]
    );
    assert!(
        !dir.path().join("lease-7").exists(),
        "a delivered cell's work dir is removed"
    );
}

fn lease_of(id: i64, robot: &str) -> pb::LeaseResponse {
    pb::LeaseResponse {
        lease: Some(pb::Lease {
            lease_id: id,
            task: Some(pb::CellTask {
                cell: Some(pb::Cell {
                    cell_id: id,
                    terrain: "flat".into(),
                    w1: 2.0,
                    w2: -6.0,
                    ..Default::default()
                }),
                robot: robot.into(),
                agents: 4,
                epochs: 2,
                checkpoint_every: 2,
                ..Default::default()
            }),
            deadline_unix_ms: 0,
            resume_from: None,
        }),
        retry_after_ms: 0,
    }
}

#[tokio::test]
async fn a_robot_this_machine_cannot_load_gives_the_cell_back_uncounted_and_waits() {
    // Session 35: a worker whose robot files were deleted under it failed every cell of a
    // 64-cell sweep, 1,000 attempts each, within a minute.
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::default();
    let ctx = ctx(rec.clone(), dir.path());
    {
        let mut s = rec.0.lock().unwrap();
        s.stop_when_out_of_leases = Some(ctx.retry.shutdown.clone());
        s.leases.push_back(lease_of(7, "no-such-robot"));
        s.leases.push_back(lease_of(8, "no-such-robot"));
        s.leases.push_back(lease_of(9, "anymal"));
    }
    let started = std::time::Instant::now();
    tokio::time::timeout(Duration::from_secs(30), slot_loop(ctx.clone(), 0))
        .await
        .expect("the slot stops once the worker is stopping");
    let calls: Vec<String> = rec
        .calls()
        .into_iter()
        .filter(|c| c != "heartbeat")
        .collect();
    let short = short_calls(&calls);
    assert_eq!(
        short,
        [
            "lease w1",
            "release worker",
            "lease w1",
            "release worker",
            "lease w1",
            "progress 1",
            "progress 2",
            "upload 2",
            "result 2",
            "lease w1",
        ],
        "{calls:?}"
    );
    assert!(
        calls[1].contains("cannot load the robot") && calls[1].contains("no-such-robot"),
        "the reason names the robot: {calls:?}"
    );
    assert_eq!(
        rec.attempts("fail_cell"),
        0,
        "nothing is counted against the cells"
    );
    // It waited 50 ms, then 100 ms (doubled), before leasing again.
    assert!(started.elapsed() >= Duration::from_millis(150));
}

/// The calls but heartbeats, each cut to its first two words, with one `progress` line per
/// epoch: how epochs group into reports depends on timing (a backlog goes in one call).
fn short_calls(calls: &[String]) -> Vec<String> {
    calls
        .iter()
        .filter(|c| *c != "heartbeat")
        .map(|c| c.split(' ').take(2).collect::<Vec<_>>().join(" "))
        .flat_map(|c| match c.strip_prefix("progress ") {
            Some(epochs) => epochs.split(',').map(|e| format!("progress {e}")).collect(),
            None => vec![c],
        })
        .collect()
}

/// Waits up to 10 s for `cond`.
async fn wait_for(cond: impl Fn() -> bool) {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while !cond() {
        assert!(
            tokio::time::Instant::now() < deadline,
            "condition not met within 10 s"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}
