//! Which grid points a terrain's runs cannot tell apart from its best point (issue 39 item
//! 5). One run's score spreads with its seed (stairs' single runs by about 0.2), so a grid's
//! answer is a set of points, not one: the best point by mean and every point whose mean is
//! within the 95% least significant difference of it, `t(0.975, dof) sd sqrt(1/n_best +
//! 1/n_point)`, with `sd` one run's spread pooled over groups of runs of one reward. The
//! paper's "the terrains' peaks overlap" then reads as: some point is near the best on every
//! terrain. Pure: the report gives it each point's scores and the groups.

use std::collections::BTreeMap;

use gaitsweep_core::stats::{t975, Summary};

/// A grid point `(w1_index, w2_index)`.
pub type GridPoint = (usize, usize);

/// The standard deviation of groups of runs pooled: each group's variance weighted by its
/// runs minus one, so groups at different levels of score share one estimate of a run's
/// spread. `Some((sd, degrees of freedom))`, `None` when no group has two finite runs.
pub fn pooled_sd<'a>(groups: impl IntoIterator<Item = &'a [f64]>) -> Option<(f64, usize)> {
    let (mut ss, mut dof) = (0.0, 0usize);
    for g in groups {
        let runs: Vec<f64> = g.iter().copied().filter(|v| v.is_finite()).collect();
        if let Some(s) = Summary::of(&runs).filter(|s| s.n > 1) {
            ss += s.sd * s.sd * (s.n - 1) as f64;
            dof += s.n - 1;
        }
    }
    (dof > 0).then(|| ((ss / dof as f64).sqrt(), dof))
}

/// Where one run's spread was read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpreadSource {
    /// The seeds of points trained more than once (the finalists).
    Replicates,
    /// First-seed runs of nearly the same reward, row by row (before any point has two
    /// seeds).
    SameReward,
}

/// The points near a terrain's best.
#[derive(Debug, Clone, PartialEq)]
pub struct NearBest {
    /// The best point by mean score (ties: the lower grid index).
    pub best: GridPoint,
    /// Its mean score.
    pub best_mean: f64,
    /// Runs of the best point.
    pub best_runs: usize,
    /// One run's pooled standard deviation.
    pub sd: f64,
    /// Its degrees of freedom.
    pub dof: usize,
    /// Where it was read from.
    pub source: SpreadSource,
    /// The points not told apart from the best at 95%, the best included, in grid order.
    pub near: Vec<GridPoint>,
    /// Points with a score.
    pub scored: usize,
}

impl NearBest {
    /// The least significant difference between the best point and one with `runs` runs.
    pub fn lsd(&self, runs: usize) -> f64 {
        t975(self.dof) * self.sd * (1.0 / self.best_runs as f64 + 1.0 / runs as f64).sqrt()
    }
}

/// The points of `scores` (each point's finite runs; points without any are ignored) not
/// told apart from the best at 95% with one run's spread `sd` over `dof` degrees of
/// freedom. `None` without a scored point, a finite `sd` or a degree of freedom.
pub fn near_best(
    scores: &BTreeMap<GridPoint, Vec<f64>>,
    sd: f64,
    dof: usize,
    source: SpreadSource,
) -> Option<NearBest> {
    if !sd.is_finite() || dof == 0 {
        return None;
    }
    let means: Vec<(GridPoint, f64, usize)> = scores
        .iter()
        .filter_map(|(&p, runs)| {
            let runs: Vec<f64> = runs.iter().copied().filter(|v| v.is_finite()).collect();
            Summary::of(&runs).map(|s| (p, s.mean, s.n))
        })
        .collect();
    // Grid order, so a strictly higher mean wins and ties keep the lower index.
    let &(best, best_mean, best_runs) =
        means
            .iter()
            .fold(None, |b: Option<&(GridPoint, f64, usize)>, m| match b {
                Some(b) if b.1 >= m.1 => Some(b),
                _ => Some(m),
            })?;
    let mut out = NearBest {
        best,
        best_mean,
        best_runs,
        sd,
        dof,
        source,
        near: Vec::new(),
        scored: means.len(),
    };
    out.near = means
        .iter()
        .filter(|&&(_, mean, runs)| best_mean - mean <= out.lsd(runs))
        .map(|m| m.0)
        .collect();
    Some(out)
}

