//! Training one grid cell on the rapier simulation: the API the daemon and `worker train`
//! call. Runs on the caller's thread (never on an async runtime).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use gaitsweep_sim::model::EvalSettings;
use gaitsweep_sim::{EnvConfig, EvalConfig, GaitScore, PpoConfig, Preset, TerrainKind, VecEnv};
use serde::{Deserialize, Serialize};

use crate::checkpoint::{self, Checkpoint, CheckpointMeta, NormalizerMeta, OptimizerMeta, RngMeta};
use crate::export::ControlInfo;
use crate::ppo::{runner::boundary_seed, EpochStats, Ppo, PpoParams, Runner, StepView, VecEnvLike};
use crate::{Error, Result};

pub use gaitsweep_sim::model::defaults::{CURRICULUM_EVAL_DIFFICULTY, EVAL_SEED};

/// Everything that defines one cell's training run.
#[derive(Clone, Debug)]
pub struct CellRunConfig {
    /// Robot preset name (`robots/<robot>/preset.toml`).
    pub robot: String,
    /// Terrain to train on.
    pub terrain: TerrainKind,
    /// Fixed difficulty, or None for the curriculum.
    pub difficulty: Option<u8>,
    /// Velocity-tracking weight.
    pub w1: f64,
    /// Torque-penalty exponent (penalty weight 10^w2).
    pub w2: f64,
    /// Robots simulated together for this cell.
    pub agents: usize,
    /// Total epochs (a resumed run continues counting from its checkpoint).
    pub epochs: u32,
    /// The cell's whole epoch budget, which schedules given as fractions
    /// (`noise_decay_start_fraction`, ...) are fractions of: the sweep's epochs, also when
    /// successive halving trains the cell to an earlier rung first (0: `epochs`).
    pub budget_epochs: u32,
    /// Seed of the run.
    pub seed: u64,
    /// Where the networks live.
    pub device: tch::Device,
    /// A checkpoint every this many epochs (and at the end).
    pub checkpoint_every: u32,
    /// Directory for checkpoints and `score.json`.
    pub out_dir: PathBuf,
    /// Continue from this checkpoint.
    pub resume_from: Option<PathBuf>,
    /// PPO hyperparameters replacing the preset's (`learning_rate = 3e-4`, ...).
    pub ppo_overrides: BTreeMap<String, f64>,
    /// How the policy is scored: at the end, and every `eval.every` epochs as well (logged
    /// as `eval/*`).
    pub eval: EvalSettings,
    /// Stop at this epoch, and score the policy there, when no epoch up to it had a mean
    /// reward other than 0 (0: train to `epochs`).
    pub stop_unrewarded_after: u32,
}

/// Per-epoch metrics: every reward term mean (`reward/<term>`), losses, KL, learning rate,
/// samples/s, seconds per phase, mean reward and episode length (and `eval/*` when an
/// intermediate evaluation ran).
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct EpochMetrics {
    /// Epochs completed (1-based).
    pub epoch: u32,
    /// Named values.
    pub values: BTreeMap<String, f64>,
}

/// Receives a training run's progress.
pub trait TrainObserver: Send {
    /// Called after every epoch.
    fn on_epoch(&mut self, m: &EpochMetrics);
    /// Called after every checkpoint is written.
    fn on_checkpoint(&mut self, epoch: u32, path: &Path);
    /// Polled before every epoch; true stops the run after a checkpoint.
    fn should_stop(&self) -> bool {
        false
    }
}

/// The result of a finished cell.
#[derive(Clone, Debug)]
pub struct CellOutcome {
    /// Gait score of the final evaluation.
    pub score: GaitScore,
    /// The last checkpoint.
    pub final_checkpoint: PathBuf,
    /// Epochs completed.
    pub epochs: u32,
    /// The run stopped at `stop_unrewarded_after` because no epoch had been rewarded.
    pub stopped_unrewarded: bool,
}

/// The preset's PPO table as the trainer's parameters.
pub fn ppo_params(c: &PpoConfig) -> PpoParams {
    c.clone()
}

/// How a preset maps actions to joint targets, for exports.
pub fn control_info(preset: &Preset) -> ControlInfo {
    ControlInfo {
        joints: preset.joints.clone(),
        action_scale: preset.control.action_scale as f64,
        default_pose: preset.default_pose.iter().map(|&q| q as f64).collect(),
        policy_dt: preset.policy_dt() as f64,
    }
}

/// The rapier simulation seen through the trainer's environment trait.
pub struct SimEnv {
    /// The simulation.
    pub env: VecEnv,
}

