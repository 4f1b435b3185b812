//! The vectorised environment: N robots, one rapier world each, stepped in parallel.

use rayon::prelude::*;

use crate::agent::{Agent, NJ};
use crate::error::{Error, Result};
use crate::preset::Preset;
use crate::reward::{GridWeights, TERM_NAMES};
use crate::robot::RobotWorld;
use crate::score::{self, GaitScore, ScoreVariant};
use crate::terrain::{curriculum_update, TerrainKind, TerrainSet, TerrainUse};
use crate::urdf::RobotModel;

/// What an environment is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnvMode {
    /// Training: the training tiles, and the first episode of each robot starts at a random
    /// step (legged_gym's `init_at_random_ep_len`) so that resets are staggered.
    Train,
    /// Evaluation: tiles from seeds disjoint from training's; every episode starts at step 0.
    Eval,
}

/// Settings of a vectorised environment.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvConfig {
    /// Training or evaluation.
    pub mode: EnvMode,
    /// Terrain kind.
    pub terrain: TerrainKind,
    /// Number of robots.
    pub num_envs: usize,
    /// Velocity tracking weight.
    pub w1: f32,
    /// Torque penalty exponent (weight 10^w2).
    pub w2: f32,
    /// Seed of spawns, commands and terrain variants.
    pub seed: u64,
    /// Fixed difficulty level, or `None` for legged_gym's curriculum (starting at 0).
    pub difficulty: Option<u8>,
    /// Episode length (s).
    pub episode_seconds: f32,
}

/// One step's outputs, borrowed from the environment.
#[derive(Debug)]
pub struct StepResult<'a> {
    /// Observations after the step (of the new episode for robots that were reset),
    /// row-major `[N * obs_dim]`.
    pub obs: &'a [f32],
    /// Reward per robot.
    pub rewards: &'a [f32],
    /// Episode ended (fall or timeout) per robot.
    pub dones: &'a [bool],
    /// Episode ended by time (bootstrap the value).
    pub timeouts: &'a [bool],
    /// Weighted reward terms, row-major `[N * n_terms]`, in [`VecEnv::reward_term_names`] order.
    pub terms: &'a [f32],
}

/// N robots, each in its own rapier world.
pub struct VecEnv {
    preset: Preset,
    cfg: EnvConfig,
    terrain: TerrainSet,
    agents: Vec<Agent>,
    weights: GridWeights,
    max_steps: u32,
    auto_reset: bool,
    mass: f32,
    half_extents: rapier3d::math::Vector,
    obs: Vec<f32>,
    rewards: Vec<f32>,
    dones: Vec<bool>,
    timeouts: Vec<bool>,
    terms: Vec<f32>,
    finished: Vec<crate::score::ScoreAccumulator>,
}

