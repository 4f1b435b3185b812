//! The sweep spec (TOML or gRPC), its validation (every problem listed) and the grid
//! expansion into cells.

use crate::{defaults, Error, Result};
use gaitsweep_model::{EvalSettings, ScoreVariant, TerrainKind};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

use crate::search::halving_rungs;
pub use crate::search::{
    halving_cost, Search, SearchSpec, DEFAULT_POPULATION, DEFAULT_REDUCTION, DEFAULT_SIGMA,
};

/// The level every cell of a sweep stored before per-level evaluation was scored at,
/// unless it had a fixed difficulty (the trainer's `CURRICULUM_EVAL_DIFFICULTY`).
pub const LEGACY_EVAL_LEVEL: u8 = 5;

/// Most cells one sweep may have.
pub const MAX_CELLS: usize = 100_000;

/// One reward-weight axis as written by a user: a range with a count, or explicit values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged, deny_unknown_fields)]
pub enum Axis {
    /// `count` evenly spaced values from `min` to `max`, ends included.
    Range {
        /// First value.
        min: f64,
        /// Last value.
        max: f64,
        /// Number of values.
        count: usize,
    },
    /// Explicit values in grid order.
    Values {
        /// The values.
        values: Vec<f64>,
    },
}

impl Axis {
    /// The values of the axis.
    pub fn values(&self) -> Vec<f64> {
        match self {
            Axis::Range { min, max, count } => match *count {
                0 => vec![],
                1 => vec![*min],
                n => (0..n)
                    .map(|i| min + (max - min) * i as f64 / (n - 1) as f64)
                    .collect(),
            },
            Axis::Values { values } => values.clone(),
        }
    }
}

/// Evaluation rollout settings.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalSpec {
    /// Robots in the evaluation rollout.
    pub robots: Option<usize>,
    /// Length of the rollout in seconds.
    pub seconds: Option<f32>,
    /// Evaluate the deterministic policy every this many epochs as well (stored per cell
    /// and epoch in `evaluations`); unset or 0: only at the end and at rungs.
    #[serde(default)]
    pub every: Option<u32>,
    /// Difficulty levels (0-9) every evaluation of a cell on rough, stairs or slopes runs
    /// at; its score is the mean over them (unset: the fixed `difficulty` if given, else
    /// [`crate::defaults::EVAL_LEVELS`]). Flat ground is evaluated at level 0.
    #[serde(default)]
    pub levels: Option<Vec<u32>>,
    /// The score's progress term: "eq4" (the paper's, default) or "bounded" (each step's
    /// displacement capped at its commanded distance).
    #[serde(default)]
    pub score: Option<String>,
}

/// A sweep spec as a user writes it (TOML) or sends it (gRPC); unset fields fall back to
/// the robot preset's grid or to defaults when resolved.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// Name of the sweep (default: robot and terrains).
    #[serde(default)]
    pub name: String,
    /// Robot preset name.
    pub robot: String,
    /// Terrain names; each gets its own grid.
    #[serde(default)]
    pub terrains: Vec<String>,
    /// Terrain difficulty level 0-9.
    pub difficulty: Option<u32>,
    /// Take the unset grid fields from the preset's Table-1 grid.
    #[serde(default)]
    pub preset_grid: bool,
    /// w1 axis (velocity tracking weight).
    pub w1: Option<Axis>,
    /// w2 axis (log10 torque penalty weight).
    pub w2: Option<Axis>,
    /// Simulated robots per cell.
    pub agents_per_cell: Option<usize>,
    /// PPO epochs per cell.
    pub epochs: Option<u32>,
    /// Checkpoint every this many epochs (0: only the final one; unset:
    /// [`crate::defaults::CHECKPOINT_EVERY`]).
    #[serde(default)]
    pub checkpoint_every: Option<u32>,
    /// Base seed.
    #[serde(default)]
    pub seed: u64,
    /// Replicates: each grid point is trained this many times with different seeds, and
    /// its result is their mean with a 95% confidence interval (default 1).
    #[serde(default)]
    pub seeds: Option<u32>,
    /// PPO hyper-parameter overrides.
    #[serde(default)]
    pub ppo: BTreeMap<String, f64>,
    /// Evaluation rollout.
    #[serde(default)]
    pub eval: EvalSpec,
    /// Search strategy (default: the full grid).
    #[serde(default)]
    pub search: Option<SearchSpec>,
    /// After the grid's single-seed pass, train the best points of each terrain with more
    /// seeds and promote among them (default: none).
    #[serde(default)]
    pub finalists: Option<crate::finalists::FinalistsSpec>,
    /// Stop a cell that was never rewarded (mean reward exactly 0 at every epoch) once it
    /// has trained this fraction of its epochs, in (0, 1) (default: off).
    #[serde(default)]
    pub stop_unrewarded: Option<f64>,
}

