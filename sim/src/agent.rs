//! One simulated robot's episode: commands, PD control over the decimation substeps,
//! reward, termination, observation and score bookkeeping.

use std::f32::consts::PI;
use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier3d::math::{Rotation, Vector};

use crate::preset::Preset;
use crate::reward::{self, GridWeights, RewardInput, RewardTerms};
use crate::robot::RobotWorld;
use crate::score::{ScoreAccumulator, ScoreStep};
use crate::terrain::{Tile, SUB_TILE};

/// Joints of a quadruped.
pub const NJ: usize = 12;

/// The command of a robot (paper: c_t = {v_d, theta_d}).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Command {
    /// Forward speed (m/s).
    pub speed: f32,
    /// Target heading (rad).
    pub heading: f32,
}

/// Wraps an angle to [-pi, pi).
pub fn wrap(a: f32) -> f32 {
    (a + PI).rem_euclid(2.0 * PI) - PI
}

/// Yaw of a rotation.
pub fn yaw_of(r: &Rotation) -> f32 {
    let fwd = *r * Vector::X;
    fwd.y.atan2(fwd.x)
}

/// What a step reports of one robot.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepReport {
    /// Total reward.
    pub reward: f32,
    /// The episode ended (fall or timeout).
    pub done: bool,
    /// It ended by time, not by a fall.
    pub timeout: bool,
}

/// One robot and its episode state.
pub struct Agent {
    pub(crate) world: RobotWorld,
    pub(crate) rng: ChaCha8Rng,
    pub(crate) level: u8,
    pub(crate) cmd: Command,
    pub(crate) cmd_yaw_rate: f32,
    origin: [f32; 2],
    actions: [f32; NJ],
    last_actions: [f32; NJ],
    q: [f32; NJ],
    qd: [f32; NJ],
    last_qd: [f32; NJ],
    air: [f32; 4],
    last_contact: [bool; 4],
    pub(crate) step_in_episode: u32,
    /// `step_in_episode` when the episode began (a staggered first episode starts late).
    pub(crate) first_step: u32,
    /// Distance the robot has been moved back by the terrain's period this episode.
    shifted: [f32; 2],
    last_pos: [f32; 2],
    /// Score of the current episode.
    pub(crate) score: ScoreAccumulator,
    /// The last reward terms.
    pub(crate) terms: RewardTerms,
    /// Frozen: done in an evaluation, no more stepping.
    pub(crate) frozen: bool,
    /// Training robot: observation noise and pushes of the preset's `domain_rand` apply.
    pub(crate) randomized: bool,
}

impl Agent {
    pub(crate) fn new(world: RobotWorld, seed: u64, level: u8) -> Agent {
        Agent {
            world,
            rng: ChaCha8Rng::seed_from_u64(seed),
            level,
            cmd: Command::default(),
            cmd_yaw_rate: 0.0,
            origin: [0.0; 2],
            actions: [0.0; NJ],
            last_actions: [0.0; NJ],
            q: [0.0; NJ],
            qd: [0.0; NJ],
            last_qd: [0.0; NJ],
            air: [0.0; 4],
            last_contact: [true; 4],
            step_in_episode: 0,
            first_step: 0,
            shifted: [0.0; 2],
            last_pos: [0.0; 2],
            score: ScoreAccumulator::default(),
            terms: RewardTerms::default(),
            frozen: false,
            randomized: false,
        }
    }

    pub(crate) fn sample_command(&mut self, p: &Preset) {
        let c = &p.commands;
        let drawn = self
            .rng
            .random_range(c.forward_speed[0]..=c.forward_speed[1]);
        self.cmd.speed = c.forward_command(drawn);
        self.cmd.heading = self.rng.random_range(c.heading[0]..=c.heading[1]);
    }

