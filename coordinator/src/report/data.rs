//! What a report shows, as plain data: the cells, the promotions, the grid and the
//! overlap across terrains. The spread of one run and the points near the best are in
//! `spread.rs`; loading from SQL in `load.rs`.

use super::{machines, SHARE_METRICS};
use crate::shape::GridValues;
use gaitsweep_core::Place;
use gaitsweep_model::GaitScore;
use std::collections::BTreeMap;

/// One cell of the sweep with its score (if it has one).
#[derive(Debug, Clone)]
pub struct ReportCell {
    /// Cell id.
    pub id: i64,
    /// Index of its terrain in [`ReportData::terrains`].
    pub terrain_index: usize,
    /// Terrain name.
    pub terrain: String,
    /// Its grid point (indices into [`ReportData::w1_values`] and
    /// [`ReportData::w2_values`]), or its generation and number as a candidate.
    pub place: Place,
    /// Replicate number within its grid point (`seeds = k` in the spec).
    pub replicate: u32,
    /// Velocity-tracking weight.
    pub w1: f64,
    /// log10 of the torque-penalty weight.
    pub w2: f64,
    /// queued, running, done, failed or cancelled.
    pub state: String,
    /// Attempts so far.
    pub attempts: u32,
    /// Epochs trained.
    pub epochs_done: u32,
    /// Last error, if any.
    pub last_error: Option<String>,
    /// The gait score and its components (done cells).
    pub score: Option<GaitScore>,
    /// The final (or latest) checkpoint, relative to the data dir.
    pub checkpoint: Option<String>,
    /// Learning curves: metric name -> (epoch, value), epochs ascending.
    pub curves: BTreeMap<String, Vec<(u32, f64)>>,
    /// Its deepest successive-halving rung evaluation (epoch, gait score), if any.
    pub rung: Option<(u32, f64)>,
    /// The CPUs that trained its epochs, in epoch order ([`machines::cpu_spans`]).
    pub trained_on: Vec<machines::CpuSpan>,
}

impl ReportCell {
    /// Its grid point as `(row, column)`; `None` for an evolutionary candidate.
    pub fn grid(&self) -> Option<(usize, usize)> {
        self.place.grid().map(|(i, j)| (i as usize, j as usize))
    }

    /// Whether a scored cell trained without ever being rewarded: its mean reward per step
    /// was exactly 0 at every epoch logged, i.e. every step's reward sum was clipped to 0
    /// (`only_positive_rewards`, legged_gym's) because the penalties, the torque's at a
    /// large w2, outweighed every positive term. PPO then had no reward to learn from, and
    /// the score is that of a policy its weights taught nothing. A cell without a score
    /// may yet be rewarded: `false`.
    pub fn never_rewarded(&self) -> bool {
        self.score.is_some()
            && self
                .curves
                .get("mean_step_reward")
                .is_some_and(|c| !c.is_empty() && c.iter().all(|&(_, v)| v == 0.0))
    }

    /// How much the torque penalty weighs against velocity tracking in the cell's training:
    /// the mean over its logged epochs of the torque penalty per step (its magnitude) over
    /// the mean tracking reward per step. The paper contrasts these two terms (w2 against
    /// w1); this says where on the grid the contrast exists. `None` before the cell is
    /// scored (a cell still training has a share of its epochs so far, which would drift on
    /// the picture unmarked), without both metrics, or without a positive tracking reward.
    pub fn torque_share(&self) -> Option<f64> {
        self.score.as_ref()?;
        let mean = |name: &str| {
            let c = self.curves.get(name).filter(|c| !c.is_empty())?;
            Some(c.iter().map(|p| p.1).sum::<f64>() / c.len() as f64)
        };
        let (torque, track) = (mean(SHARE_METRICS[0])?, mean(SHARE_METRICS[1])?);
        (track > 0.0).then(|| torque.abs() / track)
    }

    /// The composite score, if the cell has a finite one.
    pub fn value(&self) -> Option<f64> {
        self.score
            .as_ref()
            .map(|s| s.score)
            .filter(|v| v.is_finite())
    }
}

