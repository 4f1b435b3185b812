//! gaitsweep-sim: quadruped robots from URDF, simulated in rapier3d, one world per robot,
//! stepped in parallel; the reward of Kim et al. 2024 (Eq. 1) and the gait score (Eq. 4).
//!
//! This crate has no network and no libtorch: the trainer and the benchmarks drive it.

pub mod agent;
pub mod contact;
pub mod env;
pub mod error;
pub mod eval;
pub mod mirror;
pub mod preset;
pub mod render;
pub mod reward;
pub mod robot;
pub mod score;
pub mod terrain;
pub mod urdf;

pub use env::{EnvConfig, EnvMode, StepResult, VecEnv};
pub use error::{Error, Result};
pub use eval::{evaluate, EvalConfig};
/// The shared plain types (gait score, terrain kinds, preset files).
pub use gaitsweep_model as model;
pub use mirror::Mirror;
pub use preset::{GridSpec, PpoConfig, Preset};
pub use score::{GaitScore, LevelScore, ScoreVariant};
pub use terrain::TerrainKind;