    /// Starts a new episode on `tile` (legged_gym: random yaw, small xy offset).
    pub(crate) fn reset(&mut self, p: &Preset, tile: Arc<Tile>) {
        if !Arc::ptr_eq(self.world.tile(), &tile) {
            self.world.set_tile(tile);
        }
        let x = self.rng.random_range(-0.5..=0.5f32);
        let y = self.rng.random_range(-0.5..=0.5f32);
        let yaw = self.rng.random_range(-PI..PI);
        let z = self.world.tile().height(x, y) + p.spawn_height;
        self.world.reset(x, y, z, yaw, &p.default_pose);
        let r = p.reset;
        if r.dof_pos_scale != [1.0, 1.0] {
            // A pose with straighter legs than the default would start with its feet in
            // the ground: raise it until its lowest foot is where the default pose's is.
            let foot_z = self.world.lowest_foot_z();
            let mut q = [0.0f32; NJ];
            for (k, qk) in q.iter_mut().enumerate() {
                let s = self
                    .rng
                    .random_range(r.dof_pos_scale[0]..=r.dof_pos_scale[1]);
                *qk = p.default_pose[k] * s;
                if let Some([lo, hi]) = self.world.joint_limits()[k] {
                    *qk = qk.clamp(lo, hi);
                }
            }
            self.world.reset(x, y, z, yaw, &q);
            let lift = (foot_z - self.world.lowest_foot_z()).max(0.0);
            if lift > 0.0 {
                self.world.reset(x, y, z + lift, yaw, &q);
            }
        }
        if r.base_vel > 0.0 {
            let v = r.base_vel;
            let mut draw = || self.rng.random_range(-v..=v);
            let lin = Vector::new(draw(), draw(), draw());
            let ang = Vector::new(draw(), draw(), draw());
            self.world.set_base_velocity(lin, ang);
        }
        self.origin = [x, y];
        self.last_pos = [x, y];
        self.actions = [0.0; NJ];
        self.last_actions = [0.0; NJ];
        self.world.joint_state(&mut self.q, &mut self.qd);
        self.last_qd = self.qd;
        self.air = [0.0; 4];
        self.last_contact = [true; 4];
        self.step_in_episode = 0;
        self.first_step = 0;
        self.shifted = [0.0; 2];
        self.score = ScoreAccumulator::default();
        self.frozen = false;
        self.sample_command(p);
        self.update_yaw_command(p);
    }

    fn update_yaw_command(&mut self, p: &Preset) {
        let yaw = yaw_of(&self.world.base().rot);
        let c = &p.commands;
        self.cmd_yaw_rate =
            (c.heading_gain * wrap(self.cmd.heading - yaw)).clamp(-c.max_yaw_rate, c.max_yaw_rate);
    }

    /// Distance walked from the episode's origin (m), counting the moves back by the
    /// terrain's period.
    pub(crate) fn walked(&self) -> f32 {
        let b = self.world.base().pos;
        (b.x - self.shifted[0] - self.origin[0]).hypot(b.y - self.shifted[1] - self.origin[1])
    }

    /// Makes this a training robot (`on`) or an evaluated one: a training robot's shapes
    /// get a friction drawn from the preset's range, its observations are noisy and it is
    /// pushed; an evaluated robot has the preset's friction and none of that.
    pub(crate) fn set_randomized(&mut self, p: &Preset, on: bool) {
        let d = &p.domain_rand;
        self.randomized = on;
        let friction = if on && d.randomize_friction {
            self.rng
                .random_range(d.friction_range[0]..=d.friction_range[1])
        } else {
            p.control.friction
        };
        self.world.set_robot_friction(friction);
    }

    /// legged_gym's `_push_robots`: the base's horizontal velocity set to a random one.
    fn push(&mut self, p: &Preset) {
        let d = &p.domain_rand;
        if !(self.randomized && d.push_robots) {
            return;
        }
        let every = (d.push_interval_s / p.policy_dt()).round().max(1.0) as u32;
        if self.step_in_episode.is_multiple_of(every) {
            let m = d.max_push_vel_xy;
            let vx = self.rng.random_range(-m..=m);
            let vy = self.rng.random_range(-m..=m);
            self.world.push_base(vx, vy);
        }
    }

    /// Starts this episode as if `steps` of it had passed (legged_gym's
    /// `init_at_random_ep_len`): the robots of a batch then end their episodes at different
    /// times.
    pub(crate) fn skip_ahead(&mut self, steps: u32) {
        self.step_in_episode = steps;
        self.first_step = steps;
    }

    /// Seconds of this episode so far.
    pub(crate) fn episode_seconds(&self, p: &Preset) -> f32 {
        (self.step_in_episode - self.first_step) as f32 * p.policy_dt()
    }

