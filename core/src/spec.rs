//! The sweep spec (TOML or gRPC), its validation (every problem listed) and the grid
//! expansion into cells.

use crate::{defaults, Error, Result};
use gaitsweep_model::{ScoreVariant, TerrainKind};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

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

/// How a sweep spends its epochs, as a user writes it (`[search]`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchSpec {
    /// `grid` (every cell to the end, the default), `asha` (asynchronous successive
    /// halving), `cmaes` (CMA-ES in the axes' rectangle) or `genetic` (a genetic algorithm
    /// over the grid's points).
    pub method: String,
    /// ASHA: epochs of the first rung (default: epochs / reduction^3, at least 1).
    #[serde(default)]
    pub min_epochs: Option<u32>,
    /// ASHA: the reduction factor eta; a rung continues the top 1/eta (default 3).
    #[serde(default)]
    pub reduction: Option<u32>,
    /// CMA-ES and genetic: candidates per generation (default [`DEFAULT_POPULATION`]).
    #[serde(default)]
    pub population: Option<u32>,
    /// CMA-ES: initial step size as a fraction of each axis' range (default
    /// [`DEFAULT_SIGMA`]).
    #[serde(default)]
    pub sigma: Option<f64>,
    /// CMA-ES and genetic: training epochs over all candidates and replicates (default: a
    /// third of the epochs the full grid would train).
    #[serde(default)]
    pub budget_epochs: Option<u64>,
}

/// How a sweep spends its epochs, resolved.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "lowercase")]
pub enum Search {
    /// Every cell trains all its epochs.
    #[default]
    Grid,
    /// Asynchronous successive halving (Li et al. 2020): every cell trains to the first
    /// rung; a cell continues to the next rung only while it is in the top 1/`reduction`
    /// of the cells that reached its rung.
    Asha {
        /// Epochs of the first rung.
        min_epochs: u32,
        /// Reduction factor eta (>= 2).
        reduction: u32,
    },
    /// CMA-ES over continuous (w1, w2) inside the ranges of the spec's axes (one terrain):
    /// each generation's candidates are cells (`w1_index` = generation, `w2_index` =
    /// candidate), trained to `epochs` with the spec's replicates; the next generation is
    /// asked for once every cell of the last one has ended.
    Cmaes {
        /// Candidates per generation (lambda, >= 2).
        population: u32,
        /// Initial step size as a fraction of each axis' range.
        sigma: f64,
        /// Generations the epoch budget pays for.
        generations: u32,
        /// Successive halving inside each generation: epochs of the first rung (0: none,
        /// every candidate trains to the end).
        #[serde(default)]
        min_epochs: u32,
        /// Its reduction factor (with `min_epochs`).
        #[serde(default)]
        reduction: u32,
    },
    /// A genetic algorithm over the grid's points (one terrain), the paper's proposal for a
    /// cheaper search: candidates are grid points never trained before, bred from the best
    /// points so far; cells as for CMA-ES (`w1_index` = generation, `w2_index` = candidate).
    Genetic {
        /// Candidates per generation (>= 2, at most the grid's points).
        population: u32,
        /// Generations the epoch budget pays for (no more than the grid's points fill).
        generations: u32,
        /// Successive halving inside each generation: epochs of the first rung (0: none).
        #[serde(default)]
        min_epochs: u32,
        /// Its reduction factor (with `min_epochs`).
        #[serde(default)]
        reduction: u32,
    },
}

impl Search {
    /// The method's name, as a spec writes it.
    pub fn method(&self) -> &'static str {
        match self {
            Search::Grid => "grid",
            Search::Asha { .. } => "asha",
            Search::Cmaes { .. } => "cmaes",
            Search::Genetic { .. } => "genetic",
        }
    }

    /// Candidates per generation and generations of an evolutionary search (CMA-ES or the
    /// genetic algorithm); `None` for the grid and ASHA.
    pub fn generations(&self) -> Option<(u32, u32)> {
        match *self {
            Search::Cmaes {
                population,
                generations,
                ..
            }
            | Search::Genetic {
                population,
                generations,
                ..
            } => Some((population, generations)),
            _ => None,
        }
    }

    /// Successive halving's first rung and reduction factor: ASHA's, or those inside each
    /// generation of an evolutionary search; `None` when the search does not halve.
    pub fn halving(&self) -> Option<(u32, u32)> {
        match *self {
            Search::Asha {
                min_epochs,
                reduction,
            } => Some((min_epochs, reduction)),
            Search::Cmaes {
                min_epochs,
                reduction,
                ..
            }
            | Search::Genetic {
                min_epochs,
                reduction,
                ..
            } if min_epochs > 0 => Some((min_epochs, reduction)),
            _ => None,
        }
    }
}

