//! PPO must solve the point-mass task within a small seeded budget: if the sign of the
//! surrogate, GAE, the value loss or the normalisation is broken, it does not.

use std::time::Instant;

use gaitsweep_trainer::ppo::toy::PointMass;
use gaitsweep_trainer::ppo::{Ppo, PpoParams, Runner};
use tch::Device;

/// Small networks and rollouts: the task is easy, the budget is seconds.
fn toy_params() -> PpoParams {
    PpoParams {
        actor_hidden: vec![64, 64],
        critic_hidden: vec![64, 64],
        init_noise_std: 0.5,
        steps_per_env: 20,
        num_mini_batches: 4,
        num_learning_epochs: 5,
        ..PpoParams::default()
    }
}

fn eval_return(ppo: &Ppo) -> f64 {
    let mut env = PointMass::new(256, 0);
    env.evaluate(12345, &mut |obs, act| {
        ppo.act_deterministic(obs, act).unwrap()
    })
}

#[test]
fn ppo_learns_point_mass() {
    tch::set_num_threads(1);
    let seed = 7;
    let ppo = Ppo::new(4, 2, toy_params(), Device::Cpu, seed);
    let before = eval_return(&ppo);
    let mut runner = Runner::new(PointMass::new(128, seed), ppo, seed, 0, "toy".into());
    let t = Instant::now();
    let mut last = None;
    for _ in 0..60 {
        last = Some(runner.run_epoch().unwrap());
    }
    let after = eval_return(&runner.ppo);
    let last = last.unwrap();
    eprintln!(
        "toy: return {before:.2} -> {after:.2} in {:.1}s, kl {:.4}, lr {:.2e}, std {:.3}",
        t.elapsed().as_secs_f64(),
        last.update.kl,
        last.update.learning_rate,
        last.update.action_std
    );
    // A policy that stands still scores about -31 (mean distance of two uniform points
    // in [-1,1]^2 is ~1.04, over 40 steps with 0.1 m/step); driving straight to the target
    // and stopping scores about -5.5.
    assert!(
        after > -8.0,
        "point mass not learnt: eval return {after:.2} (before {before:.2})"
    );
}

#[test]
fn an_annealed_std_follows_its_schedule_and_the_mean_still_learns() {
    tch::set_num_threads(1);
    let seed = 7;
    let params = PpoParams {
        final_noise_std: 0.2,
        noise_decay_epochs: 40,
        ..toy_params()
    };
    let ppo = Ppo::new(4, 2, params, Device::Cpu, seed);
    // Geometric from 0.5 to 0.2: the midpoint is their geometric mean.
    assert_eq!(ppo.scheduled_noise_std(0), Some(0.5));
    assert!((ppo.scheduled_noise_std(20).unwrap() - (0.5f64 * 0.2).sqrt()).abs() < 1e-12);
    assert!((ppo.scheduled_noise_std(40).unwrap() - 0.2).abs() < 1e-12);
    assert!((ppo.scheduled_noise_std(400).unwrap() - 0.2).abs() < 1e-12);
    let mut runner = Runner::new(PointMass::new(128, seed), ppo, seed, 0, "toy".into());
    for epoch in 0..60u32 {
        let stats = runner.run_epoch().unwrap();
        // The update does not move an annealed std: after epoch e it is still the value
        // set before its rollout.
        let want = (0.5f64.ln() * (1.0 - (f64::from(epoch) / 40.0).min(1.0))
            + 0.2f64.ln() * (f64::from(epoch) / 40.0).min(1.0))
        .exp();
        assert!(
            (stats.update.action_std - want).abs() < 1e-5,
            "epoch {epoch}: {}",
            stats.update.action_std
        );
    }
    let after = eval_return(&runner.ppo);
    assert!(
        after > -8.0,
        "point mass not learnt with an annealed std: {after:.2}"
    );
    // The learned std (rsl_rl) is the default.
    assert_eq!(
        Ppo::new(4, 2, toy_params(), Device::Cpu, 1).scheduled_noise_std(3),
        None
    );
}

#[test]
fn a_delayed_anneal_starts_from_the_learned_std_of_each_dimension() {
    tch::set_num_threads(1);
    let seed = 7;
    let params = PpoParams {
        final_noise_std: 0.2,
        noise_decay_start: 10,
        noise_decay_epochs: 20,
        entropy_coef: 0.01,
        ..toy_params()
    };
    let ppo = Ppo::new(4, 2, params, Device::Cpu, seed);
    assert_eq!(
        ppo.scheduled_noise_std(0),
        None,
        "no fixed schedule from epoch 0"
    );
    let mut runner = Runner::new(PointMass::new(128, seed), ppo, seed, 0, "toy".into());
    let log_std =
        |ppo: &Ppo| Vec::<f64>::try_from(ppo.model.log_std.to_kind(tch::Kind::Double)).unwrap();
    for _ in 0..10 {
        runner.run_epoch().unwrap();
    }
    let learned = log_std(&runner.ppo);
    assert!(
        learned.iter().all(|l| (l - 0.5f64.ln()).abs() > 1e-4) && learned[0] != learned[1],
        "the std is learned, per dimension, before the anneal starts: {learned:?}"
    );
    for epoch in 10..40 {
        runner.run_epoch().unwrap();
        let frac = (f64::from(epoch - 10) / 20.0).min(1.0);
        let got = log_std(&runner.ppo);
        for (g, l) in got.iter().zip(&learned) {
            let want = l * (1.0 - frac) + 0.2f64.ln() * frac;
            assert!(
                (g - want).abs() < 1e-5,
                "epoch {epoch}: {got:?}, learned {learned:?}"
            );
        }
    }
}

/// Wraps the toy and poisons one observation at a given step.
struct Poisoned {
    inner: PointMass,
    steps: u32,
    at: u32,
    obs: Vec<f32>,
}

impl gaitsweep_trainer::ppo::VecEnvLike for Poisoned {
    fn num_envs(&self) -> usize {
        self.inner.num_envs()
    }
    fn obs_dim(&self) -> usize {
        4
    }
    fn act_dim(&self) -> usize {
        2
    }
    fn reseed(&mut self, seed: u64) -> gaitsweep_trainer::Result<Vec<f32>> {
        self.inner.reseed(seed)
    }
    fn step(
        &mut self,
        actions: &[f32],
    ) -> gaitsweep_trainer::Result<gaitsweep_trainer::ppo::StepView<'_>> {
        self.steps += 1;
        let mut v = self.inner.step(actions)?;
        if self.steps == self.at {
            self.obs = v.obs.to_vec();
            self.obs[5] = f32::NAN;
            v.obs = &self.obs;
        }
        Ok(v)
    }
}

#[test]
fn nan_observation_stops_the_cell_with_its_name() {
    let env = Poisoned {
        inner: PointMass::new(8, 1),
        steps: 0,
        at: 45,
        obs: vec![],
    };
    let ppo = Ppo::new(4, 2, toy_params(), Device::Cpu, 1);
    let mut runner = Runner::new(env, ppo, 1, 0, "(w1=2, w2=-6)".into());
    runner.run_epoch().unwrap();
    runner.run_epoch().unwrap();
    let e = runner.run_epoch().unwrap_err().to_string();
    assert_eq!(
        e,
        "cell (w1=2, w2=-6): non-finite observations (robot 1, index 1) in epoch 2"
    );
}
