//! One seam for the search methods (issue 41): a [`SearchMethod`] decides a sweep's first
//! cells and, given a snapshot of its cells, what is due (successive-halving decisions,
//! the next generation); the store loads the snapshot, applies the actions and knows
//! nothing of the methods. Pure: no database, no clock.
//!
//! The grid, successive halving (ASHA) over the grid, the evolutionary searches (CMA-ES
//! and the genetic algorithm, each with or without halving inside its generations) and a
//! plain random search over the grid implement it over the pure functions that decide
//! ([`crate::asha`], [`crate::evolution`]). Each also describes itself
//! ([`SearchMethod::describe`]): the CLI, the report and the live page lay a sweep out
//! and name its search from that, never from the method's name.

use crate::asha::{self, AshaCell, Decision, Standing};
use crate::evolution::{self, EvolutionParams, NextStep, Optimizer};
use gaitsweep_core::spec::CellPlan;
use gaitsweep_core::{CellId, CellState, Place, ResolvedSpec, Search};
use std::collections::{BTreeMap, BTreeSet};

/// A cell as a search method sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct CellView {
    /// The cell.
    pub id: CellId,
    /// Its grid point, or its generation and number as a candidate.
    pub place: Place,
    /// Its state.
    pub state: CellState,
    /// Its final score, once scored.
    pub score: Option<f64>,
    /// Its rung evaluations: epoch -> score.
    pub rungs: BTreeMap<u32, f64>,
}

/// What a method asks the store to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// A successive-halving decision on a paused cell: on to its next rung, or stop.
    Rung(Decision),
    /// Queue new cells (an evolutionary search's next generation), each training to
    /// `target` epochs first.
    Queue {
        /// The generation they are.
        generation: u32,
        /// The cells.
        cells: Vec<CellPlan>,
        /// Epochs to train before their first decision.
        target: u32,
    },
}

/// How a sweep's cells are laid out, for the CLI, the report and the live page.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Grid points ([`Place::Point`]) index the spec's axes (a point may have no cell, as
    /// in a random search).
    Grid,
    /// Candidates ([`Place::Candidate`]) by generation, each at its own (w1, w2) inside
    /// the axes' rectangle.
    Candidates,
}

impl Layout {
    /// As the live API writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            Layout::Grid => "grid",
            Layout::Candidates => "candidates",
        }
    }
}

/// A search method in words, for the CLI, the report and the live page.
#[derive(Debug, Clone, PartialEq)]
pub struct Description {
    /// Its name as a spec writes it (`grid`, `asha`, `cmaes`, `genetic`, `random`).
    pub name: &'static str,
    /// Its name in words, for titles ("grid search", "CMA-ES", ...).
    pub title: &'static str,
    /// How its cells are laid out.
    pub layout: Layout,
    /// How it spends the sweep's epochs, in words.
    pub budget: String,
    /// Whether the epochs it will train are known in advance (every cell it queues trains
    /// to the end, or a fixed budget), so that progress can be given an ETA; successive
    /// halving over the grid decides as it goes.
    pub known_total: bool,
}

/// The description of the search a spec names ([`method_for`]).
pub fn describe(spec: &ResolvedSpec) -> Description {
    method_for(spec).describe(spec)
}

/// A search method.
pub trait SearchMethod: Send + Sync {
    /// Its name as specs, the CLI, the report and the live page spell it.
    fn name(&self) -> &'static str;
    /// Itself in words, with how its cells are laid out.
    fn describe(&self, spec: &ResolvedSpec) -> Description;
    /// The cells a new sweep starts with.
    fn initial_cells(&self, spec: &ResolvedSpec) -> Result<Vec<CellPlan>, String>;
    /// What is due now, given every cell of the sweep (in id order).
    fn react(&self, spec: &ResolvedSpec, cells: &[CellView]) -> Result<Vec<Action>, String>;
    /// Whether it ever acts after the first cells (the store skips loading the snapshot
    /// for a method that does not).
    fn reacts(&self) -> bool {
        true
    }
}

/// The method a spec names.
pub fn method_for(spec: &ResolvedSpec) -> Box<dyn SearchMethod> {
    if let Search::Random { points } = spec.search {
        return Box::new(crate::random::Random { points });
    }
    match evolution_params(spec) {
        Some(params) => Box::new(Evolutionary {
            params,
            name: spec.search.method(),
        }),
        None if spec.halving_reduction().is_some() => Box::new(Halving),
        None => Box::new(Grid),
    }
}