impl VecEnvLike for SimEnv {
    fn num_envs(&self) -> usize {
        self.env.num_envs()
    }
    fn obs_dim(&self) -> usize {
        self.env.obs_dim()
    }
    fn act_dim(&self) -> usize {
        self.env.act_dim()
    }
    fn reseed(&mut self, seed: u64) -> Result<Vec<f32>> {
        self.env.reseed(seed);
        Ok(self.env.observations().to_vec())
    }
    fn step(&mut self, actions: &[f32]) -> Result<StepView<'_>> {
        let r = self.env.step(actions)?;
        Ok(StepView {
            obs: r.obs,
            rewards: r.rewards,
            dones: r.dones,
            timeouts: r.timeouts,
            terms: r.terms,
        })
    }
    fn term_names(&self) -> Vec<String> {
        self.env
            .reward_term_names()
            .iter()
            .map(|s| s.to_string())
            .collect()
    }
    fn levels(&self) -> Vec<u8> {
        self.env.levels()
    }
    fn variant_names(&self) -> &'static [&'static str] {
        self.env.variant_names()
    }
    fn set_levels(&mut self, levels: &[u8]) -> bool {
        self.env.set_levels(levels).is_ok()
    }
}

/// Names a cell in errors and logs.
pub fn cell_label(w1: f64, w2: f64) -> String {
    format!("(w1={w1}, w2={w2})")
}

fn validate(cfg: &CellRunConfig, p: &PpoParams) -> Result<()> {
    let bad = |m: String| Err(Error::Config(m));
    if cfg.agents == 0 {
        return bad("agents must be at least 1".into());
    }
    if cfg.checkpoint_every == 0 {
        return bad("checkpoint_every must be at least 1".into());
    }
    if let Some(problem) = cfg.eval.problem() {
        return bad(problem);
    }
    if p.num_mini_batches == 0 || p.num_learning_epochs == 0 || p.steps_per_env == 0 {
        return bad(
            "num_mini_batches, num_learning_epochs and steps_per_env must be positive".into(),
        );
    }
    if cfg.agents * p.steps_per_env < p.num_mini_batches {
        return bad(format!(
            "{} agents x {} steps is fewer samples than {} mini-batches",
            cfg.agents, p.steps_per_env, p.num_mini_batches
        ));
    }
    let stds_ok = p.final_noise_std.is_finite()
        && p.final_noise_std >= 0.0
        && p.init_noise_std.is_finite()
        && p.init_noise_std > 0.0;
    if !stds_ok {
        return bad(format!(
            "init_noise_std must be > 0 and final_noise_std >= 0 (0: learned std), got {} and {}",
            p.init_noise_std, p.final_noise_std
        ));
    }
    if p.noise_decay_start > 0 && p.final_noise_std <= 0.0 {
        return bad(format!(
            "noise_decay_start = {} anneals nothing without final_noise_std > 0 (set both, or neither)",
            p.noise_decay_start
        ));
    }
    if !(cfg.w1.is_finite() && cfg.w2.is_finite()) {
        return bad(format!("cell {} is not finite", cell_label(cfg.w1, cfg.w2)));
    }
    Ok(())
}

/// Converts an epoch's statistics to the metrics record.
pub fn epoch_metrics(s: &EpochStats, wall_seconds: f64) -> EpochMetrics {
    let mut v = BTreeMap::new();
    for (name, mean) in &s.terms {
        v.insert(format!("reward/{name}"), *mean);
    }
    v.insert("mean_step_reward".into(), s.mean_step_reward);
    if let Some((mean, max)) = s.levels {
        v.insert("curriculum/mean_level".into(), mean);
        v.insert("curriculum/max_level".into(), max);
    }
    for (name, mean) in &s.variant_levels {
        v.insert(format!("curriculum/mean_level_{name}"), *mean);
    }
    if let Some(r) = s.mean_return {
        v.insert("mean_return".into(), r);
    }
    if let Some(l) = s.mean_episode_length {
        v.insert("mean_episode_length".into(), l);
    }
    let u = &s.update;
    v.insert("loss/value".into(), u.value_loss);
    v.insert("loss/surrogate".into(), u.surrogate_loss);
    v.insert("entropy".into(), u.entropy);
    v.insert("kl".into(), u.kl);
    v.insert("learning_rate".into(), u.learning_rate);
    if let Some(m) = u.mirror_loss {
        v.insert("loss/mirror".into(), m);
    }
    v.insert("grad_norm".into(), u.grad_norm);
    v.insert("action_std".into(), u.action_std);
    v.insert("samples_per_second".into(), s.samples_per_second());
    v.insert("time/sim".into(), s.sim_seconds);
    v.insert("time/inference".into(), s.inference_seconds);
    v.insert("time/update".into(), s.update_seconds);
    v.insert("wall_seconds".into(), wall_seconds);
    EpochMetrics {
        epoch: s.epoch,
        values: v,
    }
}

