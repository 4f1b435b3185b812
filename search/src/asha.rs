//! Asynchronous successive halving (ASHA, Li et al. 2020, "A System for Massively Parallel
//! Hyperparameter Tuning") as a pure function over small structs: no IO, so every rule is
//! unit- and property-tested. The store calls [`decide`] after every rung result, inside
//! the transaction that records it, and applies what it returns.
//!
//! Rungs are the epochs of `ResolvedSpec::rungs` (the last is the full budget). A cell that
//! reaches rung `k` pauses there. It continues to rung `k + 1` as soon as it ranks in the
//! top `floor(n_k / reduction)` of the `n_k` cells that have reached rung `k` so far, without
//! waiting for the rest of the rung (ASHA's asynchronous promotion). Once no cell can reach
//! rung `k` any more (the rung is *closed*), its paused cells outside that top are stopped;
//! if the top is empty there (fewer than `reduction` cells reached the rung) the best one
//! continues, so a small grid still trains one cell to the end.

use gaitsweep_core::CellId;
use std::cmp::Ordering;

/// Where a cell stands, as far as successive halving is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Standing {
    /// Queued or running towards its next rung.
    Training,
    /// Waiting at the last rung it reached.
    Paused,
    /// Done, stopped, failed or cancelled: it reaches no further rung.
    Closed,
}

/// One cell of a successive-halving sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct AshaCell {
    /// The cell.
    pub cell: CellId,
    /// Its gait score at each rung it reached, rung 0 first.
    pub scores: Vec<f64>,
    /// Where it stands.
    pub standing: Standing,
}

/// A decision on a paused cell at a rung.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decision {
    /// The cell.
    pub cell: CellId,
    /// The rung it is paused at.
    pub rung: usize,
    /// Its score there.
    pub score: f64,
    /// True: it trains on to rung `rung + 1`; false: it stops.
    pub continued: bool,
}

/// Orders scores best first: higher wins, NaN loses, ties go to the lower cell id.
fn better(a: (CellId, f64), b: (CellId, f64)) -> Ordering {
    let key = |s: f64| if s.is_nan() { f64::NEG_INFINITY } else { s };
    key(b.1)
        .partial_cmp(&key(a.1))
        .unwrap_or(Ordering::Equal)
        .then(a.0.cmp(&b.0))
}

/// How many of the `reached` cells of a rung continue: `floor(reached / reduction)`, and at
/// least one once the rung is closed.
pub fn quota(reached: usize, reduction: u32, closed: bool) -> usize {
    let q = reached / reduction.max(2) as usize;
    if closed && reached > 0 {
        q.max(1)
    } else {
        q
    }
}

/// Whether none of `cells` is training (queued or running). A synchronous bracket (a
/// generation of the evolutionary search) is decided only then: every cell has reached its
/// rung or ended, so [`decide`] continues exactly the top `max(1, floor(n / reduction))`.
pub fn no_cell_training(cells: &[AshaCell]) -> bool {
    cells.iter().all(|c| c.standing != Standing::Training)
}

