//! Pure scheduling, lease-expiry and promotion logic: no IO, no clocks (times are passed
//! in as unix milliseconds), so every rule is unit- and property-tested.

use gaitsweep_core::{CellId, CellState, LeaseId, SweepId};

/// The next queued cell of one sweep, a candidate for a lease.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The sweep's lowest queued cell.
    pub cell: CellId,
    /// Its sweep.
    pub sweep: SweepId,
    /// Cells of that sweep running now.
    pub running: u32,
}

/// Picks the cell to lease next: fair share across sweeps (the sweep with the fewest
/// running cells first; ties go to the older sweep), in grid order within a sweep.
pub fn pick_next(candidates: &[Candidate]) -> Option<CellId> {
    candidates
        .iter()
        .min_by_key(|c| (c.running, c.sweep, c.cell))
        .map(|c| c.cell)
}

/// The state a cell takes after an attempt failed or its lease expired, given the
/// attempts started so far: back to the queue until `max_attempts` is reached.
pub fn after_failure(attempts: u32, max_attempts: u32) -> CellState {
    if attempts < max_attempts.max(1) {
        CellState::Queued
    } else {
        CellState::Failed
    }
}

/// The leases whose deadline has passed at `now_ms`.
pub fn expired(leases: impl IntoIterator<Item = (LeaseId, i64)>, now_ms: i64) -> Vec<LeaseId> {
    let mut out: Vec<LeaseId> = leases
        .into_iter()
        .filter(|&(_, deadline)| deadline <= now_ms)
        .map(|(id, _)| id)
        .collect();
    out.sort();
    out
}

/// The new deadline of a lease renewed at `now_ms`.
pub fn renew(now_ms: i64, lease_ms: i64) -> i64 {
    now_ms.saturating_add(lease_ms)
}

/// Whether a newly scored cell replaces the current best: a higher score wins, an equal
/// score goes to the lower cell id (so the result does not depend on report order), and
/// a score that is not a number never wins.
pub fn beats(new: (CellId, f64), best: Option<(CellId, f64)>) -> bool {
    let (id, score) = new;
    if score.is_nan() {
        return false;
    }
    match best {
        None => true,
        Some((bid, bscore)) => bscore.is_nan() || score > bscore || (score == bscore && id < bid),
    }
}

/// The best of a set of scored cells under [`beats`].
pub fn best_of(scores: impl IntoIterator<Item = (CellId, f64)>) -> Option<(CellId, f64)> {
    scores
        .into_iter()
        .fold(None, |best, s| if beats(s, best) { Some(s) } else { best })
}

/// The result of a grid point (terrain, w1, w2) over its replicates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointResult {
    /// The replicate whose checkpoint stands for the point: the best-scoring one.
    pub cell: CellId,
    /// Summary of the replicates' scores; promotion ranks points by its mean.
    pub stats: gaitsweep_core::stats::Summary,
}

/// A grid point's result once none of its replicates is still queued or running: the mean
/// of the scores it has (failed replicates have none) and the best replicate. `None` while
/// a replicate is open or when no replicate has a finite score.
pub fn point_result(replicates: &[(CellId, Option<f64>)], open: usize) -> Option<PointResult> {
    if open > 0 {
        return None;
    }
    let scored: Vec<(CellId, f64)> = replicates
        .iter()
        .filter_map(|&(c, s)| s.filter(|v| v.is_finite()).map(|v| (c, v)))
        .collect();
    let (cell, _) = best_of(scored.iter().copied())?;
    let values: Vec<f64> = scored.iter().map(|s| s.1).collect();
    Some(PointResult {
        cell,
        stats: gaitsweep_core::stats::Summary::of(&values)?,
    })
}

