//! PPO hyperparameters of a robot preset (rsl_rl's names) and the schedules they resolve to
//! for a cell's epoch budget.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// PPO hyperparameters (rsl_rl's names).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PpoConfig {
    /// Actor MLP hidden sizes.
    pub actor_hidden: Vec<i64>,
    /// Critic MLP hidden sizes.
    pub critic_hidden: Vec<i64>,
    /// Initial action standard deviation.
    pub init_noise_std: f64,
    /// Surrogate clip.
    pub clip_param: f64,
    /// Discount.
    pub gamma: f64,
    /// GAE lambda.
    pub lam: f64,
    /// Value loss coefficient.
    pub value_loss_coef: f64,
    /// Entropy bonus coefficient.
    pub entropy_coef: f64,
    /// Initial learning rate.
    pub learning_rate: f64,
    /// Target KL of the adaptive learning-rate schedule.
    pub desired_kl: f64,
    /// Adapt the learning rate from the KL divergence.
    pub adaptive_lr: bool,
    /// Gradient norm clip.
    pub max_grad_norm: f64,
    /// Passes over each rollout.
    pub num_learning_epochs: usize,
    /// Mini-batches per pass.
    pub num_mini_batches: usize,
    /// Policy steps per environment per epoch.
    pub steps_per_env: usize,
    /// Clip the value loss like the surrogate.
    pub clip_value_loss: bool,
    /// When > 0 the action std is not learned but annealed geometrically from
    /// `init_noise_std` to this value over `noise_decay_epochs` epochs (0: rsl_rl's learned
    /// std). The evaluation uses the action mean, which learns to carry the gait only once
    /// the noise stops doing the stepping for it.
    #[serde(default)]
    pub final_noise_std: f64,
    /// Epochs of the noise annealing (with `final_noise_std`).
    #[serde(default)]
    pub noise_decay_epochs: usize,
    /// Epoch at which the annealing starts (with `final_noise_std`). 0: from
    /// `init_noise_std` at epoch 0. Otherwise the std is learned (rsl_rl) until this epoch
    /// and then annealed geometrically, each action dimension from the value it learned, to
    /// `final_noise_std` at epoch `noise_decay_start + noise_decay_epochs`.
    #[serde(default)]
    pub noise_decay_start: usize,
    /// `noise_decay_start` as a fraction of the cell's epoch budget (0: unset), so that
    /// the schedule scales with the budget a sweep gives its cells; resolved to epochs
    /// when a cell starts ([`PpoConfig::resolve_schedule`]). Not with `noise_decay_start`.
    #[serde(default)]
    pub noise_decay_start_fraction: f64,
    /// The epoch the annealing reaches `final_noise_std`, as a fraction of the cell's epoch
    /// budget (0: unset); with it `noise_decay_epochs` is resolved from the budget too.
    #[serde(default)]
    pub noise_decay_end_fraction: f64,
    /// Weight of rsl_rl's symmetry mirror loss (0: off, rsl_rl's default): the mean squared
    /// difference between the action mean for the mirrored observation and the mirrored
    /// action mean, added to the PPO loss, so the policy learns left and right alike. Needs
    /// the preset's `mirror` joint map.
    #[serde(default)]
    pub mirror_loss_coef: f64,
    /// rsl_rl's symmetry data augmentation (off: rsl_rl's default): every sample of an
    /// update also enters it left-right mirrored, observation and action, with the
    /// original's advantage and old log-probability. Needs the preset's `mirror` joint map.
    #[serde(default)]
    pub mirror_augmentation: bool,
}

impl Default for PpoConfig {
    /// legged_gym's (rsl_rl's) defaults for ANYmal.
    fn default() -> Self {
        PpoConfig {
            actor_hidden: vec![512, 256, 128],
            critic_hidden: vec![512, 256, 128],
            init_noise_std: 1.0,
            clip_param: 0.2,
            gamma: 0.99,
            lam: 0.95,
            value_loss_coef: 1.0,
            entropy_coef: 0.01,
            learning_rate: 1e-3,
            desired_kl: 0.01,
            adaptive_lr: true,
            max_grad_norm: 1.0,
            num_learning_epochs: 5,
            num_mini_batches: 4,
            steps_per_env: 24,
            clip_value_loss: true,
            final_noise_std: 0.0,
            noise_decay_epochs: 0,
            noise_decay_start: 0,
            noise_decay_start_fraction: 0.0,
            noise_decay_end_fraction: 0.0,
            mirror_loss_coef: 0.0,
            mirror_augmentation: false,
        }
    }
}

