//! The evolutionary searches, each driven as a pure function from the scores of the
//! finished generations to the next generation's candidates: CMA-ES over continuous
//! (w1, w2) (`[search] method = "cmaes"`, Hansen 2016, from the `cmaes` crate) and the
//! genetic algorithm over the spec's grid points (`method = "genetic"`, see
//! [`crate::genetic`]).
//!
//! The crate evaluates an objective function inside its own loop; a sweep's candidates are
//! trained by workers over hours. So the optimiser's state is never stored: it is rebuilt
//! by seeding the crate with the sweep's seed and replaying every finished generation with
//! its stored scores (by candidate order), then sampling once more with a placeholder
//! objective to read the next candidates. The coordinator stores the candidates as cells and
//! the scores as results, and a restarted coordinator asks for the same generation.
//!
//! CMA-ES searches the unit square; `bounds` map it onto the spec's (w1, w2) ranges. A
//! sample outside the square is trained at the nearest point inside, and CMA-ES is told
//! that point's score minus the distance it lay outside (the standard repair-and-penalty
//! treatment of box constraints), so the search distribution is pulled back inside.

use crate::genetic::{self, GaStep};
use cmaes::{CMAESOptions, DVector, Mode};
use std::cell::RefCell;
use std::rc::Rc;

/// The rectangle of (w1, w2) a search may propose: `lo[i] <= x[i] <= hi[i]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Lower corner (w1, w2).
    pub lo: [f64; 2],
    /// Upper corner (w1, w2).
    pub hi: [f64; 2],
}

impl Bounds {
    fn to_point(self, unit: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|i| self.lo[i] + unit[i].clamp(0.0, 1.0) * (self.hi[i] - self.lo[i]))
    }
}

/// Which evolutionary search proposes the candidates.
#[derive(Debug, Clone, PartialEq)]
pub enum Optimizer {
    /// CMA-ES in the bounds' rectangle.
    Cmaes {
        /// Initial step size as a fraction of each axis' range.
        sigma: f64,
    },
    /// The genetic algorithm over the grid of these values (each sorted ascending, so
    /// that one grid step is a small change of the weight).
    Genetic {
        /// The w1 values.
        w1: Vec<f64>,
        /// The w2 values.
        w2: Vec<f64>,
    },
}

impl Optimizer {
    /// The genetic algorithm over the grid of these axis values, each sorted ascending
    /// with repeats removed (a spec's `values` may come in any order).
    pub fn genetic(w1: &[f64], w2: &[f64]) -> Self {
        let sorted = |v: &[f64]| {
            let mut v = v.to_vec();
            v.sort_by(f64::total_cmp);
            v.dedup();
            v
        };
        Optimizer::Genetic {
            w1: sorted(w1),
            w2: sorted(w2),
        }
    }
}

/// What the search needs besides the scores.
#[derive(Debug, Clone, PartialEq)]
pub struct EvolutionParams {
    /// The (w1, w2) rectangle.
    pub bounds: Bounds,
    /// Candidates per generation (lambda, at least 2).
    pub population: usize,
    /// CMA-ES or the genetic algorithm.
    pub optimizer: Optimizer,
    /// Generations the epoch budget pays for.
    pub generations: u32,
    /// Seed of the optimiser.
    pub seed: u64,
}

/// What to do after the generations given.
#[derive(Debug, Clone, PartialEq)]
pub enum NextStep {
    /// Train these (w1, w2) candidates as the next generation.
    Generation(Vec<[f64; 2]>),
    /// The search is over: the budget is spent, CMA-ES met a termination criterion or the
    /// genetic algorithm has trained every grid point.
    Done(String),
}

/// Penalty per unit-square distance a sample lay outside the bounds (scores are O(1)).
const OUT_OF_BOUNDS_PENALTY: f64 = 1.0;

/// The fitness a candidate that failed for good is given: below every score of its
/// generation, so CMA-ES moves away from it.
pub fn failed_fitness(generation_scores: &[Option<f64>]) -> Vec<f64> {
    let worst = generation_scores
        .iter()
        .flatten()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let floor = if worst.is_finite() { worst - 1.0 } else { -1.0 };
    generation_scores
        .iter()
        .map(|s| s.unwrap_or(floor))
        .collect()
}

