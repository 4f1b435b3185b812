//! The gait score (paper Eq. 4, our reading: README "What a score measures") of a cell and the locomotion
//! metrics recorded beside it. The simulator computes it (`gaitsweep_sim::score`).

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// The gait score of a cell and its components, averaged over its robots (and, for an
/// evaluation over several difficulty levels, the mean over the levels of each component).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GaitScore {
    /// J = mean(track - effort - tilt) + progress term of the sweep's [`ScoreVariant`],
    /// averaged over robots.
    pub score: f64,
    /// Mean velocity tracking kernel, in [0, 1].
    pub track: f64,
    /// Mean normalised torque |tau|_2 / (sqrt(12) tau_max), in [0, 1].
    pub effort: f64,
    /// Mean |g_xy| (horizontal part of gravity in the base frame).
    pub tilt: f64,
    /// Eq. 4's progress: sum of squared per-step base displacements (m²).
    pub progress: f64,
    /// The bounded progress: the same sum with each step's displacement capped at the
    /// commanded distance of that step (|v_cmd| dt), so running faster than commanded
    /// earns nothing (m²).
    #[serde(default)]
    pub progress_bounded: f64,
    /// Fraction of robots that fell.
    pub fall_rate: f64,
    /// Mean |v_cmd - v| (m/s).
    pub mean_vel_error: f64,
    /// Mean base speed over the steps walked (m/s).
    #[serde(default)]
    pub mean_speed: f64,
    /// Mean of max(0, |v| - |v_cmd|) over the steps walked (m/s): how much faster than
    /// commanded the robots ran, Eq. 4's progress term pays for that.
    #[serde(default)]
    pub overspeed: f64,
    /// Mean absolute joint torque (N·m).
    pub mean_abs_torque: f64,
    /// Cost of transport: mean mechanical power / (m g mean speed).
    pub cost_of_transport: f64,
    /// Robots scored (over all levels).
    pub robots: usize,
    /// The score at each evaluated difficulty level, in evaluation order (empty in scores
    /// made before per-level evaluation existed).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub levels: Vec<LevelScore>,
}

/// The gait score at one difficulty level of an evaluation.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LevelScore {
    /// Difficulty level 0..=9.
    pub level: u8,
    /// The score there (its own `levels` empty).
    pub score: GaitScore,
}

impl GaitScore {
    /// The score of an evaluation over several levels: every component is the mean over
    /// the levels (so each level weighs the same whatever its robot count), robots are
    /// summed, and the per-level scores are kept in `levels`.
    pub fn mean_of_levels(levels: Vec<LevelScore>) -> GaitScore {
        let n = levels.len().max(1) as f64;
        let mut m = GaitScore::default();
        for l in &levels {
            for ((_, sum), (_, v)) in m.components_mut().into_iter().zip(l.score.components()) {
                *sum += v / n;
            }
            m.robots += l.score.robots;
        }
        m.levels = levels;
        m
    }

    /// Every numeric component by name, the names of the `scores` table's columns: the one
    /// list the store, the validation and the metrics share.
    pub fn components(&self) -> [(&'static str, f64); 12] {
        [
            ("score", self.score),
            ("track", self.track),
            ("effort", self.effort),
            ("tilt", self.tilt),
            ("progress", self.progress),
            ("progress_bounded", self.progress_bounded),
            ("fall_rate", self.fall_rate),
            ("mean_vel_error", self.mean_vel_error),
            ("mean_speed", self.mean_speed),
            ("overspeed", self.overspeed),
            ("mean_abs_torque", self.mean_abs_torque),
            ("cost_of_transport", self.cost_of_transport),
        ]
    }

    /// [`GaitScore::components`] as places to write, in the same order.
    pub fn components_mut(&mut self) -> [(&'static str, &mut f64); 12] {
        [
            ("score", &mut self.score),
            ("track", &mut self.track),
            ("effort", &mut self.effort),
            ("tilt", &mut self.tilt),
            ("progress", &mut self.progress),
            ("progress_bounded", &mut self.progress_bounded),
            ("fall_rate", &mut self.fall_rate),
            ("mean_vel_error", &mut self.mean_vel_error),
            ("mean_speed", &mut self.mean_speed),
            ("overspeed", &mut self.overspeed),
            ("mean_abs_torque", &mut self.mean_abs_torque),
            ("cost_of_transport", &mut self.cost_of_transport),
        ]
    }
}

/// The project's walking target (README, "Robot presets"): an evaluation walks when at most
/// this share of its robots fell ...
pub const WALK_MAX_FALL_RATE: f64 = 0.10;
/// ... and its robots' mean speed error |v_cmd - v| is at most this (m/s).
pub const WALK_MAX_VEL_ERROR: f64 = 0.25;

impl GaitScore {
    /// Whether this evaluation walks by the project's target (mean over its levels).
    pub fn walks(&self) -> bool {
        self.fall_rate <= WALK_MAX_FALL_RATE && self.mean_vel_error <= WALK_MAX_VEL_ERROR
    }

    /// Whether it walks at each of its levels (at its one level if it has none).
    pub fn walks_at_every_level(&self) -> bool {
        if self.levels.is_empty() {
            return self.walks();
        }
        self.levels.iter().all(|l| l.score.walks())
    }
}

/// How many of some evaluations walk ([`WalkCount::of`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WalkCount {
    /// Evaluations with a finite score (a NaN score is a broken evaluation, not a gait).
    pub scored: usize,
    /// Of those, the ones that walk on the mean over their levels ([`GaitScore::walks`]).
    pub walks: usize,
    /// Of those, the ones that walk at every level ([`GaitScore::walks_at_every_level`]).
    pub at_every_level: usize,
}

impl WalkCount {
    /// Counts `scores`, leaving out those whose score is not finite, so that the count and
    /// its denominator are over the same evaluations wherever a sweep's walking is told.
    pub fn of<'a>(scores: impl IntoIterator<Item = &'a GaitScore>) -> Self {
        let mut c = WalkCount::default();
        for s in scores.into_iter().filter(|s| s.score.is_finite()) {
            c.scored += 1;
            c.walks += usize::from(s.walks());
            c.at_every_level += usize::from(s.walks_at_every_level());
        }
        c
    }
}

