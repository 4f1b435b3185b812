//! The evaluation rollout that scores a policy: deterministic actions, a fixed seed and
//! command schedule, one episode per robot, at each of a list of difficulty levels.

use crate::env::{EnvConfig, VecEnv};
use crate::error::Result;
use crate::preset::Preset;
use crate::score::{GaitScore, LevelScore, ScoreVariant};
use crate::terrain::TerrainKind;

/// Settings of an evaluation rollout.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalConfig {
    /// Terrain to evaluate on.
    pub terrain: TerrainKind,
    /// Difficulty levels: the policy is evaluated at each, and the score is the mean over
    /// them (every level with the same robots, spawns and commands).
    pub levels: Vec<u8>,
    /// Robots at each level (one episode each).
    pub num_robots: usize,
    /// Episode length (s); the paper's evaluation uses 20 s.
    pub episode_seconds: f32,
    /// Seed of spawns and commands: the same seed gives the same schedule.
    pub seed: u64,
    /// Which progress term the composite score uses.
    pub score: ScoreVariant,
}

/// Runs one episode per robot and level with `policy(obs [N*obs_dim], actions_out [N*12])`
/// and returns the gait score of the cell (w1, w2): the mean over the levels, each level's
/// own score in `levels`.
pub fn evaluate(
    preset: &Preset,
    w1: f32,
    w2: f32,
    cfg: &EvalConfig,
    policy: &mut dyn FnMut(&[f32], &mut [f32]),
) -> Result<GaitScore> {
    if cfg.levels.is_empty() {
        return Err(crate::Error::InvalidArgument(
            "the evaluation needs at least one difficulty level".into(),
        ));
    }
    let mut levels = Vec::with_capacity(cfg.levels.len());
    for &level in &cfg.levels {
        let score = evaluate_level(preset, w1, w2, cfg, level, policy)?;
        tracing::debug!(
            level,
            score = score.score,
            fall_rate = score.fall_rate,
            "level evaluated"
        );
        levels.push(LevelScore { level, score });
    }
    Ok(GaitScore::mean_of_levels(levels))
}

fn evaluate_level(
    preset: &Preset,
    w1: f32,
    w2: f32,
    cfg: &EvalConfig,
    level: u8,
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
            difficulty: Some(level),
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
    Ok(env.gait_score(cfg.score))
}
