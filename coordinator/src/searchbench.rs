//! The offline search benchmark: replays search strategies over a recorded full-grid sweep
//! (every replicate's final score and its evaluations at intermediate epochs), many times
//! with different arrival orders and replicate draws, and measures what each strategy
//! spends and finds against the grid's own answer. Pure: the caller loads the recording
//! (`search-bench export` writes one from a coordinator's database).
//!
//! - **Grid**: every point trained to the end; its answer (the best point mean of the
//!   final scores) is the reference.
//! - **Grid, one run per point**: every point trained to the end once, one recorded
//!   replicate drawn per point; the best drawn score is the answer. What a single-seed
//!   grid finds on this data, the bar a search with one run per candidate can reach.
//! - **Random search**: a number of grid points drawn at random, each trained to the end
//!   once (one recorded replicate drawn); the best drawn score is the answer. The
//!   baseline, at the evolutionary searches' budget.
//! - **ASHA**: every replay draws one recorded replicate per point (the noise a single run
//!   has) and runs the points as cells in a random order (the coordinator creates a halving
//!   sweep's cells in a seeded random order) on `workers` simulated workers that lease the
//!   lowest queued cell first, as the coordinator does (so a continued cell goes before the
//!   cells still waiting for their first rung), with [`gaitsweep_search::asha::decide`], the function
//!   the coordinator uses; workers' speeds are jittered so that arrivals interleave. A cell's rung score
//!   is its replicate's evaluation at the rung epoch. The answer is the best final score
//!   among the cells trained to the end.
//! - **CMA-ES**: [`gaitsweep_search::evolution::next_step`] over the axes' rectangle with the replay's
//!   seed and the coordinator's generation count for the budget. A candidate's run is the
//!   surface of point means, interpolated bilinearly in (w1, w2) between the four
//!   surrounding grid points, plus one run's noise: the deviation of a replicate drawn at
//!   the nearest grid point from that point's mean (a fresh draw per candidate; at a grid
//!   point this is exactly the drawn replicate). With halving, each generation's candidates
//!   are halved synchronously among themselves on the simulated workers, as the
//!   coordinator does, and ranked by how far they got, then by their score there; the
//!   epochs counted are those trained. Its answer is the candidate trained to the end with
//!   the best observed score; its true value is the interpolation of the point means.
//!
//! - **Genetic algorithm**: [`gaitsweep_search::evolution::next_step`] with the genetic algorithm over
//!   the grid's points ([`gaitsweep_search::genetic`]), budgeted and halved as CMA-ES is. Its
//!   candidates are grid points, so a candidate's run is a replicate drawn at its point and
//!   no interpolation is involved.
//!
//! A replay *finds the best* when its answer's nearest grid point is the grid's best point,
//! and is *within 5%* when the answer's true value is at least the best mean minus 5% of
//! its magnitude. Regret is the best mean minus the answer's true value.

use gaitsweep_core::CellId;
use gaitsweep_search::asha::{self, AshaCell, Standing};
use gaitsweep_search::evolution::{self, Bounds, EvolutionParams, NextStep, Optimizer};
use gaitsweep_search::random::random_points;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};

/// One recorded training run (a replicate of a grid point).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedRun {
    /// Its seed.
    pub seed: u64,
    /// The gait score at the full budget.
    pub score: f64,
    /// Gait scores of its intermediate evaluations, by epoch.
    pub evals: BTreeMap<u32, f64>,
    /// How its final policy walked (exports since session 47 carry it; the replays ignore it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gait: Option<RecordedGait>,
}

/// How a recorded run's final policy walked in its final evaluation: what says whether a
/// score is a gait (the falls and the tracking), beside the score.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedGait {
    /// Fraction of the evaluation robots that fell (mean over the levels).
    pub fall_rate: f64,
    /// Mean |v_cmd - v| (m/s, mean over the levels).
    pub mean_vel_error: f64,
    /// Mean speed (m/s); absent where the database predates it.
    pub mean_speed: Option<f64>,
    /// Mean of max(0, |v| - |v_cmd|) (m/s); absent where the database predates it.
    pub overspeed: Option<f64>,
    /// The same at each evaluation level, by level.
    pub levels: Vec<RecordedLevel>,
}

