//! The genetic algorithm over the spec's grid points (`[search] method = "genetic"`): the
//! paper's own proposal for a cheaper search ("it may be efficient to apply a genetic
//! algorithm based on the score function", Kim et al. 2024, section 5). A candidate is a
//! grid point, its two genes the indices of its w1 and w2 values; a point is trained at
//! most once, so every generation spends its epochs on points nobody has scored yet.
//!
//! Like [`crate::evolution`]'s CMA-ES the search is a pure function of the sweep's seed and
//! the scores of the finished generations: generation 0 is drawn from the seed, and each
//! later one is bred from every scored point so far, replayed in order, so a restarted
//! coordinator asks for the same generation. The random numbers are ChaCha8's, whose stream
//! `rand_chacha` documents as reproducible across versions and platforms.
//!
//! Breeding (a steady-state GA with the whole scored population as the mating pool):
//! each child takes each gene from one of two parents, each parent the better of two
//! points drawn at random (binary tournament); each gene then moves one grid step up or
//! down with probability 1/2 (mutation rate 1/genes, the usual default); a child that lands
//! on a point already scored or already in its generation is replaced by the nearest free
//! point (Chebyshev distance in grid steps, ties drawn at random). No crate is used: the
//! maintained GA crates (`genevo`, `oxigen`) own the evaluation loop and the population,
//! which a sweep whose evaluations take hours on other machines cannot hand them, and the
//! operators here are a few lines.

use rand::seq::IndexedRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeSet;

/// Points drawn per parent selection: 3 gives the best of 5 scored points about half the
/// matings (`1 - (4/5)^3`) while still letting the rest breed.
const TOURNAMENT: usize = 3;

/// A grid point as (w1 index, w2 index).
pub type Point = (usize, usize);

/// What to do after the generations given (grid indices).
#[derive(Debug, Clone, PartialEq)]
pub enum GaStep {
    /// Train these points as the next generation.
    Generation(Vec<Point>),
    /// Every grid point has been scored: nothing is left to search.
    Exhausted,
}

/// The next generation of the genetic algorithm on an `n1 x n2` grid after `history` (one
/// fitness per candidate of each finished generation, in candidate order; entries beyond a
/// generation's size are ignored). At most `population` points, fewer when fewer are free.
pub fn next_generation(
    n1: usize,
    n2: usize,
    population: usize,
    seed: u64,
    history: &[Vec<f64>],
) -> GaStep {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6a09_e667_f3bc_c908);
    let mut scored: Vec<(Point, f64)> = Vec::new();
    let mut generation = first(n1, n2, population, &mut rng);
    for fitness in history {
        scored.extend(generation.iter().copied().zip(fitness.iter().copied()));
        generation = breed(n1, n2, population, &scored, &mut rng);
    }
    if generation.is_empty() {
        GaStep::Exhausted
    } else {
        GaStep::Generation(generation)
    }
}

fn first(n1: usize, n2: usize, population: usize, rng: &mut ChaCha8Rng) -> Vec<Point> {
    let all: Vec<Point> = (0..n1).flat_map(|i| (0..n2).map(move |j| (i, j))).collect();
    all.choose_multiple(rng, population.min(all.len()))
        .copied()
        .collect()
}

fn breed(
    n1: usize,
    n2: usize,
    population: usize,
    scored: &[(Point, f64)],
    rng: &mut ChaCha8Rng,
) -> Vec<Point> {
    let mut taken: BTreeSet<Point> = scored.iter().map(|s| s.0).collect();
    let mut out = Vec::new();
    while out.len() < population && taken.len() < n1 * n2 {
        let a = tournament(scored, rng);
        let b = tournament(scored, rng);
        let mut child = (
            if rng.random_bool(0.5) { a.0 } else { b.0 },
            if rng.random_bool(0.5) { a.1 } else { b.1 },
        );
        child.0 = mutate(child.0, n1, rng);
        child.1 = mutate(child.1, n2, rng);
        let child = if taken.contains(&child) {
            nearest_free(child, n1, n2, &taken, rng)
        } else {
            child
        };
        taken.insert(child);
        out.push(child);
    }
    out
}

/// The best of [`TOURNAMENT`] scored points drawn at random (the first drawn on a tie).
fn tournament(scored: &[(Point, f64)], rng: &mut ChaCha8Rng) -> Point {
    let mut best = scored[rng.random_range(0..scored.len())];
    for _ in 1..TOURNAMENT {
        let x = scored[rng.random_range(0..scored.len())];
        if x.1 > best.1 {
            best = x;
        }
    }
    best.0
}