impl PpoConfig {
    /// Overrides scalar hyperparameters by name (`clip_param = 0.1`, ...). The names are
    /// the fields of this struct (read from its serialised form, so a new field is
    /// overridable without a list to keep): floats take the value, booleans 0/1, integers a
    /// whole number. An unknown name is an error listing the known ones.
    pub fn apply_overrides(&mut self, overrides: &BTreeMap<String, f64>) -> Result<()> {
        if overrides.is_empty() {
            return Ok(());
        }
        let mut table = toml::Table::try_from(&*self)
            .map_err(|e| Error::InvalidArgument(format!("ppo settings: {e}")))?;
        for (key, &v) in overrides {
            let bad =
                |what: &str| Error::InvalidArgument(format!("ppo override {key} = {v}: {what}"));
            if !v.is_finite() {
                return Err(bad("value must be finite"));
            }
            match key.as_str() {
                "noise_decay_start_fraction" | "noise_decay_end_fraction"
                    if !(0.0..=1.0).contains(&v) =>
                {
                    return Err(bad("expected a fraction of the epoch budget in [0, 1]"))
                }
                "mirror_loss_coef" if v < 0.0 => return Err(bad("expected a value >= 0")),
                _ => {}
            }
            // Epoch counts of the schedule may be 0 (off); every other count is positive.
            let min = if key == "noise_decay_start" { 0.0 } else { 1.0 };
            let known = Self::override_names(&table).join(", ");
            let slot = table
                .get_mut(key.as_str())
                .ok_or_else(|| bad(&format!("unknown hyperparameter; known: {known}")))?;
            *slot = match slot {
                toml::Value::Float(_) => toml::Value::Float(v),
                toml::Value::Boolean(_) => toml::Value::Boolean(v != 0.0),
                toml::Value::Integer(_) if v >= min && v.fract() == 0.0 => {
                    toml::Value::Integer(v as i64)
                }
                toml::Value::Integer(_) if min == 0.0 => {
                    return Err(bad("expected a whole number >= 0"))
                }
                toml::Value::Integer(_) => return Err(bad("expected a positive whole number")),
                _ => return Err(bad("not a number: set it in the preset's [ppo] table")),
            };
        }
        *self = table
            .try_into()
            .map_err(|e| Error::InvalidArgument(format!("ppo overrides: {e}")))?;
        Ok(())
    }

    /// The hyperparameters an override may name: the scalar fields.
    fn override_names(table: &toml::Table) -> Vec<String> {
        table
            .iter()
            .filter(|(_, v)| {
                matches!(
                    v,
                    toml::Value::Float(_) | toml::Value::Boolean(_) | toml::Value::Integer(_)
                )
            })
            .map(|(k, _)| k.clone())
            .collect()
    }

    /// Turns a schedule given as fractions of the epoch budget into epochs for a cell of
    /// `budget` epochs: the std is learned to `start_fraction * budget` and reaches
    /// `final_noise_std` at `end_fraction * budget`. A schedule given in epochs is kept
    /// as it is; one given both ways, or whose fractions do not rise, is an error.
    pub fn resolve_schedule(&mut self, budget: u32) -> Result<()> {
        let (start, end) = (
            self.noise_decay_start_fraction,
            self.noise_decay_end_fraction,
        );
        if start == 0.0 && end == 0.0 {
            return Ok(());
        }
        let bad = |what: String| Err(Error::InvalidArgument(what));
        if self.noise_decay_start != 0 || self.noise_decay_epochs != 0 {
            return bad(format!(
                "the noise schedule is given both in epochs (noise_decay_start = {}, \
                 noise_decay_epochs = {}) and as fractions ({start}, {end}): set one or the other",
                self.noise_decay_start, self.noise_decay_epochs
            ));
        }
        if !(0.0..=1.0).contains(&start) || !(start..=1.0).contains(&end) || end == 0.0 {
            return bad(format!(
                "noise_decay_start_fraction = {start} and noise_decay_end_fraction = {end}: \
                 need 0 <= start <= end <= 1 with end > 0"
            ));
        }
        if self.final_noise_std <= 0.0 {
            return bad(format!(
                "noise_decay_end_fraction = {end} anneals nothing without final_noise_std > 0 \
                 (set both, or neither)"
            ));
        }
        let at = |f: f64| (f * f64::from(budget)).round() as usize;
        self.noise_decay_start = at(start);
        self.noise_decay_epochs = at(end).saturating_sub(at(start));
        self.noise_decay_start_fraction = 0.0;
        self.noise_decay_end_fraction = 0.0;
        Ok(())
    }
}