/// One evaluation level of a [`RecordedGait`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedLevel {
    /// Terrain difficulty level.
    pub level: u32,
    /// Gait score at that level.
    pub score: f64,
    /// Fraction of robots that fell.
    pub fall_rate: f64,
    /// Mean |v_cmd - v| (m/s).
    pub mean_vel_error: f64,
    /// Mean speed (m/s).
    pub mean_speed: f64,
    /// Mean of max(0, |v| - |v_cmd|) (m/s).
    pub overspeed: f64,
}

/// One grid point and its replicates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedPoint {
    /// Row.
    pub w1_index: usize,
    /// Column.
    pub w2_index: usize,
    /// Every replicate that has a final score.
    pub runs: Vec<RecordedRun>,
}

/// A recorded full-grid sweep (one terrain).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Recording {
    /// Where it came from (sweep name, machine, command).
    pub source: String,
    /// Terrain.
    pub terrain: String,
    /// Epochs of every run.
    pub epochs: u32,
    /// w1 values (rows), ascending.
    pub w1_values: Vec<f64>,
    /// w2 values (columns), ascending.
    pub w2_values: Vec<f64>,
    /// Every point of the grid.
    pub points: Vec<RecordedPoint>,
    /// The spec the sweep ran with, as the coordinator stored it (exports since session 47).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec: Option<gaitsweep_core::ResolvedSpec>,
}

impl Recording {
    /// Checks that every point has a run and the axes ascend; names what is missing.
    pub fn validate(&self) -> Result<(), String> {
        let ascending = |v: &[f64]| v.windows(2).all(|w| w[0] < w[1]) && !v.is_empty();
        if !ascending(&self.w1_values) || !ascending(&self.w2_values) {
            return Err("the recording's w1 and w2 values must be non-empty and ascending".into());
        }
        for i in 0..self.w1_values.len() {
            for j in 0..self.w2_values.len() {
                if self.point(i, j).is_none_or(|p| p.runs.is_empty()) {
                    return Err(format!(
                        "grid point (w1 {}, w2 {}) has no scored run: record a full grid",
                        self.w1_values[i], self.w2_values[j]
                    ));
                }
            }
        }
        Ok(())
    }

    fn point(&self, i: usize, j: usize) -> Option<&RecordedPoint> {
        self.points
            .iter()
            .find(|p| (p.w1_index, p.w2_index) == (i, j))
    }

    fn mean(&self, i: usize, j: usize) -> f64 {
        let p = self.point(i, j).expect("validated");
        p.runs.iter().map(|r| r.score).sum::<f64>() / p.runs.len() as f64
    }

    /// The grid's answer: the best point mean and its point.
    pub fn best(&self) -> ((usize, usize), f64) {
        let mut best = ((0, 0), f64::NEG_INFINITY);
        for i in 0..self.w1_values.len() {
            for j in 0..self.w2_values.len() {
                let m = self.mean(i, j);
                if m > best.1 {
                    best = ((i, j), m);
                }
            }
        }
        best
    }

    /// Epochs a full grid with one run per point trains.
    pub fn grid_epochs(&self) -> u64 {
        (self.w1_values.len() * self.w2_values.len()) as u64 * u64::from(self.epochs)
    }

    /// Epochs at which every run has an evaluation.
    pub fn common_eval_epochs(&self) -> Vec<u32> {
        let mut common: Option<Vec<u32>> = None;
        for r in self.points.iter().flat_map(|p| &p.runs) {
            let e: Vec<u32> = r.evals.keys().copied().collect();
            common = Some(match common {
                None => e,
                Some(c) => c.into_iter().filter(|x| e.contains(x)).collect(),
            });
        }
        common.unwrap_or_default()
    }

