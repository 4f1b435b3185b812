//! gaitsweep coordinator: holds sweeps (grids of (w1, w2) cells), leases cells to worker
//! daemons over gRPC, stores scores, metrics and checkpoints in SQLite or PostgreSQL and promotes the
//! best model of each sweep.

pub mod across;
pub mod auth;
pub mod blobs;
pub mod error;
pub mod finalists;
pub mod leases;
pub mod live;
pub mod loadgen;
pub mod near_best;
pub mod presets;
pub mod report;
pub mod sched;
pub mod searchbench;
pub mod serve;
pub mod service;
pub mod shape;
pub mod snapshot;
pub mod store;
pub mod validate;
pub mod watch;

pub use error::{Error, Result};
