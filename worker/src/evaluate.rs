//! `worker eval` (the trainer's [`gaitsweep_trainer::evaluate`] from the command line): scores a checkpoint with the same rollout the trainer and the coordinator
//! use (paper Eq. 4, fixed seed and command schedule), optionally with the stochastic
//! policy the robots were trained with, so the two can be compared.

use std::path::PathBuf;

use clap::Args;
use gaitsweep_sim::{GaitScore, ScoreVariant, TerrainKind};
use gaitsweep_trainer::evaluate::EvalOptions;

use crate::{Error, Result};

/// `worker eval`: the gait score of a checkpoint.
#[derive(Args, Debug, Clone)]
pub struct EvalArgs {
    /// The checkpoint (`.safetensors`).
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Terrain (default: the one the checkpoint was trained on).
    #[arg(long)]
    pub terrain: Option<TerrainKind>,
    /// Difficulty levels 0..=9, comma-separated; the score is the mean over them and each
    /// level's own is printed under `levels` (default: the checkpoint's fixed difficulty,
    /// else 5). A sweep evaluates at the levels its spec resolved (`eval.levels`).
    #[arg(long, alias = "difficulty", value_delimiter = ',')]
    pub levels: Vec<u8>,
    /// The score's progress term: eq4 (the paper's) or bounded (capped at the commanded
    /// distance).
    #[arg(long, default_value = "eq4")]
    pub score: ScoreVariant,
    /// Robots, one episode each.
    #[arg(long, default_value_t = gaitsweep_core::defaults::EVAL_ROBOTS)]
    pub robots: usize,
    /// Episode length (s).
    #[arg(long, default_value_t = gaitsweep_core::defaults::EVAL_SECONDS)]
    pub seconds: f32,
    /// Seed of spawns and commands (default: the scoring rollout's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Action noise in units of the policy's standard deviation: 0 takes the mean (the
    /// scoring rollout), 1 samples as the robots did in training.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f32,
}

/// Scores `a.checkpoint`.
pub fn eval(a: &EvalArgs) -> Result<GaitScore> {
    gaitsweep_trainer::evaluate::eval(
        &a.checkpoint,
        &EvalOptions {
            terrain: a.terrain,
            levels: a.levels.clone(),
            score: a.score,
            robots: a.robots,
            seconds: a.seconds,
            seed: a.seed,
            noise: a.noise,
        },
    )
}

/// Runs `worker eval` and prints the score as JSON.
pub fn run(a: EvalArgs) -> Result<()> {
    crate::cli::configure_threads(None);
    let s = eval(&a)?;
    println!(
        "{}",
        serde_json::to_string_pretty(&s).map_err(|e| Error::Config(e.to_string()))?
    );
    Ok(())
}
