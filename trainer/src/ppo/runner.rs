//! The training loop of one cell: rollouts (no gradients, one batched forward pass per
//! policy step for all robots), then the PPO update; timed per phase.

use std::collections::VecDeque;
use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use tch::{Device, Tensor};

use super::storage::Rollout;
use super::{ObsNormalizer, Ppo, UpdateStats, VecEnvLike};
use crate::{Error, Result};

/// Completed episodes kept for the mean return and length (rsl_rl keeps 100).
const EPISODE_WINDOW: usize = 100;

/// What one epoch did.
#[derive(Clone, Debug, Default)]
pub struct EpochStats {
    /// Epochs completed after this one (1-based).
    pub epoch: u32,
    /// Mean undiscounted return of the last completed episodes (None before any ended).
    pub mean_return: Option<f64>,
    /// Mean length in policy steps of the last completed episodes.
    pub mean_episode_length: Option<f64>,
    /// Mean reward per robot per step in this epoch.
    pub mean_step_reward: f64,
    /// Mean per robot per step of every weighted reward term, by name.
    pub terms: Vec<(String, f64)>,
    /// The update's losses, KL and learning rate.
    pub update: UpdateStats,
    /// Seconds spent stepping the simulation.
    pub sim_seconds: f64,
    /// Seconds spent in the policy forward passes and sampling of the rollout.
    pub inference_seconds: f64,
    /// Seconds spent in the batched critic pass, GAE and the PPO update.
    pub update_seconds: f64,
    /// Robot-steps simulated.
    pub samples: u64,
    /// Mean and largest terrain level of the robots after the epoch (legged_gym's
    /// `Episode/terrain_level`).
    pub levels: Option<(f64, f64)>,
    /// Mean terrain level per terrain variant (e.g. stairs' `top` and `pit` robots), where
    /// the environment deals robots variants that differ in kind.
    pub variant_levels: Vec<(&'static str, f64)>,
}

impl EpochStats {
    /// Robot-steps per second of wall time over the whole epoch.
    pub fn samples_per_second(&self) -> f64 {
        let total = self.sim_seconds + self.inference_seconds + self.update_seconds;
        self.samples as f64 / total.max(1e-9)
    }
}

/// Seed of the reset at the start of a run (epoch 0) or of its resumption at `epoch`
/// (splitmix64 of seed and epoch).
pub fn boundary_seed(seed: u64, epoch: u32) -> u64 {
    let mut z = seed ^ (u64::from(epoch)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) & (i64::MAX as u64)
}

/// Mean level of the robots of each variant, where robot `i` has variant `i % names.len()`
/// (empty without names).
pub fn variant_means(levels: &[u8], names: &[&'static str]) -> Vec<(&'static str, f64)> {
    let k = names.len();
    let mut out: Vec<(&'static str, f64, usize)> = Vec::new();
    for (i, &l) in levels.iter().enumerate().filter(|_| k > 0) {
        let name = names[i % k];
        match out.iter_mut().find(|o| o.0 == name) {
            Some(o) => {
                o.1 += f64::from(l);
                o.2 += 1;
            }
            None => out.push((name, f64::from(l), 1)),
        }
    }
    out.sort_by_key(|o| names.iter().position(|n| *n == o.0));
    out.into_iter().map(|(n, s, c)| (n, s / c as f64)).collect()
}

/// Drives one environment and one PPO learner epoch by epoch.
pub struct Runner<E: VecEnvLike> {
    /// The vectorised environment.
    pub env: E,
    /// The learner.
    pub ppo: Ppo,
    /// The run's seed.
    pub seed: u64,
    /// Epochs completed.
    pub epoch: u32,
    /// Names the cell in errors, e.g. `(w1=2, w2=-6)`.
    pub label: String,
    needs_reseed: bool,
    rng: ChaCha8Rng,
    noise: Vec<f32>,
    obs_norm: Tensor,
    ep_return: Vec<f64>,
    ep_len: Vec<u32>,
    finished: VecDeque<(f64, u32)>,
}

impl<E: VecEnvLike> Runner<E> {
    /// Wraps an environment and a learner whose `epoch` epochs are already done. The
    /// environment is reset once, at the first epoch run (from `boundary_seed(seed,
    /// epoch)`), and never again by the runner: robots reset when their episodes end, so
    /// writing checkpoints does not change training.
    pub fn new(env: E, ppo: Ppo, seed: u64, epoch: u32, label: String) -> Self {
        let n = env.num_envs();
        Self {
            env,
            ppo,
            seed,
            epoch,
            label,
            needs_reseed: true,
            rng: ChaCha8Rng::seed_from_u64(seed),
            noise: Vec::new(),
            obs_norm: Tensor::new(),
            ep_return: vec![0.0; n],
            ep_len: vec![0; n],
            finished: VecDeque::with_capacity(EPISODE_WINDOW),
        }
    }

    fn bad(&self, quantity: &str) -> Error {
        Error::NonFinite {
            cell: self.label.clone(),
            epoch: self.epoch,
            quantity: quantity.into(),
        }
    }

    /// Folds raw observations into the statistics and returns them normalised `[N, D]`.
    fn observe(&mut self, raw: &[f32]) -> Result<Tensor> {
        if let Some(i) = raw.iter().position(|x| !x.is_finite()) {
            let d = self.env.obs_dim();
            return Err(self.bad(&format!("observations (robot {}, index {})", i / d, i % d)));
        }
        self.ppo.normalizer.update(raw);
        let (mean, denom) = self.ppo.normalizer.tensors(self.ppo.device);
        let x = Tensor::from_slice(raw).view([-1, self.env.obs_dim() as i64]);
        Ok(ObsNormalizer::apply(
            &x.to_device(self.ppo.device),
            &mean,
            &denom,
        ))
    }

    /// Runs one epoch: a rollout of `steps_per_env` steps, then the update.
    pub fn run_epoch(&mut self) -> Result<EpochStats> {
        let mut stats = EpochStats::default();
        let t0 = Instant::now();
        if self.needs_reseed {
            // All randomness (action noise, mini-batch order) comes from this generator,
            // not libtorch's process-wide one, which other cells' threads also draw from.
            let s = boundary_seed(self.seed, self.epoch);
            self.rng = ChaCha8Rng::seed_from_u64(s);
            let raw = self.env.reseed(s)?;
            self.obs_norm = self.observe(&raw)?;
            self.ep_return.iter_mut().for_each(|r| *r = 0.0);
            self.ep_len.iter_mut().for_each(|l| *l = 0);
            self.needs_reseed = false;
        }
        stats.sim_seconds += t0.elapsed().as_secs_f64();
        self.ppo.apply_noise_schedule(self.epoch);

        let p = &self.ppo.params;
        let (steps, gamma, lam) = (p.steps_per_env, p.gamma, p.lam);
        let n = self.env.num_envs();
        let device = self.ppo.device;
        let term_names = self.env.term_names();
        let mut term_sums = vec![0.0f64; term_names.len()];
        let mut reward_sum = 0.0f64;
        let mut rollout = Rollout::default();
        let mut actions_host = vec![0.0f32; n * self.env.act_dim()];
        for _ in 0..steps {
            let ti = Instant::now();
            let obs = self.obs_norm.shallow_clone();
            let rng = &mut self.rng;
            self.noise.clear();
            self.noise
                .extend((0..actions_host.len()).map(|_| -> f32 { StandardNormal.sample(rng) }));
            let noise = Tensor::from_slice(&self.noise)
                .view([n as i64, -1])
                .to_device(device);
            let (actions, means) = tch::no_grad(|| {
                let model = &self.ppo.model;
                let means = model.action_mean(&obs);
                let actions = &means + noise * model.log_std.exp();
                (actions, means)
            });
            actions
                .to_device(Device::Cpu)
                .f_copy_data(&mut actions_host, n * self.env.act_dim())?;
            stats.inference_seconds += ti.elapsed().as_secs_f64();

            let ts = Instant::now();
            let step = self.env.step(&actions_host)?;
            let (rewards, mut dones, mut timeouts) = (
                step.rewards.to_vec(),
                Vec::with_capacity(n),
                Vec::with_capacity(n),
            );
            dones.extend(step.dones.iter().map(|&d| if d { 1.0f32 } else { 0.0 }));
            timeouts.extend(step.timeouts.iter().map(|&d| if d { 1.0f32 } else { 0.0 }));
            if !term_sums.is_empty() {
                for row in step.terms.chunks_exact(term_sums.len()) {
                    term_sums
                        .iter_mut()
                        .zip(row)
                        .for_each(|(s, &x)| *s += x as f64);
                }
            }
            let next_raw = step.obs.to_vec();
            stats.sim_seconds += ts.elapsed().as_secs_f64();

            let ti = Instant::now();
            if rewards.iter().any(|r| !r.is_finite()) {
                return Err(self.bad("rewards"));
            }
            for i in 0..n {
                self.ep_return[i] += rewards[i] as f64;
                self.ep_len[i] += 1;
                reward_sum += rewards[i] as f64;
                if dones[i] > 0.5 {
                    if self.finished.len() == EPISODE_WINDOW {
                        self.finished.pop_front();
                    }
                    self.finished.push_back((self.ep_return[i], self.ep_len[i]));
                    self.ep_return[i] = 0.0;
                    self.ep_len[i] = 0;
                }
            }
            let tensor = |v: &[f32]| Tensor::from_slice(v).to_device(device);
            rollout.push(
                obs,
                actions,
                means,
                tensor(&rewards),
                tensor(&dones),
                tensor(&timeouts),
            );
            self.obs_norm = self.observe(&next_raw)?;
            stats.inference_seconds += ti.elapsed().as_secs_f64();
        }

        let tu = Instant::now();
        let batch = tch::no_grad(|| rollout.finish(&self.ppo.model, &self.obs_norm, gamma, lam));
        let label = self.label.clone();
        let epoch = self.epoch;
        stats.update = self
            .ppo
            .update(&batch, &mut self.rng)
            .map_err(|e| match e {
                Error::NonFinite { quantity, .. } => Error::NonFinite {
                    cell: label,
                    epoch,
                    quantity,
                },
                e => e,
            })?;
        stats.update_seconds = tu.elapsed().as_secs_f64();

        self.epoch += 1;
        let samples = (n * steps) as f64;
        stats.epoch = self.epoch;
        stats.samples = (n * steps) as u64;
        stats.mean_step_reward = reward_sum / samples;
        stats.terms = term_names
            .into_iter()
            .zip(term_sums)
            .map(|(k, s)| (k, s / samples))
            .collect();
        let levels = self.env.levels();
        if !levels.is_empty() {
            let mean = levels.iter().map(|&l| f64::from(l)).sum::<f64>() / levels.len() as f64;
            let max = levels.iter().copied().max().map_or(0.0, f64::from);
            stats.levels = Some((mean, max));
            stats.variant_levels = variant_means(&levels, self.env.variant_names());
        }
        if !self.finished.is_empty() {
            let k = self.finished.len() as f64;
            stats.mean_return = Some(self.finished.iter().map(|e| e.0).sum::<f64>() / k);
            stats.mean_episode_length =
                Some(self.finished.iter().map(|e| e.1 as f64).sum::<f64>() / k);
        }
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::variant_means;

    #[test]
    fn variant_means_split_robots_by_index() {
        let levels = [0, 4, 2, 6, 1];
        let m = variant_means(&levels, &["top", "pit"]);
        assert_eq!(m, vec![("top", 1.0), ("pit", 5.0)]);
        assert!(variant_means(&levels, &[]).is_empty());
        assert_eq!(variant_means(&[], &["top", "pit"]), vec![]);
        // Repeated names (the mixed terrain's tiles of one kind) are counted together.
        let m = variant_means(&levels, &["rough", "stairs_up", "rough"]);
        assert_eq!(m, vec![("rough", 8.0 / 3.0), ("stairs_up", 2.5)]);
    }
}
