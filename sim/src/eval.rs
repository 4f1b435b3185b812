//! The evaluation rollout that scores a policy: deterministic actions, a fixed seed and
//! command schedule, one episode per robot.

use crate::env::{EnvConfig, VecEnv};
use crate::error::Result;
use crate::preset::Preset;
use crate::score::GaitScore;
use crate::terrain::TerrainKind;

/// Settings of an evaluation rollout.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalConfig {
    /// Terrain to evaluate on.
    pub terrain: TerrainKind,
    /// Difficulty level.
    pub difficulty: u8,
    /// Robots (one episode each).
    pub num_robots: usize,
    /// Episode length (s); the paper's evaluation uses 20 s.
    pub episode_seconds: f32,
    /// Seed of spawns and commands: the same seed gives the same schedule.
    pub seed: u64,
}

/// Runs one episode per robot with `policy(obs [N*obs_dim], actions_out [N*12])` and
/// returns the gait score of the cell (w1, w2).
pub fn evaluate(
    preset: &Preset,
    w1: f32,
    w2: f32,
    cfg: &EvalConfig,
    policy: &mut dyn FnMut(&[f32], &mut [f32]),
) -> Result<GaitScore> {
    let mut env = VecEnv::new(
        preset,
        EnvConfig {
            mode: crate::env::EnvMode::Eval,
            terrain: cfg.terrain,
            num_envs: cfg.num_robots,
            w1,
            w2,
            seed: cfg.seed,
            difficulty: Some(cfg.difficulty),
            episode_seconds: cfg.episode_seconds,
        },
    )?;
    env.set_auto_reset(false);
    let n = env.num_envs();
    let mut actions = vec![0.0f32; n * env.act_dim()];
    let mut obs = env.observations().to_vec();
    let steps = (cfg.episode_seconds / preset.policy_dt()).round() as usize;
    for _ in 0..steps {
        policy(&obs, &mut actions);
        let r = env.step(&actions)?;
        if r.dones.iter().all(|d| *d) {
            break;
        }
        obs.copy_from_slice(r.obs);
    }
    Ok(env.gait_score())
}
