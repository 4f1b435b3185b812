//! One epoch's rollout and its GAE(lambda) returns and advantages.

use tch::{Kind, Tensor};

/// Per-step tensors of a rollout, each `[N, ...]`, stacked to `[T, N, ...]` at the end.
#[derive(Debug, Default)]
pub struct Rollout {
    obs: Vec<Tensor>,
    actions: Vec<Tensor>,
    log_probs: Vec<Tensor>,
    means: Vec<Tensor>,
    values: Vec<Tensor>,
    rewards: Vec<Tensor>,
    dones: Vec<Tensor>,
}

/// A finished rollout flattened to `[T * N, ...]`, ready for mini-batches.
#[derive(Debug)]
pub struct Batch {
    /// Normalised observations.
    pub obs: Tensor,
    /// Sampled actions.
    pub actions: Tensor,
    /// Log-probabilities of the actions under the rollout policy.
    pub log_probs: Tensor,
    /// Action means of the rollout policy.
    pub means: Tensor,
    /// Critic values during the rollout.
    pub values: Tensor,
    /// GAE returns (value targets).
    pub returns: Tensor,
    /// Advantages, normalised over the whole batch.
    pub advantages: Tensor,
}

impl Rollout {
    /// Records one policy step. `rewards` must already include the timeout bootstrap.
    #[allow(clippy::too_many_arguments)]
    pub fn push(
        &mut self,
        obs: Tensor,
        actions: Tensor,
        log_probs: Tensor,
        means: Tensor,
        values: Tensor,
        rewards: Tensor,
        dones: Tensor,
    ) {
        self.obs.push(obs);
        self.actions.push(actions);
        self.log_probs.push(log_probs);
        self.means.push(means);
        self.values.push(values);
        self.rewards.push(rewards);
        self.dones.push(dones);
    }

    /// Computes GAE with the critic's values of the observations after the last step
    /// and flattens everything. The rollout is emptied.
    pub fn finish(&mut self, last_values: &Tensor, gamma: f64, lam: f64) -> Batch {
        let t = self.values.len();
        let mut advantages: Vec<Tensor> = (0..t).map(|_| Tensor::new()).collect();
        let mut next_adv = last_values.zeros_like();
        for step in (0..t).rev() {
            let next_values = if step + 1 == t {
                last_values
            } else {
                &self.values[step + 1]
            };
            let not_done = 1.0 - &self.dones[step];
            let delta = &self.rewards[step] + &not_done * gamma * next_values - &self.values[step];
            next_adv = delta + not_done * (gamma * lam) * next_adv;
            advantages[step] = next_adv.shallow_clone();
        }
        let adv = Tensor::stack(&advantages, 0).flatten(0, 1);
        let values = Tensor::stack(&self.values, 0).flatten(0, 1);
        let returns = &adv + &values;
        let advantages = (&adv - adv.mean(Kind::Float)) / (adv.std(true) + 1e-8);
        let cat = |v: &mut Vec<Tensor>| {
            let out = Tensor::stack(v, 0).flatten(0, 1);
            v.clear();
            out
        };
        let batch = Batch {
            obs: cat(&mut self.obs),
            actions: cat(&mut self.actions),
            log_probs: cat(&mut self.log_probs),
            means: cat(&mut self.means),
            values,
            returns,
            advantages,
        };
        self.values.clear();
        self.rewards.clear();
        self.dones.clear();
        batch
    }
}