#[cfg(test)]
mod schedule_tests {
    use super::*;

    fn annealed(start: f64, end: f64) -> PpoConfig {
        PpoConfig {
            final_noise_std: 0.05,
            noise_decay_start_fraction: start,
            noise_decay_end_fraction: end,
            ..Default::default()
        }
    }

    #[test]
    fn fractions_scale_with_the_budget() {
        for (budget, start, epochs) in [(1000, 400, 300), (3000, 1200, 900), (200, 80, 60)] {
            let mut p = annealed(0.4, 0.7);
            p.resolve_schedule(budget).unwrap();
            assert_eq!((p.noise_decay_start, p.noise_decay_epochs), (start, epochs));
            assert_eq!(
                (p.noise_decay_start_fraction, p.noise_decay_end_fraction),
                (0.0, 0.0)
            );
        }
    }

    #[test]
    fn a_schedule_in_epochs_is_kept_and_mixing_both_is_refused() {
        let mut p = PpoConfig {
            final_noise_std: 0.05,
            noise_decay_start: 400,
            noise_decay_epochs: 300,
            ..Default::default()
        };
        p.resolve_schedule(3000).unwrap();
        assert_eq!((p.noise_decay_start, p.noise_decay_epochs), (400, 300));
        p.noise_decay_end_fraction = 0.7;
        let e = p.resolve_schedule(3000).unwrap_err().to_string();
        assert!(e.contains("one or the other"), "{e}");
    }

    #[test]
    fn falling_fractions_and_fractions_without_a_final_std_are_refused() {
        assert!(annealed(0.7, 0.4).resolve_schedule(1000).is_err());
        let mut p = annealed(0.4, 0.7);
        p.final_noise_std = 0.0;
        assert!(p
            .resolve_schedule(1000)
            .unwrap_err()
            .to_string()
            .contains("final_noise_std"));
        let mut o = BTreeMap::new();
        o.insert("noise_decay_end_fraction".to_string(), 1.5);
        assert!(PpoConfig::default().apply_overrides(&o).is_err());
    }

    fn with(key: &str, v: f64) -> Result<PpoConfig> {
        let mut p = PpoConfig::default();
        p.apply_overrides(&[(key.to_string(), v)].into_iter().collect())?;
        Ok(p)
    }

    #[test]
    fn every_scalar_field_is_an_override_and_nothing_else_is() {
        assert_eq!(with("learning_rate", 3e-4).unwrap().learning_rate, 3e-4);
        assert!(!with("adaptive_lr", 0.0).unwrap().adaptive_lr);
        assert_eq!(
            with("num_learning_epochs", 3.0)
                .unwrap()
                .num_learning_epochs,
            3
        );
        assert_eq!(with("noise_decay_start", 0.0).unwrap().noise_decay_start, 0);
        assert_eq!(with("mirror_loss_coef", 0.1).unwrap().mirror_loss_coef, 0.1);
        let err = |k: &str, v: f64| with(k, v).unwrap_err().to_string();
        assert!(err("num_learning_epochs", 2.5).contains("positive whole"));
        assert!(err("num_mini_batches", 0.0).contains("positive whole"));
        assert!(err("noise_decay_start", -1.0).contains(">= 0"));
        assert!(err("mirror_loss_coef", -0.1).contains(">= 0"));
        assert!(err("learning_rate", f64::NAN).contains("finite"));
        assert!(err("actor_hidden", 64.0).contains("set it in the preset"));
        let unknown = err("bogus", 1.0);
        assert!(
            unknown.contains("bogus") && unknown.contains("mirror_augmentation, mirror_loss_coef"),
            "{unknown}"
        );
        assert!(!unknown.contains("actor_hidden"), "{unknown}");
    }
}
