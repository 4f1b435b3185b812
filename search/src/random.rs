//! A plain random search over the grid (`[search] method = "random"`): a number of the
//! grid's points drawn without replacement from the sweep's seed, each trained as the grid
//! trains it (on every terrain, every replicate, to the end). The baseline every other
//! search should beat at the same share of the grid's epochs (Bergstra and Bengio 2012
//! found random search a strong one in low dimensions); search-bench replays the same draw.

use crate::method::{Action, CellView, Description, Layout, SearchMethod};
use gaitsweep_core::spec::CellPlan;
use gaitsweep_core::{Place, ResolvedSpec};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeSet;

/// Keeps the draw's stream apart from the other uses of the sweep's seed.
const STREAM: u64 = 0x7261_6e64_6f6d_0001;

/// `k` distinct points (w1 index, w2 index) of a `w1` x `w2` grid, drawn from `seed`: the
/// same seed draws the same points on every machine, and its first `k` points are the
/// first `k` of any larger draw.
pub fn random_points(w1: usize, w2: usize, k: usize, seed: u64) -> Vec<(usize, usize)> {
    let mut all: Vec<(usize, usize)> = (0..w1).flat_map(|i| (0..w2).map(move |j| (i, j))).collect();
    all.shuffle(&mut ChaCha8Rng::seed_from_u64(seed ^ STREAM));
    all.truncate(k);
    all
}

/// Random search over the grid.
pub(crate) struct Random {
    /// Grid points to train.
    pub points: u32,
}

impl SearchMethod for Random {
    fn name(&self) -> &'static str {
        "random"
    }
    fn describe(&self, spec: &ResolvedSpec) -> Description {
        let grid = spec.w1_values.len() * spec.w2_values.len();
        Description {
            name: self.name(),
            title: "random search",
            layout: Layout::Grid,
            budget: format!(
                "random search: {} of the grid's {grid} points drawn at random, each trained all its epochs",
                self.points
            ),
            known_total: true,
        }
    }
    fn initial_cells(&self, spec: &ResolvedSpec) -> Result<Vec<CellPlan>, String> {
        let drawn: BTreeSet<Place> = random_points(
            spec.w1_values.len(),
            spec.w2_values.len(),
            self.points as usize,
            spec.seed,
        )
        .into_iter()
        .map(|(i, j)| Place::point(i as u32, j as u32))
        .collect();
        Ok(spec
            .cells_in_lease_order()
            .into_iter()
            .filter(|c| drawn.contains(&c.place))
            .collect())
    }
    fn react(&self, _: &ResolvedSpec, _: &[CellView]) -> Result<Vec<Action>, String> {
        Ok(vec![])
    }
    fn reacts(&self) -> bool {
        false
    }
}
