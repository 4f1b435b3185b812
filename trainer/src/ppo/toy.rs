//! A cheap vectorised task that PPO must solve quickly: a 2-D point mass, velocity
//! controlled, must reach a random target and stay there. The tests use it to prove that
//! the trainer learns (a broken sign, GAE or normalisation fails them) in seconds.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{StepView, VecEnvLike};
use crate::Result;

/// Policy steps per episode.
pub const HORIZON: u32 = 40;
/// Distance moved per step at full action.
const SPEED: f32 = 0.1;
/// Leaving this box ends the episode as a failure.
const BOUND: f32 = 3.0;

/// `n` point masses; observation `[target - position, position]`, action a 2-D velocity
/// clipped to [-1, 1], reward `-|target - position| - 0.01 |a|^2` per step.
#[derive(Debug)]
pub struct PointMass {
    n: usize,
    rng: ChaCha8Rng,
    pos: Vec<[f32; 2]>,
    target: Vec<[f32; 2]>,
    t: Vec<u32>,
    obs: Vec<f32>,
    rewards: Vec<f32>,
    dones: Vec<bool>,
    timeouts: Vec<bool>,
    terms: Vec<f32>,
}

impl PointMass {
    /// `n` robots, seeded from `seed` until the first reseed.
    pub fn new(n: usize, seed: u64) -> Self {
        let mut env = Self {
            n,
            rng: ChaCha8Rng::seed_from_u64(seed),
            pos: vec![[0.0; 2]; n],
            target: vec![[0.0; 2]; n],
            t: vec![0; n],
            obs: vec![0.0; 4 * n],
            rewards: vec![0.0; n],
            dones: vec![false; n],
            timeouts: vec![false; n],
            terms: vec![0.0; 2 * n],
        };
        for i in 0..n {
            env.reset_one(i);
        }
        env
    }

    fn reset_one(&mut self, i: usize) {
        let mut r = || self.rng.random_range(-1.0f32..1.0);
        self.pos[i] = [r(), r()];
        self.target[i] = [r(), r()];
        self.t[i] = 0;
        self.write_obs(i);
    }

    fn write_obs(&mut self, i: usize) {
        let (p, g) = (self.pos[i], self.target[i]);
        self.obs[4 * i..4 * i + 4].copy_from_slice(&[g[0] - p[0], g[1] - p[1], p[0], p[1]]);
    }

    /// Mean return of the deterministic `policy` over one episode of every robot, from
    /// `seed`: the score the learning test checks.
    pub fn evaluate(&mut self, seed: u64, policy: &mut dyn FnMut(&[f32], &mut [f32])) -> f64 {
        let mut obs = self.reseed(seed).expect("toy reseed cannot fail");
        let mut actions = vec![0.0; 2 * self.n];
        let mut total = 0.0f64;
        for _ in 0..HORIZON {
            policy(&obs, &mut actions);
            let step = self.step(&actions).expect("toy step cannot fail");
            total += step.rewards.iter().map(|&r| r as f64).sum::<f64>();
            obs = step.obs.to_vec();
        }
        total / self.n as f64
    }
}

impl VecEnvLike for PointMass {
    fn num_envs(&self) -> usize {
        self.n
    }
    fn obs_dim(&self) -> usize {
        4
    }
    fn act_dim(&self) -> usize {
        2
    }
    fn reseed(&mut self, seed: u64) -> Result<Vec<f32>> {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
        for i in 0..self.n {
            self.reset_one(i);
        }
        Ok(self.obs.clone())
    }
    fn step(&mut self, actions: &[f32]) -> Result<StepView<'_>> {
        for i in 0..self.n {
            let a = [
                actions[2 * i].clamp(-1.0, 1.0),
                actions[2 * i + 1].clamp(-1.0, 1.0),
            ];
            let p = &mut self.pos[i];
            p[0] += SPEED * a[0];
            p[1] += SPEED * a[1];
            let g = self.target[i];
            let dist = ((g[0] - p[0]).powi(2) + (g[1] - p[1]).powi(2)).sqrt();
            let effort = 0.01 * (a[0] * a[0] + a[1] * a[1]);
            let out = p[0].abs() > BOUND || p[1].abs() > BOUND;
            self.t[i] += 1;
            self.rewards[i] = -dist - effort;
            self.terms[2 * i] = -dist;
            self.terms[2 * i + 1] = -effort;
            self.timeouts[i] = !out && self.t[i] >= HORIZON;
            self.dones[i] = out || self.timeouts[i];
            if self.dones[i] {
                self.reset_one(i);
            } else {
                self.write_obs(i);
            }
        }
        Ok(StepView {
            obs: &self.obs,
            rewards: &self.rewards,
            dones: &self.dones,
            timeouts: &self.timeouts,
            terms: &self.terms,
        })
    }
    fn term_names(&self) -> Vec<String> {
        vec!["distance".into(), "effort".into()]
    }
}