/// A promoted (best) cell.
#[derive(Debug, Clone, PartialEq)]
pub struct Promotion {
    /// Terrain it is best on; empty: over all terrains.
    pub terrain: String,
    /// The cell.
    pub cell_id: i64,
    /// Its score.
    pub score: f64,
}

/// Everything a report shows, loaded once from SQL.
#[derive(Debug, Clone)]
pub struct ReportData {
    /// Sweep id.
    pub sweep_id: i64,
    /// Sweep name.
    pub name: String,
    /// Robot preset.
    pub robot: String,
    /// running, done or cancelled.
    pub state: String,
    /// Fixed difficulty of the sweep, if any.
    pub difficulty: Option<u8>,
    /// Terrains in grid order.
    pub terrains: Vec<String>,
    /// w1 values (grid rows).
    pub w1_values: Vec<f64>,
    /// w2 values (grid columns).
    pub w2_values: Vec<f64>,
    /// Every cell.
    pub cells: Vec<ReportCell>,
    /// Latest promotion per terrain ('' = overall).
    pub promotions: Vec<Promotion>,
    /// For an evolutionary search, the (w1, w2) rectangle it searched
    /// (`([w1_lo, w2_lo], [w1_hi, w2_hi])`): its cells are candidates, not grid points,
    /// and the report draws them instead of grid pictures.
    pub evolution: Option<([f64; 2], [f64; 2])>,
    /// The search method as a spec writes it (`grid`, `asha`, `cmaes`, `genetic`, `random`).
    pub search: String,
    /// The search method in words, for titles ([`gaitsweep_search::Description::title`]).
    pub search_title: String,
    /// What the sweep was given to spend: robots, epochs, search, seeds, evaluation.
    pub budget: String,
    /// Whether the sweep has a finalist stage (`[finalists]`): its points' first seeds were
    /// picked for scoring high ([`ReportData::near_best`]).
    pub finalists: bool,
}

impl ReportData {
    /// The grid point best across the sweep's terrains ([`crate::across`]); `None` for one
    /// terrain or an evolutionary search.
    pub fn across(&self) -> Option<crate::across::AcrossTerrains> {
        if self.evolution.is_some() {
            return None;
        }
        let cells: Vec<crate::across::ScoredCell> = self
            .cells
            .iter()
            .filter_map(|c| {
                Some(crate::across::ScoredCell {
                    cell: gaitsweep_core::CellId(c.id),
                    terrain: c.terrain_index,
                    place: c.place,
                    score: c.value()?,
                })
            })
            .collect();
        crate::across::best_across(&cells, self.terrains.len())
    }

    /// The cell with this id.
    pub fn cell(&self, id: i64) -> Option<&ReportCell> {
        self.cells.iter().find(|c| c.id == id)
    }

    /// The cells of terrain `t`.
    pub fn cells_of(&self, t: usize) -> impl Iterator<Item = &ReportCell> {
        self.cells.iter().filter(move |c| c.terrain_index == t)
    }

    /// The promoted cell over all terrains: the latest overall promotion, else the best
    /// scored cell.
    pub fn promoted(&self) -> Option<&ReportCell> {
        self.promotions
            .iter()
            .find(|p| p.terrain.is_empty())
            .and_then(|p| self.cell(p.cell_id))
            .or_else(|| self.best_cell(None))
    }

    /// The best scored cell (highest score; ties: lowest id) of terrain `t`, or overall.
    pub fn best_cell(&self, t: Option<usize>) -> Option<&ReportCell> {
        self.cells
            .iter()
            .filter(|c| t.is_none_or(|t| c.terrain_index == t))
            .filter_map(|c| c.value().map(|v| (c, v)))
            .fold(None::<(&ReportCell, f64)>, |b, (c, v)| match b {
                Some((bc, bv)) if bv > v || (bv == v && bc.id < c.id) => Some((bc, bv)),
                _ => Some((c, v)),
            })
            .map(|b| b.0)
    }

