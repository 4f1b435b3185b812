//! The gait score (paper Eq. 4, our reading: README "What a score measures") and the locomotion metrics
//! recorded beside it.

pub use gaitsweep_model::{GaitScore, LevelScore, ScoreVariant};

/// One robot's per-step quantities for the score.
#[derive(Debug, Clone, Copy, Default)]
pub struct ScoreStep {
    /// Commanded velocity in the heading frame (x, y).
    pub cmd: [f32; 2],
    /// Base velocity in the heading frame (x, y).
    pub vel: [f32; 2],
    /// |tau|_2 of the step (mean over substeps of the 2-norm).
    pub torque_norm: f32,
    /// Mean |tau_j| over joints.
    pub mean_abs_torque: f32,
    /// Mechanical power sum |tau_j qd_j| (W).
    pub power: f32,
    /// Horizontal part of gravity in the base frame.
    pub gravity_xy: [f32; 2],
    /// Base displacement in the world xy plane since the previous step.
    pub displacement: [f32; 2],
    /// Length of the step (s): the commanded distance of the step is |cmd| dt.
    pub dt: f32,
}

/// Accumulates one robot's episode.
#[derive(Debug, Clone, Default)]
pub struct ScoreAccumulator {
    steps: u64,
    track: f64,
    effort: f64,
    tilt: f64,
    progress: f64,
    progress_bounded: f64,
    vel_err: f64,
    overspeed: f64,
    abs_torque: f64,
    power: f64,
    speed: f64,
    /// Whether the robot fell.
    pub fell: bool,
}

impl ScoreAccumulator {
    /// Adds one policy step. `sigma` is the tracking kernel width, `tau_max` the torque limit.
    pub fn add(&mut self, s: &ScoreStep, sigma: f32, tau_max: f32, joints: usize) {
        let ex = (s.cmd[0] - s.vel[0]) as f64;
        let ey = (s.cmd[1] - s.vel[1]) as f64;
        let err2 = ex * ex + ey * ey;
        self.steps += 1;
        self.track += (-err2 / sigma as f64).exp();
        self.effort += s.torque_norm as f64 / ((joints as f64).sqrt() * tau_max as f64);
        self.tilt += (s.gravity_xy[0] as f64).hypot(s.gravity_xy[1] as f64);
        let moved = (s.displacement[0] as f64).hypot(s.displacement[1] as f64);
        let cmd_speed = (s.cmd[0] as f64).hypot(s.cmd[1] as f64);
        self.progress += moved * moved;
        self.progress_bounded += moved.min(cmd_speed * s.dt as f64).powi(2);
        self.vel_err += err2.sqrt();
        let speed = (s.vel[0] as f64).hypot(s.vel[1] as f64);
        self.overspeed += (speed - cmd_speed).max(0.0);
        self.abs_torque += s.mean_abs_torque as f64;
        self.power += s.power as f64;
        self.speed += speed;
    }

    /// Steps accumulated.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// This robot's Eq.-4 J over its own steps.
    pub fn j(&self) -> f64 {
        self.j_over(self.steps, ScoreVariant::Eq4)
    }

    /// This robot's J over an episode of `episode_steps` (at least its own): steps after a
    /// fall count zero (README, "When a robot falls").
    pub fn j_over(&self, episode_steps: u64, variant: ScoreVariant) -> f64 {
        let t = episode_steps.max(self.steps);
        if t == 0 {
            return 0.0;
        }
        variant.j(
            self.track,
            self.effort,
            self.tilt,
            t as f64,
            self.progress,
            self.progress_bounded,
        )
    }
}

