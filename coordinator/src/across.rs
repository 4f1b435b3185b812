//! The grid point best across several terrains: the paper picks the weights where the
//! terrains' peaks overlap by eye; this makes it a rule. A point's value on a terrain is its
//! mean score (over replicates) divided by that terrain's best point mean, and the point
//! promoted across terrains is the one whose lowest such value is highest (max over points
//! of the min over terrains). Pure, so the store (the `promotions` row), `coordinator
//! show`, the report and the live page all apply the one rule.

use gaitsweep_core::stats::Summary;
use gaitsweep_core::{CellId, Place};
use std::collections::BTreeMap;

/// The rule in words, for the CLI, the report and the page.
pub const RULE: &str = "max over grid points of the min over terrains of (point mean / that terrain's best point mean)";

/// Terrain name stored in `promotions.terrain` for the point best across terrains (`''` is
/// the best single point over all terrains, a terrain's name its best there).
pub const ACROSS: &str = "*";

/// One scored cell: where it sits and its score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoredCell {
    /// The cell.
    pub cell: CellId,
    /// Index of its terrain.
    pub terrain: usize,
    /// Its grid point (an evolutionary candidate is never promoted across terrains).
    pub place: Place,
    /// Its final score.
    pub score: f64,
}

/// The point promoted across terrains.
#[derive(Debug, Clone, PartialEq)]
pub struct AcrossTerrains {
    /// Grid row.
    pub w1_index: u32,
    /// Grid column.
    pub w2_index: u32,
    /// min over terrains of the point's mean / the terrain's best mean (1: best everywhere).
    pub value: f64,
    /// Half-width of the 95% interval of `value`: the point's interval on its weakest
    /// terrain over that terrain's best mean (0 with one replicate).
    pub ci95: f64,
    /// The terrain where its value is lowest.
    pub weakest: usize,
    /// Its scored seeds on that terrain.
    pub seeds: usize,
    /// Its relative value on each terrain, by terrain index.
    pub relative: Vec<f64>,
    /// Its best replicate on the weakest terrain: the cell a promotion row names.
    pub cell: CellId,
}

impl AcrossTerrains {
    /// Its interval as people read it: "± 1.2%" of the weakest terrain's best, or, while
    /// the point has one scored seed there, that there is none yet.
    pub fn interval_text(&self) -> String {
        if self.seeds > 1 {
            format!("\u{b1} {:.1}%", 100.0 * self.ci95)
        } else {
            "(one seed: no interval yet)".to_string()
        }
    }
}

/// A point's scored replicates on one terrain.
type Replicates = Vec<(CellId, f64)>;