/// Whether a sweep is finished given how many of its cells are not terminal yet.
pub fn sweep_finished(open_cells: u32) -> bool {
    open_cells == 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn fair_share_across_sweeps() {
        let c = |cell, sweep, running| Candidate {
            cell: CellId(cell),
            sweep: SweepId(sweep),
            running,
        };
        assert_eq!(pick_next(&[]), None);
        assert_eq!(pick_next(&[c(10, 1, 2), c(20, 2, 0)]), Some(CellId(20)));
        assert_eq!(pick_next(&[c(10, 1, 1), c(20, 2, 1)]), Some(CellId(10)));
    }

    #[test]
    fn failures_requeue_until_the_limit() {
        assert_eq!(after_failure(1, 3), CellState::Queued);
        assert_eq!(after_failure(2, 3), CellState::Queued);
        assert_eq!(after_failure(3, 3), CellState::Failed);
        assert_eq!(after_failure(1, 0), CellState::Failed);
    }

    #[test]
    fn expiry_is_inclusive_of_the_deadline() {
        let l = [(LeaseId(1), 100), (LeaseId(2), 101), (LeaseId(3), 99)];
        assert_eq!(expired(l, 100), vec![LeaseId(1), LeaseId(3)]);
    }

    #[test]
    fn a_point_waits_for_its_replicates_and_ranks_by_their_mean() {
        let r = [
            (CellId(1), Some(0.2)),
            (CellId(2), Some(0.6)),
            (CellId(3), None),
        ];
        assert_eq!(point_result(&r, 1), None, "a replicate is still open");
        let p = point_result(&r, 0).unwrap();
        assert_eq!(p.cell, CellId(2));
        assert!((p.stats.mean - 0.4).abs() < 1e-12 && p.stats.n == 2);
        assert_eq!(point_result(&[(CellId(4), None)], 0), None);
    }

    proptest! {
        #[test]
        fn one_replicate_is_its_own_point(id in 0i64..100, v in -10.0f64..10.0) {
            let p = point_result(&[(CellId(id), Some(v))], 0).unwrap();
            prop_assert_eq!(p.cell, CellId(id));
            prop_assert_eq!(p.stats.mean, v);
            prop_assert_eq!(p.stats.ci95, 0.0);
        }

        #[test]
        fn the_mean_lies_within_its_interval_and_the_best_replicate_is_the_max(
            v in proptest::collection::vec(-10.0f64..10.0, 1..8)
        ) {
            let r: Vec<(CellId, Option<f64>)> =
                v.iter().enumerate().map(|(i, x)| (CellId(i as i64), Some(*x))).collect();
            let p = point_result(&r, 0).unwrap();
            let max = v.iter().cloned().fold(f64::MIN, f64::max);
            prop_assert_eq!(v[p.cell.0 as usize], max);
            let lo = v.iter().cloned().fold(f64::MAX, f64::min);
            prop_assert!(p.stats.mean >= lo - 1e-9 && p.stats.mean <= max + 1e-9);
            prop_assert!(p.stats.ci95 >= 0.0);
        }
    }

    #[test]
    fn nan_never_wins() {
        assert!(!beats((CellId(1), f64::NAN), None));
        assert!(beats((CellId(2), -5.0), Some((CellId(1), f64::NAN))));
    }

    proptest! {
        #[test]
        fn best_is_order_independent_max(mut v in proptest::collection::vec((0i64..50, -10.0f64..10.0), 1..40), seed in any::<u64>()) {
            let scores: Vec<(CellId, f64)> = v.drain(..).map(|(i, s)| (CellId(i), (s * 4.0).round() / 4.0)).collect();
            let a = best_of(scores.iter().copied()).unwrap();
            let mut shuffled = scores.clone();
            let n = shuffled.len();
            for i in 0..n { shuffled.swap(i, (seed as usize).wrapping_mul(i + 7) % n); }
            let b = best_of(shuffled.iter().copied()).unwrap();
            prop_assert_eq!(a, b);
            let max = scores.iter().map(|s| s.1).fold(f64::MIN, f64::max);
            prop_assert_eq!(a.1, max);
            prop_assert!(scores.iter().filter(|s| s.1 == max).all(|s| s.0 >= a.0));
        }

        #[test]
        fn expired_are_exactly_the_past_deadlines(d in proptest::collection::vec(0i64..1000, 0..50), now in 0i64..1000) {
            let leases: Vec<(LeaseId, i64)> = d.iter().enumerate().map(|(i, &t)| (LeaseId(i as i64), t)).collect();
            let out = expired(leases.iter().copied(), now);
            for (id, t) in &leases {
                prop_assert_eq!(out.contains(id), *t <= now);
            }
        }

        #[test]
        fn a_cell_never_runs_more_than_max_attempts(max in 1u32..6, failures in 0u32..20) {
            let mut attempts = 0;
            let mut state = CellState::Queued;
            for _ in 0..failures {
                if state != CellState::Queued { break; }
                attempts += 1;
                state = after_failure(attempts, max);
            }
            prop_assert!(attempts <= max);
            prop_assert_eq!(state == CellState::Failed, attempts == max);
        }

        #[test]
        fn pick_prefers_least_loaded(r in proptest::collection::vec(0u32..5, 1..10)) {
            let c: Vec<Candidate> = r.iter().enumerate()
                .map(|(i, &running)| Candidate { cell: CellId(100 + i as i64), sweep: SweepId(i as i64), running })
                .collect();
            let picked = pick_next(&c).unwrap();
            let min = r.iter().min().unwrap();
            let chosen = c.iter().find(|x| x.cell == picked).unwrap();
            prop_assert_eq!(chosen.running, *min);
        }
    }
}