    /// Bilinear interpolation at (w1, w2) of `f(i, j)` over the grid.
    fn interpolate(&self, w1: f64, w2: f64, f: &mut impl FnMut(usize, usize) -> f64) -> f64 {
        let (i0, i1, a) = bracket(&self.w1_values, w1);
        let (j0, j1, b) = bracket(&self.w2_values, w2);
        (1.0 - a) * ((1.0 - b) * f(i0, j0) + b * f(i0, j1))
            + a * ((1.0 - b) * f(i1, j0) + b * f(i1, j1))
    }

    fn nearest(&self, w1: f64, w2: f64) -> (usize, usize) {
        let near = |v: &[f64], x: f64| {
            (0..v.len())
                .min_by(|&a, &b| (v[a] - x).abs().total_cmp(&(v[b] - x).abs()))
                .unwrap_or(0)
        };
        (near(&self.w1_values, w1), near(&self.w2_values, w2))
    }
}

/// The two grid indices around `x` and the weight of the upper one.
fn bracket(v: &[f64], x: f64) -> (usize, usize, f64) {
    if v.len() == 1 || x <= v[0] {
        return (0, 0, 0.0);
    }
    for k in 0..v.len() - 1 {
        if x <= v[k + 1] {
            return (k, k + 1, (x - v[k]) / (v[k + 1] - v[k]));
        }
    }
    (v.len() - 1, v.len() - 1, 0.0)
}

/// What one replay found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Replay {
    /// Epochs trained, as a fraction of the full grid's (one run per point).
    pub epoch_fraction: f64,
    /// Grid best mean minus the true value of the answer.
    pub regret: f64,
    /// The answer's nearest grid point is the grid's best.
    pub found_best: bool,
    /// The answer's true value is within 5% of the grid's best mean.
    pub within_5pct: bool,
}

fn judge(rec: &Recording, epochs: u64, truth: f64, near: (usize, usize)) -> Replay {
    let (best_point, best) = rec.best();
    Replay {
        epoch_fraction: epochs as f64 / rec.grid_epochs() as f64,
        regret: best - truth,
        found_best: near == best_point,
        within_5pct: truth >= best - 0.05 * best.abs(),
    }
}

/// One replay of the grid with a single run per point (`seed` draws which recorded
/// replicate is that run): every point trained to the end, the best drawn score is the
/// answer. The reference a search with one run per candidate is measured against: on noisy
/// data even the full grid finds the best point only as often as its one run lets it.
pub fn replay_grid_single(rec: &Recording, seed: u64) -> Result<Replay, String> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut answer: Option<((usize, usize), f64)> = None;
    for i in 0..rec.w1_values.len() {
        for j in 0..rec.w2_values.len() {
            let p = rec.point(i, j).ok_or("unvalidated recording")?;
            let score = p.runs[rng.random_range(0..p.runs.len())].score;
            if answer.is_none_or(|(_, best)| score > best) {
                answer = Some(((i, j), score));
            }
        }
    }
    let ((i, j), _) = answer.ok_or("empty recording")?;
    Ok(judge(rec, rec.grid_epochs(), rec.mean(i, j), (i, j)))
}

/// One replay of a random search over the grid: `points` grid points drawn without
/// replacement (with `seed`), each trained to the end once with one recorded replicate
/// drawn; the best drawn score is the answer (the points are the coordinator's
/// `method = "random"` draw for the same seed). The baseline every other strategy should
/// beat at the same share of the grid's epochs (Bergstra and Bengio 2012 found random
/// search a strong one on low-dimensional spaces).
pub fn replay_random(rec: &Recording, points: usize, seed: u64) -> Result<Replay, String> {
    let grid = rec.w1_values.len() * rec.w2_values.len();
    if points == 0 || points > grid {
        return Err(format!(
            "a random search of {points} points over a grid of {grid}: use 1 to {grid}"
        ));
    }
    // The coordinator's draw (`method = "random"` with this seed); which recorded run
    // stands for a point is the replay's own draw.
    let drawn = random_points(rec.w1_values.len(), rec.w2_values.len(), points, seed);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut answer: Option<((usize, usize), f64)> = None;
    for &(i, j) in &drawn {
        let p = rec.point(i, j).ok_or("unvalidated recording")?;
        let score = p.runs[rng.random_range(0..p.runs.len())].score;
        if answer.is_none_or(|(_, best)| score > best) {
            answer = Some(((i, j), score));
        }
    }
    let ((i, j), _) = answer.ok_or("empty recording")?;
    let epochs = points as u64 * u64::from(rec.epochs);
    Ok(judge(rec, epochs, rec.mean(i, j), (i, j)))
}