/// Prefix of an evaluation's metrics in a training run's metrics: `eval/<component>` for
/// the score, `eval/level/<level>/<component>` for each level's.
pub const EVAL_METRICS_PREFIX: &str = "eval/";

impl GaitScore {
    /// The evaluation as training metrics (`eval/score`, `eval/level/3/fall_rate`, ...;
    /// see [`EVAL_METRICS_PREFIX`]); [`GaitScore::from_eval_metrics`] reads them back.
    pub fn eval_metrics(&self) -> BTreeMap<String, f64> {
        let mut m = BTreeMap::new();
        let mut put = |prefix: String, s: &GaitScore| {
            for (k, v) in s.components() {
                m.insert(format!("{prefix}{k}"), v);
            }
            m.insert(format!("{prefix}robots"), s.robots as f64);
        };
        put(EVAL_METRICS_PREFIX.to_string(), self);
        for l in &self.levels {
            put(format!("{EVAL_METRICS_PREFIX}level/{}/", l.level), &l.score);
        }
        m
    }

    /// The evaluation a training run logged as metrics, or `None` without `eval/score`.
    /// Components it did not log (older workers) read as 0.
    pub fn from_eval_metrics(values: &BTreeMap<String, f64>) -> Option<GaitScore> {
        let read = |prefix: &str| -> Option<GaitScore> {
            let get = |k: &str| values.get(&format!("{prefix}{k}")).copied();
            get("score")?;
            let mut s = GaitScore {
                robots: get("robots").unwrap_or(0.0).max(0.0) as usize,
                ..Default::default()
            };
            for (k, slot) in s.components_mut() {
                *slot = get(k).unwrap_or(0.0);
            }
            Some(s)
        };
        let mut score = read(EVAL_METRICS_PREFIX)?;
        let level_prefix = format!("{EVAL_METRICS_PREFIX}level/");
        let mut levels: Vec<u8> = values
            .keys()
            .filter_map(|k| k.strip_prefix(&level_prefix)?.split_once('/'))
            .filter_map(|(l, _)| l.parse().ok())
            .filter(|l| *l <= 9)
            .collect();
        levels.dedup();
        score.levels = levels
            .into_iter()
            .filter_map(|level| {
                let s = read(&format!("{level_prefix}{level}/"))?;
                Some(LevelScore { level, score: s })
            })
            .collect();
        Some(score)
    }
}

/// Which progress term the composite score J uses.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScoreVariant {
    /// The paper's Eq. 4: progress = sum of squared step displacements. It grows with
    /// speed squared, so a robot that ignores a slow command and runs fast can outscore
    /// one that tracks it.
    #[default]
    Eq4,
    /// Eq. 4 with each step's displacement capped at the commanded distance of the step:
    /// no credit for running faster than commanded.
    Bounded,
}

impl ScoreVariant {
    /// Every variant.
    pub const ALL: [ScoreVariant; 2] = [Self::Eq4, Self::Bounded];

