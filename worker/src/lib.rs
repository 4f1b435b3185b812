//! gaitsweep worker: the `worker` command line (`worker train`, `eval`, `render`,
//! `export`, `bench-train`) and the daemon that trains cells for a coordinator
//! (`worker --connect URL`). Training itself is the `gaitsweep-trainer` library.

pub mod cli;
pub mod daemon;
pub mod evaluate;
pub mod host;
pub mod render;

pub use gaitsweep_trainer::{Error, Result};
