//! `worker render`: an animated GIF of a checkpoint's gait. The policy is restored with
//! the trainer's own code ([`gaitsweep_trainer::evaluate::load_policy`]) and driven with its
//! deterministic action ([`gaitsweep_trainer::ppo::Ppo::act_deterministic`]: normalised observation,
//! action mean), exactly as the scoring rollout does; one robot walks on the checkpoint's
//! terrain and a frame is drawn by `gaitsweep_sim::render` every few policy steps.

use std::path::{Path, PathBuf};

use clap::Args;
use gaitsweep_sim::render::write_gif;
use gaitsweep_sim::{EnvConfig, TerrainKind, VecEnv};

use crate::{Error, Result};
use gaitsweep_trainer::evaluate::{check_dims, load_policy, LoadedPolicy};
use gaitsweep_trainer::train::CURRICULUM_EVAL_DIFFICULTY;

/// `worker render`: a GIF of a checkpoint's deterministic gait.
#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// The checkpoint (`.safetensors`, from `worker train` or the coordinator's data dir).
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Output GIF.
    #[arg(long, default_value = "gait.gif")]
    pub out: PathBuf,
    /// Terrain to walk on (default: the one the checkpoint was trained on).
    #[arg(long)]
    pub terrain: Option<TerrainKind>,
    /// Difficulty 0..=9 (default: the checkpoint's fixed difficulty, else the level the
    /// scoring rollout uses for curriculum runs).
    #[arg(long)]
    pub difficulty: Option<u8>,
    /// Seconds of walking to record.
    #[arg(long, default_value_t = 6.0)]
    pub seconds: f32,
    /// Commanded forward speed, m/s (a negative value keeps the preset's random commands).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub speed: f32,
    /// Commanded heading, rad (default: the preset's random headings).
    #[arg(long, allow_hyphen_values = true)]
    pub heading: Option<f32>,
    /// Draw a frame every N policy steps (default: about 25 frames per second).
    #[arg(long)]
    pub every: Option<u32>,
    /// Seed of the spawn, terrain variant and commands.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Terrain variant to walk on: stairs and slopes 0 = up to the centre (the robot starts
    /// on top), 1 = down (it starts in a pit); rough: one of two random fields.
    #[arg(long, default_value_t = 0)]
    pub variant: usize,
}

/// What [`render`] produced.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The GIF written.
    pub path: PathBuf,
    /// Frames in it.
    pub frames: usize,
    /// Seconds of simulated walking.
    pub seconds: f32,
    /// Straight-line distance the base covered (m).
    pub distance: f32,
    /// Whether the robot fell (the recording stops there).
    pub fell: bool,
    /// Terrain walked on.
    pub terrain: TerrainKind,
}

/// Renders `a.checkpoint` to `a.out`.
pub fn render(a: &RenderArgs) -> Result<Rendered> {
    if !(a.seconds > 0.0 && a.seconds.is_finite()) {
        return Err(Error::Config(format!(
            "--seconds must be > 0, got {}",
            a.seconds
        )));
    }
    if let Some(d) = a.difficulty.filter(|d| *d > 9) {
        return Err(Error::Config(format!(
            "--difficulty must be 0..=9, got {d}"
        )));
    }
    let LoadedPolicy {
        meta,
        mut preset,
        ppo,
    } = load_policy(&a.checkpoint)?;
    if a.speed >= 0.0 {
        preset.commands.forward_speed = [a.speed, a.speed];
    }
    if let Some(h) = a.heading {
        preset.commands.heading = [h, h];
    }
    let terrain = match a.terrain {
        Some(t) => t,
        None => meta.terrain.parse::<TerrainKind>()?,
    };
    let difficulty = a
        .difficulty
        .or(meta.difficulty)
        .unwrap_or(CURRICULUM_EVAL_DIFFICULTY);
    check_dims(&a.checkpoint, &meta, &preset, terrain)?;
    let dt = preset.policy_dt();
    let mut env = VecEnv::new(
        &preset,
        EnvConfig {
            mode: gaitsweep_sim::EnvMode::Eval,
            terrain,
            num_envs: a.variant + 1,
            w1: meta.w1 as f32,
            w2: meta.w2 as f32,
            seed: a.seed,
            difficulty: Some(difficulty),
            episode_seconds: a.seconds + 1.0,
        },
    )?;
    env.set_auto_reset(false);

    let every = a
        .every
        .unwrap_or_else(|| ((0.04 / dt).round() as u32).max(1))
        .max(1);
    let fps = (1.0 / (every as f32 * dt)).round().clamp(1.0, 100.0) as u16;
    let steps = (a.seconds / dt).round().max(1.0) as usize;
    let mut distance = 0.0f32;
    let r0 = a.variant;
    let mut obs = env.observations().to_vec();
    let mut actions = vec![0.0f32; env.act_dim() * env.num_envs()];
    let mut frames = vec![env.render_frame(r0)];
    let mut fell = false;
    let mut walked = 0;
    for step in 1..=steps {
        ppo.act_deterministic(&obs, &mut actions)?;
        let r = env.step(&actions)?;
        let (done, timeout) = (r.dones[r0], r.timeouts[r0]);
        obs.copy_from_slice(r.obs);
        walked = step;
        if !done {
            // After a done the robot has already started a new episode.
            distance = env.walked(r0);
        }
        if step % every as usize == 0 {
            let (pos, yaw) = env.base_pose(r0);
            tracing::debug!(
                t = step as f32 * dt,
                x = pos[0],
                y = pos[1],
                z = pos[2],
                ground = env.tile_height(r0, pos[0], pos[1]),
                yaw,
                walked = env.walked(r0),
                "render step"
            );
        }
        if step % every as usize == 0 || done {
            frames.push(env.render_frame(r0));
        }
        if done {
            fell = !timeout;
            break;
        }
    }
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(Error::io(format!("create {}", dir.display())))?;
    }
    write_gif(&a.out, env.tile(r0), &frames, env.body_half_extents(), fps)?;
    Ok(Rendered {
        path: a.out.clone(),
        frames: frames.len(),
        seconds: walked as f32 * dt,
        distance,
        fell,
        terrain,
    })
}

/// Runs `worker render` and prints what it wrote.
pub fn run(a: RenderArgs) -> Result<()> {
    crate::cli::configure_threads(None);
    let r = render(&a)?;
    println!(
        "wrote {} ({} frames, {:.1} s on {}, base moved {:.2} m{})",
        display(&r.path),
        r.frames,
        r.seconds,
        r.terrain,
        r.distance,
        if r.fell { ", fell" } else { "" }
    );
    Ok(())
}

fn display(p: &Path) -> String {
    p.display().to_string()
}