/// The fitness of a candidate that reached rung `depth` (0 = the first) of successive
/// halving with `score` there: deeper rungs rank above shallower ones whatever the scores
/// (CMA-ES uses only the ranking), scores rank within a rung.
pub fn halving_fitness(depth: usize, score: f64) -> f64 {
    10.0 * depth as f64 + score.clamp(-4.0, 4.0)
}

/// The next step of the search after `history` (one score per candidate of each finished
/// generation, in candidate order). Errors only on parameters CMA-ES refuses.
pub fn next_step(p: &EvolutionParams, history: &[Vec<f64>]) -> Result<NextStep, String> {
    if history.len() >= p.generations as usize {
        return Ok(NextStep::Done(format!(
            "the epoch budget's {} generations are done",
            p.generations
        )));
    }
    match &p.optimizer {
        Optimizer::Cmaes { sigma } => cmaes_step(p, *sigma, history),
        Optimizer::Genetic { w1, w2 } => Ok(
            match genetic::next_generation(w1.len(), w2.len(), p.population, p.seed, history) {
                GaStep::Generation(points) => {
                    NextStep::Generation(points.iter().map(|&(i, j)| [w1[i], w2[j]]).collect())
                }
                GaStep::Exhausted => NextStep::Done(format!(
                    "every one of the grid's {} points has been trained",
                    w1.len() * w2.len()
                )),
            },
        ),
    }
}