/// The evolutionary search's parameters for a spec, or `None` for other searches.
pub fn evolution_params(spec: &ResolvedSpec) -> Option<EvolutionParams> {
    let (population, generations) = spec.search.generations()?;
    let optimizer = match spec.search {
        Search::Cmaes { sigma, .. } => Optimizer::Cmaes { sigma },
        _ => Optimizer::genetic(&spec.w1_values, &spec.w2_values),
    };
    let (lo, hi) = spec.bounds();
    Some(EvolutionParams {
        bounds: evolution::Bounds { lo, hi },
        population: population as usize,
        optimizer,
        generations,
        seed: spec.seed,
    })
}

/// Every cell trained to the end.
struct Grid;

impl SearchMethod for Grid {
    fn name(&self) -> &'static str {
        "grid"
    }
    fn describe(&self, _: &ResolvedSpec) -> Description {
        Description {
            name: self.name(),
            title: "grid search",
            layout: Layout::Grid,
            budget: "every cell trains all its epochs".into(),
            known_total: true,
        }
    }
    fn initial_cells(&self, spec: &ResolvedSpec) -> Result<Vec<CellPlan>, String> {
        Ok(spec.cells_in_lease_order())
    }
    fn react(&self, _: &ResolvedSpec, _: &[CellView]) -> Result<Vec<Action>, String> {
        Ok(vec![])
    }
    fn reacts(&self) -> bool {
        false
    }
}

/// Successive halving over the grid, asynchronous (ASHA).
struct Halving;

impl SearchMethod for Halving {
    fn name(&self) -> &'static str {
        "asha"
    }
    fn describe(&self, spec: &ResolvedSpec) -> Description {
        let rungs: Vec<String> = spec.rungs().iter().map(u32::to_string).collect();
        Description {
            name: self.name(),
            title: "successive halving (ASHA)",
            layout: Layout::Grid,
            budget: format!(
                "successive halving (ASHA, reduction {}) with rungs at epochs {}",
                spec.halving_reduction().unwrap_or_default(),
                rungs.join(", ")
            ),
            known_total: false,
        }
    }
    fn initial_cells(&self, spec: &ResolvedSpec) -> Result<Vec<CellPlan>, String> {
        Ok(spec.cells_in_lease_order())
    }
    fn react(&self, spec: &ResolvedSpec, cells: &[CellView]) -> Result<Vec<Action>, String> {
        Ok(rung_decisions(spec, cells, false))
    }
}

/// CMA-ES or the genetic algorithm, generation after generation.
struct Evolutionary {
    params: EvolutionParams,
    name: &'static str,
}

impl SearchMethod for Evolutionary {
    fn name(&self) -> &'static str {
        self.name
    }
    fn describe(&self, _: &ResolvedSpec) -> Description {
        let (population, generations) = (self.params.population, self.params.generations);
        let (title, budget) = match self.params.optimizer {
            Optimizer::Cmaes { .. } => (
                "CMA-ES",
                format!("CMA-ES, {generations} generations of {population} candidates"),
            ),
            Optimizer::Genetic { .. } => (
                "genetic algorithm",
                format!("a genetic algorithm over the grid's points, up to {generations} generations of {population} candidates"),
            ),
        };
        Description {
            name: self.name,
            title,
            layout: Layout::Candidates,
            budget,
            known_total: true,
        }
    }
    fn initial_cells(&self, spec: &ResolvedSpec) -> Result<Vec<CellPlan>, String> {
        match evolution::next_step(&self.params, &[])? {
            NextStep::Generation(c) => Ok(spec.candidate_cells(0, &c)),
            NextStep::Done(why) => Err(format!(
                "the evolutionary search has nothing to train: {why}"
            )),
        }
    }

    /// Halving decisions inside each generation first; once no cell of the sweep is open
    /// (counting those decisions), the next generation from the stored ones.
    fn react(&self, spec: &ResolvedSpec, cells: &[CellView]) -> Result<Vec<Action>, String> {
        let mut actions = if spec.halving_reduction().is_some() {
            rung_decisions(spec, cells, true)
        } else {
            vec![]
        };
        let stopped: BTreeSet<CellId> = actions
            .iter()
            .filter_map(|a| match a {
                Action::Rung(d) if !d.continued => Some(d.cell),
                _ => None,
            })
            .collect();
        let open = cells.iter().any(|c| {
            matches!(
                c.state,
                CellState::Queued | CellState::Running | CellState::Paused
            ) && !stopped.contains(&c.id)
        });
        if open {
            return Ok(actions);
        }
        let history = self.history(spec, cells);
        if let NextStep::Generation(candidates) = evolution::next_step(&self.params, &history)? {
            let generation = history.len() as u32;
            actions.push(Action::Queue {
                generation,
                cells: spec.candidate_cells(generation, &candidates),
                target: spec.rungs()[0],
            });
        }
        Ok(actions)
    }
}