    /// Keeps the robot within one terrain period of the tile's centre: the terrain repeats
    /// every [`SUB_TILE`] metres, so moving the robot back by one period changes nothing it
    /// feels, and the ground is unbounded.
    fn recentre(&mut self) {
        let b = self.world.base().pos;
        let wrap = |v: f32| {
            if v > SUB_TILE {
                -SUB_TILE
            } else if v < -SUB_TILE {
                SUB_TILE
            } else {
                0.0
            }
        };
        let (dx, dy) = (wrap(b.x), wrap(b.y));
        if dx != 0.0 || dy != 0.0 {
            self.world.shift(dx, dy);
            self.shifted[0] += dx;
            self.shifted[1] += dy;
            self.last_pos[0] += dx;
            self.last_pos[1] += dy;
        }
    }

    /// Advances one policy step with `actions` (clipped to [-clip, clip]).
    pub(crate) fn step(
        &mut self,
        p: &Preset,
        w: GridWeights,
        actions: &[f32],
        max_steps: u32,
    ) -> StepReport {
        let ctl = &p.control;
        let clip = p.observation.clip;
        let mut targets = [0.0f32; NJ];
        for k in 0..NJ {
            self.actions[k] = actions[k].clamp(-clip, clip);
            targets[k] = p.default_pose[k] + ctl.action_scale * self.actions[k];
        }
        let mut tau = [0.0f32; NJ];
        let (mut torque_sq, mut torque_norm, mut abs_torque, mut power) =
            (0.0f32, 0.0f32, 0.0f32, 0.0f32);
        for _ in 0..ctl.decimation {
            self.world
                .step(&targets, &mut self.q, &mut self.qd, &mut tau);
            let sq: f32 = tau.iter().map(|t| t * t).sum();
            torque_sq += sq;
            torque_norm += sq.sqrt();
            abs_torque += tau.iter().map(|t| t.abs()).sum::<f32>() / NJ as f32;
            // Power of the torques at the velocities they were computed from.
            power += tau
                .iter()
                .zip(&self.qd)
                .map(|(t, v)| (t * v).abs())
                .sum::<f32>();
        }
        let dec = ctl.decimation as f32;
        let dt = p.policy_dt();
        self.world.joint_state(&mut self.q, &mut self.qd);
        let base = self.world.base();
        let yaw = yaw_of(&base.rot);
        let heading_rot = Rotation::from_rotation_z(-yaw);
        let vh = heading_rot * base.linvel;
        let ang_b = base.rot.inverse() * base.angvel;
        let lin_b = base.rot.inverse() * base.linvel;
        let grav_b = base.rot.inverse() * Vector::new(0.0, 0.0, -1.0);
        let mut contact = [false; 4];
        self.world.foot_contacts(&mut contact);
        let air_time = reward::feet_air_time(
            &mut self.air,
            &mut self.last_contact,
            &contact,
            dt,
            self.cmd.speed,
        );
        let dof_acc_sq: f32 = (0..NJ)
            .map(|k| ((self.qd[k] - self.last_qd[k]) / dt).powi(2))
            .sum();
        let action_rate_sq: f32 = (0..NJ)
            .map(|k| (self.actions[k] - self.last_actions[k]).powi(2))
            .sum();

        self.step_in_episode += 1;
        let fell = self.world.base_contact()
            || grav_b.z > -0.3
            || base.pos.z - self.world.tile().height(base.pos.x, base.pos.y)
                < 0.35 * p.nominal_base_height;
        let timeout = !fell && self.step_in_episode >= max_steps;
        if fell {
            tracing::debug!(
                target: "gaitsweep_sim::falls",
                step = self.step_in_episode,
                base_contact = self.world.base_contact(),
                gravity_z = grav_b.z,
                height = base.pos.z - self.world.tile().height(base.pos.x, base.pos.y),
                cmd_speed = self.cmd.speed,
                forward = vh.x,
                lateral = vh.y,
                q = ?self.q,
                "robot fell"
            );
        }

        let inp = RewardInput {
            cmd_speed: self.cmd.speed,
            cmd_yaw_rate: self.cmd_yaw_rate,
            vel_heading: [vh.x, vh.y, vh.z],
            linvel_base: [lin_b.x, lin_b.y, lin_b.z],
            angvel_base: [ang_b.x, ang_b.y, ang_b.z],
            torque_sq: torque_sq / dec,
            dof_acc_sq,
            action_rate_sq,
            air_time,
            gravity_xy: [grav_b.x, grav_b.y],
            leg_contacts: self.world.leg_contacts() as u32,
            dof_pos_out: reward::dof_pos_out(
                &self.q,
                self.world.joint_limits(),
                p.reward.soft_dof_pos_limit,
            ),
            fell,
        };
        self.terms = reward::compute(&inp, w, &p.reward, dt);
        self.score.add(
            &ScoreStep {
                cmd: [self.cmd.speed, 0.0],
                vel: [vh.x, vh.y],
                torque_norm: torque_norm / dec,
                mean_abs_torque: abs_torque / dec,
                power: power / dec,
                gravity_xy: [grav_b.x, grav_b.y],
                displacement: [base.pos.x - self.last_pos[0], base.pos.y - self.last_pos[1]],
                dt,
            },
            p.reward.tracking_sigma,
            ctl.torque_limit,
            NJ,
        );
        self.score.fell |= fell;
        self.last_pos = [base.pos.x, base.pos.y];
        self.recentre();
        self.last_qd = self.qd;
        self.last_actions = self.actions;

        let resample = (p.commands.resample_seconds / dt).round().max(1.0) as u32;
        if self.step_in_episode.is_multiple_of(resample) {
            self.sample_command(p);
        }
        self.update_yaw_command(p);
        self.push(p);
        StepReport {
            reward: self.terms.total(p.reward.only_positive_rewards),
            done: fell || timeout,
            timeout,
        }
    }

