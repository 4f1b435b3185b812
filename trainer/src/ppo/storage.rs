//! One epoch's rollout and its GAE(lambda) returns and advantages.

use tch::{Kind, Tensor};

use super::ActorCritic;

/// Per-step tensors of a rollout, each `[N, ...]`, stacked to `[T, N, ...]` at the end.
///
/// Only what the policy step itself needs (the actor's means) is computed step by step;
/// the critic's values and the log-probabilities are computed for the whole rollout in
/// one batched pass in [`Rollout::finish`], with the same weights the robots acted with.
#[derive(Debug, Default)]
pub struct Rollout {
    obs: Vec<Tensor>,
    actions: Vec<Tensor>,
    means: Vec<Tensor>,
    rewards: Vec<Tensor>,
    dones: Vec<Tensor>,
    timeouts: Vec<Tensor>,
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
    /// Records one policy step: 1.0 in `dones` where an episode ended, in `timeouts` where
    /// it ended by time (bootstrapped with the critic's value, not a failure).
    pub fn push(
        &mut self,
        obs: Tensor,
        actions: Tensor,
        means: Tensor,
        rewards: Tensor,
        dones: Tensor,
        timeouts: Tensor,
    ) {
        self.obs.push(obs);
        self.actions.push(actions);
        self.means.push(means);
        self.rewards.push(rewards);
        self.dones.push(dones);
        self.timeouts.push(timeouts);
    }

    /// Evaluates the critic and the log-probabilities over the whole rollout, computes GAE
    /// with `last_obs` (the observations after the last step) and flattens everything.
    /// The rollout is emptied. Call without gradients.
    pub fn finish(
        &mut self,
        model: &ActorCritic,
        last_obs: &Tensor,
        gamma: f64,
        lam: f64,
    ) -> Batch {
        let t = self.obs.len();
        let cat = |v: &mut Vec<Tensor>| {
            let out = Tensor::stack(v, 0);
            v.clear();
            out
        };
        let obs = cat(&mut self.obs);
        let n = obs.size()[1];
        let obs = obs.flatten(0, 1);
        let actions = cat(&mut self.actions).flatten(0, 1);
        let means = cat(&mut self.means).flatten(0, 1);
        let log_probs = model.log_prob(&means, &actions);
        let values = model.value(&obs);
        let last_values = model.value(last_obs);
        let step_values = values.view([t as i64, n]);
        // Time-limit ends are not failures: bootstrap them with the critic's value.
        let rewards = cat(&mut self.rewards) + &step_values * gamma * cat(&mut self.timeouts);
        let dones = cat(&mut self.dones);

        let mut advantages: Vec<Tensor> = (0..t).map(|_| Tensor::new()).collect();
        let mut next_adv = last_values.zeros_like();
        for step in (0..t).rev() {
            let next_values = if step + 1 == t {
                last_values.shallow_clone()
            } else {
                step_values.get(step as i64 + 1)
            };
            let not_done = 1.0 - dones.get(step as i64);
            let delta = rewards.get(step as i64) + &not_done * gamma * next_values
                - step_values.get(step as i64);
            next_adv = delta + not_done * (gamma * lam) * next_adv;
            advantages[step] = next_adv.shallow_clone();
        }
        let adv = Tensor::stack(&advantages, 0).flatten(0, 1);
        let returns = &adv + &values;
        let advantages = (&adv - adv.mean(Kind::Float)) / (adv.std(true) + 1e-8);
        Batch {
            obs,
            actions,
            log_probs,
            means,
            values,
            returns,
            advantages,
        }
    }
}
