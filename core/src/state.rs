//! Lifecycle states of cells and sweeps, with their stored names.

use crate::{Error, Result};
use std::fmt;
use std::str::FromStr;

/// Lifecycle state of a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CellState {
    /// Waiting for a worker.
    Queued,
    /// Leased to a worker slot.
    Running,
    /// Finished with a score.
    Done,
    /// Failed more often than allowed.
    Failed,
    /// Its sweep was cancelled.
    Cancelled,
    /// Reached a rung of successive halving and waits for the rung's decision.
    Paused,
    /// Stopped by successive halving at a rung; its evaluations and checkpoints stay.
    Stopped,
}

impl CellState {
    /// The name stored in SQLite.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Queued => "queued",
            Self::Running => "running",
            Self::Done => "done",
            Self::Failed => "failed",
            Self::Cancelled => "cancelled",
            Self::Paused => "paused",
            Self::Stopped => "stopped",
        }
    }

    /// True for states a cell never leaves.
    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            Self::Done | Self::Failed | Self::Cancelled | Self::Stopped
        )
    }
}

impl fmt::Display for CellState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for CellState {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Ok(match s {
            "queued" => Self::Queued,
            "running" => Self::Running,
            "done" => Self::Done,
            "failed" => Self::Failed,
            "cancelled" => Self::Cancelled,
            "paused" => Self::Paused,
            "stopped" => Self::Stopped,
            _ => {
                return Err(Error::UnknownValue {
                    what: "cell state",
                    value: s.into(),
                })
            }
        })
    }
}

/// Lifecycle state of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SweepState {
    /// Cells are queued or running.
    Running,
    /// Every cell is done or failed.
    Done,
    /// Cancelled by a user.
    Cancelled,
}

impl SweepState {
    /// The name stored in SQLite.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Running => "running",
            Self::Done => "done",
            Self::Cancelled => "cancelled",
        }
    }
}

impl fmt::Display for SweepState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for SweepState {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Ok(match s {
            "running" => Self::Running,
            "done" => Self::Done,
            "cancelled" => Self::Cancelled,
            _ => {
                return Err(Error::UnknownValue {
                    what: "sweep state",
                    value: s.into(),
                })
            }
        })
    }
}
