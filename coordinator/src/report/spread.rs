//! The spread of one run, read from the runs of nearly the same reward or from the
//! finalists' seeds, and the points it does not tell apart from the best.

use super::{ReportData, NEGLIGIBLE_TORQUE_SHARE};
use crate::near_best::{NearBest, SpreadSource};
use gaitsweep_core::stats::Summary;
use std::collections::BTreeMap;

/// One row's first-seed runs of nearly the same reward ([`ReportData::same_reward_rows`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SameRewardRow {
    /// The row (index into [`ReportData::w1_values`]).
    pub w1_index: usize,
    /// `(w2_index, score)` of each run, w2 ascending.
    pub runs: Vec<(usize, f64)>,
    /// Mean score of the runs.
    pub mean: f64,
    /// Sample standard deviation of the runs' scores (n - 1).
    pub sd: f64,
}

impl SameRewardRow {
    /// The rows' pooled standard deviation: each row's variance weighted by its degrees of
    /// freedom, so that rows at different levels of score share one estimate of a run's
    /// spread. `Some((sd, degrees of freedom))`, `None` without rows.
    pub fn pooled(rows: &[SameRewardRow]) -> Option<(f64, usize)> {
        let scores: Vec<Vec<f64>> = rows
            .iter()
            .map(|r| r.runs.iter().map(|run| run.1).collect())
            .collect();
        crate::near_best::pooled_sd(scores.iter().map(Vec::as_slice))
    }
}

impl ReportData {
    /// Grid points `(w1_index, w2_index)` of terrain `t` that have a scored cell and whose
    /// every scored cell was never rewarded ([`ReportCell::never_rewarded`]), in grid order.
    pub fn unrewarded_points(&self, t: usize) -> Vec<(usize, usize)> {
        let mut points: BTreeMap<(usize, usize), bool> = BTreeMap::new();
        for c in self.cells_of(t).filter(|c| c.value().is_some()) {
            if let Some(p) = c.grid() {
                *points.entry(p).or_insert(true) &= c.never_rewarded();
            }
        }
        points
            .into_iter()
            .filter_map(|(p, none)| none.then_some(p))
            .collect()
    }

    /// The columns (w2 indices) of terrain `t` where the torque penalty is negligible: some
    /// cell there has a [`ReportCell::torque_share`] and every such cell's is under
    /// [`NEGLIGIBLE_TORQUE_SHARE`].
    pub fn negligible_torque_columns(&self, t: usize) -> Vec<usize> {
        let mut cols: BTreeMap<usize, bool> = BTreeMap::new();
        for c in self.cells_of(t) {
            if let (Some((_, j)), Some(share)) = (c.grid(), c.torque_share()) {
                *cols.entry(j).or_insert(true) &= share < NEGLIGIBLE_TORQUE_SHARE;
            }
        }
        cols.into_iter()
            .filter_map(|(j, small)| small.then_some(j))
            .collect()
    }

    /// Per row of terrain `t`, the first-seed runs whose weights give nearly the same reward:
    /// scored cells of replicate 0 whose [`ReportCell::torque_share`] is under
    /// [`NEGLIGIBLE_TORQUE_SHARE`]. Across them only w2 differs, and it shapes their reward
    /// by under 1%, so their scores are draws of one reward that differ by their seeds: the
    /// spread of a single run, measured without spending replicates. Rows with fewer than two
    /// such runs are left out. It picks cells, not columns
    /// ([`ReportData::negligible_torque_columns`] needs every cell of a column under 1%).
    pub fn same_reward_rows(&self, t: usize) -> Vec<SameRewardRow> {
        let mut rows: BTreeMap<usize, Vec<(usize, f64)>> = BTreeMap::new();
        for c in self.cells_of(t).filter(|c| c.replicate == 0) {
            if let (Some((i, j)), Some(v), Some(share)) = (c.grid(), c.value(), c.torque_share()) {
                if share < NEGLIGIBLE_TORQUE_SHARE {
                    rows.entry(i).or_default().push((j, v));
                }
            }
        }
        rows.into_iter()
            .filter(|(_, runs)| runs.len() > 1)
            .filter_map(|(w1_index, mut runs)| {
                runs.sort_by_key(|r| r.0);
                let s = Summary::of(&runs.iter().map(|r| r.1).collect::<Vec<_>>())?;
                Some(SameRewardRow {
                    w1_index,
                    runs,
                    mean: s.mean,
                    sd: s.sd,
                })
            })
            .collect()
    }

    /// The points of terrain `t` not told apart from its best point at 95%
    /// ([`crate::near_best`]), over every replicate's score. One run's spread is pooled over
    /// the points trained on more than one seed once every one of their cells has ended
    /// (scored, failed, cancelled or stopped); until then a finalist stage would give a
    /// degree of freedom or two, whose t quantile widens the set several times over, and the
    /// spread is read from the rows' runs of nearly the same reward
    /// ([`ReportData::same_reward_rows`]) instead. After a finalist stage only the seeds
    /// drawn after the selection count: the first was picked for scoring high, so with it
    /// the spread would come out wider than a run's. `None` before either gives a degree
    /// of freedom.
    pub fn near_best(&self, t: usize) -> Option<NearBest> {
        let mut scores: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
        let mut unselected: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
        // Per point: (trained more than once, every one of its cells ended).
        let mut stage: BTreeMap<(usize, usize), (bool, bool)> = BTreeMap::new();
        for c in self.cells_of(t) {
            let Some(p) = c.grid() else { continue };
            if let Some(v) = c.value() {
                scores.entry(p).or_default().push(v);
                if !self.finalists || c.replicate > 0 {
                    unselected.entry(p).or_default().push(v);
                }
            }
            let (replicated, ended) = stage.entry(p).or_insert((false, true));
            *replicated |= c.replicate > 0;
            *ended &= c
                .state
                .parse::<gaitsweep_core::CellState>()
                .is_ok_and(gaitsweep_core::CellState::is_terminal);
        }
        let mut replicated = stage.values().filter(|s| s.0).peekable();
        let stage_ended = replicated.peek().is_some() && replicated.all(|s| s.1);
        let replicates = stage_ended
            .then(|| crate::near_best::pooled_sd(unselected.values().map(Vec::as_slice)))
            .flatten()
            .map(|(sd, dof)| (sd, dof, SpreadSource::Replicates));
        let (sd, dof, source) = replicates.or_else(|| {
            SameRewardRow::pooled(&self.same_reward_rows(t))
                .map(|(sd, dof)| (sd, dof, SpreadSource::SameReward))
        })?;
        crate::near_best::near_best(&scores, sd, dof, source)
    }
}