/// Rungs of successive halving: `min_epochs * reduction^k` below `epochs`, then `epochs`.
fn halving_rungs(min_epochs: u32, reduction: u32, epochs: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let mut r = u64::from(min_epochs.max(1));
    while r < u64::from(epochs) {
        out.push(r as u32);
        r *= u64::from(reduction.max(2));
    }
    out.push(epochs);
    out
}

/// Epochs synchronous successive halving spends on `n` cells over `rungs` (each rung keeps
/// the top `max(1, floor(n / reduction))`): what one generation of an evolutionary search
/// with successive halving is budgeted at.
pub fn halving_cost(n: u32, rungs: &[u32], reduction: u32) -> u64 {
    let (mut alive, mut prev, mut cost) = (u64::from(n), 0u64, 0u64);
    for (k, &r) in rungs.iter().enumerate() {
        cost += alive * (u64::from(r) - prev);
        prev = u64::from(r);
        if k + 1 < rungs.len() {
            alive = (alive / u64::from(reduction.max(2))).max(1);
        }
    }
    cost
}

/// Default CMA-ES population in two dimensions (4 + floor(3 ln 2), Hansen 2016).
pub const DEFAULT_POPULATION: u32 = 6;
/// Default CMA-ES initial step size, as a fraction of each axis' range.
pub const DEFAULT_SIGMA: f64 = 0.3;

/// Default ASHA reduction factor (Li et al. 2020 use 3 or 4).
pub const DEFAULT_REDUCTION: u32 = 3;

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
    /// Robots in the evaluation rollout.
    pub eval_robots: usize,
    /// Evaluation seconds.
    pub eval_seconds: f32,
    /// Intermediate evaluations every this many epochs (0: none).
    #[serde(default)]
    pub eval_every: u32,
    /// Difficulty levels of every evaluation of a cell on rough, stairs or slopes (see
    /// [`ResolvedSpec::eval_levels_for`]); empty in specs stored before per-level
    /// evaluation, which were evaluated at one level.
    #[serde(default)]
    pub eval_levels: Vec<u8>,
    /// The progress term of the score (specs stored before the option read as Eq. 4).
    #[serde(default)]
    pub score: ScoreVariant,
    /// Search strategy (specs stored before searches existed read as the grid).
    #[serde(default)]
    pub search: Search,
    /// The finalist stage, if any (specs stored before it read as none).
    #[serde(default)]
    pub finalists: Option<crate::finalists::Finalists>,
}