/// A validated spec with every default filled in: what the coordinator stores and runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResolvedSpec {
    /// Name of the sweep.
    pub name: String,
    /// Robot preset name.
    pub robot: String,
    /// Terrains, in grid order.
    #[serde(with = "terrain_names")]
    pub terrains: Vec<TerrainKind>,
    /// Terrain difficulty level.
    pub difficulty: Option<u8>,
    /// w1 values (grid rows).
    pub w1_values: Vec<f64>,
    /// w2 values (grid columns).
    pub w2_values: Vec<f64>,
    /// Simulated robots per cell.
    pub agents_per_cell: usize,
    /// PPO epochs per cell.
    pub epochs: u32,
    /// Checkpoint interval in epochs, at least 1 (the final checkpoint is always written).
    pub checkpoint_every: u32,
    /// Base seed.
    pub seed: u64,
    /// Replicates per grid point (specs stored before replicates existed read as 1).
    #[serde(default = "one")]
    pub replicates: u32,
    /// PPO overrides.
    pub ppo_overrides: BTreeMap<String, f64>,
    /// How every cell is scored (robots, seconds, the levels of a terrain with levels, the
    /// score's variant, the interval of periodic evaluations); a cell's own is
    /// [`ResolvedSpec::eval_for`].
    #[serde(flatten)]
    pub eval: EvalSettings,
    /// Search strategy (specs stored before searches existed read as the grid).
    #[serde(default)]
    pub search: Search,
    /// The finalist stage, if any (specs stored before it read as none).
    #[serde(default)]
    pub finalists: Option<crate::finalists::Finalists>,
    /// The fraction of its epochs after which a cell never rewarded stops
    /// ([`ResolvedSpec::stop_unrewarded_after`]); none: every cell trains to the end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_unrewarded: Option<f64>,
}

/// One cell of an expanded grid.
#[derive(Debug, Clone, PartialEq)]
pub struct CellPlan {
    /// Index into the terrain list.
    pub terrain_index: usize,
    /// Terrain.
    pub terrain: TerrainKind,
    /// Grid point or evolutionary candidate.
    pub place: crate::Place,
    /// Velocity tracking weight.
    pub w1: f64,
    /// Torque penalty exponent.
    pub w2: f64,
    /// Replicate number within its grid point, from 0.
    pub replicate: u32,
    /// The cell's own seed.
    pub seed: u64,
}

/// The grid defaults a robot preset provides.
#[derive(Debug, Clone, PartialEq)]
pub struct PresetGrid {
    /// w1 axis.
    pub w1: Axis,
    /// w2 axis.
    pub w2: Axis,
    /// Agents per cell.
    pub agents_per_cell: usize,
    /// Epochs.
    pub epochs: u32,
}

impl SweepSpec {
    /// Parses a TOML spec (unknown keys are an error).
    pub fn from_toml(text: &str) -> Result<Self> {
        Ok(toml::from_str(text)?)
    }