/// Deterministic evaluation of the current policy.
fn eval_policy(preset: &Preset, cfg: &CellRunConfig, ppo: &Ppo) -> Result<GaitScore> {
    let ecfg = EvalConfig {
        terrain: cfg.terrain,
        levels: cfg.eval.levels.clone(),
        num_robots: cfg.eval.robots,
        episode_seconds: cfg.eval.seconds,
        seed: EVAL_SEED,
        score: cfg.eval.score,
    };
    crate::evaluate::score_policy(preset, cfg.w1, cfg.w2, &ecfg, ppo, 0.0)
}

/// Trains one cell: resumes from `cfg.resume_from` if set, writes a checkpoint every
/// `checkpoint_every` epochs and at the end, evaluates and writes `score.json`.
///
/// Checkpoints never change training: the robots are reset (from `(seed, epoch)`, with
/// staggered episode starts) only when a run starts or resumes, and a run with any
/// `checkpoint_every` trains exactly as one with a single final checkpoint (same machine,
/// same libtorch thread count). A resumed run restores the networks, optimiser, observation
/// statistics and curriculum levels, but its robots start new episodes, as legged_gym's
/// resume does, so it does not replay the uninterrupted run bit for bit.
pub fn train_cell(cfg: &CellRunConfig, observer: &mut dyn TrainObserver) -> Result<CellOutcome> {
    let budget = if cfg.budget_epochs == 0 {
        cfg.epochs
    } else {
        cfg.budget_epochs
    };
    let preset = Preset::load(&cfg.robot)?.for_cell(cfg.terrain, &cfg.ppo_overrides, budget)?;
    let params = ppo_params(&preset.ppo);
    validate(cfg, &params)?;
    std::fs::create_dir_all(&cfg.out_dir)
        .map_err(Error::io(format!("create {}", cfg.out_dir.display())))?;
    let label = cell_label(cfg.w1, cfg.w2);

    let env = VecEnv::new(
        &preset,
        EnvConfig {
            mode: gaitsweep_sim::EnvMode::Train,
            terrain: cfg.terrain,
            num_envs: cfg.agents,
            w1: cfg.w1 as f32,
            w2: cfg.w2 as f32,
            seed: cfg.seed,
            difficulty: cfg.difficulty,
            episode_seconds: preset.control.episode_seconds,
        },
    )?;
    let (obs_dim, act_dim) = (env.obs_dim(), env.act_dim());
    let mut meta = CheckpointMeta {
        format: checkpoint::FORMAT_VERSION,
        robot: cfg.robot.clone(),
        preset_digest: preset.digest.clone(),
        terrain: cfg.terrain.to_string(),
        difficulty: cfg.difficulty,
        w1: cfg.w1,
        w2: cfg.w2,
        seed: cfg.seed,
        epoch: 0,
        agents: cfg.agents,
        obs_dim,
        act_dim,
        checkpoint_every: cfg.checkpoint_every,
        ppo: params.clone(),
        normalizer: NormalizerMeta { count: 0, mean: vec![], var: vec![], eps: 0.0, clip: 0.0 },
        optimizer: OptimizerMeta { kind: "adam".into(), learning_rate: 0.0, step: 0, betas: [0.0; 2], eps: 0.0 },
        rng: RngMeta { scheme: "sim and trainer generator seeded from boundary_seed(seed, epoch) at the start and at each resumption; checkpoints never reset robots".into(), resume_seed: 0 },
        levels: Vec::new(),
        rewarded: false,
    };

    let mut ppo = Ppo::new(
        obs_dim,
        act_dim,
        params,
        cfg.device,
        boundary_seed(cfg.seed, 0),
    );
    if ppo.params.mirror_loss_coef > 0.0 || ppo.params.mirror_augmentation {
        let on = if ppo.params.mirror_loss_coef > 0.0 {
            format!("ppo.mirror_loss_coef = {}", ppo.params.mirror_loss_coef)
        } else {
            "ppo.mirror_augmentation".to_string()
        };
        let m = env.mirror()?.ok_or_else(|| {
            Error::Config(format!(
                "{on} needs the preset's `mirror` joint map, which {} does not name; add one \
                 (robots/anymal/preset.toml shows how) or turn it off",
                cfg.robot
            ))
        })?;
        ppo.set_mirror(&m.obs, &m.act);
    }
    let mut start = 0;
    let mut last_ckpt: Option<(u32, PathBuf)> = None;
    let mut sim = SimEnv { env };
    if let Some(path) = &cfg.resume_from {
        let ckpt = Checkpoint::load(path)?;
        ckpt.check_matches(&meta)?;
        ckpt.restore(&mut ppo)?;
        start = ckpt.meta.epoch;
        meta.rewarded = ckpt.meta.rewarded;
        last_ckpt = Some((start, path.clone()));
        if !ckpt.meta.levels.is_empty() && !sim.set_levels(&ckpt.meta.levels) {
            tracing::warn!(cell = %label, "curriculum levels not restored: the resumed run restarts the curriculum");
        }
        tracing::info!(cell = %label, checkpoint = %path.display(), epoch = start, "resumed");
    }
    let mut runner = Runner::new(sim, ppo, cfg.seed, start, label.clone());
    let t0 = Instant::now();
    let save = |runner: &Runner<SimEnv>, meta: &mut CheckpointMeta| -> Result<PathBuf> {
        meta.epoch = runner.epoch;
        meta.levels = if cfg.difficulty.is_none() {
            runner.env.levels()
        } else {
            Vec::new()
        };
        meta.rng.resume_seed = boundary_seed(cfg.seed, runner.epoch);
        checkpoint::save(&cfg.out_dir, &runner.ppo, meta)
    };

    let mut last_eval: Option<(u32, GaitScore)> = None;
    let mut stopped_unrewarded = false;
    while runner.epoch < cfg.epochs {
        if observer.should_stop() {
            let path = save(&runner, &mut meta)?;
            observer.on_checkpoint(runner.epoch, &path);
            tracing::info!(cell = %label, epoch = runner.epoch, "stopped on request");
            return Err(Error::Stopped {
                epoch: runner.epoch,
                checkpoint: path,
            });
        }
        if cfg.stop_unrewarded_after > 0
            && runner.epoch >= cfg.stop_unrewarded_after
            && !meta.rewarded
        {
            // Every step's reward was clipped to 0 (only_positive_rewards): the weights teach
            // this cell nothing, and the rest of its budget would not change that.
            tracing::info!(cell = %label, epoch = runner.epoch, of = cfg.epochs,
                "never rewarded: stopped, scored here");
            stopped_unrewarded = true;
            break;
        }
        let stats = runner.run_epoch()?;
        meta.rewarded |= stats.mean_step_reward != 0.0;
        let mut m = epoch_metrics(&stats, t0.elapsed().as_secs_f64());
        if cfg.eval.every > 0 && runner.epoch % cfg.eval.every == 0 {
            let te = Instant::now();
            let s = eval_policy(&preset, cfg, &runner.ppo)?;
            // The final evaluation is this one when the last epoch lands here.
            last_eval = Some((runner.epoch, s.clone()));
            m.values.extend(s.eval_metrics());
            m.values
                .insert("eval/seconds".into(), te.elapsed().as_secs_f64());
        }
        observer.on_epoch(&m);
        if runner.epoch % cfg.checkpoint_every == 0 || runner.epoch == cfg.epochs {
            let path = save(&runner, &mut meta)?;
            observer.on_checkpoint(runner.epoch, &path);
            last_ckpt = Some((runner.epoch, path));
        }
    }
    let final_checkpoint = match last_ckpt {
        Some((epoch, p)) if epoch == runner.epoch => p,
        _ => {
            let path = save(&runner, &mut meta)?;
            observer.on_checkpoint(runner.epoch, &path);
            path
        }
    };

    let score = match last_eval {
        Some((epoch, s)) if epoch == runner.epoch => s,
        _ => eval_policy(&preset, cfg, &runner.ppo)?,
    };
    let score_path = cfg.out_dir.join("score.json");
    let json = serde_json::to_string_pretty(&score).expect("score serialises");
    std::fs::write(&score_path, json + "\n")
        .map_err(Error::io(format!("write {}", score_path.display())))?;
    tracing::info!(cell = %label, epochs = runner.epoch, score = score.score, fall_rate = score.fall_rate,
        mean_vel_error = score.mean_vel_error, "cell done");
    Ok(CellOutcome {
        score,
        final_checkpoint,
        epochs: runner.epoch,
        stopped_unrewarded,
    })
}
