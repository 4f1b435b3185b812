//! The trainer library's error type.

use std::path::PathBuf;

/// Errors of the trainer library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The simulation failed (bad preset, URDF, terrain, ...).
    #[error(transparent)]
    Sim(#[from] gaitsweep_sim::Error),
    /// A libtorch operation failed.
    #[error("libtorch: {0}")]
    Torch(#[from] tch::TchError),
    /// File IO failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A NaN or infinity appeared; the cell stops and its last good checkpoint stays.
    #[error("cell {cell}: non-finite {quantity} in epoch {epoch}")]
    NonFinite {
        /// The cell, e.g. `(w1=2, w2=-6)`.
        cell: String,
        /// The epoch (0-based) in which it appeared.
        epoch: u32,
        /// What was not finite (observations, rewards, surrogate loss, gradients, ...).
        quantity: String,
    },
    /// A checkpoint file is unreadable, truncated or does not fit this run.
    #[error("checkpoint {}: {reason}", path.display())]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The observer asked the run to stop; a checkpoint was written first.
    #[error("stopped on request after epoch {epoch} (checkpoint {})", checkpoint.display())]
    Stopped {
        /// Epochs completed.
        epoch: u32,
        /// The checkpoint written on stopping.
        checkpoint: PathBuf,
    },
    /// The run's configuration is invalid.
    #[error("invalid configuration: {0}")]
    Config(String),
}

impl Error {
    /// An [`Error::Io`] with what was being done.
    pub fn io(context: impl Into<String>) -> impl FnOnce(std::io::Error) -> Error {
        let context = context.into();
        move |source| Error::Io { context, source }
    }

    /// An [`Error::Checkpoint`] for `path`.
    pub fn checkpoint(path: &std::path::Path, reason: impl Into<String>) -> Error {
        Error::Checkpoint {
            path: path.to_path_buf(),
            reason: reason.into(),
        }
    }
}

/// Result alias of the trainer library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl From<gaitsweep_sim::model::Error> for Error {
    fn from(e: gaitsweep_sim::model::Error) -> Self {
        Error::Sim(e.into())
    }
}