/// The decisions due now for the paused cells of a sweep with `rungs` rungs (the last is
/// the full budget, where cells finish instead of pausing) and reduction factor
/// `reduction`. Each paused cell gets at most one decision; a cell not decided stays
/// paused until a later result changes its rung's ranking or closes the rung.
pub fn decide(cells: &[AshaCell], rungs: usize, reduction: u32) -> Vec<Decision> {
    let mut out = Vec::new();
    let mut lower_closed = true;
    let mut continued_below = false;
    for k in 0..rungs.saturating_sub(1) {
        let mut reached: Vec<(CellId, f64)> = cells
            .iter()
            .filter(|c| c.scores.len() > k)
            .map(|c| (c.cell, c.scores[k]))
            .collect();
        reached.sort_by(|a, b| better(*a, *b));
        let heading_here = cells
            .iter()
            .any(|c| c.standing == Standing::Training && c.scores.len() <= k);
        let closed = lower_closed && !continued_below && !heading_here;
        let q = quota(reached.len(), reduction, closed);
        for (rank, &(cell, score)) in reached.iter().enumerate() {
            let paused_here = cells.iter().any(|c| {
                c.cell == cell && c.standing == Standing::Paused && c.scores.len() == k + 1
            });
            if !paused_here {
                continue;
            }
            if rank < q {
                out.push(Decision {
                    cell,
                    rung: k,
                    score,
                    continued: true,
                });
                continued_below = true;
            } else if closed {
                out.push(Decision {
                    cell,
                    rung: k,
                    score,
                    continued: false,
                });
            }
        }
        lower_closed = closed;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cell(id: i64, scores: &[f64], standing: Standing) -> AshaCell {
        AshaCell {
            cell: CellId(id),
            scores: scores.to_vec(),
            standing,
        }
    }

    #[test]
    fn a_cell_continues_once_it_is_in_the_top_third_of_its_rung() {
        use Standing::*;
        // Two of six reached rung 0: floor(2/3) = 0, nobody continues yet.
        let mut cells = vec![
            cell(1, &[0.5], Paused),
            cell(2, &[0.7], Paused),
            cell(3, &[], Training),
            cell(4, &[], Training),
            cell(5, &[], Training),
            cell(6, &[], Training),
        ];
        assert!(decide(&cells, 3, 3).is_empty());
        // A third arrives: the best of three continues, nobody is stopped (rung open).
        cells[2] = cell(3, &[0.6], Paused);
        let d = decide(&cells, 3, 3);
        assert_eq!(d.len(), 1);
        assert_eq!((d[0].cell, d[0].rung, d[0].continued), (CellId(2), 0, true));
    }

    #[test]
    fn a_closed_rung_stops_the_rest_and_always_continues_one() {
        use Standing::*;
        let cells = vec![
            cell(1, &[0.5], Paused),
            cell(2, &[0.7], Paused),
            cell(3, &[f64::NAN], Paused),
            cell(4, &[], Closed), // failed before rung 0
        ];
        let d = decide(&cells, 2, 4);
        let cont: Vec<_> = d.iter().filter(|d| d.continued).map(|d| d.cell).collect();
        let stop: Vec<_> = d.iter().filter(|d| !d.continued).map(|d| d.cell).collect();
        assert_eq!(cont, vec![CellId(2)]);
        assert_eq!(stop, vec![CellId(1), CellId(3)]);
    }

    #[test]
    fn a_higher_rung_stays_open_while_a_lower_one_can_still_send_cells() {
        use Standing::*;
        // Rung 1 has one paused cell, rung 0 still waits for a training cell: rung 1 must
        // not stop anybody yet.
        let cells = vec![
            cell(1, &[0.9, 0.1], Paused),
            cell(2, &[0.2], Paused),
            cell(3, &[0.3], Paused),
            cell(4, &[], Training),
        ];
        assert!(decide(&cells, 3, 3).iter().all(|d| d.continued));
        assert!(decide(&cells, 3, 3).iter().all(|d| d.rung == 0));
    }

    #[test]
    fn the_final_rung_takes_no_decisions() {
        let cells = vec![cell(1, &[0.5, 0.6], Standing::Closed)];
        assert!(decide(&cells, 2, 3).is_empty());
        assert!(decide(&[], 1, 3).is_empty());
    }

    /// A decision with the rung's ranking when it was taken: (decision, rank, cells that
    /// had reached the rung, whether a cell could still reach it).
    type Logged = (Decision, usize, usize, bool);

    /// Plays a whole sweep: training cells finish in the order `order` picks, each at its
    /// next rung with the score `score(cell, rung)`; the decisions are applied after every
    /// result. Returns the decisions with the rung's ranking at the time.
    fn play(
        scores: &[Vec<f64>],
        rungs: usize,
        reduction: u32,
        order: &[usize],
    ) -> (Vec<AshaCell>, Vec<Logged>) {
        play_as(scores, rungs, reduction, order, false)
    }

    /// [`play`], with `synchronous` deciding only while no cell trains (an evolutionary
    /// search's generation).
    fn play_as(
        scores: &[Vec<f64>],
        rungs: usize,
        reduction: u32,
        order: &[usize],
        synchronous: bool,
    ) -> (Vec<AshaCell>, Vec<Logged>) {
        let mut cells: Vec<AshaCell> = (0..scores.len())
            .map(|i| cell(i as i64, &[], Standing::Training))
            .collect();
        let mut log = Vec::new();
        let mut pick = order.iter().cycle();
        for _ in 0..10_000 {
            let training: Vec<usize> = (0..cells.len())
                .filter(|&i| cells[i].standing == Standing::Training)
                .collect();
            if training.is_empty() {
                break;
            }
            let i = training[*pick.next().unwrap() % training.len()];
            let k = cells[i].scores.len();
            cells[i].scores.push(scores[i][k]);
            cells[i].standing = if k + 1 == rungs {
                Standing::Closed
            } else {
                Standing::Paused
            };
            let due = if synchronous && !no_cell_training(&cells) {
                vec![]
            } else {
                decide(&cells, rungs, reduction)
            };
            for d in due {
                let mut reached: Vec<(CellId, f64)> = cells
                    .iter()
                    .filter(|c| c.scores.len() > d.rung)
                    .map(|c| (c.cell, c.scores[d.rung]))
                    .collect();
                reached.sort_by(|a, b| better(*a, *b));
                let rank = reached.iter().position(|r| r.0 == d.cell).unwrap();
                let open = cells
                    .iter()
                    .any(|c| c.standing == Standing::Training && c.scores.len() <= d.rung);
                log.push((d, rank, reached.len(), open));
                let c = &mut cells[d.cell.0 as usize];
                assert_eq!(c.standing, Standing::Paused, "decided twice: {d:?}");
                c.standing = if d.continued {
                    Standing::Training
                } else {
                    Standing::Closed
                };
            }
        }
        (cells, log)
    }

    /// Scores of `n` cells at `rungs` rungs, drawn from `raw`.
    fn scores_from(raw: &[f64], n: usize, rungs: usize) -> Vec<Vec<f64>> {
        (0..n)
            .map(|i| (0..rungs).map(|k| raw[(i * 5 + k) % raw.len()]).collect())
            .collect()
    }

    proptest! {
        #[test]
        fn every_sweep_ends_and_every_decision_follows_the_rules(
            n in 1usize..16,
            rungs in 1usize..5,
            reduction in 2u32..5,
            raw in proptest::collection::vec(-1.0f64..1.0, 80),
            order in proptest::collection::vec(0usize..100, 1..40),
        ) {
            let scores = scores_from(&raw, n, rungs);
            let (cells, log) = play(&scores, rungs, reduction, &order);
            // Everyone ends closed (done or stopped), nobody is left paused or training.
            prop_assert!(cells.iter().all(|c| c.standing == Standing::Closed));
            // At least one cell trains the full budget.
            prop_assert!(cells.iter().any(|c| c.scores.len() == rungs));
            for (d, rank, reached, open) in &log {
                if d.continued {
                    // Continued only from inside the rung's top (at least one once closed).
                    prop_assert!(*rank < quota(*reached, reduction, !*open));
                } else {
                    // Stopped only once nobody else can reach the rung, outside its top.
                    prop_assert!(!*open);
                    prop_assert!(*rank >= quota(*reached, reduction, true));
                }
            }
            // The best cell of rung 0 always gets past it when there is a later rung.
            if rungs > 1 {
                let best = (0..n).max_by(|&a, &b| better(
                    (CellId(b as i64), scores[b][0]), (CellId(a as i64), scores[a][0]))).unwrap();
                prop_assert!(cells[best].scores.len() > 1);
            }
        }

        #[test]
        fn a_synchronous_bracket_keeps_exactly_its_top_at_every_rung_whatever_the_order(
            n in 1usize..16,
            rungs in 1usize..5,
            reduction in 2u32..5,
            raw in proptest::collection::vec(-1.0f64..1.0, 80),
            order in proptest::collection::vec(0usize..100, 1..40),
        ) {
            let scores = scores_from(&raw, n, rungs);
            let (cells, _) = play_as(&scores, rungs, reduction, &order, true);
            prop_assert!(cells.iter().all(|c| c.standing == Standing::Closed));
            // n cells reach rung 0, then max(1, floor(n_k / eta)) each next rung: what
            // `halving_cost` budgets a generation at.
            let mut alive = n;
            for k in 0..rungs {
                prop_assert_eq!(cells.iter().filter(|c| c.scores.len() > k).count(), alive);
                alive = (alive / reduction as usize).max(1);
            }
            // The arrival order changes nothing.
            let (again, _) = play_as(&scores, rungs, reduction, &[0], true);
            prop_assert_eq!(
                cells.iter().map(|c| c.scores.len()).collect::<Vec<_>>(),
                again.iter().map(|c| c.scores.len()).collect::<Vec<_>>()
            );
        }

        #[test]
        fn a_rung_that_arrives_at_once_keeps_exactly_its_top(
            n in 1usize..30,
            reduction in 2u32..5,
            raw in proptest::collection::vec(-1.0f64..1.0, 30),
        ) {
            // Synchronous successive halving is the special case where every cell reaches
            // the rung before any decision: exactly max(1, floor(n / eta)) continue.
            let cells: Vec<AshaCell> = (0..n)
                .map(|i| cell(i as i64, &[raw[i]], Standing::Paused))
                .collect();
            let d = decide(&cells, 2, reduction);
            prop_assert_eq!(d.len(), n);
            let kept = d.iter().filter(|d| d.continued).count();
            prop_assert_eq!(kept, (n / reduction as usize).max(1));
            let worst_kept = d.iter().filter(|d| d.continued).map(|d| d.score).fold(f64::INFINITY, f64::min);
            let best_stopped = d.iter().filter(|d| !d.continued).map(|d| d.score).fold(f64::NEG_INFINITY, f64::max);
            prop_assert!(worst_kept >= best_stopped);
        }
    }
}
