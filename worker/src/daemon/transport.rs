//! The daemon's connection to the coordinator: TLS and token, retries with backoff, and
//! how a failed call is read (transient, refused certificate, unknown worker).

use super::*;
use gaitsweep_core::client::{self, collect_checkpoint, Auth, DownloadError};

pub(super) type Client = WorkerServiceClient<InterceptedService<Channel, Auth>>;

/// The calls the daemon makes to its coordinator. The daemon's loops are written against
/// this trait, not the gRPC client, so that they are unit-tested without a server
/// (`daemon/tests.rs`); [`Client`] is the implementation used in production.
pub(crate) trait Coordinator: Clone + Send + Sync + 'static {
    /// Registers this worker.
    fn register(
        &self,
        r: pb::RegisterRequest,
    ) -> impl Future<Output = std::result::Result<pb::RegisterResponse, Status>> + Send;
    /// Asks for a cell for one slot.
    fn lease(
        &self,
        r: pb::LeaseRequest,
    ) -> impl Future<Output = std::result::Result<pb::LeaseResponse, Status>> + Send;
    /// Renews leases.
    fn heartbeat(
        &self,
        r: pb::HeartbeatRequest,
    ) -> impl Future<Output = std::result::Result<pb::HeartbeatResponse, Status>> + Send;
    /// Reports epoch metrics.
    fn report_progress(
        &self,
        r: pb::ReportProgressRequest,
    ) -> impl Future<Output = std::result::Result<pb::ReportProgressResponse, Status>> + Send;
    /// Uploads one checkpoint: a header, then chunks.
    fn upload_checkpoint(
        &self,
        msgs: Vec<pb::UploadCheckpointRequest>,
    ) -> impl Future<Output = std::result::Result<pb::UploadCheckpointResponse, Status>> + Send;
    /// Downloads a checkpoint by sha256 and checks it.
    fn download_checkpoint(
        &self,
        sha256: String,
        size_hint: u64,
    ) -> impl Future<Output = std::result::Result<Vec<u8>, DownloadError>> + Send;
    /// Reports a finished cell.
    fn report_result(
        &self,
        r: pb::ReportResultRequest,
    ) -> impl Future<Output = std::result::Result<pb::ReportResultResponse, Status>> + Send;
    /// Reports a cell whose training failed.
    fn fail_cell(
        &self,
        r: pb::FailCellRequest,
    ) -> impl Future<Output = std::result::Result<pb::FailCellResponse, Status>> + Send;
    /// Gives a cell back (the worker is stopping).
    fn release_lease(
        &self,
        r: pb::ReleaseLeaseRequest,
    ) -> impl Future<Output = std::result::Result<pb::ReleaseLeaseResponse, Status>> + Send;
}

impl Coordinator for Client {
    async fn register(
        &self,
        r: pb::RegisterRequest,
    ) -> std::result::Result<pb::RegisterResponse, Status> {
        Ok(WorkerServiceClient::register(&mut self.clone(), r)
            .await?
            .into_inner())
    }
    async fn lease(&self, r: pb::LeaseRequest) -> std::result::Result<pb::LeaseResponse, Status> {
        Ok(WorkerServiceClient::lease(&mut self.clone(), r)
            .await?
            .into_inner())
    }
    async fn heartbeat(
        &self,
        r: pb::HeartbeatRequest,
    ) -> std::result::Result<pb::HeartbeatResponse, Status> {
        Ok(WorkerServiceClient::heartbeat(&mut self.clone(), r)
            .await?
            .into_inner())
    }
    async fn report_progress(
        &self,
        r: pb::ReportProgressRequest,
    ) -> std::result::Result<pb::ReportProgressResponse, Status> {
        Ok(WorkerServiceClient::report_progress(&mut self.clone(), r)
            .await?
            .into_inner())
    }
    async fn upload_checkpoint(
        &self,
        msgs: Vec<pb::UploadCheckpointRequest>,
    ) -> std::result::Result<pb::UploadCheckpointResponse, Status> {
        Ok(
            WorkerServiceClient::upload_checkpoint(&mut self.clone(), tokio_stream::iter(msgs))
                .await?
                .into_inner(),
        )
    }
    async fn download_checkpoint(
        &self,
        sha256: String,
        size_hint: u64,
    ) -> std::result::Result<Vec<u8>, DownloadError> {
        let req = pb::DownloadCheckpointRequest {
            sha256: sha256.clone(),
        };
        let mut s = WorkerServiceClient::download_checkpoint(&mut self.clone(), req)
            .await
            .map_err(DownloadError::Call)?
            .into_inner();
        collect_checkpoint(&mut s, &sha256, size_hint).await
    }
    async fn report_result(
        &self,
        r: pb::ReportResultRequest,
    ) -> std::result::Result<pb::ReportResultResponse, Status> {
        Ok(WorkerServiceClient::report_result(&mut self.clone(), r)
            .await?
            .into_inner())
    }
    async fn fail_cell(
        &self,
        r: pb::FailCellRequest,
    ) -> std::result::Result<pb::FailCellResponse, Status> {
        Ok(WorkerServiceClient::fail_cell(&mut self.clone(), r)
            .await?
            .into_inner())
    }
    async fn release_lease(
        &self,
        r: pb::ReleaseLeaseRequest,
    ) -> std::result::Result<pb::ReleaseLeaseResponse, Status> {
        Ok(WorkerServiceClient::release_lease(&mut self.clone(), r)
            .await?
            .into_inner())
    }
}

