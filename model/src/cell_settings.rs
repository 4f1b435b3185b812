//! The one place that decides what a cell trains with (issue 41): the robot preset (its
//! `base` chain already laid under it when it was loaded), the terrain's
//! `[terrain.<kind>.*]` tables, the spec's PPO overrides and the schedule resolved against
//! the cell's epoch budget, in that order. The coordinator calls it for every terrain of a
//! sweep when the sweep is created, so a spec is checked against what its cells will really
//! use; the trainer and `worker bench-train` call it when a cell starts.

use std::collections::BTreeMap;

use crate::preset::{settings_on, DomainRandConfig, RewardConfig, TerrainOverrides};
use crate::{defaults, PpoConfig, Result, ScoreVariant, TerrainKind};
use serde::{Deserialize, Serialize};

/// The settings of one cell: PPO (overrides applied, schedule in epochs), domain
/// randomisation and the fixed reward weights.
#[derive(Debug, Clone, PartialEq)]
pub struct CellSettings {
    /// PPO hyperparameters, with any fraction-of-budget schedule turned into epochs.
    pub ppo: PpoConfig,
    /// Domain randomisation and observation noise.
    pub domain_rand: DomainRandConfig,
    /// Fixed reward weights (w1 and w2 come from the grid).
    pub reward: RewardConfig,
}

/// The parts of a preset that [`CellSettings::resolve`] reads: both the model's
/// `PresetFile` and the simulation's `Preset` carry them.
#[derive(Debug, Clone, Copy)]
pub struct PresetSettings<'a> {
    /// The preset's `[ppo]`.
    pub ppo: &'a PpoConfig,
    /// The preset's `[domain_rand]`.
    pub domain_rand: &'a DomainRandConfig,
    /// The preset's `[reward]`.
    pub reward: &'a RewardConfig,
    /// The preset's `[terrain.<kind>.*]` tables.
    pub by_terrain: &'a BTreeMap<TerrainKind, TerrainOverrides>,
}

impl CellSettings {
    /// What a cell on `terrain` with `budget` epochs trains with. An unknown or invalid
    /// override, a terrain table that does not fit, or a schedule that cannot be resolved
    /// is an error naming the setting.
    pub fn resolve(
        preset: PresetSettings<'_>,
        terrain: TerrainKind,
        overrides: &BTreeMap<String, f64>,
        budget: u32,
    ) -> Result<CellSettings> {
        let on = settings_on(
            preset.ppo,
            preset.domain_rand,
            preset.reward,
            preset.by_terrain,
            terrain,
        )?;
        let mut ppo = on.ppo;
        ppo.apply_overrides(overrides)?;
        ppo.resolve_schedule(budget)?;
        Ok(CellSettings {
            ppo,
            domain_rand: on.domain_rand,
            reward: on.reward,
        })
    }
}

/// How a cell's policy is scored, as one value from the sweep's spec (its `[eval]`, stored in
/// the resolved spec) to the trainer: the deterministic policy in a rollout from
/// [`crate::defaults::EVAL_SEED`]. Serialised with the names a stored spec has always used
/// (`eval_robots`, `eval_seconds`, `eval_levels`, `score`, `eval_every`), flattened into it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalSettings {
    /// Robots, one episode each, at each level.
    #[serde(rename = "eval_robots")]
    pub robots: usize,
    /// Episode length (s).
    #[serde(rename = "eval_seconds")]
    pub seconds: f32,
    /// Difficulty levels (0-9); the score is the mean over them. In a sweep's spec: the
    /// levels of a cell on a terrain with levels (empty in specs stored before per-level
    /// evaluation; `ResolvedSpec::eval_for` gives a cell's).
    #[serde(rename = "eval_levels", default)]
    pub levels: Vec<u8>,
    /// The progress term of the composite score (specs stored before it read as Eq. 4).
    #[serde(default)]
    pub score: ScoreVariant,
    /// Evaluate every this many epochs as well (0: only at the end).
    #[serde(rename = "eval_every", default)]
    pub every: u32,
}

