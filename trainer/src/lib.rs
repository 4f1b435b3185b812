//! gaitsweep-trainer: trains one PPO policy per grid cell on the rapier simulation with
//! libtorch (rsl_rl's PPO, legged_gym's runner), evaluates it with the gait score, writes
//! and restores checkpoints and exports policies. No network and no async runtime: the
//! worker daemon and `worker train` drive it from their own threads.

pub mod checkpoint;
pub mod device;
pub mod error;
pub mod evaluate;
pub mod export;
pub mod onnx;
pub mod ppo;
pub mod train;

pub use error::{Error, Result};
