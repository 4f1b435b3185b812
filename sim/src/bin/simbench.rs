//! Simulation benchmark: robot-steps/s (physics steps x robots per second) for each robot,
//! terrain, thread count and solver setting, with random actions.
//!
//! `cargo run --release -p gaitsweep-sim --bin simbench -- --robots anymal,heavy`

use std::time::Instant;

use anyhow::Result;
use clap::Parser;
use gaitsweep_sim::{EnvConfig, Preset, TerrainKind, VecEnv};
use rand::{Rng, SeedableRng};

#[derive(Parser)]
struct Args {
    /// Robots to run.
    #[arg(long, value_delimiter = ',', default_value = "anymal,heavy")]
    robots: Vec<String>,
    /// Terrains to run.
    #[arg(long, value_delimiter = ',', default_value = "flat,rough,stairs")]
    terrains: Vec<String>,
    /// Thread counts to run.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// Robots per environment.
    #[arg(long, default_value_t = 64)]
    robots_per_env: usize,
    /// Policy steps to time (after 25 warm-up steps).
    #[arg(long, default_value_t = 200)]
    steps: usize,
    /// Skip rapier's default solver settings (4 iterations).
    #[arg(long)]
    no_default: bool,
    /// Also run the preset without leg colliders (base and feet only).
    #[arg(long)]
    no_legs: bool,
    /// Also run the preset with parry's per-triangle capsule-terrain contacts.
    #[arg(long)]
    parry_contacts: bool,
    /// Extra settings to compare: backend:iterations:pgs, e.g. impulse:1:4.
    #[arg(long, value_delimiter = ',', value_parser = parse_setting)]
    extra: Vec<(String, gaitsweep_sim::robot::JointBackend, usize, usize)>,
    /// Print one JSON object per line instead of a table.
    #[arg(long)]
    json: bool,
}

fn parse_setting(
    s: &str,
) -> Result<(String, gaitsweep_sim::robot::JointBackend, usize, usize), String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [b, i, g] = parts[..] else {
        return Err(format!("expected backend:iterations:pgs, got {s}"));
    };
    let backend = match b {
        "multibody" => gaitsweep_sim::robot::JointBackend::Multibody,
        "impulse" => gaitsweep_sim::robot::JointBackend::Impulse,
        _ => return Err(format!("unknown backend {b}")),
    };
    Ok((
        s.to_string(),
        backend,
        i.parse().map_err(|e| format!("{e}"))?,
        g.parse().map_err(|e| format!("{e}"))?,
    ))
}

fn run(p: &Preset, terrain: TerrainKind, n: usize, steps: usize, threads: usize) -> Result<f64> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| -> Result<f64> {
        let mut env = VecEnv::new(
            p,
            EnvConfig {
                mode: gaitsweep_sim::EnvMode::Train,
                terrain,
                num_envs: n,
                w1: 7.0,
                w2: -6.0,
                seed: 3,
                difficulty: Some(3),
                episode_seconds: 20.0,
            },
        )?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut actions = vec![0.0f32; n * 12];
        let mut step = |env: &mut VecEnv| -> Result<()> {
            actions
                .iter_mut()
                .for_each(|a| *a = rng.random_range(-1.0..1.0));
            env.step(&actions)?;
            Ok(())
        };
        for _ in 0..25 {
            step(&mut env)?;
        }
        let t = Instant::now();
        for _ in 0..steps {
            step(&mut env)?;
        }
        let physics_steps = (steps * n * p.control.decimation) as f64;
        Ok(physics_steps / t.elapsed().as_secs_f64())
    })
}

fn main() -> Result<()> {
    let a = Args::parse();
    if !a.json {
        println!("| robot | terrain | solver iterations | threads | robot-steps/s |");
        println!("|---|---|---|---|---|");
    }
    for robot in &a.robots {
        let preset = Preset::load(robot)?;
        let mut settings = vec![("preset", preset.clone())];
        if a.no_legs {
            // The same preset with only the base and the feet touching the terrain: what the
            // thigh and shank colliders cost.
            let mut d = preset.clone();
            d.control.leg_collisions = false;
            settings.push(("preset, no leg colliders", d));
        }
        if a.parry_contacts {
            // The contacts the leg capsules had before the closed-form ones, for comparison.
            let mut d = preset.clone();
            d.control.capsule_contacts = gaitsweep_sim::robot::CapsuleContacts::Parry;
            settings.push(("preset, parry's capsule contacts", d));
        }
        for (label, backend, iters, pgs) in &a.extra {
            let mut d = preset.clone();
            d.control.joints = *backend;
            d.control.solver_iterations = *iters;
            d.control.pgs_iterations = *pgs;
            settings.push((label.as_str(), d));
        }
        if !a.no_default {
            // rapier's own defaults: one multibody, 4 solver iterations, 1 internal PGS iteration.
            let mut d = preset.clone();
            d.control.joints = gaitsweep_sim::robot::JointBackend::Multibody;
            d.control.solver_iterations = 4;
            d.control.pgs_iterations = 1;
            settings.push(("rapier default", d));
        }
        for terrain in &a.terrains {
            let terrain: TerrainKind = terrain.parse()?;
            for (label, p) in &settings {
                for &th in &a.threads {
                    let rate = run(p, terrain, a.robots_per_env, a.steps, th)?;
                    if a.json {
                        println!(
                            "{}",
                            serde_json::json!({"robot": robot, "terrain": terrain.to_string(), "setting": label, "solver_iterations": p.control.solver_iterations, "threads": th, "robot_steps_per_s": rate})
                        );
                    } else {
                        println!("| {robot} | {terrain} | {:?} {} it, {} pgs ({label}) | {th} | {rate:.0} |", p.control.joints, p.control.solver_iterations, p.control.pgs_iterations);
                    }
                }
            }
        }
    }
    Ok(())
}
