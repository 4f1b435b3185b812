//! The model library's error type.

use std::path::PathBuf;

/// Errors of the model library: a preset file that cannot be read, or a value that names
/// nothing known. Each says what was wrong and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A robot preset (TOML) could not be read or is invalid.
    #[error("preset {path}: {message}")]
    Preset {
        /// The preset file.
        path: PathBuf,
        /// What was wrong and what to do.
        message: String,
    },
    /// A value names nothing known (a terrain, a hyper-parameter, ...).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}

/// Result alias of the model library.
pub type Result<T, E = Error> = std::result::Result<T, E>;