impl Default for EvalSettings {
    fn default() -> Self {
        EvalSettings {
            robots: defaults::EVAL_ROBOTS,
            seconds: defaults::EVAL_SECONDS,
            levels: defaults::EVAL_LEVELS.to_vec(),
            score: ScoreVariant::Eq4,
            every: 0,
        }
    }
}

impl EvalSettings {
    /// Why these settings cannot score a policy, if they cannot.
    pub fn problem(&self) -> Option<String> {
        if let Some(l) = self.levels.iter().find(|l| **l > 9) {
            return Some(format!("evaluation level {l} is out of range: use 0 to 9"));
        }
        if self.levels.is_empty() {
            return Some("the evaluation needs at least one difficulty level".into());
        }
        if self.robots == 0 || !(self.seconds.is_finite() && self.seconds > 0.0) {
            return Some(format!(
                "the evaluation needs at least 1 robot and a positive length, got {} robots x {} s",
                self.robots, self.seconds
            ));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PresetFile;

    fn overrides(kv: &[(&str, f64)]) -> BTreeMap<String, f64> {
        kv.iter().map(|(k, v)| (k.to_string(), *v)).collect()
    }

    #[test]
    fn eval_settings_name_what_cannot_score() {
        assert_eq!(EvalSettings::default().problem(), None);
        let bad = |e: EvalSettings| e.problem().unwrap();
        assert!(bad(EvalSettings {
            levels: vec![10],
            ..Default::default()
        })
        .contains("level 10"));
        assert!(bad(EvalSettings {
            levels: vec![],
            ..Default::default()
        })
        .contains("at least one"));
        assert!(bad(EvalSettings {
            robots: 0,
            ..Default::default()
        })
        .contains("0 robots"));
        assert!(bad(EvalSettings {
            seconds: f32::NAN,
            ..Default::default()
        })
        .contains("positive"));
    }

    #[test]
    fn terrain_tables_then_overrides_then_the_schedule() {
        let mut p = PresetFile::load("anymal").unwrap();
        let mut t = TerrainOverrides::default();
        t.ppo
            .insert("learning_rate".into(), toml::Value::Float(5e-4));
        t.ppo
            .insert("entropy_coef".into(), toml::Value::Float(0.02));
        p.terrain.insert(TerrainKind::Stairs, t);
        let o = overrides(&[("entropy_coef", 0.005)]);
        let stairs = CellSettings::resolve(p.settings(), TerrainKind::Stairs, &o, 1000).unwrap();
        assert_eq!(stairs.ppo.learning_rate, 5e-4, "the terrain's table");
        assert_eq!(stairs.ppo.entropy_coef, 0.005, "the spec's override wins");
        let rough = CellSettings::resolve(p.settings(), TerrainKind::Rough, &o, 1000).unwrap();
        assert_eq!(rough.ppo.learning_rate, p.ppo.learning_rate);
        // anymal anneals from 1/2 to 3/4 of the budget.
        assert_eq!(rough.ppo.noise_decay_start, 500);
        assert_eq!(rough.ppo.noise_decay_epochs, 250);
    }

    #[test]
    fn an_override_that_clashes_with_the_presets_schedule_is_an_error() {
        // The schedule is given as fractions by the preset: an override in epochs clashes.
        let p = PresetFile::load("anymal").unwrap();
        let o = overrides(&[("noise_decay_start", 300.0)]);
        let e = CellSettings::resolve(p.settings(), TerrainKind::Rough, &o, 1000)
            .unwrap_err()
            .to_string();
        assert!(e.contains("both in epochs"), "{e}");
        let e = CellSettings::resolve(
            p.settings(),
            TerrainKind::Rough,
            &overrides(&[("bogus", 1.0)]),
            10,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("bogus") && e.contains("known"), "{e}");
    }
}
