//! gaitsweep-model: the plain domain types every other crate shares, with serde and no
//! simulation, network or libtorch: the gait score, the terrain kinds, and the robot preset
//! files (`robots/<name>/preset.toml`, read with their `base` chain). The coordinator links
//! this crate, not the simulator.

pub mod cell_settings;
pub mod defaults;
pub mod error;
pub mod ppo_config;
pub mod preset;
pub mod score;
pub mod terrain;

pub use cell_settings::{CellSettings, EvalSettings};
pub use error::{Error, Result};
pub use preset::{GridSpec, PpoConfig, PresetFile};
pub use score::{
    GaitScore, LevelScore, ScoreVariant, WalkCount, WALK_MAX_FALL_RATE, WALK_MAX_VEL_ERROR,
};
pub use terrain::TerrainKind;
