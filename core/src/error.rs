//! The error type of gaitsweep-core.

/// Errors of the core crate.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A sweep spec has one or more problems; every problem is listed.
    #[error("invalid sweep spec: {}", .0.join("; "))]
    InvalidSpec(Vec<String>),
    /// A sweep spec is not valid TOML or has unknown keys.
    #[error("sweep spec is not valid toml, fix the syntax: {0}")]
    SpecToml(#[from] toml::de::Error),
    /// A wire message lacks a field that must be set.
    #[error("message {message} is missing required field {field}")]
    MissingField {
        /// The message type.
        message: &'static str,
        /// The missing field.
        field: &'static str,
    },
    /// A wire or stored value is not one of the known names.
    #[error("unknown {what} {value:?}")]
    UnknownValue {
        /// What kind of value.
        what: &'static str,
        /// The value received.
        value: String,
    },
}

/// Result alias of the core crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