/// One cell of an expanded grid.
#[derive(Debug, Clone, PartialEq)]
pub struct CellPlan {
    /// Index into the terrain list.
    pub terrain_index: usize,
    /// Terrain.
    pub terrain: TerrainKind,
    /// Row (w1 index).
    pub w1_index: usize,
    /// Column (w2 index).
    pub w2_index: usize,
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
            eval_robots: self.eval.robots.unwrap_or(defaults::EVAL_ROBOTS),
            eval_seconds: self.eval.seconds.unwrap_or(defaults::EVAL_SECONDS),
            eval_every: self.eval.every.unwrap_or(0),
            eval_levels,
            score,
            search,
            finalists,
        })
    }

    fn resolve_search(
        &self,
        epochs: u32,
        replicates: u32,
        grid_epochs: u64,
        points: usize,
        problems: &mut Vec<String>,
    ) -> Search {
        let Some(s) = &self.search else {
            return Search::Grid;
        };
        let method = s.method.trim();
        let evolutionary = matches!(method, "cmaes" | "genetic");
        if !(method == "asha" || evolutionary) && (s.min_epochs.is_some() || s.reduction.is_some())
        {
            problems.push(
                "search.min_epochs and search.reduction belong to method = \"asha\", \"cmaes\" or \"genetic\""
                    .into(),
            );
        }
        // Successive halving (method asha, or inside each generation of cmaes or genetic
        // when min_epochs or reduction is given).
        let halving = |problems: &mut Vec<String>| -> (u32, u32) {
            let reduction = s.reduction.unwrap_or(DEFAULT_REDUCTION);
            if reduction < 2 {
                problems.push(format!(
                    "search.reduction is {reduction}: use 2 or more (each rung keeps the top 1/reduction)"
                ));
            }
            let min_epochs = s
                .min_epochs
                .unwrap_or_else(|| (epochs / reduction.max(2).pow(3)).max(1));
            if min_epochs == 0 || (epochs > 0 && min_epochs >= epochs) {
                problems.push(format!(
                    "search.min_epochs is {min_epochs}: use 1 to {} (less than epochs, so there is a rung before the end)",
                    epochs.saturating_sub(1)
                ));
            }
            (min_epochs, reduction)
        };
        if !evolutionary && (s.population.is_some() || s.budget_epochs.is_some()) {
            problems.push(
                "search.population and search.budget_epochs belong to method = \"cmaes\" or \"genetic\""
                    .into(),
            );
        }
        if method != "cmaes" && s.sigma.is_some() {
            problems.push("search.sigma belongs to method = \"cmaes\"".into());
        }
        match method {
            "" | "grid" => Search::Grid,
            "cmaes" | "genetic" => {
                let population = s.population.unwrap_or(DEFAULT_POPULATION);
                if !(2..=1000).contains(&population) {
                    problems.push(format!(
                        "search.population is {population}: use 2 to 1000 candidates per generation"
                    ));
                }
                let sigma = s.sigma.unwrap_or(DEFAULT_SIGMA);
                if !(sigma.is_finite() && sigma > 0.0 && sigma <= 1.0) {
                    problems.push(format!(
                        "search.sigma is {sigma}: use a step size above 0 and at most 1 (a fraction of each axis' range)"
                    ));
                }
                let (min_epochs, reduction) = if s.min_epochs.is_some() || s.reduction.is_some() {
                    halving(problems)
                } else {
                    (0, 0)
                };
                let per_generation = if min_epochs > 0 {
                    halving_cost(
                        population,
                        &halving_rungs(min_epochs, reduction, epochs),
                        reduction,
                    )
                } else {
                    u64::from(population.max(1)) * u64::from(epochs)
                } * u64::from(replicates);
                let budget = s.budget_epochs.unwrap_or(grid_epochs / 3);
                let generations = budget / per_generation.max(1);
                if epochs > 0 && generations == 0 {
                    problems.push(format!(
                        "search.budget_epochs is {budget}: one generation of {population} candidates x {replicates} replicates needs {per_generation} epochs"
                    ));
                }
                if method == "cmaes" {
                    Search::Cmaes {
                        population,
                        sigma,
                        generations: generations.min(u64::from(u32::MAX)) as u32,
                        min_epochs,
                        reduction,
                    }
                } else {
                    // The genetic algorithm trains each grid point once: no budget buys
                    // more generations than the points fill.
                    let filled = points.div_ceil(population.max(1) as usize) as u64;
                    Search::Genetic {
                        population,
                        generations: generations.min(filled) as u32,
                        min_epochs,
                        reduction,
                    }
                }
            }
            "asha" => {
                let (min_epochs, reduction) = halving(problems);
                Search::Asha {
                    min_epochs,
                    reduction,
                }
            }
            other => {
                problems.push(format!(
                    "search.method {other:?} is unknown: use \"grid\", \"asha\", \"cmaes\" or \"genetic\""
                ));
                Search::Grid
            }
        }
    }
}

impl ResolvedSpec {
    /// The difficulty levels a cell on `terrain` is evaluated at: 0 on flat ground (which
    /// has no levels), the spec's `eval_levels` elsewhere; a spec stored before per-level
    /// evaluation keeps the one level it was scored at (its difficulty, else 5).
    pub fn eval_levels_for(&self, terrain: &str) -> Vec<u8> {
        if self.eval_levels.is_empty() {
            return vec![self.difficulty.unwrap_or(LEGACY_EVAL_LEVEL)];
        }
        match terrain.parse::<TerrainKind>() {
            Ok(TerrainKind::Flat) => vec![0],
            _ => self.eval_levels.clone(),
        }
    }

