//! gaitsweep worker: trains one PPO policy per grid cell on the rapier simulation with
//! libtorch, locally (`worker train`) or for a coordinator (`worker --connect URL`).

pub mod checkpoint;
pub mod cli;
pub mod daemon;
pub mod error;
pub mod evaluate;
pub mod export;
pub mod ppo;
pub mod render;
pub mod train;

pub use error::{Error, Result};