fn mix(seed: u64, i: u64) -> u64 {
    // splitmix64: independent streams per robot from one seed.
    let mut z = seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Chebyshev distance (m) of (x, y) from the nearest sub-tile centre, for diagnostics.
fn sub_tile_ring(x: f32, y: f32) -> f32 {
    crate::terrain::sub(x)
        .abs()
        .max(crate::terrain::sub(y).abs())
}

impl VecEnv {
    /// Builds `cfg.num_envs` robots of `preset` on `cfg.terrain`.
    pub fn new(preset: &Preset, cfg: EnvConfig) -> Result<VecEnv> {
        if cfg.num_envs == 0 {
            return Err(Error::InvalidArgument("num_envs must be at least 1".into()));
        }
        if !(cfg.w1.is_finite() && cfg.w2.is_finite()) {
            return Err(Error::InvalidArgument(format!(
                "w1 and w2 must be finite, got {} and {}",
                cfg.w1, cfg.w2
            )));
        }
        if !(cfg.episode_seconds > 0.0) {
            return Err(Error::InvalidArgument(format!(
                "episode_seconds must be > 0, got {}",
                cfg.episode_seconds
            )));
        }
        let model = RobotModel::load(preset)?;
        let terrain = TerrainSet::new(
            cfg.terrain,
            match cfg.mode {
                EnvMode::Train => TerrainUse::Train,
                EnvMode::Eval => TerrainUse::Eval,
            },
        );
        let level = cfg.difficulty.unwrap_or(0);
        let agents: Vec<Agent> = (0..cfg.num_envs)
            .into_par_iter()
            .map(|i| {
                let world = RobotWorld::new(preset, &model, terrain.tile(level, i).clone());
                Agent::new(world, mix(cfg.seed, i as u64), level)
            })
            .collect();
        let n = cfg.num_envs;
        let preset = preset.for_terrain(cfg.terrain);
        let max_steps = (cfg.episode_seconds / preset.policy_dt()).round().max(1.0) as u32;
        let mut env = VecEnv {
            weights: GridWeights {
                w1: cfg.w1,
                w2: cfg.w2,
            },
            max_steps,
            auto_reset: true,
            mass: model.total_mass,
            // The box the render draws: the base's first collision shape's bounds in the
            // base frame (a box, or legged_gym's cylinder along x).
            half_extents: model.links[0]
                .shapes
                .first()
                .map(|(pose, s)| {
                    crate::robot::shared_shape(s, preset.control.capsule_legs)
                        .compute_aabb(pose)
                        .half_extents()
                })
                .unwrap_or(rapier3d::math::Vector::splat(0.2)),
            obs: vec![0.0; n * preset.obs_dim()],
            rewards: vec![0.0; n],
            dones: vec![false; n],
            timeouts: vec![false; n],
            terms: vec![0.0; n * TERM_NAMES.len()],
            finished: Vec::new(),
            preset,
            terrain,
            agents,
            cfg,
        };
        env.reset();
        Ok(env)
    }

    /// Number of robots.
    pub fn num_envs(&self) -> usize {
        self.agents.len()
    }

    /// Observation size.
    pub fn obs_dim(&self) -> usize {
        self.preset.obs_dim()
    }

    /// Action size (12).
    pub fn act_dim(&self) -> usize {
        NJ
    }

    /// Policy time step (s).
    pub fn policy_dt(&self) -> f32 {
        self.preset.policy_dt()
    }

    /// The preset.
    pub fn preset(&self) -> &Preset {
        &self.preset
    }

    /// Names of the reward terms.
    pub fn reward_term_names(&self) -> &[&'static str] {
        &TERM_NAMES
    }

    /// Whether done robots start a new episode (training) or freeze (evaluation).
    pub fn set_auto_reset(&mut self, on: bool) {
        self.auto_reset = on;
    }

    /// Resets every robot from the configured seed; returns the observations.
    pub fn reset(&mut self) -> &[f32] {
        self.reseed(self.cfg.seed);
        &self.obs
    }

    /// Resets every robot from `seed` (the start of a run, or its resumption). In training
    /// mode each robot's episode then starts at a random step, as legged_gym's
    /// `init_at_random_ep_len`, so that the robots do not all reset together.
    pub fn reseed(&mut self, seed: u64) {
        use rand::{Rng, SeedableRng};
        let (p, terrain, od) = (&self.preset, &self.terrain, self.preset.obs_dim());
        let (stagger, max_steps) = (self.cfg.mode == EnvMode::Train, self.max_steps);
        self.agents
            .par_iter_mut()
            .zip(self.obs.par_chunks_mut(od))
            .enumerate()
            .for_each(|(i, (a, o))| {
                a.rng = rand_chacha::ChaCha8Rng::seed_from_u64(mix(seed, i as u64));
                a.reset(p, terrain.tile(a.level, i).clone());
                a.set_randomized(p, stagger);
                if stagger {
                    let start = a.rng.random_range(0..max_steps);
                    a.skip_ahead(start);
                }
                a.observe(p, o);
            });
        self.finished.clear();
    }

    /// Steps each robot has been in its current episode, counted from its episode's
    /// (possibly staggered) start step.
    pub fn episode_steps(&self) -> Vec<u32> {
        self.agents.iter().map(|a| a.step_in_episode).collect()
    }

    /// Current observations.
    pub fn observations(&self) -> &[f32] {
        &self.obs
    }

    /// The left-right mirror of this environment's observations and actions (`None`
    /// when the preset names no joint mirror).
    pub fn mirror(&self) -> Result<Option<crate::mirror::Mirror>> {
        crate::mirror::Mirror::for_preset(&self.preset).map_err(Error::InvalidArgument)
    }

    /// Names of the terrain variants robots are dealt in turn (robot `i` gets variant
    /// `i % len`), where the variants differ in kind: stairs and slopes start robots on
    /// top of the pyramid or in its pit; the mixed terrain's tiles are named by their kind
    /// (repeated names are counted together). Empty for flat and rough ground.
    pub fn variant_names(&self) -> &'static [&'static str] {
        match self.cfg.terrain {
            TerrainKind::Stairs | TerrainKind::Slopes => &["top", "pit"],
            TerrainKind::Mixed => &crate::terrain::MIXED_NAMES,
            TerrainKind::Flat | TerrainKind::Rough => &[],
        }
    }

    /// Difficulty level per robot.
    pub fn levels(&self) -> Vec<u8> {
        self.agents.iter().map(|a| a.level).collect()
    }

    /// Sets each robot's curriculum level (a resumed run restores the levels it saved);
    /// they take effect at the next reset or reseed. Errors on a length mismatch.
    pub fn set_levels(&mut self, levels: &[u8]) -> Result<()> {
        if levels.len() != self.agents.len() {
            return Err(Error::InvalidArgument(format!(
                "expected {} levels, got {}",
                self.agents.len(),
                levels.len()
            )));
        }
        for (a, l) in self.agents.iter_mut().zip(levels) {
            a.level = (*l).min(crate::terrain::LEVELS - 1);
        }
        Ok(())
    }

    /// Advances every robot one policy step with `actions` (`[N * 12]`, row-major).
    pub fn step(&mut self, actions: &[f32]) -> Result<StepResult<'_>> {
        let n = self.agents.len();
        if actions.len() != n * NJ {
            return Err(Error::InvalidArgument(format!(
                "expected {} actions ({} robots x {NJ}), got {}",
                n * NJ,
                n,
                actions.len()
            )));
        }
        let (p, terrain, w, max_steps, auto_reset, curriculum) = (
            &self.preset,
            &self.terrain,
            self.weights,
            self.max_steps,
            self.auto_reset,
            self.cfg.difficulty.is_none(),
        );
        let od = p.obs_dim();
        let nt = TERM_NAMES.len();
        let finished: Vec<Option<crate::score::ScoreAccumulator>> = self
            .agents
            .par_iter_mut()
            .zip(actions.par_chunks(NJ))
            .zip(self.obs.par_chunks_mut(od))
            .zip(self.terms.par_chunks_mut(nt))
            .zip(self.rewards.par_iter_mut())
            .zip(self.dones.par_iter_mut().zip(self.timeouts.par_iter_mut()))
            .enumerate()
            .map(|(i, (((((a, act), o), t), r), (d, to)))| {
                if a.frozen {
                    *r = 0.0;
                    *d = true;
                    *to = false;
                    t.fill(0.0);
                    return None;
                }
                let rep = a.step(p, w, act, max_steps);
                *r = rep.reward;
                *d = rep.done;
                *to = rep.timeout;
                t.copy_from_slice(&a.terms.values);
                let mut done_score = None;
                if rep.done {
                    let b = a.world.base().pos;
                    tracing::debug!(
                        target: "gaitsweep_sim::episodes",
                        robot = i,
                        variant = i % 2,
                        level = a.level,
                        walked = a.walked(),
                        seconds = a.episode_seconds(p),
                        cmd_speed = a.cmd.speed,
                        heading = a.cmd.heading,
                        timeout = rep.timeout,
                        base_height = b.z - a.world.tile().height(b.x, b.y),
                        // Chebyshev distance from the nearest sub-tile centre: on stairs and
                        // slopes below 1.5 m the robot is on the platform, near 4 m at a border.
                        ring = sub_tile_ring(b.x, b.y),
                        "episode ended"
                    );
                    done_score = Some(a.score.clone());
                    if auto_reset {
                        if curriculum {
                            // legged_gym demotes on the command times the full episode length;
                            // a staggered first episode is shorter, so use the time it lasted.
                            let commanded = a.cmd.speed * a.episode_seconds(p);
                            let (level, walked) = (a.level, a.walked());
                            let rng = &mut a.rng;
                            a.level = curriculum_update(level, walked, commanded, || {
                                if p.curriculum.random_after_last {
                                    rand::Rng::random_range(rng, 0..crate::terrain::LEVELS)
                                } else {
                                    level
                                }
                            });
                        }
                        a.reset(p, terrain.tile(a.level, i).clone());
                    } else {
                        a.frozen = true;
                    }
                }
                a.observe(p, o);
                done_score
            })
            .collect();
        self.finished.extend(finished.into_iter().flatten());
        if let Some(i) = self.obs.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                robot: i / od,
                quantity: "observation",
            });
        }
        Ok(StepResult {
            obs: &self.obs,
            rewards: &self.rewards,
            dones: &self.dones,
            timeouts: &self.timeouts,
            terms: &self.terms,
        })
    }

    /// Scores of episodes that ended since the last reset, plus the running episodes of
    /// frozen (evaluated) robots; used by the evaluation.
    pub fn gait_score(&self, variant: ScoreVariant) -> GaitScore {
        score::summarize(
            &self.finished,
            self.mass,
            u64::from(self.max_steps),
            variant,
        )
    }

    /// Robot mass (kg).
    pub fn robot_mass(&self) -> f32 {
        self.mass
    }

    /// Base heights above the ground the feet stand on (mean terrain height under the
    /// four feet) and tilts |g_xy|, per robot.
    pub fn base_heights_and_tilts(&self) -> Vec<(f32, f32)> {
        self.agents
            .iter()
            .map(|a| {
                let b = a.world.base();
                let g = b.rot.inverse() * rapier3d::math::Vector::new(0.0, 0.0, -1.0);
                let feet = a.world.foot_positions();
                let ground = feet
                    .iter()
                    .map(|f| a.world.tile().height(f.x, f.y))
                    .sum::<f32>()
                    / feet.len() as f32;
                (b.pos.z - ground, g.x.hypot(g.y))
            })
            .collect()
    }

    /// Body and foot positions of robot `i` (for rendering).
    pub fn robot_geometry(
        &self,
        i: usize,
    ) -> (Vec<rapier3d::math::Vector>, Vec<rapier3d::math::Vector>) {
        let w = &self.agents[i].world;
        (w.body_positions(), w.foot_positions())
    }

    /// A rendering frame of robot `i` (see [`crate::render`]).
    pub fn render_frame(&self, i: usize) -> crate::render::Frame {
        let w = &self.agents[i].world;
        let b = w.base();
        let bodies = w.body_positions();
        crate::render::Frame {
            base_pos: b.pos,
            base_rot: b.rot,
            joints: bodies[1..].to_vec(),
            feet: w.foot_positions(),
        }
    }

    /// Half extents of robot `i`'s body box (for rendering).
    pub fn body_half_extents(&self) -> rapier3d::math::Vector {
        self.half_extents
    }

    /// Tilts robot `i` by `angle` about its base x axis, keeping its joints (tests use it
    /// to check fall detection).
    pub fn tip_over(&mut self, i: usize, angle: f32) {
        let a = &mut self.agents[i];
        let b = a.world.base();
        let mut q = [0.0; NJ];
        let mut qd = [0.0; NJ];
        a.world.joint_state(&mut q, &mut qd);
        let yaw = crate::agent::yaw_of(&b.rot);
        a.world.reset_with_rotation(
            b.pos.x,
            b.pos.y,
            b.pos.z,
            rapier3d::math::Rotation::from_rotation_z(yaw)
                * rapier3d::math::Rotation::from_rotation_x(angle),
            &q,
        );
    }

    /// The physics' terrain height under (x, y) for robot `i` (ray cast against its collider).
    pub fn ray_height(&mut self, i: usize, x: f32, y: f32) -> Option<f32> {
        self.agents[i].world.ray_height(x, y)
    }

    /// Distance robot `i` has walked from where its current episode began (m), counting
    /// the moves back by the terrain's period.
    pub fn walked(&self, i: usize) -> f32 {
        self.agents[i].walked()
    }

    /// Base position and yaw of robot `i`.
    pub fn base_pose(&self, i: usize) -> ([f32; 3], f32) {
        let b = self.agents[i].world.base();
        ([b.pos.x, b.pos.y, b.pos.z], crate::agent::yaw_of(&b.rot))
    }

    /// The tile robot `i` stands on.
    pub fn tile(&self, i: usize) -> &crate::terrain::Tile {
        self.agents[i].world.tile()
    }

    /// The tile's terrain height under (x, y) for robot `i`.
    pub fn tile_height(&self, i: usize, x: f32, y: f32) -> f32 {
        self.agents[i].world.tile().height(x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mirror::Mirror;
    use rand::{Rng, SeedableRng};

    /// A robot and its mirror image, driven by mirrored actions, observe mirrored states:
    /// the maps of [`Mirror`] are what the simulator computes, height scan included.
    #[test]
    fn a_mirrored_robot_observes_the_mirrored_observation() {
        let mut preset = Preset::load("anymal").unwrap();
        // Gauss-Seidel solves the constraints in order, and a mirrored robot's order is not
        // the mirror of the robot's: converge the solver so that physics is symmetric too.
        preset.control.solver_iterations = 30;
        let cfg = EnvConfig {
            mode: EnvMode::Eval,
            terrain: TerrainKind::Stairs,
            num_envs: 3,
            w1: 7.0,
            w2: -6.0,
            seed: 1,
            difficulty: Some(3),
            episode_seconds: 20.0,
        };
        let mut env = VecEnv::new(&preset, cfg).unwrap();
        let m = env.mirror().unwrap().expect("anymal names its mirror");
        let p = env.preset.clone();
        // Robots 0 and 2 live on the same tile (robot 1 on the pit variant): mirrored spots
        // near the platform's edge, so the scan reaches over a step, mirrored headings.
        for (i, side) in [(0usize, 1.0f32), (2, -1.0)] {
            let a = &mut env.agents[i];
            let (x, y, yaw) = (0.4, side * 1.2, side * 0.3);
            let z = a.world.tile().height(x, y) + p.spawn_height;
            a.world.reset(x, y, z, yaw, &p.default_pose);
            a.cmd.speed = 0.6;
            a.cmd.heading = side;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let od = env.obs_dim();
        let (mut scan_steps, mut unmirrored) = (0, 0.0f32);
        let rms = |x: &[f32], y: &[f32]| {
            let s: f32 = x.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum();
            (s / x.len() as f32).sqrt()
        };
        for step in 0..15 {
            let a0: Vec<f32> = (0..NJ).map(|_| rng.random_range(-0.5..0.5)).collect();
            let mut actions = vec![0.0; 3 * NJ];
            actions[..NJ].copy_from_slice(&a0);
            actions[2 * NJ..].copy_from_slice(&Mirror::apply(&m.act, &a0));
            env.step(&actions).unwrap();
            let o = env.observations();
            let want = Mirror::apply(&m.obs, &o[..od]);
            // Rapier's solver is not exactly mirror-symmetric (constraint order), so the
            // two robots drift apart by a few percent; a wrong index or sign is off by the
            // size of the value itself, as the identity (no mirror) shows.
            let got = &o[2 * od..];
            for (part, range) in [("proprioception", 0..48), ("height scan", 48..od)] {
                let zero = vec![0.0; range.len()];
                let size = rms(&got[range.clone()], &zero);
                let off = rms(&want[range.clone()], &got[range.clone()]) / size;
                assert!(
                    off < 0.03,
                    "step {step}: {part} mirrored off by {off} of its size"
                );
                if range.start == 0 {
                    unmirrored = unmirrored.max(rms(&o[range.clone()], &got[range]) / size);
                }
            }
            // The scan is not one height repeated: it sees the step.
            let scan = &o[48..od];
            if scan.iter().any(|v| (v - scan[0]).abs() > 0.1) {
                scan_steps += 1;
            }
        }
        assert!(scan_steps > 0, "the scan never reached the step");
        assert!(
            unmirrored > 0.5,
            "the robots stayed too alike to test the mirror: {unmirrored}"
        );
    }
}