/// The coordinator's worker service at `--connect` (TLS and token from the arguments);
/// connects lazily, so an absent coordinator is retried like any transient failure.
pub(super) fn connect(args: &DaemonArgs) -> Result<Client> {
    let ep = client::endpoint(&args.connect, args.tls_ca.as_deref()).map_err(Error::Config)?;
    let auth = Auth::new(args.token.as_deref()).map_err(Error::Config)?;
    Ok(
        WorkerServiceClient::with_interceptor(ep.connect_lazy(), auth)
            .max_decoding_message_size(client::MAX_MESSAGE),
    )
}

/// Exponential backoff from 200 ms to a cap, with up to 100 ms of jitter.
#[derive(Clone, Copy)]
pub(super) struct Backoff {
    first: Duration,
    max: Duration,
}

impl Backoff {
    pub(super) fn new(max: Duration) -> Self {
        Self::starting_at(Duration::from_millis(200), max)
    }

    /// Backoff whose first wait is `first` (tests use a millisecond).
    pub(super) fn starting_at(first: Duration, max: Duration) -> Self {
        Self { first, max }
    }

    pub(super) fn delay(&self, attempt: u32) -> Duration {
        let base = self.first.saturating_mul(1 << attempt.min(10));
        let jitter_ms = (self.first.as_millis() as u64 / 2).max(1);
        let jitter = Duration::from_millis(rand::random::<u64>() % jitter_ms);
        base.min(self.max) + jitter
    }
}

/// Whether a failed call may succeed later (the coordinator is away, busy, or its disk
/// is full). A refused TLS certificate is not: retrying cannot fix it.
pub(super) fn transient(s: &Status) -> bool {
    if tls_refused(s).is_some() {
        return false;
    }
    if reason::of(s) == Some(reason::DISK_FULL) {
        return true;
    }
    matches!(
        s.code(),
        Code::Unavailable
            | Code::DeadlineExceeded
            | Code::Unknown
            | Code::Aborted
            | Code::Internal
            | Code::Cancelled
    )
}

/// How calls are retried: the backoff, and the flag of a stopping worker (which tries a
/// few times only).
#[derive(Clone)]
pub(super) struct Retry {
    pub(super) backoff: Backoff,
    pub(super) shutdown: Arc<AtomicBool>,
}

impl Retry {
    /// Whether the worker is stopping.
    pub(super) fn stopping(&self) -> bool {
        self.shutdown.load(Ordering::Relaxed)
    }

    /// Calls `f` until it succeeds, fails permanently, or `stop` is set (or, once the worker
    /// is stopping, after a few attempts).
    pub(super) async fn call<T, F, Fut>(
        &self,
        what: &str,
        stop: Option<&AtomicBool>,
        f: F,
    ) -> std::result::Result<T, Status>
    where
        F: FnMut() -> Fut,
        Fut: Future<Output = std::result::Result<T, Status>>,
    {
        retry(what, &self.backoff, stop, &self.shutdown, f).await
    }
}

async fn retry<T, F, Fut>(
    what: &str,
    backoff: &Backoff,
    stop: Option<&AtomicBool>,
    shutdown: &AtomicBool,
    mut f: F,
) -> std::result::Result<T, Status>
where
    F: FnMut() -> Fut,
    Fut: Future<Output = std::result::Result<T, Status>>,
{
    let mut attempt = 0;
    loop {
        match f().await {
            Ok(r) => {
                if attempt > 0 {
                    tracing::info!(
                        call = what,
                        attempts = attempt + 1,
                        "coordinator reachable again, delivered"
                    );
                }
                return Ok(r);
            }
            // A stopping worker tries a few times only: its coordinator may be stopping too.
            Err(s)
                if transient(&s)
                    && !stop.is_some_and(|s| s.load(Ordering::Relaxed))
                    && !(shutdown.load(Ordering::Relaxed) && attempt >= 3) =>
            {
                let d = backoff.delay(attempt);
                if attempt == 0 || attempt % 10 == 0 {
                    let why = match s.code() {
                        Code::Unavailable | Code::DeadlineExceeded | Code::Cancelled => {
                            "coordinator unreachable, retrying"
                        }
                        _ if reason::of(&s) == Some(reason::DISK_FULL) => {
                            "the coordinator's disk is full, retrying"
                        }
                        _ => "the coordinator could not take the call, retrying",
                    };
                    tracing::warn!(call = what, code = ?s.code(), error = %s.message(), retry_in_ms = d.as_millis() as u64, "{why}");
                }
                attempt += 1;
                tokio::time::sleep(d).await;
            }
            Err(s) => return Err(s),
        }
    }
}

/// The coordinator's answer for a worker id it does not know (its database was replaced).
pub(super) fn is_unknown_worker(s: &tonic::Status) -> bool {
    reason::of(s) == Some(reason::UNKNOWN_WORKER)
}

/// What is wrong if the call failed because the TLS handshake refused the certificate.
pub(super) fn tls_refused(s: &Status) -> Option<String> {
    gaitsweep_core::reason::tls_problem(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_coordinator_disk_is_retried_a_too_large_upload_is_not() {
        let full = reason::with(Status::resource_exhausted("disk full"), reason::DISK_FULL);
        assert!(transient(&full));
        assert!(!transient(&Status::resource_exhausted(
            "checkpoint too large"
        )));
        assert!(transient(&Status::unavailable("connection refused")));
    }

    #[test]
    fn unknown_workers_are_recognised_by_reason_not_text() {
        let s = reason::with(
            Status::failed_precondition("anything at all"),
            reason::UNKNOWN_WORKER,
        );
        assert!(is_unknown_worker(&s));
        assert!(!is_unknown_worker(&Status::failed_precondition(
            "worker \"w\" is not registered: call register first"
        )));
    }
}
