//! The `worker` command line's subcommands (`train`, `export`, `bench-train`); `main.rs`
//! only parses and dispatches.

use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use gaitsweep_sim::{EnvConfig, Preset, TerrainKind, VecEnv};
use indicatif::{ProgressBar, ProgressStyle};

use crate::{Error, Result};
use gaitsweep_trainer::ppo::{Ppo, Runner};
use gaitsweep_trainer::train::{
    self, CellRunConfig, EpochMetrics, EvalSettings, SimEnv, TrainObserver,
};

pub use gaitsweep_trainer::device::{configure_threads, parse_device, DEFAULT_TORCH_THREADS};

fn parse_overrides(sets: &[String]) -> Result<BTreeMap<String, f64>> {
    sets.iter()
        .map(|kv| {
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| Error::Config(format!("--set {kv:?}: expected key=value")))?;
            let v: f64 = match v.trim() {
                "true" => 1.0,
                "false" => 0.0,
                v => v
                    .parse()
                    .map_err(|_| Error::Config(format!("--set {kv:?}: value is not a number")))?,
            };
            Ok((k.trim().to_string(), v))
        })
        .collect()
}

/// `worker train`: trains one cell locally.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Robot preset.
    #[arg(long, default_value = "anymal")]
    pub robot: String,
    /// Terrain: flat, rough, stairs, slopes or mixed.
    #[arg(long, default_value = "flat")]
    pub terrain: TerrainKind,
    /// Fixed difficulty 0..=9 (default: curriculum).
    #[arg(long)]
    pub difficulty: Option<u8>,
    /// Velocity-tracking weight.
    #[arg(long, allow_hyphen_values = true)]
    pub w1: f64,
    /// Torque-penalty exponent (weight 10^w2).
    #[arg(long, allow_hyphen_values = true)]
    pub w2: f64,
    /// Robots (default: the preset's agents per cell).
    #[arg(long)]
    pub agents: Option<usize>,
    /// Epochs (default: the preset's).
    #[arg(long)]
    pub epochs: Option<u32>,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Output directory (checkpoints, metrics.jsonl, TensorBoard events, score.json).
    #[arg(long)]
    pub out: PathBuf,
    /// A checkpoint every K epochs.
    #[arg(long, default_value_t = gaitsweep_core::defaults::CHECKPOINT_EVERY)]
    pub checkpoint_every: u32,
    /// Continue from this checkpoint.
    #[arg(long)]
    pub resume: Option<PathBuf>,
    /// Override a PPO hyperparameter of the preset, e.g. `--set learning_rate=3e-4`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Evaluate every N epochs (tracking error, fall rate, score into metrics.jsonl).
    #[arg(long)]
    pub eval_every: Option<u32>,
    /// Robots of the evaluations.
    #[arg(long, default_value_t = gaitsweep_core::defaults::EVAL_ROBOTS)]
    pub eval_robots: usize,
    /// Episode length of the evaluations (s).
    #[arg(long, default_value_t = gaitsweep_core::defaults::EVAL_SECONDS)]
    pub eval_seconds: f32,
    /// Difficulty levels of the evaluations, comma-separated; the score is the mean over
    /// them (default: 0 on flat, the fixed --difficulty, else 0,3,5,7).
    #[arg(long, value_delimiter = ',')]
    pub eval_levels: Vec<u8>,
    /// The score's progress term: eq4 (the paper's) or bounded (capped at the commanded
    /// distance).
    #[arg(long, default_value = "eq4")]
    pub score: gaitsweep_sim::ScoreVariant,
    /// Stop at this epoch, scored there, if no epoch up to it had a mean reward other
    /// than 0 (default: train every epoch).
    #[arg(long)]
    pub stop_unrewarded_after: Option<u32>,
    /// libtorch threads (default 1).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar (log lines only).
    #[arg(long)]
    pub quiet: bool,
}

/// Writes `metrics.jsonl`, TensorBoard scalars and the progress bar of `worker train`.
pub struct LocalObserver {
    metrics: File,
    events: gaitsweep_core::tensorboard::EventWriter,
    bar: ProgressBar,
}

