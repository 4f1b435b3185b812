//! The PPO update (rsl_rl's `PPO.update`): mini-batches over several learning epochs,
//! clipped surrogate, clipped value loss, entropy bonus, KL-adaptive learning rate and
//! gradient-norm clipping.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use tch::{Device, Kind, Tensor};

use super::storage::Batch;
use super::{non_finite, ActorCritic, Adam, ObsNormalizer, PpoParams};
use crate::Result;

/// Bounds of the adaptive learning rate (rsl_rl's).
const LR_MIN: f64 = 1e-5;
const LR_MAX: f64 = 1e-2;

/// Averages over the mini-batch updates of one epoch.
#[derive(Clone, Debug, Default)]
pub struct UpdateStats {
    /// Value-function loss.
    pub value_loss: f64,
    /// Clipped surrogate loss.
    pub surrogate_loss: f64,
    /// Policy entropy.
    pub entropy: f64,
    /// KL divergence between the rollout policy and the updated one.
    pub kl: f64,
    /// Gradient norm before clipping.
    pub grad_norm: f64,
    /// Learning rate after the update.
    pub learning_rate: f64,
    /// Mean action standard deviation after the update.
    pub action_std: f64,
    /// The symmetry mirror loss (before its coefficient), when the loss or the mirrored
    /// samples are on.
    pub mirror_loss: Option<f64>,
}

/// The left-right mirror as index and sign tensors, for the symmetry loss and the
/// mirrored samples.
#[derive(Debug)]
struct MirrorTensors {
    obs_index: Tensor,
    obs_sign: Tensor,
    act_index: Tensor,
    act_sign: Tensor,
}

/// Policy, value function, optimiser and observation normaliser of one cell.
#[derive(Debug)]
pub struct Ppo {
    /// Hyperparameters.
    pub params: PpoParams,
    /// The networks.
    pub model: ActorCritic,
    /// Adam over `model.named_parameters()`.
    pub optim: Adam,
    /// Running observation statistics.
    pub normalizer: ObsNormalizer,
    /// Where the networks live.
    pub device: Device,
    /// Whether the action std follows the noise schedule in the current epoch (set by
    /// [`Ppo::apply_noise_schedule`]); the update then leaves it alone.
    std_scheduled: bool,
    /// The observation and action mirror of the symmetry loss and the mirrored samples
    /// (set with [`Ppo::set_mirror`]; on when `params.mirror_loss_coef > 0` or
    /// `params.mirror_augmentation`).
    mirror: Option<MirrorTensors>,
}

impl Ppo {
    /// Fresh networks initialised from `seed`.
    pub fn new(
        obs_dim: usize,
        act_dim: usize,
        params: PpoParams,
        device: Device,
        seed: u64,
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let model = ActorCritic::new(
            obs_dim as i64,
            act_dim as i64,
            &params.actor_hidden,
            &params.critic_hidden,
            params.init_noise_std,
            device,
            &mut rng,
        );
        let optim = Adam::new(
            model
                .named_parameters()
                .into_iter()
                .map(|(_, t)| t)
                .collect(),
            params.learning_rate,
        );
        Self {
            params,
            model,
            optim,
            normalizer: ObsNormalizer::new(obs_dim),
            device,
            std_scheduled: false,
            mirror: None,
        }
    }

    /// Sets the left-right mirror of observations and actions (`out[k] = sign * in[src]`
    /// for each `(src, sign)`) that the symmetry loss compares the policy against and the
    /// mirrored samples are made with.
    pub fn set_mirror(&mut self, obs: &[(usize, f32)], act: &[(usize, f32)]) {
        let split = |map: &[(usize, f32)]| {
            let index: Vec<i64> = map.iter().map(|&(i, _)| i as i64).collect();
            let sign: Vec<f32> = map.iter().map(|&(_, s)| s).collect();
            (
                Tensor::from_slice(&index).to_device(self.device),
                Tensor::from_slice(&sign).to_device(self.device),
            )
        };
        let ((obs_index, obs_sign), (act_index, act_sign)) = (split(obs), split(act));
        self.mirror = Some(MirrorTensors {
            obs_index,
            obs_sign,
            act_index,
            act_sign,
        });
    }

