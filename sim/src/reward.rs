//! The per-step reward of Kim et al. 2024 (Eq. 1), term by term, as pure functions of a
//! robot's state so that each term can be checked by hand.

use crate::preset::RewardConfig;

/// Names of the reward terms, in the order of [`RewardTerms::values`].
pub const TERM_NAMES: [&str; 12] = [
    "tracking_lin_vel",
    "torques",
    "tracking_ang_vel",
    "dof_acc",
    "lin_vel_z",
    "ang_vel_xy",
    "action_rate",
    "feet_air_time",
    "collision",
    "dof_pos_limits",
    "orientation",
    "termination",
];

/// Index of the termination term, added after the clip at zero (legged_gym).
const TERMINATION: usize = 11;

/// What the reward reads of one robot after one policy step.
#[derive(Debug, Clone, Default)]
pub struct RewardInput {
    /// Commanded forward speed (m/s), heading frame.
    pub cmd_speed: f32,
    /// Commanded yaw rate (rad/s).
    pub cmd_yaw_rate: f32,
    /// Base velocity in the heading (yaw) frame: forward, lateral, vertical.
    pub vel_heading: [f32; 3],
    /// Base linear velocity in the base frame (legged_gym's `lin_vel_z` reads its z: walking
    /// up a slope or stairs is not punished).
    pub linvel_base: [f32; 3],
    /// Base angular velocity in the base frame.
    pub angvel_base: [f32; 3],
    /// Mean over the decimation substeps of the sum of squared joint torques (N²·m²).
    pub torque_sq: f32,
    /// Sum of squared joint accelerations ((rad/s²)²).
    pub dof_acc_sq: f32,
    /// Sum of squared action changes.
    pub action_rate_sq: f32,
    /// Feet air time reward before weighting: sum over feet touching down this step of
    /// (air time - 0.5 s); zero when the command is below 0.1 m/s.
    pub air_time: f32,
    /// Horizontal part of gravity in the base frame (0 when upright).
    pub gravity_xy: [f32; 2],
    /// Leg shapes (thighs, shanks) touching the terrain.
    pub leg_contacts: u32,
    /// Sum over joints of how far each lies outside its soft position limits (rad).
    pub dof_pos_out: f32,
    /// Whether the robot fell this step (not a timeout).
    pub fell: bool,
}

/// The grid weights of a cell: w1 and the torque exponent w2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridWeights {
    /// Velocity tracking weight.
    pub w1: f32,
    /// Torque penalty weight exponent: the weight is 10^w2.
    pub w2: f32,
}

/// Weighted reward terms of one step (each already multiplied by the policy dt).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RewardTerms {
    /// Term values in [`TERM_NAMES`] order.
    pub values: [f32; 12],
}

impl RewardTerms {
    /// The total reward: the sum of the terms, clipped at zero before the termination
    /// term is added when `only_positive` is set (legged_gym's `only_positive_rewards`, so
    /// that a penalty-dominated step never makes ending the episode early pay).
    pub fn total(&self, only_positive: bool) -> f32 {
        let rest: f32 = self
            .values
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != TERMINATION)
            .map(|(_, v)| v)
            .sum();
        let rest = if only_positive { rest.max(0.0) } else { rest };
        rest + self.values[TERMINATION]
    }
}

/// legged_gym's `dof_pos_limits` input: how far `q` lies outside the soft limits, the
/// middle `soft` fraction of `[lower, upper]`.
pub fn dof_pos_out(q: &[f32], limits: &[Option<[f32; 2]>], soft: f32) -> f32 {
    q.iter()
        .zip(limits)
        .filter_map(|(q, l)| l.map(|[lo, hi]| (q, lo, hi)))
        .map(|(q, lo, hi)| {
            let (m, r) = ((lo + hi) / 2.0, (hi - lo) / 2.0 * soft);
            (m - r - q).max(0.0) + (q - m - r).max(0.0)
        })
        .sum()
}

/// Computes every term of Eq. 1 plus the preset's fixed terms, multiplied by `dt` as
/// legged_gym does.
pub fn compute(inp: &RewardInput, w: GridWeights, r: &RewardConfig, dt: f32) -> RewardTerms {
    let ev = inp.cmd_speed - inp.vel_heading[0];
    let lin_err = ev * ev + inp.vel_heading[1] * inp.vel_heading[1];
    let yaw_err = inp.cmd_yaw_rate - inp.angvel_base[2];
    let values = [
        w.w1 * (-lin_err / r.tracking_sigma).exp(),
        -(10f32).powf(w.w2) * inp.torque_sq,
        r.w3_heading * (-(yaw_err * yaw_err) / r.tracking_sigma).exp(),
        -r.w4_dof_acc * inp.dof_acc_sq,
        -r.lin_vel_z * inp.linvel_base[2] * inp.linvel_base[2],
        -r.ang_vel_xy * (inp.angvel_base[0].powi(2) + inp.angvel_base[1].powi(2)),
        -r.action_rate * inp.action_rate_sq,
        r.feet_air_time * inp.air_time,
        -r.collision * inp.leg_contacts as f32,
        -r.dof_pos_limits * inp.dof_pos_out,
        -r.orientation * (inp.gravity_xy[0].powi(2) + inp.gravity_xy[1].powi(2)),
        if inp.fell { -r.termination } else { 0.0 },
    ];
    RewardTerms {
        values: values.map(|v| v * dt),
    }
}