    /// Fills values that specs stored by earlier versions left at 0 ("the worker's
    /// default"), so every spec read back carries concrete values.
    pub fn with_defaults(mut self) -> Self {
        if self.checkpoint_every == 0 {
            self.checkpoint_every = self.epochs.max(1);
        }
        if self.eval_robots == 0 {
            self.eval_robots = defaults::EVAL_ROBOTS;
        }
        if self.eval_seconds <= 0.0 {
            self.eval_seconds = defaults::EVAL_SECONDS;
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
                            w1_index: i,
                            w2_index: j,
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

    /// The epochs an evolutionary search is budgeted at: its generations times what one
    /// costs (with successive halving inside a generation, its synchronous cost).
    pub fn budget_epochs(&self) -> Option<u64> {
        let (population, generations) = self.search.generations()?;
        let per = match self.search.halving() {
            Some((_, reduction)) => halving_cost(population, &self.rungs(), reduction),
            None => u64::from(population) * u64::from(self.epochs),
        };
        Some(u64::from(generations) * per * u64::from(self.replicates.max(1)))
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
    /// becomes `w1_index = generation`, `w2_index = k`, on the first terrain, once per
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
                    w1_index: generation as usize,
                    w2_index: k,
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
mod tests {
    use super::*;

    fn grid() -> PresetGrid {
        PresetGrid {
            w1: Axis::Range {
                min: 2.0,
                max: 12.0,
                count: 4,
            },
            w2: Axis::Range {
                min: -10.0,
                max: -2.0,
                count: 7,
            },
            agents_per_cell: 146,
            epochs: 3000,
        }
    }

    fn ok(_: &str) -> std::result::Result<(PresetGrid, Option<String>), String> {
        Ok((grid(), None))
    }

    #[test]
    fn asha_rungs_grow_by_the_reduction_up_to_the_budget() {
        let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
        let r = SweepSpec::from_toml(&format!(
            "{base}eval = {{ every = 50 }}\n[search]\nmethod = \"asha\"\nmin_epochs = 100\nreduction = 3\n"
        ))
        .unwrap()
        .resolve_with(ok)
        .unwrap();
        assert_eq!(
            r.search,
            Search::Asha {
                min_epochs: 100,
                reduction: 3
            }
        );
        assert_eq!(r.rungs(), vec![100, 300, 900, 2700, 3000]);
        assert_eq!(r.eval_every, 50);
        // Defaults: reduction 3, first rung at epochs / 27.
        let d = SweepSpec::from_toml(&format!("{base}[search]\nmethod = \"asha\"\n"))
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!(d.rungs(), vec![111, 333, 999, 2997, 3000]);
        // A grid has one rung, the end; a stored spec without `search` reads as a grid.
        let g = SweepSpec::from_toml(base)
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!((g.search, g.rungs()), (Search::Grid, vec![3000]));
        let mut json = serde_json::to_value(&g).unwrap();
        json.as_object_mut().unwrap().remove("search");
        json.as_object_mut().unwrap().remove("eval_every");
        let old: ResolvedSpec = serde_json::from_value(json).unwrap();
        assert_eq!((old.search, old.eval_every), (Search::Grid, 0));
        // The wire form round-trips.
        let wire = crate::pb::SweepSpec::from(&r);
        let back = SweepSpec::from(wire).resolve_with(ok).unwrap();
        assert_eq!((back.search, back.eval_every), (r.search, 50));
    }

    #[test]
    fn bad_searches_are_named() {
        let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
        let err = |extra: &str| {
            SweepSpec::from_toml(&format!("{base}{extra}"))
                .unwrap()
                .resolve_with(ok)
                .unwrap_err()
                .to_string()
        };
        assert!(
            err("[search]\nmethod = \"bayes\"\n").contains("search.method \"bayes\" is unknown")
        );
        assert!(
            err("[search]\nmethod = \"asha\"\nreduction = 1\n").contains("search.reduction is 1")
        );
        assert!(err("[search]\nmethod = \"asha\"\nmin_epochs = 3000\n")
            .contains("search.min_epochs is 3000"));
        assert!(err("seeds = 2\n[search]\nmethod = \"asha\"\n").contains("use seeds = 1"));
        assert!(err("[search]\nmethod = \"grid\"\nreduction = 3\n").contains("belong to method"));
    }

    #[test]
    fn cmaes_searches_inside_the_axes_with_a_budget_of_generations() {
        // The preset's Table-1 grid: 4 x 7 cells x 3000 epochs = 84,000 epochs.
        let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
        let parse = |extra: &str| {
            SweepSpec::from_toml(&format!("{base}{extra}"))
                .unwrap()
                .resolve_with(ok)
        };
        let d = parse("[search]\nmethod = \"cmaes\"\n").unwrap();
        // Default budget: a third of the grid's epochs, 28,000 = 1.5 generations of 6 x 3000.
        assert_eq!(
            d.search,
            Search::Cmaes {
                population: DEFAULT_POPULATION,
                sigma: DEFAULT_SIGMA,
                generations: 1,
                min_epochs: 0,
                reduction: 0
            }
        );
        let r = parse("seeds = 2\n[search]\nmethod = \"cmaes\"\npopulation = 4\nsigma = 0.2\nbudget_epochs = 72000\n")
            .unwrap();
        assert_eq!(
            r.search,
            Search::Cmaes {
                population: 4,
                sigma: 0.2,
                generations: 3,
                min_epochs: 0,
                reduction: 0
            }
        );
        let (lo, hi) = r.bounds();
        assert_eq!((lo[0], hi[0]), (2.0, 12.0));
        let cells = r.candidate_cells(2, &[[3.0, -5.0], [4.0, -6.0]]);
        assert_eq!(cells.len(), 4, "two candidates x two replicates");
        assert_eq!(
            (cells[3].w1_index, cells[3].w2_index, cells[3].replicate),
            (2, 1, 1)
        );
        assert_eq!((cells[3].w1, cells[3].w2), (4.0, -6.0));
        let seeds: std::collections::BTreeSet<u64> = cells.iter().map(|c| c.seed).collect();
        assert_eq!(seeds.len(), 4);
        // The wire form round-trips.
        let back = SweepSpec::from(crate::pb::SweepSpec::from(&r))
            .resolve_with(ok)
            .unwrap();
        assert_eq!(back.search, r.search);

        let err = |extra: &str| parse(extra).unwrap_err().to_string();
        assert!(err("[search]\nmethod = \"cmaes\"\nbudget_epochs = 100\n")
            .contains("one generation of 6 candidates x 1 replicates needs 18000 epochs"));
        // Successive halving inside each generation: rungs 100, 300, 900, 2700, 3000; a
        // generation of 6 costs 6x100 + 2x200 + 1x600 + 1x1800 + 1x300 = 3700 epochs.
        let h = parse("[search]\nmethod = \"cmaes\"\nmin_epochs = 100\nbudget_epochs = 28000\n")
            .unwrap();
        assert_eq!(h.rungs(), vec![100, 300, 900, 2700, 3000]);
        assert_eq!(halving_cost(6, &h.rungs(), 3), 3700);
        assert_eq!(
            h.search,
            Search::Cmaes {
                population: 6,
                sigma: DEFAULT_SIGMA,
                generations: 7,
                min_epochs: 100,
                reduction: 3
            }
        );
        assert_eq!(h.budget_epochs(), Some(25900));
        let back = SweepSpec::from(crate::pb::SweepSpec::from(&h))
            .resolve_with(ok)
            .unwrap();
        assert_eq!(back.search, h.search);
        assert!(
            err("seeds = 2\n[search]\nmethod = \"cmaes\"\nmin_epochs = 100\n")
                .contains("use seeds = 1")
        );
        assert!(err("[search]\nmethod = \"cmaes\"\npopulation = 1\n")
            .contains("search.population is 1"));
        assert!(err("[search]\nmethod = \"cmaes\"\nsigma = 0\n").contains("search.sigma is 0"));
        assert!(
            err("w2 = { values = [-6.0] }\n[search]\nmethod = \"cmaes\"\n")
                .contains("give w1 and w2 a range")
        );
        let two = SweepSpec::from_toml(
            "robot = \"anymal\"\nterrains = [\"flat\", \"rough\"]\npreset_grid = true\n[search]\nmethod = \"cmaes\"\n",
        )
        .unwrap()
        .resolve_with(ok)
        .unwrap_err()
        .to_string();
        assert!(two.contains("searches one terrain"), "{two}");
        assert!(err("[search]\nmethod = \"asha\"\npopulation = 6\n")
            .contains("belong to method = \"cmaes\""));
        assert!(err("[search]\nmethod = \"grid\"\nmin_epochs = 6\n")
            .contains("belong to method = \"asha\", \"cmaes\" or \"genetic\""));
    }

    /// The specs of the real search sweeps kept beside their recording resolve to the
    /// searches BENCHMARKS.md reports them with.
    #[test]
    fn the_kept_search_specs_resolve() {
        let resolve = |text: &str| {
            SweepSpec::from_toml(text)
                .unwrap()
                .resolve_with(ok)
                .unwrap()
        };
        let asha = resolve(include_str!(
            "../../tests/data/search-asha-anymal-flat-4x4-600.toml"
        ));
        assert_eq!(asha.rungs(), vec![50, 100, 200, 400, 600]);
        let cmaes = resolve(include_str!(
            "../../tests/data/search-cmaes-anymal-flat-4x4-600.toml"
        ));
        assert_eq!(
            (
                cmaes.search.method(),
                cmaes.search.generations(),
                cmaes.rungs()
            ),
            ("cmaes", Some((8, 2)), vec![100, 300, 600])
        );
        let genetic = resolve(include_str!(
            "../../tests/data/search-genetic-anymal-flat-4x4-600.toml"
        ));
        assert_eq!(
            (
                genetic.search.method(),
                genetic.search.generations(),
                genetic.rungs()
            ),
            ("genetic", Some((8, 2)), vec![100, 300, 600])
        );
        assert_eq!(genetic.budget_epochs(), Some(3000));
    }

    #[test]
    fn genetic_breeds_grid_points_with_a_budget_no_larger_than_the_grid() {
        // The 600-epoch recording's 4 x 4 grid (9,600 epochs): halving at 100 / 300 / 600
        // costs 8x100 + 2x200 + 1x300 = 1500 epochs a generation of 8, so 3200 epochs pay
        // for 2 generations; the 16 points are spent after 2 as well.
        let base = "robot = \"anymal\"\nterrains = [\"flat\"]\nepochs = 600\nagents_per_cell = 64\n\
                    w1 = { min = 2.0, max = 12.0, count = 4 }\nw2 = { min = -10.0, max = -2.0, count = 4 }\n";
        let parse = |extra: &str| {
            SweepSpec::from_toml(&format!("{base}{extra}"))
                .unwrap()
                .resolve_with(ok)
        };
        let g = parse("[search]\nmethod = \"genetic\"\npopulation = 8\nmin_epochs = 100\nreduction = 3\nbudget_epochs = 3200\n")
            .unwrap();
        let want = Search::Genetic {
            population: 8,
            generations: 2,
            min_epochs: 100,
            reduction: 3,
        };
        assert_eq!(g.search, want);
        assert_eq!(g.rungs(), vec![100, 300, 600]);
        assert_eq!(g.budget_epochs(), Some(3000));
        assert_eq!(
            (g.search.method(), g.search.generations()),
            ("genetic", Some((8, 2)))
        );
        let back = SweepSpec::from(crate::pb::SweepSpec::from(&g))
            .resolve_with(ok)
            .unwrap();
        assert_eq!(back.search, g.search);
        // A budget the size of the grid still stops when every point is trained: 16 points
        // in generations of 6 are 3 generations.
        let big = parse("[search]\nmethod = \"genetic\"\nbudget_epochs = 1000000\n").unwrap();
        assert_eq!(big.search.generations(), Some((DEFAULT_POPULATION, 3)));

        let err = |extra: &str| parse(extra).unwrap_err().to_string();
        assert!(err("[search]\nmethod = \"genetic\"\npopulation = 20\n")
            .contains("search.population is 20 but the grid has 16 points"));
        assert!(err("[search]\nmethod = \"genetic\"\nsigma = 0.3\n")
            .contains("search.sigma belongs to method = \"cmaes\""));
        assert!(
            err("seeds = 2\n[search]\nmethod = \"genetic\"\nmin_epochs = 100\n")
                .contains("use seeds = 1")
        );
        let one = SweepSpec::from_toml(
            "robot = \"anymal\"\nagents_per_cell = 64\nepochs = 600\nw1 = { values = [3.0] }\nw2 = { values = [-6.0] }\n[search]\nmethod = \"genetic\"\n",
        )
        .unwrap()
        .resolve_with(ok)
        .unwrap_err()
        .to_string();
        assert!(one.contains("at least 2 points"), "{one}");
        assert!(err("[search]\nmethod = \"evolve\"\n").contains("\"genetic\""));
    }

    #[test]
    fn preset_grid_is_one_flag_away() {
        let spec =
            SweepSpec::from_toml("robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n")
                .unwrap();
        let r = spec.resolve_with(ok).unwrap();
        assert_eq!(r.cell_count(), 28);
        assert_eq!(r.agents_per_cell, 146);
        assert!((r.w1_values[1] - 5.3333).abs() < 1e-3);
    }

    #[test]
    fn explicit_lists_and_ranges() {
        let text = r#"
            robot = "anymal"
            terrains = ["flat", "rough"]
            w1 = { min = 2.0, max = 4.0, count = 2 }
            w2 = { values = [-6.0, -4.0, -2.0] }
            agents_per_cell = 4
            epochs = 2
            checkpoint_every = 1
            seed = 9
            ppo = { learning_rate = 0.0005 }
            eval = { robots = 2, seconds = 2.0 }
        "#;
        let r = SweepSpec::from_toml(text)
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        let cells = r.cells();
        assert_eq!(cells.len(), 12);
        assert_eq!(cells[3].w2, -6.0);
        assert_eq!(cells[3].w1, 4.0);
        assert_eq!(cells[6].terrain_index, 1);
        let seeds: std::collections::BTreeSet<u64> = cells.iter().map(|c| c.seed).collect();
        assert_eq!(seeds.len(), 12);
    }

    #[test]
    fn a_score_covers_the_evaluation_levels_the_spec_resolves() {
        let base = "robot = \"anymal\"\nterrains = [\"flat\", \"rough\", \"stairs\"]\nagents_per_cell = 4\n\
                    epochs = 10\nw1 = { values = [2.0] }\nw2 = { values = [-6.0] }\n";
        let r = SweepSpec::from_toml(base)
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!(r.eval_levels, crate::defaults::EVAL_LEVELS);
        assert_eq!(r.eval_levels_for("flat"), [0]);
        assert_eq!(r.eval_levels_for("stairs"), [0, 3, 5, 7]);
        assert_eq!(r.score, ScoreVariant::Eq4);
        let given = format!("{base}eval = {{ levels = [2, 6], score = \"bounded\" }}\n");
        let r = SweepSpec::from_toml(&given)
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!(
            (r.eval_levels_for("rough"), r.score),
            (vec![2, 6], ScoreVariant::Bounded)
        );
        let fixed = format!("difficulty = 4\n{base}");
        let r = SweepSpec::from_toml(&fixed)
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!(r.eval_levels_for("rough"), [4]);
        // The task a worker gets carries the levels of its cell's terrain and the variant.
        let json = serde_json::to_value(&r).unwrap();
        let back: ResolvedSpec = serde_json::from_value(json.clone()).unwrap();
        assert_eq!(back, r);
        // A spec stored before per-level evaluation keeps its one level.
        let mut old = json;
        old.as_object_mut().unwrap().remove("eval_levels");
        old.as_object_mut().unwrap().remove("score");
        old["difficulty"] = serde_json::Value::Null;
        let old: ResolvedSpec = serde_json::from_value(old).unwrap();
        assert_eq!(old.eval_levels_for("rough"), [LEGACY_EVAL_LEVEL]);
        assert_eq!(old.score, ScoreVariant::Eq4);
        let bad = format!("{base}eval = {{ levels = [3, 12, 3], score = \"fast\" }}\n");
        let Err(Error::InvalidSpec(p)) = SweepSpec::from_toml(&bad).unwrap().resolve_with(ok)
        else {
            panic!("accepted {bad}")
        };
        let all = p.join("\n");
        for needle in [
            "eval.levels has 12",
            "lists a level twice",
            "eval.score \"fast\"",
        ] {
            assert!(all.contains(needle), "{needle} not in {all}");
        }
    }

    #[test]
    fn every_problem_is_listed() {
        let text = "robot = \"\"\nterrains = [\"lava\", \"flat\", \"flat\"]\ndifficulty = 12\nagents_per_cell = 0\nepochs = 0\nw1 = { values = [] }\n";
        let err = SweepSpec::from_toml(text)
            .unwrap()
            .resolve_with(ok)
            .unwrap_err();
        let Error::InvalidSpec(p) = err else {
            panic!("wrong error {err}")
        };
        let all = p.join("\n");
        for needle in [
            "robot is empty",
            "lava",
            "listed twice",
            "difficulty",
            "agents_per_cell is 0",
            "epochs is 0",
            "w1.values is empty",
            "w2 is missing",
        ] {
            assert!(all.contains(needle), "{needle} not in {all}");
        }
    }

    /// Fault-injection findings: a huge count ran the coordinator out of memory, and a
    /// negative w1 or a descending range were accepted without comment.
    #[test]
    fn huge_counts_descending_ranges_and_negative_w1_are_refused() {
        let text = "robot = \"anymal\"\nterrains = [\"flat\"]\nagents_per_cell = 1\nepochs = 1\n\
                    w1 = { min = -1.0, max = 2.0, count = 2 }\n\
                    w2 = { min = -2.0, max = -6.0, count = 1000000000000 }\n";
        let err = SweepSpec::from_toml(text)
            .unwrap()
            .resolve_with(ok)
            .unwrap_err();
        let all = err.to_string();
        for needle in [
            "w2.count is 1000000000000",
            "w2 runs from min -2 down to max -6",
            "w1 -1 is negative",
        ] {
            assert!(all.contains(needle), "{needle} not in {all}");
        }
    }

    /// Every default is decided when the spec is resolved: nothing reaches a worker as 0.
    #[test]
    fn defaults_are_decided_at_resolution() {
        let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
        let r = SweepSpec::from_toml(base)
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!(r.checkpoint_every, crate::defaults::CHECKPOINT_EVERY);
        assert_eq!(r.eval_robots, crate::defaults::EVAL_ROBOTS);
        assert_eq!(r.eval_seconds, crate::defaults::EVAL_SECONDS);
        let only_final = SweepSpec::from_toml(&format!("{base}checkpoint_every = 0\n"))
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!(
            only_final.checkpoint_every, 3000,
            "only the final checkpoint"
        );
        let mut old = r.clone();
        (old.checkpoint_every, old.eval_robots, old.eval_seconds) = (0, 0, 0.0);
        let old = old.with_defaults();
        assert_eq!(
            (old.checkpoint_every, old.eval_robots, old.eval_seconds),
            (
                3000,
                crate::defaults::EVAL_ROBOTS,
                crate::defaults::EVAL_SECONDS
            )
        );
    }

    #[test]
    fn unknown_keys_are_rejected() {
        assert!(matches!(
            SweepSpec::from_toml("robot = \"anymal\"\nbogus = 1\n"),
            Err(Error::SpecToml(_))
        ));
    }

    proptest::proptest! {
        #[test]
        fn grid_expansion_covers_every_pair(n1 in 1usize..6, n2 in 1usize..6, nt in 1usize..3) {
            let terrains = ["flat", "rough"][..nt].iter().map(|s| s.to_string()).collect();
            let spec = SweepSpec {
                robot: "anymal".into(), terrains,
                w1: Some(Axis::Range { min: 0.0, max: 1.0, count: n1 }),
                w2: Some(Axis::Range { min: -3.0, max: -1.0, count: n2 }),
                agents_per_cell: Some(1), epochs: Some(1), ..Default::default()
            };
            let r = spec.resolve_with(ok).unwrap();
            let cells = r.cells();
            proptest::prop_assert_eq!(cells.len(), n1 * n2 * nt);
            let pairs: std::collections::BTreeSet<(usize, usize, usize)> =
                cells.iter().map(|c| (c.terrain_index, c.w1_index, c.w2_index)).collect();
            proptest::prop_assert_eq!(pairs.len(), cells.len());
            proptest::prop_assert_eq!(cells[0].w1, 0.0);
            proptest::prop_assert_eq!(cells.last().unwrap().w2, if n2 == 1 { -3.0 } else { -1.0 });
        }
    }

    #[test]
    fn successive_halving_leases_its_grid_in_a_seeded_random_order() {
        let text = "robot = \"anymal\"\nterrains = [\"flat\"]\nw1 = { min = 2.0, max = 12.0, count = 4 }\nw2 = { min = -10.0, max = -2.0, count = 4 }\nagents_per_cell = 2\nepochs = 90\nseed = 1\n";
        let resolve = |t: &str| {
            SweepSpec::from_toml(t)
                .unwrap()
                .resolve_with(|_| Ok((grid(), None)))
                .unwrap()
        };
        let plain = resolve(text);
        assert_eq!(plain.cells_in_lease_order(), plain.cells());
        let asha = resolve(&format!(
            "{text}[search]\nmethod = \"asha\"\nmin_epochs = 10\n"
        ));
        let (grid_order, lease) = (asha.cells(), asha.cells_in_lease_order());
        assert_ne!(lease, grid_order, "a 4 x 4 grid is not leased row by row");
        // The same cells with the same seeds, only in another order, and the same order on
        // every call.
        let mut sorted = lease.clone();
        sorted.sort_by_key(|c| (c.w1_index, c.w2_index));
        assert_eq!(sorted, grid_order);
        assert_eq!(asha.cells_in_lease_order(), lease);
        // The first four leased are not all of one row.
        let rows: std::collections::BTreeSet<usize> =
            lease[..4].iter().map(|c| c.w1_index).collect();
        assert!(rows.len() > 1, "{rows:?}");
    }

    #[test]
    fn replicates_multiply_the_cells_and_keep_replicate_zero_seeds() {
        let text = "robot = \"anymal\"\nterrains = [\"flat\"]\nw1 = { values = [2.0, 8.0] }\nw2 = { values = [-6.0] }\nagents_per_cell = 2\nepochs = 3\nseed = 5\n";
        let one = SweepSpec::from_toml(text)
            .unwrap()
            .resolve_with(|_| Ok((grid(), None)))
            .unwrap();
        let three = SweepSpec::from_toml(&format!("{text}seeds = 3\n"))
            .unwrap()
            .resolve_with(|_| Ok((grid(), None)))
            .unwrap();
        assert_eq!((one.replicates, three.replicates), (1, 3));
        let (a, b) = (one.cells(), three.cells());
        assert_eq!(
            (a.len(), b.len(), three.cell_count(), three.point_count()),
            (2, 6, 6, 2)
        );
        for p in &a {
            let r0 = b
                .iter()
                .find(|c| c.w1_index == p.w1_index && c.replicate == 0)
                .unwrap();
            assert_eq!(
                r0.seed, p.seed,
                "replicate 0 trains as the cell did without replicates"
            );
        }
        let seeds: std::collections::BTreeSet<u64> = b.iter().map(|c| c.seed).collect();
        assert_eq!(seeds.len(), 6);
        for bad in ["seeds = 0", "seeds = 33"] {
            let e = SweepSpec::from_toml(&format!("{text}{bad}\n"))
                .unwrap()
                .resolve_with(|_| Ok((grid(), None)))
                .unwrap_err()
                .to_string();
            assert!(e.contains("replicates per grid point"), "{e}");
        }
        // A spec stored before replicates existed reads as one replicate.
        let mut json = serde_json::to_value(&one).unwrap();
        json.as_object_mut().unwrap().remove("replicates");
        let old: ResolvedSpec = serde_json::from_value(json).unwrap();
        assert_eq!(old.replicates, 1);
    }
}