    /// J from the summed components: `(track - effort - tilt) / T + progress`.
    pub fn j(self, track: f64, effort: f64, tilt: f64, t: f64, progress: f64, bounded: f64) -> f64 {
        let p = match self {
            Self::Eq4 => progress,
            Self::Bounded => bounded,
        };
        (track - effort - tilt) / t + p
    }
}

impl fmt::Display for ScoreVariant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Eq4 => "eq4",
            Self::Bounded => "bounded",
        })
    }
}

impl FromStr for ScoreVariant {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "eq4" | "" => Ok(Self::Eq4),
            "bounded" => Ok(Self::Bounded),
            other => Err(format!(
                "score {other:?} is unknown: use \"eq4\" (the paper's) or \"bounded\" (progress capped at the commanded distance)"
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(level: u8, score: f64, fall_rate: f64, robots: usize) -> LevelScore {
        LevelScore {
            level,
            score: GaitScore {
                score,
                fall_rate,
                robots,
                ..Default::default()
            },
        }
    }

    #[test]
    fn walking_is_few_falls_and_a_small_speed_error_at_every_level() {
        let at = |fall_rate: f64, mean_vel_error: f64| GaitScore {
            fall_rate,
            mean_vel_error,
            ..Default::default()
        };
        assert!(at(0.10, 0.25).walks() && !at(0.11, 0.1).walks() && !at(0.0, 0.26).walks());
        let levels = |a: GaitScore, b: GaitScore| {
            GaitScore::mean_of_levels(vec![
                LevelScore { level: 0, score: a },
                LevelScore { level: 7, score: b },
            ])
        };
        let both = levels(at(0.02, 0.1), at(0.08, 0.2));
        assert!(both.walks() && both.walks_at_every_level());
        // 5% falls on average, but 10.5% at level 7.
        let one = levels(at(0.0, 0.1), at(0.105, 0.2));
        assert!(one.walks() && !one.walks_at_every_level());
        let broken = GaitScore {
            score: f64::NAN,
            ..both.clone()
        };
        assert_eq!(
            WalkCount::of([&both, &one, &broken]),
            WalkCount {
                scored: 2,
                walks: 2,
                at_every_level: 1
            },
            "a NaN score is neither counted nor walking"
        );
    }

    #[test]
    fn components_and_their_places_are_the_same_list() {
        let mut s = GaitScore::default();
        for (i, (_, v)) in s.components_mut().into_iter().enumerate() {
            *v = i as f64 + 1.0;
        }
        let names_mut: Vec<&str> = GaitScore::default()
            .components_mut()
            .map(|(k, _)| k)
            .to_vec();
        let read: Vec<(&str, f64)> = s.components().to_vec();
        assert_eq!(read.iter().map(|(k, _)| *k).collect::<Vec<_>>(), names_mut);
        for (i, (k, v)) in read.into_iter().enumerate() {
            assert_eq!(v, i as f64 + 1.0, "{k}");
        }
    }

    #[test]
    fn levels_weigh_the_same_and_are_kept() {
        let m = GaitScore::mean_of_levels(vec![at(0, 1.0, 0.0, 4), at(7, 0.2, 0.5, 2)]);
        assert!((m.score - 0.6).abs() < 1e-12);
        assert!((m.fall_rate - 0.25).abs() < 1e-12);
        assert_eq!(m.robots, 6);
        assert_eq!(m.levels.iter().map(|l| l.level).collect::<Vec<_>>(), [0, 7]);
    }

    #[test]
    fn an_evaluation_reads_back_from_its_metrics() {
        let mut s = GaitScore::mean_of_levels(vec![at(0, 1.0, 0.0, 4), at(7, 0.2, 0.5, 4)]);
        s.overspeed = 0.3;
        let m = s.eval_metrics();
        assert_eq!(m["eval/level/7/fall_rate"], 0.5);
        assert_eq!(GaitScore::from_eval_metrics(&m), Some(s));
        assert_eq!(GaitScore::from_eval_metrics(&BTreeMap::new()), None);
    }

    #[test]
    fn variants_parse_and_print_back() {
        for v in ScoreVariant::ALL {
            assert_eq!(v.to_string().parse::<ScoreVariant>(), Ok(v));
        }
        assert!("fast"
            .parse::<ScoreVariant>()
            .unwrap_err()
            .contains("bounded"));
    }

    #[test]
    fn old_score_json_reads_with_the_new_fields_zero() {
        let old = r#"{"score":0.5,"track":0.6,"effort":0.1,"tilt":0.0,"progress":0.0,
            "fall_rate":0.0,"mean_vel_error":0.1,"mean_abs_torque":3.0,"cost_of_transport":1.0,"robots":8}"#;
        let s: GaitScore = serde_json::from_str(old).unwrap();
        assert_eq!((s.overspeed, s.levels.len()), (0.0, 0));
    }
}
