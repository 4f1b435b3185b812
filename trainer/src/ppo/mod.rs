//! PPO as legged_gym's rsl_rl does it, on libtorch: a Gaussian actor with a learned
//! log-std, a separate critic, GAE(lambda), clipped surrogate and value losses, an entropy
//! bonus, an adaptive learning rate from the KL divergence, gradient-norm clipping and
//! running observation normalisation.
//!
//! The trainer is generic over [`VecEnvLike`] so that it runs on the rapier simulation and
//! on the cheap [`toy`] task that the tests use to prove that learning works.

pub mod adam;
mod algo;
mod net;
mod normalizer;
pub mod runner;
mod storage;
pub mod toy;

pub use adam::Adam;
pub use algo::{Ppo, UpdateStats};
pub use net::{ActorCritic, Mlp};
pub use normalizer::{ObsNormalizer, NORM_CLIP, NORM_EPS};
pub use runner::{EpochStats, Runner};

use crate::Result;

/// One step of a vectorised environment, borrowed from it.
#[derive(Debug)]
pub struct StepView<'a> {
    /// Observations after the step (done robots already reset), `[N * obs_dim]`.
    pub obs: &'a [f32],
    /// Rewards of the step, `[N]`.
    pub rewards: &'a [f32],
    /// Episode ended (fall or timeout), `[N]`.
    pub dones: &'a [bool],
    /// Episode ended only because of its time limit, `[N]`: the critic bootstraps these.
    pub timeouts: &'a [bool],
    /// Weighted reward terms of the step, `[N * n_terms]` (may be empty).
    pub terms: &'a [f32],
}

/// What the trainer needs from a vectorised environment.
pub trait VecEnvLike {
    /// Number of robots stepped together.
    fn num_envs(&self) -> usize;
    /// Length of one robot's observation.
    fn obs_dim(&self) -> usize;
    /// Length of one robot's action.
    fn act_dim(&self) -> usize;
    /// Resets every robot from `seed` and returns the observations `[N * obs_dim]`.
    fn reseed(&mut self, seed: u64) -> Result<Vec<f32>>;
    /// Applies `actions` `[N * act_dim]` and advances one policy step.
    fn step(&mut self, actions: &[f32]) -> Result<StepView<'_>>;
    /// Names of the reward terms in [`StepView::terms`].
    fn term_names(&self) -> Vec<String> {
        Vec::new()
    }
    /// Per-robot curriculum levels (empty when the task has none); checkpoints keep them.
    fn levels(&self) -> Vec<u8> {
        Vec::new()
    }
    /// Names of the terrain variants robots are dealt in turn (robot `i` gets variant
    /// `i % len`); the curriculum level is also logged per variant. Empty: one group.
    fn variant_names(&self) -> &'static [&'static str] {
        &[]
    }
    /// Restores curriculum levels (applied by the next reseed); false when unsupported.
    fn set_levels(&mut self, _levels: &[u8]) -> bool {
        false
    }
}

/// PPO hyperparameters: the preset's `[ppo]` table, used as is.
pub use gaitsweep_sim::PpoConfig as PpoParams;

/// Error for a NaN or infinity in `quantity`; the runner names the cell and epoch.
pub(crate) fn non_finite(quantity: &str) -> crate::Error {
    crate::Error::NonFinite {
        cell: String::new(),
        epoch: 0,
        quantity: quantity.to_string(),
    }
}