    /// The left-right mirror of normalised observations `obs`: the mirror acts on raw
    /// observations, so they are un-normalised and normalised again with `norm`. The rollout
    /// normalised each step with the statistics of that moment and `norm` is the end's, so
    /// the raw values are recovered to within one rollout's drift of the statistics (small
    /// after the first epochs); storing raw observations would make it exact.
    fn mirror_obs(&self, obs: &Tensor, norm: &(Tensor, Tensor)) -> Tensor {
        let m = self.mirror.as_ref().expect("called with a mirror set");
        let (nmean, denom) = norm;
        let raw = obs * denom + nmean;
        let mirrored = raw.index_select(1, &m.obs_index) * &m.obs_sign;
        ObsNormalizer::apply(&mirrored, nmean, denom)
    }

    /// The left-right mirror of actions (or action means) `act`.
    fn mirror_act(&self, act: &Tensor) -> Tensor {
        let m = self.mirror.as_ref().expect("called with a mirror set");
        act.index_select(1, &m.act_index) * &m.act_sign
    }

    /// rsl_rl's symmetry loss on normalised observations `obs` whose action means are
    /// `mean`: the mean squared difference between the action mean of each mirrored
    /// observation and the mirror of its action mean (held fixed).
    fn mirror_loss(&self, obs: &Tensor, mean: &Tensor, norm: &(Tensor, Tensor)) -> Tensor {
        let x = self.mirror_obs(obs, norm);
        let target = self.mirror_act(&mean.detach());
        (self.model.action_mean(&x) - target)
            .square()
            .mean(Kind::Float)
    }

    /// Deterministic actions (the means) for raw observations `[N * obs_dim]`, with the
    /// current normalisation and no statistics update: the evaluation policy.
    pub fn act_deterministic(&self, obs: &[f32], actions: &mut [f32]) -> Result<()> {
        let dim = self.normalizer.dim() as i64;
        let (mean, denom) = self.normalizer.tensors(self.device);
        let out = tch::no_grad(|| -> Result<Tensor> {
            let x = Tensor::from_slice(obs)
                .view([-1, dim])
                .to_device(self.device);
            let x = ObsNormalizer::apply(&x, &mean, &denom);
            Ok(self
                .model
                .action_mean(&x)
                .to_device(Device::Cpu)
                .flatten(0, -1))
        })?;
        out.f_copy_data(actions, actions.len())?;
        Ok(())
    }

    /// Actions sampled from the Gaussian policy with its standard deviation times `scale`
    /// (1: as the robots act in training), current normalisation, no statistics update.
    pub fn act_sampled(
        &self,
        obs: &[f32],
        actions: &mut [f32],
        scale: f32,
        rng: &mut ChaCha8Rng,
    ) -> Result<()> {
        self.act_deterministic(obs, actions)?;
        let std: Vec<f32> = Vec::<f32>::try_from(self.model.log_std.exp().to_device(Device::Cpu))?;
        for (k, a) in actions.iter_mut().enumerate() {
            let z: f32 = rand_distr::Distribution::sample(&rand_distr::StandardNormal, rng);
            *a += scale * std[k % std.len()] * z;
        }
        Ok(())
    }

    /// The annealed action std at `epoch` of a schedule that starts at epoch 0 from
    /// `init_noise_std`, or `None` when the std is learned or its annealing starts later
    /// (from the values it learned, see [`Ppo::apply_noise_schedule`]).
    pub fn scheduled_noise_std(&self, epoch: u32) -> Option<f64> {
        let p = &self.params;
        if p.final_noise_std <= 0.0 || p.noise_decay_start > 0 {
            return None;
        }
        let frac = if p.noise_decay_epochs == 0 {
            1.0
        } else {
            (f64::from(epoch) / p.noise_decay_epochs as f64).min(1.0)
        };
        Some((p.init_noise_std.ln() * (1.0 - frac) + p.final_noise_std.ln() * frac).exp())
    }