fn cmaes_step(p: &EvolutionParams, sigma: f64, history: &[Vec<f64>]) -> Result<NextStep, String> {
    // The objective answers from `history` while replaying and records the samples of the
    // generation asked for.
    struct Feed {
        history: Vec<Vec<f64>>,
        generation: usize,
        index: usize,
        asked: Vec<[f64; 2]>,
    }
    let feed = Rc::new(RefCell::new(Feed {
        history: history.to_vec(),
        generation: 0,
        index: 0,
        asked: Vec::new(),
    }));
    let f = Rc::clone(&feed);
    let bounds = p.bounds;
    let objective = move |x: &DVector<f64>| -> f64 {
        let mut f = f.borrow_mut();
        let unit = [x[0], x[1]];
        let (g, i) = (f.generation, f.index);
        f.index += 1;
        match f.history.get(g) {
            Some(scores) => {
                let outside = unit
                    .iter()
                    .map(|u| (u - u.clamp(0.0, 1.0)).powi(2))
                    .sum::<f64>()
                    .sqrt();
                scores.get(i).copied().unwrap_or(f64::MIN / 4.0) - OUT_OF_BOUNDS_PENALTY * outside
            }
            None => {
                f.asked.push(bounds.to_point(unit));
                0.0
            }
        }
    };
    let mut es = CMAESOptions::new(vec![0.5, 0.5], sigma)
        .mode(Mode::Maximize)
        .population_size(p.population)
        .seed(p.seed)
        .build(objective)
        .map_err(|e| format!("cma-es refuses the search parameters: {e:?}"))?;
    for g in 0..history.len() {
        {
            let mut f = feed.borrow_mut();
            f.generation = g;
            f.index = 0;
        }
        if let Some(end) = es.next() {
            return Ok(NextStep::Done(format!(
                "cma-es stopped after generation {g}: {:?}",
                end.reasons
            )));
        }
    }
    {
        let mut f = feed.borrow_mut();
        f.generation = history.len();
        f.index = 0;
    }
    let _ = es.next();
    let asked = std::mem::take(&mut feed.borrow_mut().asked);
    Ok(NextStep::Generation(asked))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(generations: u32) -> EvolutionParams {
        EvolutionParams {
            bounds: Bounds {
                lo: [2.0, -10.0],
                hi: [12.0, -2.0],
            },
            population: 6,
            optimizer: Optimizer::Cmaes { sigma: 0.3 },
            generations,
            seed: 7,
        }
    }

    /// A smooth score surface with its peak inside the bounds, at (9, -4).
    fn score(x: [f64; 2]) -> f64 {
        1.0 - ((x[0] - 9.0) / 10.0).powi(2) - ((x[1] + 4.0) / 8.0).powi(2)
    }

    fn run(p: &EvolutionParams) -> Vec<Vec<[f64; 2]>> {
        let mut history = Vec::new();
        let mut gens = Vec::new();
        while let NextStep::Generation(c) = next_step(p, &history).unwrap() {
            history.push(c.iter().map(|&x| score(x)).collect());
            gens.push(c);
        }
        gens
    }

    #[test]
    fn candidates_stay_inside_the_bounds_and_fill_a_generation() {
        let p = params(8);
        let gens = run(&p);
        assert_eq!(gens.len(), 8);
        for g in &gens {
            assert_eq!(g.len(), 6);
            for x in g {
                assert!(
                    (2.0..=12.0).contains(&x[0]) && (-10.0..=-2.0).contains(&x[1]),
                    "{x:?}"
                );
            }
        }
    }

    #[test]
    fn a_replay_asks_for_the_same_generation() {
        let p = params(5);
        let gens = run(&p);
        let history: Vec<Vec<f64>> = gens[..3]
            .iter()
            .map(|g| g.iter().map(|&x| score(x)).collect())
            .collect();
        assert_eq!(
            next_step(&p, &history).unwrap(),
            NextStep::Generation(gens[3].clone())
        );
    }

    #[test]
    fn the_search_closes_in_on_the_best_point() {
        let gens = run(&params(12));
        let last = gens.last().unwrap();
        let mean = [0, 1].map(|i| last.iter().map(|x| x[i]).sum::<f64>() / last.len() as f64);
        assert!(
            (mean[0] - 9.0).abs() < 1.0 && (mean[1] + 4.0).abs() < 1.0,
            "{mean:?}"
        );
        let best_first = gens[0].iter().map(|&x| score(x)).fold(f64::MIN, f64::max);
        let best_last = last.iter().map(|&x| score(x)).fold(f64::MIN, f64::max);
        assert!(
            best_last > best_first && best_last > 0.99,
            "{best_first} -> {best_last}"
        );
    }

    #[test]
    fn a_peak_on_the_edge_pulls_candidates_to_the_edge() {
        let p = params(12);
        let edge = |x: [f64; 2]| -((x[0] - 12.0) / 10.0).powi(2) - ((x[1] + 6.0) / 8.0).powi(2);
        let mut history = Vec::new();
        let mut last = vec![];
        while let NextStep::Generation(c) = next_step(&p, &history).unwrap() {
            history.push(c.iter().map(|&x| edge(x)).collect());
            last = c;
        }
        let mean_w1 = last.iter().map(|x| x[0]).sum::<f64>() / last.len() as f64;
        let best = last.iter().map(|&x| edge(x)).fold(f64::MIN, f64::max);
        assert!(mean_w1 > 10.5 && best > -0.03, "{last:?}");
        assert!(
            last.iter().any(|x| x[0] == 12.0),
            "nobody trained on the edge: {last:?}"
        );
    }

    #[test]
    fn the_budget_ends_the_search_and_failures_score_below_their_generation() {
        assert!(matches!(
            next_step(&params(0), &[]).unwrap(),
            NextStep::Done(_)
        ));
        assert_eq!(
            failed_fitness(&[Some(0.5), None, Some(-0.2)]),
            vec![0.5, -1.2, -0.2]
        );
        assert_eq!(failed_fitness(&[None, None]), vec![-1.0, -1.0]);
        assert!(next_step(
            &EvolutionParams {
                population: 1,
                ..params(3)
            },
            &[]
        )
        .is_err());
    }

    #[test]
    fn the_genetic_algorithm_proposes_grid_points_until_the_grid_is_spent() {
        let (w1, w2) = (vec![2.0, 12.0], vec![-10.0, -6.0, -2.0]);
        let p = EvolutionParams {
            population: 4,
            optimizer: Optimizer::Genetic {
                w1: w1.clone(),
                w2: w2.clone(),
            },
            ..params(10)
        };
        let mut history = Vec::new();
        let mut seen = Vec::new();
        let why = loop {
            match next_step(&p, &history).unwrap() {
                NextStep::Generation(c) => {
                    assert!(
                        c.iter().all(|x| w1.contains(&x[0]) && w2.contains(&x[1])),
                        "{c:?}"
                    );
                    history.push(c.iter().map(|&x| score(x)).collect());
                    seen.extend(c);
                }
                NextStep::Done(why) => break why,
            }
        };
        assert_eq!((history.len(), seen.len()), (2, 6), "{seen:?}");
        assert!(why.contains("6 points"), "{why}");
    }
}