    /// Writes the observation (legged_gym's layout) into `out`.
    pub(crate) fn observe(&mut self, p: &Preset, out: &mut [f32]) {
        let o = &p.observation;
        let d = &p.domain_rand;
        let noisy = self.randomized && d.add_noise;
        // legged_gym's noise_scale_vec: half-widths in observation units.
        let level = if noisy { d.noise_level } else { 0.0 };
        let scales = [
            (3, d.noise_lin_vel * o.lin_vel_scale),
            (3, d.noise_ang_vel * o.ang_vel_scale),
            (3, d.noise_gravity),
            (3, 0.0),
            (NJ, d.noise_dof_pos * o.dof_pos_scale),
            (NJ, d.noise_dof_vel * o.dof_vel_scale),
            (NJ, 0.0),
        ];
        let rng = &mut self.rng;
        let base = self.world.base();
        let inv = base.rot.inverse();
        let lv = inv * base.linvel;
        let av = inv * base.angvel;
        let g = inv * Vector::new(0.0, 0.0, -1.0);
        let mut i = 0;
        let mut put = |v: f32| {
            out[i] = v;
            i += 1;
        };
        for v in [lv.x, lv.y, lv.z] {
            put(v * o.lin_vel_scale);
        }
        for v in [av.x, av.y, av.z] {
            put(v * o.ang_vel_scale);
        }
        for v in [g.x, g.y, g.z] {
            put(v);
        }
        put(self.cmd.speed * o.lin_vel_scale);
        put(0.0);
        put(self.cmd_yaw_rate * o.ang_vel_scale);
        for k in 0..NJ {
            put((self.q[k] - p.default_pose[k]) * o.dof_pos_scale);
        }
        for k in 0..NJ {
            put(self.qd[k] * o.dof_vel_scale);
        }
        for k in 0..NJ {
            put(self.actions[k]);
        }
        let yaw = yaw_of(&base.rot);
        let scan = &mut out[i..];
        height_scan(
            self.world.tile(),
            [base.pos.x, base.pos.y, base.pos.z],
            yaw,
            p,
            scan,
        );
        if level > 0.0 {
            let mut j = 0;
            let height = (out.len() - i, d.noise_height * o.height_scale);
            for (n, half) in scales.into_iter().chain(std::iter::once(height)) {
                for v in &mut out[j..j + n] {
                    if half > 0.0 {
                        *v += rng.random_range(-1.0..=1.0f32) * half * level;
                    }
                }
                j += n;
            }
        }
        for v in out.iter_mut() {
            *v = v.clamp(-o.clip, o.clip);
        }
    }
}

/// legged_gym's height scan: for each point of the preset's grid, laid out in the yaw frame
/// around the base, `clip(base_z - nominal_height - h, -1, 1) * height_scale`.
pub fn height_scan(tile: &Tile, base: [f32; 3], yaw: f32, p: &Preset, out: &mut [f32]) {
    let o = &p.observation;
    let (s, c) = yaw.sin_cos();
    let mut i = 0;
    for &sx in &o.scan_x {
        for &sy in &o.scan_y {
            let (x, y) = (base[0] + c * sx - s * sy, base[1] + s * sx + c * sy);
            let h = tile.height(x, y);
            out[i] = (base[2] - p.nominal_base_height - h).clamp(-1.0, 1.0) * o.height_scale;
            i += 1;
        }
    }
}