/// Successive halving settings of a replay.
#[derive(Debug, Clone, Copy)]
pub struct AshaSetup {
    /// First rung, epochs.
    pub min_epochs: u32,
    /// Reduction factor.
    pub reduction: u32,
    /// Simulated workers (one cell each at a time).
    pub workers: usize,
}

/// The rungs successive halving uses on this recording, or why it cannot.
pub fn asha_rungs(rec: &Recording, s: &AshaSetup) -> Result<Vec<u32>, String> {
    let mut rungs = Vec::new();
    let mut r = u64::from(s.min_epochs.max(1));
    while r < u64::from(rec.epochs) {
        rungs.push(r as u32);
        r *= u64::from(s.reduction.max(2));
    }
    let have = rec.common_eval_epochs();
    if let Some(missing) = rungs.iter().find(|r| !have.contains(r)) {
        return Err(format!(
            "rung at epoch {missing} has no recorded evaluation in every run; recorded: {have:?}"
        ));
    }
    rungs.push(rec.epochs);
    Ok(rungs)
}

/// Asynchronous successive halving of `values.len()` cells as the coordinator runs it:
/// `workers` simulated workers (one cell each, the same speed with a random jitter so that
/// arrivals interleave as on a real cluster) lease the queued cell with the lowest index
/// first (the coordinator leases the lowest cell id, so a continued cell goes before the
/// cells still waiting for their first rung), and [`gaitsweep_search::asha::decide`] continues or stops
/// each cell at each rung. `values[c][k]` is cell `c`'s score at `rungs[k]` (the last one
/// its final score). With `synchronous` a rung is decided only while no cell trains, as
/// the coordinator does inside an evolutionary search's generation. Returns the index of
/// the deepest rung each cell trained to and the epochs trained.
fn simulate_halving(
    values: &[Vec<f64>],
    rungs: &[u32],
    reduction: u32,
    workers: usize,
    synchronous: bool,
    rng: &mut StdRng,
) -> (Vec<usize>, u64) {
    let last = rungs.len() - 1;
    let n = values.len();
    let mut target = vec![0usize; n];
    let mut trained = vec![0u32; n];
    let mut depth = vec![0usize; n];
    let mut scores: Vec<Vec<f64>> = vec![vec![]; n];
    let mut standing = vec![Standing::Training; n];
    let mut queue: BTreeSet<usize> = (0..n).collect();
    let mut busy: Vec<(f64, usize)> = Vec::new();
    let mut now = 0.0;
    let mut epochs = 0u64;
    loop {
        while busy.len() < workers.max(1) {
            let Some(c) = queue.pop_first() else { break };
            let work = f64::from(rungs[target[c]] - trained[c]);
            busy.push((now + work * rng.random_range(0.8..1.25), c));
        }
        let Some(k) = (0..busy.len()).min_by(|&a, &b| busy[a].0.total_cmp(&busy[b].0)) else {
            break;
        };
        let (t, c) = busy.swap_remove(k);
        now = t;
        epochs += u64::from(rungs[target[c]] - trained[c]);
        trained[c] = rungs[target[c]];
        depth[c] = target[c];
        if target[c] == last {
            standing[c] = Standing::Closed;
        } else {
            scores[c].push(values[c][target[c]]);
            standing[c] = Standing::Paused;
        }
        let view: Vec<AshaCell> = (0..n)
            .map(|x| AshaCell {
                cell: CellId(x as i64),
                scores: scores[x].clone(),
                standing: standing[x],
            })
            .collect();
        let due = if synchronous && !asha::no_cell_training(&view) {
            vec![]
        } else {
            asha::decide(&view, rungs.len(), reduction)
        };
        for d in due {
            let x = d.cell.0 as usize;
            if d.continued {
                target[x] = d.rung + 1;
                standing[x] = Standing::Training;
                queue.insert(x);
            } else {
                standing[x] = Standing::Closed;
            }
        }
    }
    (depth, epochs)
}