    /// Sets the action std for `epoch`, called once at the start of each epoch. Learned
    /// (no-op) without `final_noise_std` or before `noise_decay_start`. With a start of 0
    /// it is [`Ppo::scheduled_noise_std`]. With a later start each dimension keeps the
    /// value it learned at the start epoch and then moves, epoch by epoch, along the
    /// straight line in log-std to `ln(final_noise_std)` at `start + noise_decay_epochs`:
    /// one step of `1/(epochs left)` of the remaining distance, so a resumed run needs no
    /// other state than the std in its checkpoint.
    pub fn apply_noise_schedule(&mut self, epoch: u32) {
        let fixed = self.scheduled_noise_std(epoch);
        let p = &self.params;
        let e = epoch as usize;
        self.std_scheduled = p.final_noise_std > 0.0 && e >= p.noise_decay_start;
        if !self.std_scheduled {
            return;
        }
        let (start, end) = (
            p.noise_decay_start,
            p.noise_decay_start + p.noise_decay_epochs,
        );
        let target = p.final_noise_std.ln();
        let log_std = &mut self.model.log_std;
        tch::no_grad(|| {
            if let Some(std) = fixed {
                let _ = log_std.fill_(std.ln());
            } else if e >= end {
                let _ = log_std.fill_(target);
            } else if e > start {
                let step = (log_std.detach() * -1.0 + target) / (end - e + 1) as f64;
                let _ = log_std.g_add_(&step);
            }
        });
    }

