//! The coordinator library's error type and its one mapping to gRPC status codes.

use gaitsweep_core::{reason, CellId, LeaseId, SweepId};

/// Errors of the coordinator library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A domain-level problem (bad spec, bad wire message).
    #[error(transparent)]
    Core(#[from] gaitsweep_core::Error),
    /// The database failed.
    #[error("database: {0}")]
    Db(#[from] sqlx::Error),
    /// Applying the embedded migrations failed.
    #[error("database migration failed, check that the data dir belongs to this version: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    /// File IO failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Stored JSON could not be read or written.
    #[error("stored json is invalid: {0}")]
    Json(#[from] serde_json::Error),
    /// No sweep has this id.
    #[error("sweep {0} does not exist: list sweeps to see valid ids")]
    UnknownSweep(SweepId),
    /// No cell has this id.
    #[error("cell {0} does not exist")]
    UnknownCell(CellId),
    /// No lease has this id.
    #[error("lease {0} does not exist: lease a cell first")]
    UnknownLease(LeaseId),
    /// The worker id is not registered.
    #[error("worker {0:?} is not registered: call register first")]
    UnknownWorker(String),
    /// No checkpoint has this hash.
    #[error("checkpoint {0} is not stored")]
    UnknownCheckpoint(String),
    /// A checkpoint is listed in the database but its file is not in the data dir.
    #[error("checkpoint {sha256} is listed but its file {path} is missing: a data dir restored from a snapshot holds only the checkpoints it resumes from and the best cells' (README, \"Recording over several sittings\"); retrain that cell for its model")]
    CheckpointFileMissing {
        /// The checkpoint's hash.
        sha256: String,
        /// Where its file should be.
        path: String,
    },
    /// Nothing was promoted yet.
    #[error("sweep {0} has no promoted cell yet: wait until a cell finishes")]
    NothingPromoted(SweepId),
    /// The cell of a lease is finished or cancelled; the report is refused.
    #[error("cell {cell} is {state}: stop working on it")]
    CellClosed {
        /// The cell.
        cell: CellId,
        /// Its state.
        state: String,
    },
    /// An upload was larger than allowed.
    #[error("checkpoint of {size} bytes exceeds the limit of {limit} bytes: raise --max-checkpoint-mb or send a smaller file")]
    TooLarge {
        /// Bytes sent or announced.
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// An upload did not match its announced hash or size.
    #[error("checkpoint upload is corrupt: {0}")]
    Corrupt(String),
    /// The server could not be set up or failed while serving.
    #[error("server: {0}")]
    Server(String),
    /// A database could not be opened for reading.
    #[error("{what}: {message}")]
    OpenDb {
        /// What was opened, and where.
        what: String,
        /// Why it failed, and what to check.
        message: String,
    },
    /// A report's figure could not be drawn or written.
    #[error("{what}: {message}")]
    Plot {
        /// What was being drawn or written, and where.
        what: String,
        /// The plotting library's error.
        message: String,
    },
    /// A request is malformed.
    #[error("bad request: {0}")]
    BadRequest(String),
    /// A group of metric reports committed together failed; every report in it gets this.
    #[error("storing metrics failed, retry the report: {message}")]
    Write {
        /// The database's error.
        message: String,
        /// Whether the database or disk was full.
        disk_full: bool,
    },
}

impl Error {
    /// Whether the error is the disk (or SQLite's database) being full.
    pub fn is_disk_full(&self) -> bool {
        match self {
            Error::Io { source, .. } => {
                source.kind() == std::io::ErrorKind::StorageFull
                    || source.raw_os_error() == Some(28)
            }
            // SQLITE_FULL (13): "database or disk is full"; PostgreSQL's disk_full (53100).
            Error::Db(sqlx::Error::Database(d)) => {
                matches!(d.code().as_deref(), Some("13") | Some("53100"))
            }
            Error::Write { disk_full, .. } => *disk_full,
            _ => false,
        }
    }
}

/// Result alias of the coordinator library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl From<Error> for tonic::Status {
    fn from(e: Error) -> Self {
        use tonic::Status;
        let msg = e.to_string();
        match e {
            Error::Core(gaitsweep_core::Error::InvalidSpec(_))
            | Error::Core(gaitsweep_core::Error::SpecToml(_))
            | Error::Core(gaitsweep_core::Error::MissingField { .. })
            | Error::Core(gaitsweep_core::Error::UnknownValue { .. })
            | Error::Corrupt(_)
            | Error::BadRequest(_) => Status::invalid_argument(msg),
            Error::UnknownSweep(_)
            | Error::UnknownCell(_)
            | Error::UnknownLease(_)
            | Error::UnknownCheckpoint(_)
            | Error::CheckpointFileMissing { .. }
            | Error::NothingPromoted(_) => Status::not_found(msg),
            Error::UnknownWorker(_) => {
                reason::with(Status::failed_precondition(msg), reason::UNKNOWN_WORKER)
            }
            Error::CellClosed { .. } => Status::failed_precondition(msg),
            Error::TooLarge { .. } => Status::resource_exhausted(msg),
            ref e if e.is_disk_full() => {
                tracing::error!(error = %msg, "disk full");
                reason::with(
                    Status::resource_exhausted(format!(
                        "the coordinator's disk is full ({msg}): free space in its data dir; workers retry"
                    )),
                    reason::DISK_FULL,
                )
            }
            Error::Db(_)
            | Error::Migrate(_)
            | Error::Server(_)
            | Error::OpenDb { .. }
            | Error::Io { .. }
            | Error::Write { .. }
            | Error::Plot { .. }
            | Error::Json(_) => {
                tracing::error!(error = %msg, "internal error");
                Status::internal(msg)
            }
        }
    }
}

/// Wraps an IO error with what was being done.
pub(crate) fn io(context: impl Into<String>) -> impl FnOnce(std::io::Error) -> Error {
    let context = context.into();
    move |source| Error::Io { context, source }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fault-injection finding: a full disk at upload reached the worker as an internal
    /// error, logged as "coordinator unreachable".
    #[test]
    fn a_full_disk_is_resource_exhausted_with_its_reason() {
        let e = io("write checkpoint")(std::io::Error::from_raw_os_error(28));
        let s = tonic::Status::from(e);
        assert_eq!(s.code(), tonic::Code::ResourceExhausted);
        assert_eq!(reason::of(&s), Some(reason::DISK_FULL));
        assert!(s.message().contains("disk is full"), "{}", s.message());
        let too_large = tonic::Status::from(Error::TooLarge { size: 2, limit: 1 });
        assert_eq!(too_large.code(), tonic::Code::ResourceExhausted);
        assert_eq!(
            reason::of(&too_large),
            None,
            "a too-large upload is not retried"
        );
    }

    /// The daemon recognises an unknown worker by a reason key, not by the message text.
    #[test]
    fn an_unknown_worker_carries_its_reason() {
        let s = tonic::Status::from(Error::UnknownWorker("w-1".into()));
        assert_eq!(s.code(), tonic::Code::FailedPrecondition);
        assert_eq!(reason::of(&s), Some(reason::UNKNOWN_WORKER));
        let closed = tonic::Status::from(Error::CellClosed {
            cell: CellId(1),
            state: "done".into(),
        });
        assert_eq!(reason::of(&closed), None);
    }
}
