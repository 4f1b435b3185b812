//! Scores a policy with the rollout the trainer and the coordinator use (paper Eq. 4, fixed
//! seed and command schedule), optionally with the stochastic policy the robots were
//! trained with, so the two can be compared (`worker eval`).

use std::path::Path;

use gaitsweep_sim::{evaluate, EvalConfig, GaitScore, Preset, ScoreVariant, TerrainKind};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::checkpoint::{Checkpoint, CheckpointMeta};
use crate::ppo::Ppo;
use crate::train::{CURRICULUM_EVAL_DIFFICULTY, EVAL_SEED};
use crate::{Error, Result};

/// A checkpoint's policy restored with the trainer's own code, and the preset it runs on.
pub struct LoadedPolicy {
    /// The checkpoint's metadata (robot, terrain, w1, w2, ...).
    pub meta: CheckpointMeta,
    /// The robot preset as it is now (a warning is logged when it changed since training).
    pub preset: Preset,
    /// The restored learner (networks and observation normalisation).
    pub ppo: Ppo,
}

/// Loads `path` and restores its policy on the CPU.
pub fn load_policy(path: &Path) -> Result<LoadedPolicy> {
    let ckpt = Checkpoint::load(path)?;
    let meta = ckpt.meta.clone();
    let preset = Preset::load(&meta.robot)?;
    if preset.digest != meta.preset_digest {
        tracing::warn!(robot = %meta.robot, "the robot preset changed since this checkpoint was trained; using the current one");
    }
    let mut ppo = Ppo::new(
        meta.obs_dim,
        meta.act_dim,
        meta.ppo.clone(),
        tch::Device::Cpu,
        0,
    );
    ckpt.restore(&mut ppo)?;
    Ok(LoadedPolicy { meta, preset, ppo })
}

/// Refuses a policy whose observation or action size differs from what `preset` gives
/// robots on `terrain` (e.g. a flat-ground policy, without the height scan, on rough).
pub fn check_dims(
    path: &Path,
    meta: &CheckpointMeta,
    preset: &Preset,
    terrain: TerrainKind,
) -> Result<()> {
    let (obs, act) = (preset.obs_dim_on(terrain), preset.joints.len());
    if (obs, act) == (meta.obs_dim, meta.act_dim) {
        return Ok(());
    }
    Err(Error::checkpoint(
        path,
        format!(
            "policy has obs/act dims {}/{} (trained on {}) but the {} preset gives {}/{} on {}; \
             evaluate it on the terrain it was trained on, or with the preset it was trained with",
            meta.obs_dim, meta.act_dim, meta.terrain, meta.robot, obs, act, terrain
        ),
    ))
}

/// What to evaluate a checkpoint on; `None` takes what the checkpoint was trained with.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalOptions {
    /// Terrain (default: the checkpoint's).
    pub terrain: Option<TerrainKind>,
    /// Difficulty levels 0..=9, the score the mean over them (empty: the checkpoint's
    /// fixed difficulty, else [`CURRICULUM_EVAL_DIFFICULTY`]).
    pub levels: Vec<u8>,
    /// The progress term of the composite score.
    pub score: ScoreVariant,
    /// Robots, one episode each.
    pub robots: usize,
    /// Episode length (s).
    pub seconds: f32,
    /// Seed of spawns and commands (default: the scoring rollout's).
    pub seed: Option<u64>,
    /// Action noise in units of the policy's standard deviation (0: the action mean).
    pub noise: f32,
}

/// The gait score of the checkpoint at `path`.
pub fn eval(path: &Path, a: &EvalOptions) -> Result<GaitScore> {
    if !(a.seconds > 0.0 && a.seconds.is_finite()) || a.robots == 0 || !(a.noise >= 0.0) {
        return Err(Error::Config(format!(
            "seconds must be > 0, robots >= 1 and noise >= 0, got {}, {} and {}",
            a.seconds, a.robots, a.noise
        )));
    }
    let LoadedPolicy { meta, preset, ppo } = load_policy(path)?;
    let terrain = match a.terrain {
        Some(t) => t,
        None => meta.terrain.parse::<TerrainKind>()?,
    };
    check_dims(path, &meta, &preset, terrain)?;
    if let Some(l) = a.levels.iter().find(|l| **l > 9) {
        return Err(Error::Config(format!(
            "evaluation level {l} is out of range: use 0 to 9"
        )));
    }
    let levels = if a.levels.is_empty() {
        vec![meta.difficulty.unwrap_or(CURRICULUM_EVAL_DIFFICULTY)]
    } else {
        a.levels.clone()
    };
    let cfg = EvalConfig {
        terrain,
        levels,
        num_robots: a.robots,
        episode_seconds: a.seconds,
        seed: a.seed.unwrap_or(EVAL_SEED),
        score: a.score,
    };
    score_policy(&preset, meta.w1, meta.w2, &cfg, &ppo, a.noise)
}

/// The gait score of `ppo`'s policy in the evaluation rollout `cfg` of cell (w1, w2):
/// the action mean when `noise` is 0, else actions sampled with `noise` times the policy's
/// standard deviation (drawn from a generator seeded with `cfg.seed`).
pub fn score_policy(
    preset: &Preset,
    w1: f64,
    w2: f64,
    cfg: &EvalConfig,
    ppo: &Ppo,
    noise: f32,
) -> Result<GaitScore> {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut failed = None;
    let score = evaluate(preset, w1 as f32, w2 as f32, cfg, &mut |obs, act| {
        if failed.is_none() {
            let r = if noise > 0.0 {
                ppo.act_sampled(obs, act, noise, &mut rng)
            } else {
                ppo.act_deterministic(obs, act)
            };
            failed = r.err();
        }
    })?;
    match failed {
        Some(e) => Err(e),
        None => Ok(score),
    }
}