    /// Validates the spec with a preset lookup (`robot -> (grid, PPO override problem)` or
    /// the reason the robot is unknown) and fills in defaults. Lists every problem.
    pub fn resolve_with(
        &self,
        preset: impl FnOnce(&str) -> std::result::Result<(PresetGrid, Option<String>), String>,
    ) -> Result<ResolvedSpec> {
        let mut problems = Vec::new();
        let mut grid = None;
        if self.robot.trim().is_empty() {
            problems.push("robot is empty: name a robot preset such as \"anymal\"".to_string());
        } else {
            match preset(&self.robot) {
                Ok((g, override_problem)) => {
                    if let Some(p) = override_problem {
                        problems.push(format!("ppo overrides: {p}"));
                    }
                    grid = Some(g);
                }
                Err(e) => problems.push(format!("robot {:?}: {e}", self.robot)),
            }
        }
        let mut terrains = Vec::new();
        if self.terrains.is_empty() {
            problems
                .push("terrains is empty: list at least one of flat, rough, stairs, slopes".into());
        }
        for t in &self.terrains {
            match t.parse::<TerrainKind>() {
                Ok(k) if terrains.contains(&k) => {
                    problems.push(format!("terrain {t:?} is listed twice"))
                }
                Ok(k) => terrains.push(k),
                Err(_) => problems.push(format!(
                    "terrain {t:?} is unknown: use flat, rough, stairs, slopes or mixed"
                )),
            }
        }
        if let Some(d) = self.difficulty {
            if d > 9 {
                problems.push(format!("difficulty {d} is out of range: use 0 to 9"));
            }
        }
        let from_preset = |field: &str, problems: &mut Vec<String>| {
            if !self.preset_grid {
                problems.push(format!(
                    "{field} is missing: set it or set preset_grid = true"
                ));
            }
        };
        let axis = |name: &str,
                    given: &Option<Axis>,
                    preset: Option<&Axis>,
                    problems: &mut Vec<String>| {
            let axis = match (given, preset) {
                (Some(a), _) => Some(a.clone()),
                (None, p) => {
                    from_preset(name, problems);
                    if self.preset_grid {
                        p.cloned()
                    } else {
                        None
                    }
                }
            };
            if let Some(Axis::Range { min, max, count }) = given {
                if *count > 1 && min > max {
                    problems.push(format!(
                        "{name} runs from min {min} down to max {max}: write the smaller value as min"
                    ));
                }
            }
            if let Some(Axis::Range { count, .. }) = &axis {
                // Checked before expanding: a count of billions must not allocate billions.
                if *count > MAX_CELLS {
                    problems.push(format!(
                        "{name}.count is {count}, more than the limit of {MAX_CELLS} cells"
                    ));
                    return vec![];
                }
            }
            let values = axis.map(|a| a.values()).unwrap_or_default();
            if let Some(Axis::Range { count: 0, .. }) = given {
                problems.push(format!("{name}.count is 0: use at least 1"));
            }
            if let Some(Axis::Values { values }) = given {
                if values.is_empty() {
                    problems.push(format!("{name}.values is empty: list at least one value"));
                }
            }
            if values.iter().any(|v| !v.is_finite()) {
                problems.push(format!("{name} has a value that is not finite"));
            }
            values
        };
        let w1_values = axis("w1", &self.w1, grid.as_ref().map(|g| &g.w1), &mut problems);
        let w2_values = axis("w2", &self.w2, grid.as_ref().map(|g| &g.w2), &mut problems);
        if let Some(v) = w1_values.iter().find(|v| **v < 0.0) {
            problems.push(format!(
                "w1 {v} is negative: w1 weighs the velocity-tracking reward, a negative weight rewards ignoring the command; use values >= 0"
            ));
        }
        if w2_values.iter().any(|v| *v > 3.0) {
            problems.push(
                "w2 is the log10 of the torque weight: values above 3 are not sensible".into(),
            );
        }
        let agents_per_cell = match self.agents_per_cell {
            Some(0) => {
                problems.push("agents_per_cell is 0: use at least 1".into());
                0
            }
            Some(n) => n,
            None => {
                from_preset("agents_per_cell", &mut problems);
                grid.as_ref().map_or(0, |g| g.agents_per_cell)
            }
        };
        let epochs = match self.epochs {
            Some(0) => {
                problems.push("epochs is 0: use at least 1".into());
                0
            }
            Some(n) => n,
            None => {
                from_preset("epochs", &mut problems);
                grid.as_ref().map_or(0, |g| g.epochs)
            }
        };
        if let Some(s) = self.eval.seconds {
            if !(s.is_finite() && s > 0.0) {
                problems.push(format!("eval.seconds {s} must be a positive number"));
            }
        }
        if self.eval.robots == Some(0) {
            problems.push("eval.robots is 0: use at least 1".into());
        }
        let eval_levels: Vec<u8> = match &self.eval.levels {
            Some(l) if l.is_empty() => {
                problems.push(
                    "eval.levels is empty: list at least one level, e.g. [0, 3, 5, 7]".into(),
                );
                vec![]
            }
            Some(l) => {
                if let Some(bad) = l.iter().find(|v| **v > 9) {
                    problems.push(format!("eval.levels has {bad}: levels run from 0 to 9"));
                }
                let mut seen = l.clone();
                seen.sort_unstable();
                seen.dedup();
                if seen.len() != l.len() {
                    problems.push(format!("eval.levels {l:?} lists a level twice"));
                }
                l.iter().map(|v| (*v).min(9) as u8).collect()
            }
            None => match self.difficulty {
                Some(d) => vec![d.min(9) as u8],
                None => defaults::EVAL_LEVELS.to_vec(),
            },
        };
        let score = match self
            .eval
            .score
            .as_deref()
            .unwrap_or("")
            .parse::<ScoreVariant>()
        {
            Ok(v) => v,
            Err(e) => {
                problems.push(format!("eval.{e}"));
                ScoreVariant::Eq4
            }
        };
        for (k, v) in &self.ppo {
            if !v.is_finite() {
                problems.push(format!("ppo.{k} is not a finite number"));
            }
        }
        let replicates = self.seeds.unwrap_or(1);
        let grid_epochs = (terrains.len().max(1) * w1_values.len() * w2_values.len()) as u64
            * u64::from(replicates.max(1))
            * u64::from(epochs);
        let points = w1_values.len() * w2_values.len();
        let search = self.resolve_search(
            epochs,
            replicates.max(1),
            grid_epochs,
            points,
            &mut problems,
        );
        if search.generations().is_some() && terrains.len() > 1 {
            problems.push(format!(
                "search.method {} searches one terrain, the spec has {}: create one sweep per terrain",
                search.method(),
                terrains.len()
            ));
        }
        if let Search::Genetic { population, .. } = search {
            let points = w1_values.len() * w2_values.len();
            if points < 2 {
                problems.push(
                    "search.method genetic breeds grid points: give w1 and w2 at least 2 points between them".into(),
                );
            } else if population as usize > points {
                problems.push(format!(
                    "search.population is {population} but the grid has {points} points: a generation of the genetic algorithm trains distinct points, use at most {points} (or method = \"grid\")"
                ));
            }
        }
        if let Search::Cmaes { .. } = search {
            let span = |v: &[f64]| {
                let (lo, hi) = min_max(v);
                hi > lo
            };
            if !span(&w1_values) || !span(&w2_values) {
                problems.push(
                    "search.method cmaes searches between each axis' smallest and largest value: give w1 and w2 a range (min < max)".into(),
                );
            }
        }
        if search.halving().is_some() && self.seeds.unwrap_or(1) > 1 {
            problems.push(
                "successive halving (search.method asha, or cmaes or genetic with min_epochs) ranks single training runs: use seeds = 1 with it".into(),
            );
        }
        if let Some(f) = self.stop_unrewarded {
            if !(f.is_finite() && f > 0.0 && f < 1.0) {
                problems.push(format!(
                    "stop_unrewarded is {f}: give the fraction of a cell's epochs after which a cell never rewarded stops, between 0 and 1 (e.g. 0.1), or leave it out"
                ));
            } else if search.halving().is_some() {
                problems.push(
                    "stop_unrewarded stops cells before successive halving's rungs could rank them: leave it out, or search without min_epochs".into(),
                );
            }
        }
        if replicates == 0 || replicates > MAX_REPLICATES {
            problems.push(format!(
                "seeds is {replicates}: use 1 to {MAX_REPLICATES} replicates per grid point"
            ));
        }
        let finalists = self.finalists.as_ref().and_then(|f| {
            f.resolve(
                &search,
                replicates,
                w1_values.len() * w2_values.len(),
                &mut problems,
            )
        });
        let cells = match search.generations() {
            Some((population, generations)) => population as usize * generations as usize,
            None => terrains.len().max(1) * w1_values.len() * w2_values.len(),
        } * replicates.clamp(1, MAX_REPLICATES) as usize;
        if cells > MAX_CELLS {
            problems.push(format!(
                "the grid has {cells} cells, more than the limit of {MAX_CELLS}"
            ));
        }
        if !problems.is_empty() {
            return Err(Error::InvalidSpec(problems));
        }
        let name = if self.name.trim().is_empty() {
            let t: Vec<String> = terrains.iter().map(|t| t.to_string()).collect();
            format!("{}-{}", self.robot, t.join("-"))
        } else {
            self.name.clone()
        };
        Ok(ResolvedSpec {
            name,
            robot: self.robot.clone(),
            terrains,
            difficulty: self.difficulty.map(|d| d as u8),
            w1_values,
            w2_values,
            agents_per_cell,
            epochs,
            checkpoint_every: defaults::checkpoint_every(self.checkpoint_every, epochs),
            seed: self.seed,
            replicates,
            ppo_overrides: self.ppo.clone(),
            eval: EvalSettings {
                robots: self.eval.robots.unwrap_or(defaults::EVAL_ROBOTS),
                seconds: self.eval.seconds.unwrap_or(defaults::EVAL_SECONDS),
                levels: eval_levels,
                score,
                every: self.eval.every.unwrap_or(0),
            },
            search,
            finalists,
            stop_unrewarded: self.stop_unrewarded,
        })
    }
}

