//! How a sweep spends its epochs: the `[search]` section as written, its resolved form
//! (grid, asynchronous successive halving, CMA-ES, genetic, random), its validation and the
//! successive-halving rungs and costs.

use crate::spec::SweepSpec;
use serde::{Deserialize, Serialize};

/// How a sweep spends its epochs, as a user writes it (`[search]`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchSpec {
    /// `grid` (every cell to the end, the default), `asha` (asynchronous successive
    /// halving), `cmaes` (CMA-ES in the axes' rectangle), `genetic` (a genetic algorithm
    /// over the grid's points) or `random` (grid points drawn at random).
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
    /// CMA-ES, genetic and random: training epochs over all candidates (random: points,
    /// on every terrain) and replicates (default: a third of the epochs the full grid would
    /// train).
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
    /// each generation's candidates are cells ([`crate::Place::Candidate`]), trained to `epochs` with the spec's replicates; the next generation is
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
    /// points so far; cells as for CMA-ES.
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
    /// A plain random search over the grid: `points` grid points drawn from the sweep's
    /// seed, each trained as the grid would (every terrain, every replicate, to the end).
    Random {
        /// Grid points drawn (1 to the grid's points).
        points: u32,
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
            Search::Random { .. } => "random",
        }
    }

    /// The epochs a search with a fixed budget trains in all, given the spec's epochs,
    /// replicates, terrains and rungs; `None` for the grid (its cells tell) and ASHA (it
    /// decides as it goes).
    pub fn budget_epochs(
        &self,
        epochs: u32,
        replicates: u32,
        terrains: usize,
        rungs: &[u32],
    ) -> Option<u64> {
        let replicates = u64::from(replicates.max(1));
        if let Search::Random { points } = *self {
            return Some(
                u64::from(points) * u64::from(epochs) * replicates * terrains.max(1) as u64,
            );
        }
        let (population, generations) = self.generations()?;
        let per = match self.halving() {
            Some((_, reduction)) => halving_cost(population, rungs, reduction),
            None => u64::from(population) * u64::from(epochs),
        };
        Some(u64::from(generations) * per * replicates)
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
pub(crate) fn halving_rungs(min_epochs: u32, reduction: u32, epochs: u32) -> Vec<u32> {
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

impl SweepSpec {
    pub(crate) fn resolve_search(
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
        if !evolutionary && s.population.is_some() {
            problems.push("search.population belongs to method = \"cmaes\" or \"genetic\"".into());
        }
        if !(evolutionary || method == "random") && s.budget_epochs.is_some() {
            problems.push(
                "search.budget_epochs belongs to method = \"cmaes\", \"genetic\" or \"random\""
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
            "random" => {
                // Every drawn point trains as the grid would: on every terrain, with every
                // replicate, to the end.
                let per_point = grid_epochs / points.max(1) as u64;
                let budget = s.budget_epochs.unwrap_or(grid_epochs / 3);
                let drawn = budget / per_point.max(1);
                if epochs > 0 && (drawn == 0 || drawn > points as u64) {
                    problems.push(format!(
                        "search.budget_epochs is {budget}: a random search trains {per_point} epochs per grid point (every terrain and replicate); use {per_point} to {grid_epochs} for 1 to {points} points"
                    ));
                }
                Search::Random {
                    points: drawn.clamp(1, points.max(1) as u64) as u32,
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
                    "search.method {other:?} is unknown: use \"grid\", \"asha\", \"cmaes\", \"genetic\" or \"random\""
                ));
                Search::Grid
            }
        }
    }
}