    /// Grid `[w1_index][w2_index]` of terrain `t` filled with `f(cell)`.
    pub fn grid<T: Clone>(&self, t: usize, empty: T, f: impl Fn(&ReportCell) -> T) -> Vec<Vec<T>> {
        let mut g = vec![vec![empty; self.w2_values.len()]; self.w1_values.len()];
        for c in self.cells_of(t) {
            if let Some(slot) = c.grid().and_then(|(i, j)| g.get_mut(i)?.get_mut(j)) {
                *slot = f(c);
            }
        }
        g
    }

    /// Grid `[w1_index][w2_index]` of terrain `t`: per grid point the mean of `f` over its
    /// replicates that have a value (`seeds = k` trains each point k times).
    pub fn grid_mean(&self, t: usize, f: impl Fn(&ReportCell) -> Option<f64>) -> GridValues {
        let mut sum = vec![vec![(0.0, 0usize); self.w2_values.len()]; self.w1_values.len()];
        for c in self.cells_of(t) {
            if let (Some(v), Some(slot)) =
                (f(c), c.grid().and_then(|(i, j)| sum.get_mut(i)?.get_mut(j)))
            {
                slot.0 += v;
                slot.1 += 1;
            }
        }
        sum.into_iter()
            .map(|r| {
                r.into_iter()
                    .map(|(s, n)| (n > 0).then(|| s / n as f64))
                    .collect()
            })
            .collect()
    }

    /// The shape of terrain `t`'s grid ([`crate::shape`]) over its points' mean scores and
    /// mean speeds, both from the cells with a finite score, with the points never rewarded
    /// ([`ReportData::unrewarded_points`]) left out of the standing rows and the largest step.
    pub fn shape(&self, t: usize) -> Option<crate::shape::Shape> {
        let score = self.grid_mean(t, |c| c.value());
        let speed = self.grid_mean(t, |c| c.value().and(c.score.as_ref()).map(|s| s.mean_speed));
        crate::shape::shape(&score, &speed, &self.unrewarded_points(t))
    }

    /// Grid points `(w1_index, w2_index)` whose mean score is in the top quartile of their
    /// terrain's point means on every terrain, and per grid position the number of terrains
    /// where it is in the top quartile (none where a terrain has not scored it yet: a 0
    /// there would claim a comparison that has not been made). Point means, so that a
    /// point's extra seeds count once, as one terrain.
    pub fn overlap(&self) -> (Vec<(usize, usize)>, GridValues) {
        let mut count = vec![vec![Some(0.0); self.w2_values.len()]; self.w1_values.len()];
        for (i, row) in count.iter_mut().enumerate() {
            for (j, n) in row.iter_mut().enumerate() {
                let scored_everywhere = (0..self.terrains.len()).all(|t| {
                    self.cells_of(t)
                        .any(|c| c.grid() == Some((i, j)) && c.value().is_some())
                });
                if !scored_everywhere {
                    *n = None;
                }
            }
        }
        for t in 0..self.terrains.len() {
            let means = self.grid_mean(t, |c| c.value());
            let mut v: Vec<f64> = means.iter().flatten().flatten().copied().collect();
            if v.is_empty() {
                continue;
            }
            v.sort_by(|a, b| b.total_cmp(a));
            let threshold = v[v.len().div_ceil(4) - 1];
            for (i, row) in means.iter().enumerate() {
                for (j, m) in row.iter().enumerate() {
                    if m.is_some_and(|x| x >= threshold) {
                        if let Some(Some(n)) = count.get_mut(i).and_then(|r| r.get_mut(j)) {
                            *n += 1.0;
                        }
                    }
                }
            }
        }
        let all = self.terrains.len() as f64;
        let mut cells = Vec::new();
        for (i, row) in count.iter().enumerate() {
            for (j, n) in row.iter().enumerate() {
                if all > 0.0 && *n == Some(all) {
                    cells.push((i, j));
                }
            }
        }
        (cells, count)
    }
}
