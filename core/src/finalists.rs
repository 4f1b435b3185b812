//! Finalists: after a grid's single-seed pass, the best points of each terrain are trained
//! again with more seeds (the paper's study: one seed per cell, then replicates of the best
//! points), and the sweep promotes among them by the mean over their seeds.

use serde::{Deserialize, Serialize};

use crate::spec::{splitmix64, CellPlan, ResolvedSpec, Search, MAX_REPLICATES};

/// `[finalists]` as a user writes it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FinalistsSpec {
    /// Points per terrain that become finalists (by their single-seed score).
    pub top: u32,
    /// Seeds each finalist ends with, the first pass's included (so `seeds - 1` more).
    pub seeds: u32,
}

/// Validated finalists of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Finalists {
    /// Points per terrain.
    pub top: u32,
    /// Seeds per finalist in all.
    pub seeds: u32,
}

impl FinalistsSpec {
    /// Checks the section against the rest of the spec; pushes every problem.
    pub(crate) fn resolve(
        &self,
        search: &Search,
        replicates: u32,
        points_per_terrain: usize,
        problems: &mut Vec<String>,
    ) -> Option<Finalists> {
        let before = problems.len();
        if !matches!(search, Search::Grid) {
            problems.push(format!(
                "finalists follow a full grid: search.method {} ranks its own candidates, drop [finalists] or use method = \"grid\"",
                search.method()
            ));
        }
        if replicates > 1 {
            problems.push(format!(
                "finalists add seeds to the best points of a single-seed grid, but seeds is {replicates}: use seeds = 1 with [finalists]"
            ));
        }
        if self.top == 0 || self.top as usize > points_per_terrain {
            problems.push(format!(
                "finalists.top is {}: use 1 to {points_per_terrain} (the grid's points per terrain)",
                self.top
            ));
        }
        if self.seeds < 2 || self.seeds > MAX_REPLICATES {
            problems.push(format!(
                "finalists.seeds is {}: use 2 to {MAX_REPLICATES} (seeds per finalist, the first pass's included)",
                self.seeds
            ));
        }
        (problems.len() == before).then_some(Finalists {
            top: self.top,
            seeds: self.seeds,
        })
    }
}

/// A grid point of a sweep: (terrain index, w1 index, w2 index).
pub type Point = (usize, usize, usize);

impl ResolvedSpec {
    /// The finalist stage's cells for `points`: replicates 1..seeds of each, with the seeds
    /// a grid of `seeds = finalists.seeds` gives those replicates (so a finalist trains
    /// exactly as that point would in a fully replicated grid). Empty without finalists.
    pub fn finalist_cells(&self, points: &[Point]) -> Vec<CellPlan> {
        let Some(f) = self.finalists else {
            return vec![];
        };
        let per_terrain = self.w1_values.len() * self.w2_values.len();
        let all = self.point_count() as u64;
        let mut out = Vec::new();
        for &(ti, i, j) in points {
            let (Some(terrain), Some(&w1), Some(&w2)) = (
                self.terrains.get(ti),
                self.w1_values.get(i),
                self.w2_values.get(j),
            ) else {
                continue;
            };
            let ordinal = (ti * per_terrain + i * self.w2_values.len() + j) as u64;
            for r in 1..f.seeds {
                out.push(CellPlan {
                    terrain_index: ti,
                    terrain: *terrain,
                    place: crate::Place::point(i as u32, j as u32),
                    w1,
                    w2,
                    replicate: r,
                    seed: splitmix64(self.seed.wrapping_add(ordinal + u64::from(r) * all)),
                });
            }
        }
        out
    }

    /// Cells the finalist stage will queue: `top` points of each terrain, `seeds - 1` more
    /// seeds each (fewer only if a terrain ends with fewer scored points). 0 without
    /// finalists. What a progress count adds while the first pass runs.
    pub fn finalist_cell_count(&self) -> usize {
        self.finalists.map_or(0, |f| {
            self.terrains.len() * f.top as usize * (f.seeds as usize).saturating_sub(1)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::{Axis, PresetGrid, SweepSpec};

    fn resolve(extra: &str) -> crate::Result<ResolvedSpec> {
        let text = format!(
            "robot = \"anymal\"\nterrains = [\"rough\", \"stairs\"]\nw1 = {{ values = [2.0, 7.0, 12.0] }}\nw2 = {{ values = [-10.0, -2.0] }}\nagents_per_cell = 8\nepochs = 10\n{extra}"
        );
        SweepSpec::from_toml(&text).unwrap().resolve_with(|_| {
            Ok((
                PresetGrid {
                    w1: Axis::Values { values: vec![1.0] },
                    w2: Axis::Values { values: vec![1.0] },
                    agents_per_cell: 8,
                    epochs: 10,
                },
                None,
            ))
        })
    }

    #[test]
    fn finalists_train_with_the_seeds_of_a_replicated_grid() {
        let s = resolve("[finalists]\ntop = 2\nseeds = 3").unwrap();
        assert_eq!(s.finalists, Some(Finalists { top: 2, seeds: 3 }));
        assert_eq!(s.cell_count(), 12, "the first pass is one seed per point");
        let replicated = resolve("seeds = 3").unwrap().cells();
        let picks = [(1, 2, 0), (0, 0, 1)];
        let cells = s.finalist_cells(&picks);
        assert_eq!(cells.len(), 4);
        assert_eq!(
            s.finalist_cell_count(),
            8,
            "2 terrains x 2 points x 2 more seeds"
        );
        assert_eq!(resolve("").unwrap().finalist_cell_count(), 0);
        for c in &cells {
            let twin = replicated
                .iter()
                .find(|r| {
                    (r.terrain_index, r.place, r.replicate)
                        == (c.terrain_index, c.place, c.replicate)
                })
                .unwrap();
            assert_eq!(c, twin);
            assert!(c.replicate >= 1);
        }
    }

    #[test]
    fn bad_finalists_say_what_to_use() {
        let problems = |extra: &str| match resolve(extra) {
            Err(crate::Error::InvalidSpec(p)) => p.join("\n"),
            other => panic!("expected an invalid spec, got {other:?}"),
        };
        assert!(problems("[finalists]\ntop = 7\nseeds = 3").contains("use 1 to 6"));
        assert!(problems("[finalists]\ntop = 2\nseeds = 1").contains("use 2 to"));
        assert!(problems("seeds = 2\n[finalists]\ntop = 2\nseeds = 3").contains("seeds = 1"));
        assert!(
            problems("[search]\nmethod = \"asha\"\n[finalists]\ntop = 2\nseeds = 3")
                .contains("method = \"grid\"")
        );
        assert!(SweepSpec::from_toml(
            "robot = \"anymal\"\n[finalists]\ntop = 1\nseeds = 2\nbest = 3"
        )
        .is_err());
    }
}