/// The points near the best on every one of `terrains` (in grid order); empty when there
/// are none or no terrain.
pub fn near_best_everywhere(terrains: &[NearBest]) -> Vec<GridPoint> {
    let Some((first, rest)) = terrains.split_first() else {
        return Vec::new();
    };
    first
        .near
        .iter()
        .copied()
        .filter(|p| rest.iter().all(|t| t.near.contains(p)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn grid(points: &[(GridPoint, &[f64])]) -> BTreeMap<GridPoint, Vec<f64>> {
        points.iter().map(|(p, v)| (*p, v.to_vec())).collect()
    }

    #[test]
    fn pooled_sd_weights_each_group_by_its_runs_minus_one() {
        // Groups {1, 3} (ss 2, 1 dof) and {10, 11, 12} (ss 2, 2 dof): sqrt(4 / 3).
        let (sd, dof) = pooled_sd([
            &[1.0, 3.0][..],
            &[10.0, 11.0, 12.0],
            &[7.0],
            &[f64::NAN, 2.0],
        ])
        .unwrap();
        assert_eq!(dof, 3, "single runs and NaNs add no degree of freedom");
        assert!((sd - (4.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(pooled_sd([&[1.0][..], &[]]), None);
    }

    #[test]
    fn points_within_the_least_significant_difference_are_near_the_best() {
        // sd 0.1 with 8 dof (t 2.306): single run against a 3-run best needs more than
        // 2.306 * 0.1 * sqrt(1/3 + 1) = 0.266; two 3-run points more than 0.188.
        let scores = grid(&[
            ((0, 0), &[1.0, 1.1, 0.9]),
            ((0, 1), &[0.85, 0.85, 0.85]),
            ((0, 2), &[0.75]),
            ((1, 0), &[0.7]),
            ((1, 1), &[0.79, 0.8, 0.81]),
            ((1, 2), &[]),
        ]);
        let n = near_best(&scores, 0.1, 8, SpreadSource::Replicates).unwrap();
        assert_eq!(n.best, (0, 0));
        assert!((n.best_mean - 1.0).abs() < 1e-12);
        assert_eq!((n.best_runs, n.scored), (3, 5));
        assert!((n.lsd(1) - 0.2663).abs() < 1e-3 && (n.lsd(3) - 0.1883).abs() < 1e-3);
        assert_eq!(
            n.near,
            vec![(0, 0), (0, 1), (0, 2)],
            "0.85 (3 runs) and 0.75 (1 run) are within reach; 0.7 (1 run) and 0.8 (3 runs) are not"
        );
        let tie = grid(&[((0, 1), &[0.5]), ((1, 0), &[0.5]), ((0, 0), &[0.2])]);
        let t = near_best(&tie, 0.01, 5, SpreadSource::SameReward).unwrap();
        assert_eq!(
            (t.best, t.near.clone()),
            ((0, 1), vec![(0, 1), (1, 0)]),
            "a tie keeps the lower index"
        );
        assert_eq!(near_best(&scores, 0.1, 0, SpreadSource::Replicates), None);
        assert_eq!(
            near_best(&scores, f64::NAN, 3, SpreadSource::Replicates),
            None
        );
        assert_eq!(
            near_best(&BTreeMap::new(), 0.1, 3, SpreadSource::Replicates),
            None
        );
    }

    #[test]
    fn points_near_the_best_on_every_terrain_are_their_intersection() {
        let rough = grid(&[((0, 0), &[1.0]), ((0, 1), &[0.95]), ((1, 1), &[0.2])]);
        let stairs = grid(&[((0, 0), &[0.1]), ((0, 1), &[0.9]), ((1, 1), &[0.95])]);
        let a = near_best(&rough, 0.05, 10, SpreadSource::SameReward).unwrap();
        let b = near_best(&stairs, 0.05, 10, SpreadSource::SameReward).unwrap();
        assert_eq!(near_best_everywhere(&[a.clone(), b]), vec![(0, 1)]);
        assert_eq!(near_best_everywhere(std::slice::from_ref(&a)), a.near);
        assert!(near_best_everywhere(&[]).is_empty());
    }

    proptest! {
        /// The best is always near itself, every near point is within the least significant
        /// difference, and a wider spread never shrinks the set.
        #[test]
        fn the_set_contains_the_best_and_grows_with_the_spread(
            runs in proptest::collection::vec(proptest::collection::vec(-1.0f64..2.0, 1..4), 1..12),
            sd in 0.001f64..0.5,
            dof in 1usize..40,
        ) {
            let scores: BTreeMap<GridPoint, Vec<f64>> =
                runs.into_iter().enumerate().map(|(k, v)| ((k / 4, k % 4), v)).collect();
            let n = near_best(&scores, sd, dof, SpreadSource::Replicates).unwrap();
            prop_assert!(n.near.contains(&n.best));
            for (p, v) in &scores {
                let mean = v.iter().sum::<f64>() / v.len() as f64;
                prop_assert!(mean <= n.best_mean);
                prop_assert_eq!(n.near.contains(p), n.best_mean - mean <= n.lsd(v.len()));
            }
            let wider = near_best(&scores, 2.0 * sd, dof, SpreadSource::Replicates).unwrap();
            prop_assert!(n.near.iter().all(|p| wider.near.contains(p)));
        }
    }
}
