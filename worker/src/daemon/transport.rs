//! The daemon's connection to the coordinator: TLS and token, retries with backoff, and
//! how a failed call is read (transient, refused certificate, unknown worker).

use super::*;
use gaitsweep_core::client::{self, Auth};

pub(super) type Client = WorkerServiceClient<InterceptedService<Channel, Auth>>;

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

/// Exponential backoff from 200 ms to a cap.
#[derive(Clone, Copy)]
pub(super) struct Backoff {
    max: Duration,
}

impl Backoff {
    pub(super) fn new(max: Duration) -> Self {
        Self { max }
    }

    pub(super) fn delay(&self, attempt: u32) -> Duration {
        let base = Duration::from_millis(200).saturating_mul(1 << attempt.min(10));
        let jitter = Duration::from_millis(rand::random::<u64>() % 100);
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

/// Calls `f` until it succeeds, fails permanently, or `stop` is set (or, once the worker
/// is stopping, after a few attempts).
pub(super) async fn retry<T, F, Fut>(
    what: &str,
    backoff: &Backoff,
    stop: Option<&AtomicBool>,
    mut f: F,
) -> std::result::Result<T, Status>
where
    F: FnMut() -> Fut,
    Fut: Future<Output = std::result::Result<tonic::Response<T>, Status>>,
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
                return Ok(r.into_inner());
            }
            // A stopping worker tries a few times only: its coordinator may be stopping too.
            Err(s)
                if transient(&s)
                    && !stop.is_some_and(|s| s.load(Ordering::Relaxed))
                    && !(SHUTDOWN.load(Ordering::Relaxed) && attempt >= 3) =>
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