/// One ASHA replay with `seed`: one recorded replicate drawn per point, the points as
/// cells in a random lease order.
pub fn replay_asha(rec: &Recording, s: &AshaSetup, seed: u64) -> Result<Replay, String> {
    let rungs = asha_rungs(rec, s)?;
    let last = rungs.len() - 1;
    let mut rng = StdRng::seed_from_u64(seed);
    let mut cells: Vec<((usize, usize), Vec<f64>)> = Vec::new();
    for i in 0..rec.w1_values.len() {
        for j in 0..rec.w2_values.len() {
            let p = rec.point(i, j).ok_or("unvalidated recording")?;
            let run = &p.runs[rng.random_range(0..p.runs.len())];
            let v = rungs[..last]
                .iter()
                .map(|r| run.evals.get(r).copied().ok_or("missing evaluation"))
                .chain(std::iter::once(Ok(run.score)))
                .collect::<Result<Vec<f64>, _>>()?;
            cells.push(((i, j), v));
        }
    }
    // The coordinator creates a halving sweep's cells, and so leases them, in a random
    // order fixed by the sweep's seed (`ResolvedSpec::cells_in_lease_order`); a replay
    // draws its own.
    cells.shuffle(&mut rng);
    let (points, values): (Vec<(usize, usize)>, Vec<Vec<f64>>) = cells.into_iter().unzip();
    let (depth, epochs) =
        simulate_halving(&values, &rungs, s.reduction, s.workers, false, &mut rng);
    let answer = (0..values.len())
        .filter(|&c| depth[c] == last)
        .max_by(|&a, &b| values[a][last].total_cmp(&values[b][last]))
        .ok_or("no cell reached the full budget")?;
    let (i, j) = points[answer];
    Ok(judge(rec, epochs, rec.mean(i, j), (i, j)))
}

/// Evolutionary-search settings of a replay.
#[derive(Debug, Clone, Copy)]
pub struct EvolutionSetup {
    /// The genetic algorithm over the grid's points instead of CMA-ES.
    pub genetic: bool,
    /// Candidates per generation.
    pub population: usize,
    /// CMA-ES: initial step, fraction of each axis' range.
    pub sigma: f64,
    /// Epoch budget as a fraction of the grid's.
    pub budget_fraction: f64,
    /// Successive halving inside each generation (first rung, reduction, simulated
    /// workers), as the coordinator's `method = "cmaes"` or `"genetic"` with `min_epochs`.
    pub halving: Option<AshaSetup>,
}

