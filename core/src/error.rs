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

/// One line for a binary to print: `e`'s message followed by each cause in its source
/// chain that the message does not already spell out. Our errors put their cause in their
/// own message (so logs show it), which a plain chain would repeat.
pub fn one_line(e: &(dyn std::error::Error + 'static)) -> String {
    let mut line = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        cause = c.source();
    }
    line
}

/// A binary's exit: success, or its error printed on stderr as [`one_line`] and exit code 1.
pub fn exit<E: AsRef<dyn std::error::Error + 'static>>(
    r: std::result::Result<(), E>,
) -> std::process::ExitCode {
    match r {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(e.as_ref()));
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::one_line;

    #[derive(Debug, thiserror::Error)]
    #[error("write /x: {source}")]
    struct Repeats {
        source: std::io::Error,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("upload failed")]
    struct Hides {
        #[source]
        cause: std::io::Error,
    }

    #[test]
    fn a_cause_is_printed_once_whether_or_not_the_message_spells_it_out() {
        let io = || std::io::Error::other("disk full");
        assert_eq!(one_line(&Repeats { source: io() }), "write /x: disk full");
        assert_eq!(one_line(&Hides { cause: io() }), "upload failed: disk full");
    }
}