    /// Runs the learning epochs over `batch` (mini-batches shuffled with `rng`) and
    /// returns averaged statistics.
    pub fn update(&mut self, batch: &Batch, rng: &mut ChaCha8Rng) -> Result<UpdateStats> {
        let p = self.params.clone();
        let n = batch.obs.size()[0];
        let mb = n / p.num_mini_batches as i64;
        let old_log_std = self.model.log_std.detach().copy();
        let old_var = (&old_log_std * 2.0).exp();
        // The normalisation the mirror needs, when the symmetry loss (a weight > 0) or the
        // mirrored samples are on.
        let use_loss = self.mirror.is_some() && p.mirror_loss_coef > 0.0;
        let augment = self.mirror.is_some() && p.mirror_augmentation;
        let mirror_norm = (use_loss || augment).then(|| self.normalizer.tensors(self.device));
        let mut mirror_sum = 0.0;
        let mut stats = UpdateStats::default();
        let mut updates = 0.0;
        for _ in 0..p.num_learning_epochs {
            let mut order: Vec<i64> = (0..n).collect();
            order.shuffle(rng);
            let perm = Tensor::from_slice(&order).to_device(self.device);
            for i in 0..p.num_mini_batches as i64 {
                let idx = perm.narrow(0, i * mb, mb);
                let pick = |t: &Tensor| t.index_select(0, &idx);
                let (obs, actions, old_logp, old_mean) = (
                    pick(&batch.obs),
                    pick(&batch.actions),
                    pick(&batch.log_probs),
                    pick(&batch.means),
                );
                let (old_values, returns, adv) = (
                    pick(&batch.values),
                    pick(&batch.returns),
                    pick(&batch.advantages),
                );
                // rsl_rl's symmetry data augmentation: each sample also enters the update
                // mirrored (observation and action), with the original's old log-probability,
                // value, return and advantage, as if the acting policy had been symmetric.
                let (obs, actions, old_logp, old_values, returns, adv) = match &mirror_norm {
                    Some(norm) if augment => {
                        let twice = |t: &Tensor| Tensor::cat(&[t, t], 0);
                        (
                            Tensor::cat(&[&obs, &self.mirror_obs(&obs, norm)], 0),
                            Tensor::cat(&[&actions, &self.mirror_act(&actions)], 0),
                            twice(&old_logp),
                            twice(&old_values),
                            twice(&returns),
                            twice(&adv),
                        )
                    }
                    _ => (obs, actions, old_logp, old_values, returns, adv),
                };

                let mean = self.model.action_mean(&obs);
                let values = self.model.value(&obs);
                let logp = self.model.log_prob(&mean, &actions);
                let entropy = self.model.entropy();

                // The KL and the symmetry loss read the collected samples only (the first
                // `mb` rows when the batch is augmented), as rsl_rl does.
                let own_mean = mean.narrow(0, 0, mb);
                let kl = tch::no_grad(|| {
                    let log_std = &self.model.log_std;
                    let var = (log_std * 2.0).exp();
                    let per_dim = (log_std - &old_log_std)
                        + (&old_var + (&old_mean - &own_mean).square()) / (var * 2.0)
                        - 0.5;
                    per_dim
                        .sum_dim_intlist(-1, false, Kind::Float)
                        .mean(Kind::Float)
                })
                .double_value(&[]);
                if !kl.is_finite() {
                    return Err(non_finite("kl"));
                }
                if p.adaptive_lr && p.desired_kl > 0.0 {
                    if kl > 2.0 * p.desired_kl {
                        self.optim.lr = (self.optim.lr / 1.5).max(LR_MIN);
                    } else if kl < p.desired_kl / 2.0 && kl > 0.0 {
                        self.optim.lr = (self.optim.lr * 1.5).min(LR_MAX);
                    }
                }

                let ratio = (&logp - &old_logp).exp();
                let surr = -&adv * &ratio;
                let surr_clipped = -&adv * ratio.clamp(1.0 - p.clip_param, 1.0 + p.clip_param);
                let surrogate = surr.max_other(&surr_clipped).mean(Kind::Float);

                let value_loss = if p.clip_value_loss {
                    let clipped =
                        &old_values + (&values - &old_values).clamp(-p.clip_param, p.clip_param);
                    let a = (&values - &returns).square();
                    let b = (clipped - &returns).square();
                    a.max_other(&b).mean(Kind::Float)
                } else {
                    (&values - &returns).square().mean(Kind::Float)
                };

                let mut loss =
                    &surrogate + &value_loss * p.value_loss_coef - &entropy * p.entropy_coef;
                if let Some(norm) = &mirror_norm {
                    // With mirrored samples the action means of the mirrored observations
                    // are already the batch's second half.
                    let mirror = if augment {
                        (mean.narrow(0, mb, mb) - self.mirror_act(&own_mean.detach()))
                            .square()
                            .mean(Kind::Float)
                    } else {
                        self.mirror_loss(&obs, &mean, norm)
                    };
                    mirror_sum += mirror.double_value(&[]);
                    if use_loss {
                        // A new graph node, not tch's in-place `+=` on a tensor autograd
                        // has recorded.
                        #[allow(clippy::assign_op_pattern)]
                        {
                            loss = loss + mirror * p.mirror_loss_coef;
                        }
                    }
                }
                let loss_v = loss.double_value(&[]);
                if !loss_v.is_finite() {
                    let which = [
                        ("surrogate loss", surrogate.double_value(&[])),
                        ("value loss", value_loss.double_value(&[])),
                        ("entropy", entropy.double_value(&[])),
                    ]
                    .into_iter()
                    .find(|(_, v)| !v.is_finite())
                    .map_or("loss", |(q, _)| q);
                    return Err(non_finite(which));
                }
                self.optim.zero_grad();
                loss.backward();
                let grad_norm = self.optim.clip_grad_norm(p.max_grad_norm);
                if !grad_norm.is_finite() {
                    return Err(non_finite("gradients"));
                }
                self.optim.step();
                if self.std_scheduled {
                    // An annealed std is not a parameter: undo the optimiser's step on it.
                    tch::no_grad(|| {
                        self.model.log_std.copy_(&old_log_std);
                    });
                }

                stats.value_loss += value_loss.double_value(&[]);
                stats.surrogate_loss += surrogate.double_value(&[]);
                stats.entropy += entropy.double_value(&[]);
                stats.kl += kl;
                stats.grad_norm += grad_norm;
                updates += 1.0;
            }
        }
        stats.value_loss /= updates;
        stats.surrogate_loss /= updates;
        stats.entropy /= updates;
        stats.kl /= updates;
        stats.grad_norm /= updates;
        stats.learning_rate = self.optim.lr;
        if mirror_norm.is_some() {
            stats.mirror_loss = Some(mirror_sum / updates);
        }
        stats.action_std = self.model.log_std.exp().mean(Kind::Float).double_value(&[]);
        Ok(stats)
    }
}