impl ResolvedSpec {
    /// The difficulty levels a cell on `terrain` is evaluated at: 0 on flat ground (which
    /// has no levels), the spec's `eval_levels` elsewhere; a spec stored before per-level
    /// evaluation keeps the one level it was scored at (its difficulty, else 5).
    pub fn eval_levels_for(&self, terrain: &str) -> Vec<u8> {
        if self.eval.levels.is_empty() {
            return vec![self.difficulty.unwrap_or(LEGACY_EVAL_LEVEL)];
        }
        match terrain.parse::<TerrainKind>() {
            Ok(TerrainKind::Flat) => vec![0],
            _ => self.eval.levels.clone(),
        }
    }

    /// The epoch at which a cell whose mean reward was exactly 0 at every epoch so far stops
    /// and is scored: `stop_unrewarded` of the epochs, rounded up, at least 1 (0: never).
    pub fn stop_unrewarded_after(&self) -> u32 {
        // The epsilon keeps a product such as 0.07 x 100 = 7.000000000000001 at 7.
        self.stop_unrewarded.map_or(0, |f| {
            ((f * f64::from(self.epochs) - 1e-9).ceil() as u32).clamp(1, self.epochs.max(1))
        })
    }

    /// How a cell on `terrain` is scored: the sweep's evaluation with that terrain's levels.
    pub fn eval_for(&self, terrain: &str) -> EvalSettings {
        EvalSettings {
            levels: self.eval_levels_for(terrain),
            ..self.eval.clone()
        }
    }

