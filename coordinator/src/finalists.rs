//! The finalist stage of a grid (`[finalists]` in a spec): which points get more seeds
//! after the single-seed pass, and which finalist the sweep promotes once they are trained.
//! Pure, so the store and the tests apply one rule.

use std::collections::{BTreeMap, BTreeSet};

use gaitsweep_core::finalists::Point;
use gaitsweep_core::stats::Summary;
use gaitsweep_core::CellId;

use crate::across::ScoredCell;

/// The rule in words, for logs and docs.
pub const RULE: &str = "the top points of each terrain by their single-seed score get more seeds, then the point best across terrains gets them on every terrain where it has not; the finalist with the highest mean over its seeds is promoted";

fn point(c: &ScoredCell) -> Point {
    let (i, j) = c.place.pair();
    (c.terrain, i as usize, j as usize)
}

/// The `top` best points of each terrain by score (finite scores only), best first; ties
/// go to the lower (w1, w2) index. Cells of one point are averaged (the first pass has one).
pub fn pick(cells: &[ScoredCell], top: u32) -> Vec<Point> {
    let mut by_terrain: BTreeMap<usize, Vec<(Point, f64)>> = BTreeMap::new();
    for (p, s) in summaries(cells) {
        by_terrain.entry(p.0).or_default().push((p, s.mean));
    }
    let mut out = Vec::new();
    for (_, mut points) in by_terrain {
        // Stable sort over grid order: equal means keep the lower index first.
        points.sort_by(|a, b| b.1.total_cmp(&a.1));
        out.extend(points.into_iter().take(top as usize).map(|p| p.0));
    }
    out
}

/// The finalists still to queue before a sweep over several terrains may end: the point
/// best across the terrains ([`crate::across::best_across`]) on each terrain where it is not
/// yet a finalist, so that the weights handed back for every terrain hold on as many seeds
/// as each terrain's own best (and the rule's value gets an interval). Empty with fewer
/// than two terrains, no such point, or one that is a finalist everywhere.
///
/// Each call adds the pick's missing terrains to `finalists`, so a sweep that calls it
/// whenever its cells close queues at most every point once per terrain: if the new seeds
/// move the pick to another point, that point is confirmed next.
pub fn across_to_confirm(
    cells: &[ScoredCell],
    terrains: usize,
    finalists: &BTreeSet<Point>,
) -> Vec<Point> {
    let Some(a) = crate::across::best_across(cells, terrains) else {
        return vec![];
    };
    (0..terrains)
        .map(|t| (t, a.w1_index as usize, a.w2_index as usize))
        .filter(|p| !finalists.contains(p))
        .collect()
}

/// A promoted finalist.
#[derive(Debug, Clone, PartialEq)]
pub struct Winner {
    /// Its grid point.
    pub point: Point,
    /// Its best-scoring replicate, whose checkpoint is the model.
    pub cell: CellId,
    /// Mean, spread and interval over its scored seeds.
    pub stats: Summary,
}

/// The promoted finalists: the best over all terrains, and the best of each terrain (by
/// terrain index), each by the mean over its seeds; ties go to the lower grid index.
/// Cells of points outside `finalists` are ignored.
pub fn winners(
    cells: &[ScoredCell],
    finalists: &BTreeSet<Point>,
) -> (Option<Winner>, BTreeMap<usize, Winner>) {
    let inside: Vec<ScoredCell> = cells
        .iter()
        .filter(|c| finalists.contains(&point(c)))
        .copied()
        .collect();
    let mut per_terrain: BTreeMap<usize, Winner> = BTreeMap::new();
    let mut overall: Option<Winner> = None;
    for (p, stats) in summaries(&inside) {
        let cell = inside
            .iter()
            .filter(|c| point(c) == p && c.score.is_finite())
            .fold(None::<(CellId, f64)>, |b, c| match b {
                Some((bc, bv)) if bv > c.score || (bv == c.score && bc < c.cell) => Some((bc, bv)),
                _ => Some((c.cell, c.score)),
            });
        let Some((cell, _)) = cell else { continue };
        let w = Winner {
            point: p,
            cell,
            stats,
        };
        // Points come in grid order, so strictly higher wins and ties keep the lower index.
        if per_terrain
            .get(&p.0)
            .is_none_or(|b| w.stats.mean > b.stats.mean)
        {
            per_terrain.insert(p.0, w.clone());
        }
        if overall.as_ref().is_none_or(|b| w.stats.mean > b.stats.mean) {
            overall = Some(w);
        }
    }
    (overall, per_terrain)
}