/// One replay of the evolutionary search (CMA-ES or the genetic algorithm) with `seed`.
pub fn replay_evolution(rec: &Recording, s: &EvolutionSetup, seed: u64) -> Result<Replay, String> {
    let (rungs, reduction) = match &s.halving {
        Some(h) => (asha_rungs(rec, h)?, h.reduction),
        None => (vec![rec.epochs], 2),
    };
    let per_generation = gaitsweep_core::spec::halving_cost(s.population as u32, &rungs, reduction);
    let generations =
        ((s.budget_fraction * rec.grid_epochs() as f64) as u64 / per_generation.max(1)) as u32;
    let params = EvolutionParams {
        bounds: Bounds {
            lo: [rec.w1_values[0], rec.w2_values[0]],
            hi: [
                *rec.w1_values.last().unwrap_or(&0.0),
                *rec.w2_values.last().unwrap_or(&0.0),
            ],
        },
        population: s.population,
        optimizer: if s.genetic {
            Optimizer::genetic(&rec.w1_values, &rec.w2_values)
        } else {
            Optimizer::Cmaes { sigma: s.sigma }
        },
        generations,
        seed,
    };
    let mut rng = StdRng::seed_from_u64(seed ^ 0x5eed);
    let mut history: Vec<Vec<f64>> = Vec::new();
    let mut best: Option<([f64; 2], f64)> = None;
    let last = rungs.len() - 1;
    let mut epochs = 0u64;
    while let NextStep::Generation(candidates) = evolution::next_step(&params, &history)? {
        // A candidate's run: the point means' surface interpolated at the candidate, plus
        // one run's noise, the deviation of a replicate drawn at the nearest grid point from
        // that point's mean (at every rung the same replicate). At a grid point it is exactly
        // the drawn replicate; between points its noise keeps a single run's size (averaging
        // draws of the four surrounding points would shrink it).
        let runs: Vec<Vec<f64>> = candidates
            .iter()
            .map(|x| {
                let (ni, nj) = rec.nearest(x[0], x[1]);
                let near = rec.point(ni, nj).expect("validated");
                let drawn = &near.runs[rng.random_range(0..near.runs.len())];
                rungs
                    .iter()
                    .enumerate()
                    .map(|(k, &r)| {
                        let at =
                            |run: &RecordedRun| if k == last { run.score } else { run.evals[&r] };
                        let mean_at = |i: usize, j: usize| {
                            let p = rec.point(i, j).expect("validated");
                            p.runs.iter().map(at).sum::<f64>() / p.runs.len() as f64
                        };
                        rec.interpolate(x[0], x[1], &mut |i, j| mean_at(i, j)) + at(drawn)
                            - mean_at(ni, nj)
                    })
                    .collect()
            })
            .collect();
        // The generation's candidates are cells of their own, halved synchronously among
        // themselves as the coordinator does; without halving each trains to the end.
        let (depth, spent) = match &s.halving {
            Some(h) => simulate_halving(&runs, &rungs, reduction, h.workers, true, &mut rng),
            None => (
                vec![last; runs.len()],
                runs.len() as u64 * u64::from(rec.epochs),
            ),
        };
        epochs += spent;
        let mut fitness = vec![0.0; candidates.len()];
        for (c, &d) in depth.iter().enumerate() {
            let v = runs[c][d];
            fitness[c] = if s.halving.is_some() {
                evolution::halving_fitness(d, v)
            } else {
                v
            };
            if d == last && best.is_none_or(|b| v > b.1) {
                best = Some((candidates[c], v));
            }
        }
        history.push(fitness);
    }
    let (x, _) = best.ok_or_else(|| {
        format!(
            "the budget ({:.0} epochs) pays for no generation ({per_generation} epochs each): \
             lower the population or raise the budget",
            s.budget_fraction * rec.grid_epochs() as f64
        )
    })?;
    let truth = rec.interpolate(x[0], x[1], &mut |i, j| rec.mean(i, j));
    Ok(judge(rec, epochs, truth, rec.nearest(x[0], x[1])))
}

/// Replays summarised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Replays.
    pub replays: usize,
    /// Mean fraction of the grid's epochs used.
    pub epoch_fraction: f64,
    /// Mean regret.
    pub mean_regret: f64,
    /// Largest regret.
    pub max_regret: f64,
    /// Fraction of replays that found the grid's best point.
    pub p_best: f64,
    /// Fraction of replays within 5% of the grid's best mean.
    pub p_within_5pct: f64,
}

/// Summarises replays.
pub fn summarise(r: &[Replay]) -> Summary {
    let n = r.len().max(1) as f64;
    Summary {
        replays: r.len(),
        epoch_fraction: r.iter().map(|x| x.epoch_fraction).sum::<f64>() / n,
        mean_regret: r.iter().map(|x| x.regret).sum::<f64>() / n,
        max_regret: r.iter().map(|x| x.regret).fold(0.0, f64::max),
        p_best: r.iter().filter(|x| x.found_best).count() as f64 / n,
        p_within_5pct: r.iter().filter(|x| x.within_5pct).count() as f64 / n,
    }
}

#[cfg(test)]
#[path = "searchbench_tests.rs"]
mod tests;