    /// Fills values that specs stored by earlier versions left at 0 ("the worker's
    /// default"), so every spec read back carries concrete values.
    pub fn with_defaults(mut self) -> Self {
        if self.checkpoint_every == 0 {
            self.checkpoint_every = self.epochs.max(1);
        }
        if self.eval.robots == 0 {
            self.eval.robots = defaults::EVAL_ROBOTS;
        }
        if self.eval.seconds <= 0.0 {
            self.eval.seconds = defaults::EVAL_SECONDS;
        }
        self
    }

    /// Expands the grid: terrains x w1 x w2 x replicates, in that order, each cell with its
    /// own seed. Replicate 0 of a point has the seed a grid without replicates gives it.
    pub fn cells(&self) -> Vec<CellPlan> {
        let points = self.point_count() as u64;
        let mut out = Vec::with_capacity(self.cell_count());
        let mut ordinal = 0u64;
        for (ti, terrain) in self.terrains.iter().enumerate() {
            for (i, &w1) in self.w1_values.iter().enumerate() {
                for (j, &w2) in self.w2_values.iter().enumerate() {
                    for r in 0..self.replicates.max(1) {
                        let n = ordinal + u64::from(r) * points;
                        out.push(CellPlan {
                            terrain_index: ti,
                            terrain: *terrain,
                            place: crate::Place::point(i as u32, j as u32),
                            w1,
                            w2,
                            replicate: r,
                            seed: splitmix64(self.seed.wrapping_add(n)),
                        });
                    }
                    ordinal += 1;
                }
            }
        }
        out
    }