/// The point best across `terrains` terrains, or `None` when fewer than two terrains,
/// no point is scored on every terrain, or a terrain's best mean is not positive (the
/// ratio would not rank: a user reads the per-terrain promotions instead).
pub fn best_across(cells: &[ScoredCell], terrains: usize) -> Option<AcrossTerrains> {
    if terrains < 2 {
        return None;
    }
    // (w1, w2) -> terrain -> replicates.
    let mut points: BTreeMap<(u32, u32), BTreeMap<usize, Replicates>> = BTreeMap::new();
    for c in cells
        .iter()
        .filter(|c| c.score.is_finite() && c.terrain < terrains)
    {
        let Some(point) = c.place.grid() else {
            continue;
        };
        points
            .entry(point)
            .or_default()
            .entry(c.terrain)
            .or_default()
            .push((c.cell, c.score));
    }
    let summary = |r: &[(CellId, f64)]| Summary::of(&r.iter().map(|x| x.1).collect::<Vec<_>>());
    let mut best_mean = vec![f64::NEG_INFINITY; terrains];
    for by_terrain in points.values() {
        for (&t, r) in by_terrain {
            if let Some(s) = summary(r) {
                best_mean[t] = best_mean[t].max(s.mean);
            }
        }
    }
    if best_mean.iter().any(|b| !(*b > 0.0)) {
        return None;
    }
    let mut best: Option<AcrossTerrains> = None;
    for (&(i, j), by_terrain) in &points {
        if by_terrain.len() < terrains {
            continue;
        }
        let stats: Vec<(Summary, &Vec<(CellId, f64)>)> = (0..terrains)
            .filter_map(|t| Some((summary(&by_terrain[&t])?, &by_terrain[&t])))
            .collect();
        let relative: Vec<f64> = stats
            .iter()
            .enumerate()
            .map(|(t, (s, _))| s.mean / best_mean[t])
            .collect();
        let (weakest, value) =
            relative
                .iter()
                .copied()
                .enumerate()
                .fold(
                    (0, f64::INFINITY),
                    |a, (t, v)| if v < a.1 { (t, v) } else { a },
                );
        let (s, replicates) = &stats[weakest];
        let cell = replicates
            .iter()
            .fold(None::<(CellId, f64)>, |b, &(c, v)| match b {
                Some((bc, bv)) if bv > v || (bv == v && bc < c) => Some((bc, bv)),
                _ => Some((c, v)),
            })?
            .0;
        // Strictly higher wins: points are visited in grid order, so a tie goes to the
        // lower (w1, w2) index whatever order the results arrived in.
        if best.as_ref().is_none_or(|b| value > b.value) {
            best = Some(AcrossTerrains {
                w1_index: i,
                w2_index: j,
                value,
                ci95: s.ci95 / best_mean[weakest],
                weakest,
                seeds: s.n,
                relative,
                cell,
            });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cell(id: i64, terrain: usize, i: u32, j: u32, score: f64) -> ScoredCell {
        ScoredCell {
            cell: CellId(id),
            terrain,
            place: Place::point(i, j),
            score,
        }
    }

    #[test]
    fn the_point_good_on_both_terrains_beats_the_peaks_of_each() {
        // Point (0,0) peaks on terrain 0, (0,2) on terrain 1; (0,1) is 90% of both.
        let cells = [
            cell(1, 0, 0, 0, 1.0),
            cell(2, 0, 0, 1, 0.9),
            cell(3, 0, 0, 2, 0.2),
            cell(4, 1, 0, 0, 0.1),
            cell(5, 1, 0, 1, 0.45),
            cell(6, 1, 0, 2, 0.5),
        ];
        let a = best_across(&cells, 2).unwrap();
        assert_eq!((a.w1_index, a.w2_index), (0, 1));
        assert!((a.value - 0.9).abs() < 1e-12);
        assert_eq!(a.relative.len(), 2);
        assert_eq!(
            a.interval_text(),
            "(one seed: no interval yet)",
            "not \u{b1} 0.0%"
        );
        assert_eq!(best_across(&cells, 1), None);
    }

    #[test]
    fn replicates_give_an_interval_and_the_best_replicate_of_the_weakest_terrain() {
        let cells = [
            cell(1, 0, 0, 0, 1.0),
            cell(2, 0, 0, 0, 0.8),
            cell(3, 1, 0, 0, 0.5),
            cell(4, 1, 0, 0, 0.7),
            cell(5, 1, 1, 0, 1.2),
            cell(6, 0, 1, 0, 0.1),
        ];
        let a = best_across(&cells, 2).unwrap();
        assert_eq!((a.w1_index, a.weakest), (0, 1));
        assert!((a.value - 0.5).abs() < 1e-12, "{a:?}");
        assert_eq!(a.cell, CellId(4));
        // 0.5 and 0.7: t(1) 12.706 x SD 0.141 / sqrt 2 = 1.271, over the best mean 1.2.
        assert!((a.ci95 - 12.706 * 0.02f64.sqrt() / 2f64.sqrt() / 1.2).abs() < 1e-9);
        assert_eq!(a.interval_text(), "\u{b1} 105.9%");
    }

    #[test]
    fn a_terrain_without_a_positive_best_promotes_nothing() {
        let cells = [cell(1, 0, 0, 0, 1.0), cell(2, 1, 0, 0, -0.1)];
        assert_eq!(best_across(&cells, 2), None);
    }

    proptest! {
        /// The promoted point's lowest relative value is at least every other complete
        /// point's, and no relative value exceeds 1.
        #[test]
        fn no_point_is_better_on_its_weakest_terrain(
            scores in proptest::collection::vec(0.01f64..1.0, 12),
        ) {
            let cells: Vec<ScoredCell> = scores
                .iter()
                .enumerate()
                .map(|(k, &s)| cell(k as i64, k % 2, (k / 2 % 3) as u32, (k / 6) as u32, s))
                .collect();
            let a = best_across(&cells, 2).unwrap();
            prop_assert!(a.relative.iter().all(|r| *r <= 1.0 + 1e-12));
            for p in 0..6u32 {
                let (i, j) = (p % 3, p / 3);
                let on = |t: usize| cells.iter().find(|c| c.terrain == t && c.place == Place::point(i, j)).unwrap().score;
                let best = |t: usize| cells.iter().filter(|c| c.terrain == t).map(|c| c.score).fold(0.0, f64::max);
                let v = (on(0) / best(0)).min(on(1) / best(1));
                prop_assert!(v <= a.value + 1e-12);
            }
        }
    }
}
