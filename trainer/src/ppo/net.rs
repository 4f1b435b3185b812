//! Actor and critic MLPs with ELU activations and a learned log-std.
//!
//! The tensors are held directly (not in a `VarStore`) so that their order and names are
//! fixed: the checkpoint, the optimiser state and the export all rely on that order.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use tch::{Device, Kind, Tensor};

/// A multilayer perceptron: ELU after every hidden layer, linear output.
#[derive(Debug)]
pub struct Mlp {
    /// `(weight [out, in], bias [out])` per layer, input to output.
    pub layers: Vec<(Tensor, Tensor)>,
}

impl Mlp {
    /// Creates the MLP with PyTorch's default `nn.Linear` initialisation (uniform in
    /// +-1/sqrt(fan_in)), as rsl_rl gets it, drawn from `rng` rather than libtorch's
    /// process-wide generator so that cells trained side by side stay reproducible.
    pub fn new(
        input: i64,
        hidden: &[i64],
        output: i64,
        device: Device,
        rng: &mut ChaCha8Rng,
    ) -> Self {
        let mut sizes = vec![input];
        sizes.extend_from_slice(hidden);
        sizes.push(output);
        let layers = sizes
            .windows(2)
            .map(|io| {
                let bound = 1.0 / (io[0] as f32).sqrt();
                let mut uniform = |n: i64| -> Vec<f32> {
                    (0..n).map(|_| rng.random_range(-bound..bound)).collect()
                };
                let w = Tensor::from_slice(&uniform(io[1] * io[0]))
                    .view([io[1], io[0]])
                    .to_device(device)
                    .set_requires_grad(true);
                let b = Tensor::from_slice(&uniform(io[1]))
                    .to_device(device)
                    .set_requires_grad(true);
                (w, b)
            })
            .collect();
        Self { layers }
    }

    /// Applies the MLP to `x` `[B, input]`.
    pub fn forward(&self, x: &Tensor) -> Tensor {
        let last = self.layers.len() - 1;
        let mut h = x.shallow_clone();
        for (i, (w, b)) in self.layers.iter().enumerate() {
            h = h.linear(w, Some(b));
            if i < last {
                h = h.elu();
            }
        }
        h
    }

    /// Layer sizes `[input, hidden..., output]`.
    pub fn sizes(&self) -> Vec<i64> {
        let mut s = vec![self.layers[0].0.size()[1]];
        s.extend(self.layers.iter().map(|(w, _)| w.size()[0]));
        s
    }

    fn named(&self, prefix: &str) -> Vec<(String, Tensor)> {
        let mut out = Vec::with_capacity(2 * self.layers.len());
        for (i, (w, b)) in self.layers.iter().enumerate() {
            out.push((format!("{prefix}.{i}.weight"), w.shallow_clone()));
            out.push((format!("{prefix}.{i}.bias"), b.shallow_clone()));
        }
        out
    }
}

/// The policy (Gaussian with state-independent learned log-std) and the value function.
#[derive(Debug)]
pub struct ActorCritic {
    /// Maps normalised observations to action means.
    pub actor: Mlp,
    /// Maps normalised observations to a value.
    pub critic: Mlp,
    /// Log standard deviation of the action noise, `[act_dim]`.
    pub log_std: Tensor,
}

/// 0.5 * ln(2 pi), a constant of the Gaussian log-density.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_7;

impl ActorCritic {
    /// Creates both networks and the log-std (`ln(init_noise_std)`).
    pub fn new(
        obs_dim: i64,
        act_dim: i64,
        actor_hidden: &[i64],
        critic_hidden: &[i64],
        init_noise_std: f64,
        device: Device,
        rng: &mut ChaCha8Rng,
    ) -> Self {
        let actor = Mlp::new(obs_dim, actor_hidden, act_dim, device, rng);
        let critic = Mlp::new(obs_dim, critic_hidden, 1, device, rng);
        let log_std = Tensor::full([act_dim], init_noise_std.ln(), (Kind::Float, device))
            .set_requires_grad(true);
        Self {
            actor,
            critic,
            log_std,
        }
    }

    /// Every trainable tensor with its checkpoint name, in a fixed order.
    pub fn named_parameters(&self) -> Vec<(String, Tensor)> {
        let mut out = self.actor.named("actor");
        out.extend(self.critic.named("critic"));
        out.push(("log_std".to_string(), self.log_std.shallow_clone()));
        out
    }

    /// Action means `[B, act_dim]`.
    pub fn action_mean(&self, obs: &Tensor) -> Tensor {
        self.actor.forward(obs)
    }

    /// Values `[B]`.
    pub fn value(&self, obs: &Tensor) -> Tensor {
        self.critic.forward(obs).squeeze_dim(-1)
    }

    /// Log-density of `actions` under N(mean, exp(log_std)^2), summed over action dims.
    pub fn log_prob(&self, mean: &Tensor, actions: &Tensor) -> Tensor {
        let z = (actions - mean) * (-&self.log_std).exp();
        (z.square() * -0.5 - &self.log_std - HALF_LN_2PI).sum_dim_intlist(-1, false, Kind::Float)
    }

    /// Entropy of the (state-independent) action distribution, a scalar.
    pub fn entropy(&self) -> Tensor {
        (&self.log_std + 0.5 + HALF_LN_2PI).sum(Kind::Float)
    }
}