    /// The grid's cells in the order the coordinator creates them, and so leases them (it
    /// leases the lowest queued cell id first). Under successive halving the order is a
    /// random permutation fixed by the cells' seeds: asynchronous promotion decides each rung
    /// among the cells that reached it first, so cells leased row by row would be judged
    /// against the low-w1 rows only and, on a surface that rises along w1, nearly every
    /// arrival would beat the ones before it and continue (ASHA's worst case; the search
    /// benchmark measured 59% of the grid's epochs instead of under 50% on a smooth
    /// synthetic field). Every other grid keeps grid order.
    pub fn cells_in_lease_order(&self) -> Vec<CellPlan> {
        let mut cells = self.cells();
        if matches!(self.search, Search::Asha { .. }) {
            cells.sort_by_key(|c| splitmix64(c.seed ^ 0x0A5A_0A5A_0A5A_0A5A));
        }
        cells
    }

    /// The epochs at which a cell's training is evaluated and decided on: for the grid
    /// only the last; with successive halving `min_epochs * reduction^k` below `epochs`,
    /// then `epochs`.
    pub fn rungs(&self) -> Vec<u32> {
        match self.search.halving() {
            Some((min_epochs, reduction)) => halving_rungs(min_epochs, reduction, self.epochs),
            None => vec![self.epochs],
        }
    }

    /// The epochs a search with a fixed budget is given ([`Search::budget_epochs`]): an
    /// evolutionary search's generations times what one costs (with successive halving
    /// inside a generation, its synchronous cost), a random search's points.
    pub fn budget_epochs(&self) -> Option<u64> {
        self.search.budget_epochs(
            self.epochs,
            self.replicates,
            self.terrains.len(),
            &self.rungs(),
        )
    }

    /// Successive halving's reduction factor, if this spec halves (ASHA, or an
    /// evolutionary search with rungs inside each generation).
    pub fn halving_reduction(&self) -> Option<u32> {
        self.search.halving().map(|h| h.1)
    }

    /// The (w1, w2) rectangle an evolutionary search proposes from: each axis' smallest
    /// and largest value, as `([w1_lo, w2_lo], [w1_hi, w2_hi])`.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        let (a, b) = (min_max(&self.w1_values), min_max(&self.w2_values));
        ([a.0, b.0], [a.1, b.1])
    }

    /// The cells of one generation of an evolutionary search: candidate `k` at `(w1, w2)`
    /// becomes candidate `k` of `generation`, on the first terrain, once per
    /// replicate, each with its own seed.
    pub fn candidate_cells(&self, generation: u32, candidates: &[[f64; 2]]) -> Vec<CellPlan> {
        let terrain = self.terrains.first().copied().unwrap_or(TerrainKind::Flat);
        let mut out = Vec::with_capacity(candidates.len() * self.replicates.max(1) as usize);
        for (k, c) in candidates.iter().enumerate() {
            for r in 0..self.replicates.max(1) {
                let n = (u64::from(generation) << 32) | ((k as u64) << 12) | u64::from(r);
                out.push(CellPlan {
                    terrain_index: 0,
                    terrain,
                    place: crate::Place::candidate(generation, k as u32),
                    w1: c[0],
                    w2: c[1],
                    replicate: r,
                    seed: splitmix64(self.seed.wrapping_add(n)),
                });
            }
        }
        out
    }

    /// Number of grid points (terrains x w1 x w2).
    pub fn point_count(&self) -> usize {
        self.terrains.len() * self.w1_values.len() * self.w2_values.len()
    }

    /// Number of cells: grid points times replicates.
    pub fn cell_count(&self) -> usize {
        self.point_count() * self.replicates.max(1) as usize
    }
}

/// Stores terrains by their names (`flat`, `rough`, ...).
mod terrain_names {
    use gaitsweep_model::TerrainKind;
    use serde::{de::Error as _, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &[TerrainKind], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter().map(|t| t.to_string()))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<TerrainKind>, D::Error> {
        Vec::<String>::deserialize(d)?
            .iter()
            .map(|s| {
                s.parse()
                    .map_err(|_| D::Error::custom(format!("unknown terrain {s:?}")))
            })
            .collect()
    }
}

fn one() -> u32 {
    1
}

/// Most replicates a grid point may have.
pub const MAX_REPLICATES: u32 = 32;

/// Smallest and largest of `v` (NaN-free values; (inf, -inf) when empty).
fn min_max(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        })
}

/// A well-mixed 64-bit hash, so neighbouring cells get unrelated seeds.
pub(crate) fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) >> 1 // fits in i64 for SQLite
}

#[cfg(test)]
#[path = "spec_tests.rs"]
mod tests;