impl LocalObserver {
    /// Appends to `dir/metrics.jsonl` (a resumed run continues the file).
    pub fn new(dir: &Path, start: u32, epochs: u32, quiet: bool) -> Result<Self> {
        std::fs::create_dir_all(dir).map_err(Error::io(format!("create {}", dir.display())))?;
        let path = dir.join("metrics.jsonl");
        let metrics = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(Error::io(format!("open {}", path.display())))?;
        let events = gaitsweep_core::tensorboard::EventWriter::create(dir).map_err(Error::io(
            format!("start a tensorboard event file in {}", dir.display()),
        ))?;
        let bar = if quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(epochs as u64)
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{bar:30} epoch {pos}/{len} {elapsed_precise} eta {eta} {msg}",
            )
            .expect("valid template"),
        );
        bar.set_position(start as u64);
        Ok(Self {
            metrics,
            events,
            bar,
        })
    }
}

impl TrainObserver for LocalObserver {
    fn on_epoch(&mut self, m: &EpochMetrics) {
        let line = serde_json::to_string(m).expect("metrics serialise");
        if let Err(e) = writeln!(self.metrics, "{line}") {
            tracing::warn!(error = %e, "cannot write metrics.jsonl");
        }
        let scalars = m.values.iter().map(|(k, v)| (k.as_str(), *v));
        if let Err(e) = self
            .events
            .scalars(m.epoch, scalars)
            .and_then(|()| self.events.flush())
        {
            tracing::warn!(error = %e, path = %self.events.path().display(), "cannot write tensorboard events");
        }
        let g = |k: &str| m.values.get(k).copied().unwrap_or(f64::NAN);
        self.bar.set_position(m.epoch as u64);
        self.bar.set_message(format!(
            "{:.0} samples/s  reward/step {:.4}  return {:.2}  ep.len {:.0}",
            g("samples_per_second"),
            g("mean_step_reward"),
            g("mean_return"),
            g("mean_episode_length")
        ));
        if m.values.contains_key("eval/score") {
            self.bar.println(format!(
                "epoch {}: eval |v_cmd - v| {:.3} m/s, fall rate {:.3}, score {:.4}",
                m.epoch,
                g("eval/mean_vel_error"),
                g("eval/fall_rate"),
                g("eval/score")
            ));
        }
    }
    fn on_checkpoint(&mut self, epoch: u32, path: &Path) {
        tracing::debug!(epoch, path = %path.display(), "checkpoint");
    }
}

/// Runs `worker train`.
pub fn train(a: TrainArgs) -> Result<()> {
    configure_threads(a.threads);
    let preset = Preset::load(&a.robot)?;
    let cfg = CellRunConfig {
        robot: a.robot.clone(),
        terrain: a.terrain,
        difficulty: a.difficulty,
        w1: a.w1,
        w2: a.w2,
        agents: a.agents.unwrap_or(preset.grid.agents_per_cell),
        epochs: a.epochs.unwrap_or(preset.grid.epochs),
        budget_epochs: 0,
        seed: a.seed,
        device: parse_device(&a.device)?,
        checkpoint_every: a.checkpoint_every,
        out_dir: a.out.clone(),
        resume_from: a.resume.clone(),
        ppo_overrides: parse_overrides(&a.set)?,
        eval: EvalSettings {
            robots: a.eval_robots,
            seconds: a.eval_seconds,
            levels: gaitsweep_core::defaults::eval_levels(a.terrain, a.difficulty, &a.eval_levels),
            score: a.score,
            every: a.eval_every.unwrap_or(0),
        },
        stop_unrewarded_after: a.stop_unrewarded_after.unwrap_or(0),
    };
    let start = match &cfg.resume_from {
        Some(p) => {
            gaitsweep_trainer::checkpoint::Checkpoint::load(p)?
                .meta
                .epoch
        }
        None => 0,
    };
    let mut obs = LocalObserver::new(&cfg.out_dir, start, cfg.epochs, a.quiet)?;
    let outcome = train::train_cell(&cfg, &mut obs)?;
    obs.bar.finish();
    if outcome.stopped_unrewarded {
        println!(
            "never rewarded: stopped at epoch {} of {} (every step's reward was 0)",
            outcome.epochs, cfg.epochs
        );
    }
    let s = &outcome.score;
    println!(
        "score {:.4} (track {:.3}, effort {:.3}, tilt {:.3}, progress {:.3}, bounded progress {:.3}); |v_cmd - v| {:.3} m/s, overspeed {:.3} m/s, fall rate {:.3}; checkpoint {}",
        s.score, s.track, s.effort, s.tilt, s.progress, s.progress_bounded, s.mean_vel_error,
        s.overspeed, s.fall_rate, outcome.final_checkpoint.display()
    );
    for l in &s.levels {
        println!(
            "  level {}: score {:.4}, fall rate {:.3}, |v_cmd - v| {:.3} m/s, overspeed {:.3} m/s",
            l.level, l.score.score, l.score.fall_rate, l.score.mean_vel_error, l.score.overspeed
        );
    }
    Ok(())
}