/// Averages robots' accumulators into a cell's score. `mass` is the robot's mass (kg);
/// `episode_steps` is the evaluation episode's full length T: the track, effort and tilt
/// sums are divided by T for every robot, so a robot that fell at step k gets nothing for
/// steps k..T (README, "When a robot falls"). The velocity error, torque and cost of transport are
/// means over the steps each robot walked. `variant` picks the progress term of J; both
/// progress terms are reported.
pub fn summarize(
    robots: &[ScoreAccumulator],
    mass: f32,
    episode_steps: u64,
    variant: ScoreVariant,
) -> GaitScore {
    let n = robots.len().max(1) as f64;
    let mut s = GaitScore {
        robots: robots.len(),
        ..Default::default()
    };
    let (mut power, mut speed) = (0.0, 0.0);
    for r in robots {
        let t = r.steps.max(1) as f64;
        let full = episode_steps.max(r.steps).max(1) as f64;
        s.score += r.j_over(episode_steps, variant) / n;
        s.track += r.track / full / n;
        s.effort += r.effort / full / n;
        s.tilt += r.tilt / full / n;
        s.progress += r.progress / n;
        s.progress_bounded += r.progress_bounded / n;
        s.overspeed += r.overspeed / t / n;
        s.fall_rate += if r.fell { 1.0 / n } else { 0.0 };
        s.mean_vel_error += r.vel_err / t / n;
        s.mean_abs_torque += r.abs_torque / t / n;
        power += r.power / t / n;
        speed += r.speed / t / n;
    }
    s.mean_speed = speed;
    s.cost_of_transport = if speed > 1e-3 {
        power / (mass as f64 * 9.81 * speed)
    } else {
        0.0
    };
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_component_matches_a_hand_computation() {
        let mut a = ScoreAccumulator::default();
        let s1 = ScoreStep {
            cmd: [1.0, 0.0],
            vel: [0.5, 0.0],
            torque_norm: 80.0,
            mean_abs_torque: 10.0,
            power: 50.0,
            gravity_xy: [0.3, 0.4],
            displacement: [0.01, 0.0],
            dt: 0.02,
        };
        let s2 = ScoreStep {
            vel: [1.0, 0.0],
            gravity_xy: [0.0, 0.0],
            displacement: [0.02, 0.0],
            ..s1
        };
        a.add(&s1, 0.25, 80.0, 12);
        a.add(&s2, 0.25, 80.0, 12);
        let track = ((-0.25f64 / 0.25).exp() + 1.0) / 2.0;
        let effort = 80.0 / (12f64.sqrt() * 80.0);
        let tilt = 0.5 / 2.0;
        let progress = 0.0001 + 0.0004;
        assert!((a.j() - (track - effort - tilt + progress)).abs() < 1e-6);
        let mut b = a.clone();
        b.fell = true;
        let s = summarize(&[a.clone(), b], 25.0, 2, ScoreVariant::Eq4);
        assert!((s.track - track).abs() < 1e-6);
        assert!((s.effort - effort).abs() < 1e-6);
        assert!((s.tilt - tilt).abs() < 1e-6);
        assert!((s.progress - progress).abs() < 1e-8);
        assert!((s.fall_rate - 0.5).abs() < 1e-12);
        assert!((s.mean_vel_error - 0.25).abs() < 1e-6);
        assert!((s.mean_abs_torque - 10.0).abs() < 1e-9);
        assert!((s.cost_of_transport - 50.0 / (25.0 * 9.81 * 0.75)).abs() < 1e-6);
        assert_eq!(s.robots, 2);
        assert!((s.score - a.j()).abs() < 1e-9);
    }

    #[test]
    fn a_fall_forfeits_the_rest_of_the_episode() {
        let step = ScoreStep {
            cmd: [1.0, 0.0],
            vel: [1.0, 0.0],
            torque_norm: 0.0,
            mean_abs_torque: 0.0,
            power: 0.0,
            gravity_xy: [0.0, 0.0],
            displacement: [0.0, 0.0],
            dt: 0.02,
        };
        let mut walked = ScoreAccumulator::default();
        for _ in 0..100 {
            walked.add(&step, 0.25, 80.0, 12);
        }
        let mut fell = ScoreAccumulator::default();
        for _ in 0..25 {
            fell.add(&step, 0.25, 80.0, 12);
        }
        fell.fell = true;
        let s = summarize(&[walked, fell], 25.0, 100, ScoreVariant::Eq4);
        // Perfect tracking: 1 for the walker, 25/100 for the robot that fell at step 25.
        assert!((s.track - (1.0 + 0.25) / 2.0).abs() < 1e-9, "{}", s.track);
        assert!((s.score - s.track).abs() < 1e-9);
        assert!((s.fall_rate - 0.5).abs() < 1e-12);
        assert!(s.mean_vel_error.abs() < 1e-9);
    }

    /// A robot commanded 0.5 m/s for 1,000 steps of 0.02 s: one tracks it, one ignores it
    /// and runs at 2 m/s. Eq. 4's progress (speed squared) pays the runner more than the
    /// tracking term it loses; the bounded variant does not.
    #[test]
    fn eq4_pays_for_running_past_the_command_and_bounded_does_not() {
        let run = |speed: f32| {
            let mut a = ScoreAccumulator::default();
            for _ in 0..1000 {
                a.add(
                    &ScoreStep {
                        cmd: [0.5, 0.0],
                        vel: [speed, 0.0],
                        torque_norm: 0.0,
                        mean_abs_torque: 0.0,
                        power: 0.0,
                        gravity_xy: [0.0, 0.0],
                        displacement: [speed * 0.02, 0.0],
                        dt: 0.02,
                    },
                    0.25,
                    80.0,
                    12,
                );
            }
            a
        };
        let (tracker, runner) = (run(0.5), run(2.0));
        let eq4 = |r: &ScoreAccumulator| {
            summarize(std::slice::from_ref(r), 25.0, 1000, ScoreVariant::Eq4)
        };
        let bounded = |r: &ScoreAccumulator| {
            summarize(std::slice::from_ref(r), 25.0, 1000, ScoreVariant::Bounded)
        };
        assert!(
            eq4(&runner).score > eq4(&tracker).score,
            "{} vs {}",
            eq4(&runner).score,
            eq4(&tracker).score
        );
        assert!(bounded(&tracker).score > bounded(&runner).score + 0.9);
        // The capped progress is what tracking earns: 1,000 steps of 0.01 m.
        assert!((bounded(&runner).progress_bounded - 0.1).abs() < 1e-6);
        assert!((eq4(&runner).overspeed - 1.5).abs() < 1e-6);
        assert!(eq4(&tracker).overspeed.abs() < 1e-9);
        assert!((eq4(&runner).mean_speed - 2.0).abs() < 1e-6);
    }
}