impl Evolutionary {
    /// Each stored generation's fitness per candidate: the mean of its scored replicates;
    /// with halving, a candidate stopped at a rung ranks by how far it got, then by its
    /// score there; one with neither (failed for good) ranks below its generation.
    fn history(&self, spec: &ResolvedSpec, cells: &[CellView]) -> Vec<Vec<f64>> {
        let places = || {
            cells
                .iter()
                .filter_map(|c| Some((c, c.place.generation()?)))
        };
        let generations = places().map(|(_, (g, _))| g + 1).max().unwrap_or(0) as usize;
        let mut sums = vec![vec![(0.0, 0u32); self.params.population]; generations];
        for (c, (g, k)) in places() {
            if let (Some(s), Some(slot)) = (
                c.score,
                sums.get_mut(g as usize).and_then(|g| g.get_mut(k as usize)),
            ) {
                slot.0 += s;
                slot.1 += 1;
            }
        }
        let rungs = spec.rungs();
        let halving = spec.halving_reduction().is_some();
        // The deepest rung evaluation of each candidate (the later cell on a tie).
        let mut deepest: BTreeMap<(u32, u32), (u32, CellId, usize, f64)> = BTreeMap::new();
        for (c, place) in places().filter(|_| halving) {
            for (&epoch, &score) in &c.rungs {
                let Some(depth) = rungs.iter().position(|r| *r == epoch) else {
                    continue;
                };
                let slot = deepest.entry(place).or_insert((epoch, c.id, depth, score));
                if (epoch, c.id) > (slot.0, slot.1) {
                    *slot = (epoch, c.id, depth, score);
                }
            }
        }
        let last = rungs.len() - 1;
        sums.iter()
            .enumerate()
            .map(|(g, cands)| {
                let values: Vec<Option<f64>> = cands
                    .iter()
                    .enumerate()
                    .map(|(k, (sum, n))| {
                        let fin = (*n > 0).then(|| sum / f64::from(*n));
                        if !halving {
                            return fin;
                        }
                        match fin {
                            Some(v) => Some(evolution::halving_fitness(last, v)),
                            None => deepest
                                .get(&(g as u32, k as u32))
                                .map(|(_, _, d, v)| evolution::halving_fitness(*d, *v)),
                        }
                    })
                    .collect();
                evolution::failed_fitness(&values)
            })
            .collect()
    }
}

/// The successive-halving decisions that are due ([`asha::decide`]). `per_generation`:
/// an evolutionary search halves inside each generation, its candidates
/// competing with each other, not with earlier generations, and synchronously (a rung is
/// decided once none of the generation trains): the next generation waits for the whole
/// one anyway, and the budget buys generations at synchronous halving's cost, which
/// asynchronous promotion could overrun.
fn rung_decisions(spec: &ResolvedSpec, cells: &[CellView], per_generation: bool) -> Vec<Action> {
    let Some(reduction) = spec.halving_reduction() else {
        return vec![];
    };
    let rungs = spec.rungs();
    let mut groups: BTreeMap<u32, Vec<AshaCell>> = BTreeMap::new();
    for c in cells {
        let scores = rungs[..rungs.len() - 1]
            .iter()
            .map_while(|r| c.rungs.get(r).copied())
            .collect();
        let standing = match c.state {
            CellState::Queued | CellState::Running => Standing::Training,
            CellState::Paused => Standing::Paused,
            _ => Standing::Closed,
        };
        groups
            .entry(match c.place.generation() {
                Some((g, _)) if per_generation => g,
                _ => 0,
            })
            .or_default()
            .push(AshaCell {
                cell: c.id,
                scores,
                standing,
            });
    }
    groups
        .values()
        .filter(|cells| !per_generation || asha::no_cell_training(cells))
        .flat_map(|cells| asha::decide(cells, rungs.len(), reduction))
        .map(Action::Rung)
        .collect()
}

#[cfg(test)]
#[path = "method_tests.rs"]
mod tests;
