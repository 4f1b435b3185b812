//! The simulation library's error type.

use std::path::PathBuf;

/// Errors of the simulation library. Each names the file or value at fault and what was
/// expected, so a user can fix the input.
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
    /// A URDF could not be parsed or does not describe a supported quadruped.
    #[error("urdf {path}: {element}: {message}")]
    Urdf {
        /// The URDF file.
        path: PathBuf,
        /// The element at fault (a joint, link or the document).
        element: String,
        /// What was wrong and what was expected.
        message: String,
    },
    /// A preset file or a value of the shared model is invalid.
    #[error(transparent)]
    Model(#[from] gaitsweep_model::Error),
    /// A caller passed an invalid argument (wrong action length, unknown terrain, ...).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// The simulation produced a non-finite number.
    #[error("simulation of robot {robot} produced a non-finite {quantity}; lower the action scale or the time step")]
    NonFinite {
        /// Index of the robot in the vectorised environment.
        robot: usize,
        /// What was not finite.
        quantity: &'static str,
    },
}

/// Result alias of the simulation library.
pub type Result<T, E = Error> = std::result::Result<T, E>;