/// Feet air time bookkeeping (legged_gym): returns the air-time reward of this step and
/// updates the per-foot timers.
pub fn feet_air_time(
    air: &mut [f32; 4],
    last_contact: &mut [bool; 4],
    contact: &[bool; 4],
    dt: f32,
    cmd_speed: f32,
) -> f32 {
    let mut reward = 0.0;
    for f in 0..4 {
        // A foot counts as in contact if it is now or was last step (filters PhysX-style flicker).
        let filt = contact[f] || last_contact[f];
        let first_contact = air[f] > 0.0 && filt;
        air[f] += dt;
        if first_contact {
            reward += air[f] - 0.5;
        }
        if filt {
            air[f] = 0.0;
        }
        last_contact[f] = contact[f];
    }
    if cmd_speed > 0.1 {
        reward
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preset::Preset;

    #[test]
    fn every_term_matches_a_hand_computation() {
        // The hand computation below is written for a heading weight of 0.5.
        let r = RewardConfig {
            w3_heading: 0.5,
            ..Preset::load("anymal").unwrap().reward
        };
        let inp = RewardInput {
            cmd_speed: 1.0,
            cmd_yaw_rate: 0.5,
            vel_heading: [0.8, 0.1, 0.7],
            linvel_base: [0.5, 0.3, 0.2],
            angvel_base: [0.3, -0.4, 0.1],
            torque_sq: 1000.0,
            dof_acc_sq: 4.0e5,
            action_rate_sq: 2.0,
            air_time: 0.3,
            leg_contacts: 2,
            dof_pos_out: 0.25,
            gravity_xy: [0.3, 0.4],
            fell: true,
        };
        let mut r = r;
        r.termination = 3.0;
        r.dof_pos_limits = 10.0;
        r.orientation = 5.0;
        let w = GridWeights { w1: 7.0, w2: -6.0 };
        let dt = 0.02;
        let t = compute(&inp, w, &r, dt).values;
        let close =
            |a: f32, b: f64| assert!((a as f64 - b).abs() < 1e-6 * (1.0 + b.abs()), "{a} vs {b}");
        // exp(-((1-0.8)^2 + 0.1^2) / 0.25) = exp(-0.2)
        close(t[0], 7.0 * (-0.2f64).exp() * 0.02);
        close(t[1], -1e-6 * 1000.0 * 0.02);
        // exp(-(0.5-0.1)^2/0.25) = exp(-0.64)
        close(t[2], 0.5 * (-0.64f64).exp() * 0.02);
        close(t[3], -2.5e-7 * 4.0e5 * 0.02);
        close(t[4], -2.0 * 0.04 * 0.02);
        close(t[5], -0.05 * 0.25 * 0.02);
        close(t[6], -0.01 * 2.0 * 0.02);
        close(t[7], 1.0 * 0.3 * 0.02);
        close(t[8], -2.0 * 0.02);
        close(t[9], -10.0 * 0.25 * 0.02);
        close(t[10], -5.0 * 0.25 * 0.02);
        close(t[11], -3.0 * 0.02);
    }

    #[test]
    fn only_positive_clips_the_sum_before_the_termination_term() {
        let mut t = RewardTerms::default();
        t.values[0] = 0.1;
        t.values[1] = -0.3;
        t.values[TERMINATION] = -0.05;
        assert!((t.total(false) - (-0.25)).abs() < 1e-7);
        // Clipped: max(0.1 - 0.3, 0) - 0.05.
        assert!((t.total(true) - (-0.05)).abs() < 1e-7);
        t.values[1] = -0.02;
        assert!((t.total(true) - (0.08 - 0.05)).abs() < 1e-7);
        assert_eq!(TERM_NAMES[TERMINATION], "termination");
    }

    #[test]
    fn soft_limits_count_only_what_lies_outside() {
        let lim = [Some([-1.0, 1.0]), None, Some([0.0, 2.0])];
        assert_eq!(dof_pos_out(&[0.5, 9.0, 1.0], &lim, 1.0), 0.0);
        assert!((dof_pos_out(&[1.25, 9.0, -0.5], &lim, 1.0) - 0.75).abs() < 1e-6);
        // soft 0.9: limits shrink to [-0.9, 0.9] and [0.1, 1.9].
        assert!((dof_pos_out(&[0.95, 0.0, 0.0], &lim, 0.9) - 0.15).abs() < 1e-6);
    }

    #[test]
    fn air_time_rewards_touchdown_after_long_swing() {
        let mut air = [0.0; 4];
        let mut last = [true; 4];
        let dt = 0.02;
        // Foot 0 lifts for 40 steps (0.8 s), then touches down.
        for _ in 0..40 {
            assert_eq!(
                feet_air_time(&mut air, &mut last, &[false, true, true, true], dt, 1.0),
                0.0
            );
        }
        let r = feet_air_time(&mut air, &mut last, &[true, true, true, true], dt, 1.0);
        // The first lifted step is filtered by the previous contact, so air = 0.8 s at touchdown.
        assert!((r - (0.8 - 0.5)).abs() < 1e-4, "{r}");
        assert_eq!(air, [0.0; 4]);
    }
}