/// `worker export`: a checkpoint's actor as TorchScript, ONNX and safetensors.
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// The checkpoint (`ckpt-NNNNNN.safetensors`).
    pub checkpoint: PathBuf,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `worker export`.
pub fn export(a: ExportArgs) -> Result<()> {
    let ckpt = gaitsweep_trainer::checkpoint::Checkpoint::load(&a.checkpoint)?;
    // The action mapping comes from the preset, when it is still the one trained with.
    let control = match Preset::load(&ckpt.meta.robot) {
        Ok(p) if p.digest == ckpt.meta.preset_digest => Some(train::control_info(&p)),
        _ => {
            tracing::warn!(robot = %ckpt.meta.robot, "preset missing or changed: policy.json has no control section");
            None
        }
    };
    let files = gaitsweep_trainer::export::export(&a.checkpoint, &a.out, control)?;
    println!(
        "{}\n{}\n{}\n{}",
        files.torchscript.display(),
        files.onnx.display(),
        files.safetensors.display(),
        files.json.display()
    );
    Ok(())
}

/// `worker bench-train`: end-to-end training throughput with the split per phase.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Robot preset.
    #[arg(long, default_value = "anymal")]
    pub robot: String,
    /// Terrains to measure.
    #[arg(long, value_delimiter = ',', default_value = "flat,rough")]
    pub terrain: Vec<TerrainKind>,
    /// Robots (default: the preset's agents per cell).
    #[arg(long)]
    pub agents: Option<usize>,
    /// Measured epochs (after one warm-up epoch).
    #[arg(long, default_value_t = 5)]
    pub epochs: u32,
    /// libtorch threads (default 1).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Override a PPO hyperparameter of the preset, e.g. `--set num_learning_epochs=2`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// Runs `worker bench-train` and prints one line per terrain.
pub fn bench(a: BenchArgs) -> Result<()> {
    configure_threads(a.threads);
    let preset = Preset::load(&a.robot)?;
    let agents = a.agents.unwrap_or(preset.grid.agents_per_cell);
    let overrides = parse_overrides(&a.set)?;
    let budget = a.epochs + 1;
    let params = train::ppo_params(&preset.for_cell(TerrainKind::Flat, &overrides, budget)?.ppo);
    let mid = |v: Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
    let (w1, w2) = (mid(preset.grid.w1.values()), mid(preset.grid.w2.values()));
    println!(
        "robot {} agents {agents} steps/env {} learning epochs {} mini-batches {} torch threads {} cores {}",
        a.robot, params.steps_per_env, params.num_learning_epochs, params.num_mini_batches,
        tch::get_num_threads(), cores()
    );
    for terrain in &a.terrain {
        let preset = preset.for_cell(*terrain, &overrides, budget)?;
        let params = train::ppo_params(&preset.ppo);
        let env = VecEnv::new(
            &preset,
            EnvConfig {
                mode: gaitsweep_sim::EnvMode::Train,
                terrain: *terrain,
                num_envs: agents,
                w1: w1 as f32,
                w2: w2 as f32,
                seed: 1,
                difficulty: None,
                episode_seconds: preset.control.episode_seconds,
            },
        )?;
        let ppo = Ppo::new(
            env.obs_dim(),
            env.act_dim(),
            params.clone(),
            tch::Device::Cpu,
            1,
        );
        let mut runner = Runner::new(SimEnv { env }, ppo, 1, 0, "bench".into());
        runner.run_epoch()?;
        let (mut sim, mut inf, mut upd, mut samples) = (0.0, 0.0, 0.0, 0u64);
        let t = Instant::now();
        for _ in 0..a.epochs {
            let s = runner.run_epoch()?;
            sim += s.sim_seconds;
            inf += s.inference_seconds;
            upd += s.update_seconds;
            samples += s.samples;
        }
        let wall = t.elapsed().as_secs_f64();
        println!(
            "{terrain}: {:.0} samples/s end to end; sim {:.1}% inference {:.1}% update {:.1}% (learner {:.1}%); {:.2} s/epoch",
            samples as f64 / wall,
            100.0 * sim / wall,
            100.0 * inf / wall,
            100.0 * upd / wall,
            100.0 * (inf + upd) / wall,
            wall / a.epochs as f64
        );
    }
    Ok(())
}

fn cores() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}