/// Each point's summary over its finite scores, in grid order.
fn summaries(cells: &[ScoredCell]) -> BTreeMap<Point, Summary> {
    let mut scores: BTreeMap<Point, Vec<f64>> = BTreeMap::new();
    for c in cells.iter().filter(|c| c.score.is_finite()) {
        scores.entry(point(c)).or_default().push(c.score);
    }
    scores
        .into_iter()
        .filter_map(|(p, v)| Some((p, Summary::of(&v)?)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cell(id: i64, t: usize, i: u32, j: u32, score: f64) -> ScoredCell {
        ScoredCell {
            cell: CellId(id),
            terrain: t,
            place: gaitsweep_core::Place::point(i, j),
            score,
        }
    }

    #[test]
    fn the_top_points_of_each_terrain_are_picked() {
        let cells = [
            cell(1, 0, 0, 0, 0.2),
            cell(2, 0, 0, 1, 0.9),
            cell(3, 0, 1, 0, f64::NAN),
            cell(4, 0, 1, 1, 0.5),
            cell(5, 1, 0, 0, 0.7),
            cell(6, 1, 0, 1, 0.7),
            cell(7, 1, 1, 1, 0.1),
        ];
        assert_eq!(
            pick(&cells, 2),
            vec![(0, 0, 1), (0, 1, 1), (1, 0, 0), (1, 0, 1)],
            "best first, a NaN never picked, a tie keeps grid order"
        );
        assert_eq!(pick(&cells, 9).len(), 6, "at most the scored points");
    }

    #[test]
    fn the_finalist_with_the_best_mean_wins_not_the_best_single_run() {
        // Point (0,0,0) had the lucky first run 0.9, its other seeds 0.3 and 0.3 (mean 0.5);
        // point (0,0,1) scored 0.8, 0.7, 0.6 (mean 0.7). A non-finalist's 0.95 is ignored.
        let cells = [
            cell(1, 0, 0, 0, 0.9),
            cell(2, 0, 0, 1, 0.8),
            cell(3, 0, 1, 1, 0.95),
            cell(4, 0, 0, 0, 0.3),
            cell(5, 0, 0, 0, 0.3),
            cell(6, 0, 0, 1, 0.7),
            cell(7, 0, 0, 1, 0.6),
        ];
        let f: BTreeSet<Point> = [(0, 0, 0), (0, 0, 1)].into();
        let (best, per) = winners(&cells, &f);
        let best = best.unwrap();
        assert_eq!((best.point, best.cell), ((0, 0, 1), CellId(2)));
        assert!((best.stats.mean - 0.7).abs() < 1e-12 && best.stats.n == 3);
        assert!(best.stats.ci95 > 0.0);
        assert_eq!(per[&0], best);
    }

    #[test]
    fn the_point_best_across_terrains_is_confirmed_where_it_is_no_finalist() {
        // Terrain 0's top point is (0,0), terrain 1's (1,1); (0,1) is 90% of both bests.
        let cells = [
            cell(1, 0, 0, 0, 1.0),
            cell(2, 0, 0, 1, 0.9),
            cell(3, 0, 1, 1, 0.1),
            cell(4, 1, 0, 0, 0.1),
            cell(5, 1, 0, 1, 0.45),
            cell(6, 1, 1, 1, 0.5),
        ];
        let picked: BTreeSet<Point> = pick(&cells, 1).into_iter().collect();
        assert_eq!(picked, [(0, 0, 0), (1, 1, 1)].into());
        assert_eq!(
            across_to_confirm(&cells, 2, &picked),
            vec![(0, 0, 1), (1, 0, 1)],
            "a finalist on neither terrain: both"
        );
        let mut with_one: BTreeSet<Point> = picked.clone();
        with_one.insert((0, 0, 1));
        assert_eq!(across_to_confirm(&cells, 2, &with_one), vec![(1, 0, 1)]);
        with_one.insert((1, 0, 1));
        assert!(across_to_confirm(&cells, 2, &with_one).is_empty(), "done");
        assert!(
            across_to_confirm(&cells, 1, &picked).is_empty(),
            "one terrain has nothing across it"
        );
    }

    proptest! {
        /// Confirming the pick over and over (new seeds may move it) ends, with the last
        /// pick a finalist on every terrain.
        #[test]
        fn confirming_the_pick_across_terrains_ends(
            scores in proptest::collection::vec((0usize..2, 0u32..3, 0u32..3, 0.0f64..1.0), 1..30),
            later in proptest::collection::vec(0.0f64..1.0, 60),
        ) {
            let mut cells: Vec<ScoredCell> = scores
                .iter()
                .enumerate()
                .map(|(k, &(t, i, j, s))| cell(k as i64, t, i, j, s))
                .collect();
            let mut finalists: BTreeSet<Point> = pick(&cells, 1).into_iter().collect();
            let mut rounds = 0;
            loop {
                let missing = across_to_confirm(&cells, 2, &finalists);
                if missing.is_empty() {
                    break;
                }
                rounds += 1;
                prop_assert!(rounds <= 18, "at most every point once per terrain");
                for p in missing {
                    prop_assert!(finalists.insert(p), "never queued twice");
                    // Two more seeds, with arbitrary scores.
                    for _ in 0..2 {
                        let k = cells.len();
                        cells.push(cell(k as i64, p.0, p.1 as u32, p.2 as u32, later[k % later.len()]));
                    }
                }
            }
            if let Some(a) = crate::across::best_across(&cells, 2) {
                for t in 0..2 {
                    prop_assert!(finalists.contains(&(t, a.w1_index as usize, a.w2_index as usize)));
                }
            }
        }

        #[test]
        fn winners_are_finalists_with_the_highest_mean(
            scores in proptest::collection::vec((0usize..2, 0u32..3, 0u32..3, -1.0f64..1.0), 1..40),
            top in 1u32..4,
        ) {
            let cells: Vec<ScoredCell> = scores
                .iter()
                .enumerate()
                .map(|(k, &(t, i, j, s))| cell(k as i64, t, i, j, s))
                .collect();
            let picked: BTreeSet<Point> = pick(&cells, top).into_iter().collect();
            for t in 0..2 {
                let n = picked.iter().filter(|p| p.0 == t).count();
                let points: BTreeSet<Point> = cells.iter().filter(|c| c.terrain == t).map(point).collect();
                prop_assert_eq!(n, points.len().min(top as usize));
            }
            let (best, per) = winners(&cells, &picked);
            let means = summaries(&cells);
            if let Some(b) = &best {
                prop_assert!(picked.contains(&b.point));
                for p in &picked {
                    prop_assert!(means[p].mean <= b.stats.mean);
                }
                prop_assert!(cells.iter().any(|c| c.cell == b.cell && point(c) == b.point));
            }
            for (t, w) in &per {
                prop_assert_eq!(w.point.0, *t);
                for p in picked.iter().filter(|p| p.0 == *t) {
                    prop_assert!(means[p].mean <= w.stats.mean);
                }
            }
        }
    }
}