/// One grid step up or down with probability 1/2, inside `0..n`.
fn mutate(gene: usize, n: usize, rng: &mut ChaCha8Rng) -> usize {
    if n < 2 || !rng.random_bool(0.5) {
        return gene;
    }
    if gene == 0 {
        1
    } else if gene + 1 == n || rng.random_bool(0.5) {
        gene - 1
    } else {
        gene + 1
    }
}

/// The free point nearest `p` in grid steps (Chebyshev), ties drawn at random; the caller
/// guarantees one is free.
fn nearest_free(
    p: Point,
    n1: usize,
    n2: usize,
    taken: &BTreeSet<Point>,
    rng: &mut ChaCha8Rng,
) -> Point {
    let free: Vec<(usize, Point)> = (0..n1)
        .flat_map(|i| (0..n2).map(move |j| (i, j)))
        .filter(|q| !taken.contains(q))
        .map(|q| (p.0.abs_diff(q.0).max(p.1.abs_diff(q.1)), q))
        .collect();
    let d = free.iter().map(|f| f.0).min().expect("a free point");
    let ties: Vec<Point> = free.iter().filter(|f| f.0 == d).map(|f| f.1).collect();
    *ties.choose(rng).expect("a free point")
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A surface on a 4 x 7 grid (the paper's ANYmal grid) with its peak at (3, 5).
    fn score(p: Point) -> f64 {
        -((p.0 as f64 - 3.0).powi(2)) - ((p.1 as f64 - 5.0) / 2.0).powi(2)
    }

    fn run(
        n1: usize,
        n2: usize,
        population: usize,
        seed: u64,
        generations: usize,
    ) -> Vec<Vec<Point>> {
        let mut history = Vec::new();
        let mut gens = Vec::new();
        while gens.len() < generations {
            match next_generation(n1, n2, population, seed, &history) {
                GaStep::Generation(g) => {
                    history.push(g.iter().map(|&p| score(p)).collect());
                    gens.push(g);
                }
                GaStep::Exhausted => break,
            }
        }
        gens
    }

    #[test]
    fn a_replay_asks_for_the_same_generation() {
        let gens = run(4, 7, 5, 11, 4);
        let history: Vec<Vec<f64>> = gens[..2]
            .iter()
            .map(|g| g.iter().map(|&p| score(p)).collect())
            .collect();
        assert_eq!(
            next_generation(4, 7, 5, 11, &history),
            GaStep::Generation(gens[2].clone())
        );
    }

    #[test]
    fn children_gather_around_the_best_points() {
        // Over 200 seeds, the second generation lies nearer the peak than points drawn
        // uniformly from those not yet trained would (the expectation of such a draw is
        // the mean distance of the free points).
        let dist = |p: &Point| p.0.abs_diff(3).max(p.1.abs_diff(5)) as f64;
        let (mut uniform, mut bred) = (0.0, 0.0);
        for seed in 0..200 {
            let gens = run(4, 7, 5, seed, 2);
            let free: Vec<Point> = (0..4)
                .flat_map(|i| (0..7).map(move |j| (i, j)))
                .filter(|p| !gens[0].contains(p))
                .collect();
            uniform += free.iter().map(dist).sum::<f64>() / free.len() as f64;
            bred += gens[1].iter().map(dist).sum::<f64>() / gens[1].len() as f64;
        }
        let (uniform, bred) = (uniform / 200.0, bred / 200.0);
        assert!(
            bred < 0.85 * uniform,
            "mean distance to the peak: uniform {uniform:.3}, bred {bred:.3}"
        );
    }

    proptest! {
        #[test]
        fn every_point_is_trained_once_and_the_grid_runs_out(
            n1 in 1usize..6,
            n2 in 1usize..8,
            population in 1usize..10,
            seed in any::<u64>(),
        ) {
            let gens = run(n1, n2, population, seed, 1000);
            let all: Vec<Point> = gens.iter().flatten().copied().collect();
            let distinct: BTreeSet<Point> = all.iter().copied().collect();
            prop_assert_eq!(distinct.len(), all.len(), "a point trained twice");
            prop_assert_eq!(all.len(), n1 * n2, "the grid is not exhausted");
            prop_assert!(all.iter().all(|p| p.0 < n1 && p.1 < n2));
            for g in &gens[..gens.len() - 1] {
                prop_assert_eq!(g.len(), population.min(n1 * n2));
            }
        }
    }
}
