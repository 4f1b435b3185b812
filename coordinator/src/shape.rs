//! The shape of a terrain's score grid, for holding a sweep against the paper's findings
//! (issue 39 item 5): where the peak is (in the grid's interior or on its edge), whether
//! the score rises towards it between neighbouring points, how much of the score's range
//! one step spans (a cliff), and which rows of w1 stand still at every w2 (the heavy
//! robot's w1 = 2 row in the paper). Pure: the report gives
//! it the grid's point means.

/// Below this mean speed (m/s) a grid point counts as standing still: the command
/// sampler's own dead zone (speeds under 0.2 m/s are commanded as 0).
pub const STANDING_SPEED: f64 = 0.2;

/// A grid of values `[w1_index][w2_index]`, `None` where a point has no value.
pub type GridValues = Vec<Vec<Option<f64>>>;

/// A grid's shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    /// The best point (w1 index, w2 index) by mean score.
    pub peak: (usize, usize),
    /// Its mean score.
    pub peak_mean: f64,
    /// Whether it is off the grid's first and last row and column.
    pub interior: bool,
    /// Steps between neighbouring scored points (along w1 or w2, on the same side of the
    /// peak) where the point nearer the peak scores higher.
    pub rising: usize,
    /// Such steps compared.
    pub steps: usize,
    /// The largest score difference between two neighbouring points, both rewarded: where
    /// one step spans most of the grid's range the surface is a cliff, where it takes
    /// several it is a raised peak. `None` without such a step or with no difference.
    pub largest_step: Option<Step>,
    /// Rows (w1 indices) whose every point is scored and stands still (mean speed under
    /// [`STANDING_SPEED`]), leaving out the points never rewarded (at least one must remain).
    pub standing_rows: Vec<usize>,
}

/// The largest step between two neighbouring points of a grid ([`Shape::largest_step`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// Its score difference as a share of the range of the rewarded points' means (best
    /// minus lowest).
    pub share: f64,
    /// The two points (w1 index, w2 index): the one farther from the peak, then the nearer.
    pub points: [(usize, usize); 2],
}

/// The shape of a grid of point means `score[i][j]` (w1 index i, w2 index j) with the
/// points' mean speeds and the points never rewarded, which are left out of the standing
/// rows and the largest step: a policy that learned nothing can run and fall at 4 m/s, and
/// its score says nothing of what its weights teach. `None` when no point is scored.
pub fn shape(
    score: &[Vec<Option<f64>>],
    speed: &[Vec<Option<f64>>],
    unrewarded: &[(usize, usize)],
) -> Option<Shape> {
    let mut peak: Option<((usize, usize), f64)> = None;
    for (i, row) in score.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            if let Some(v) = v.filter(|v| v.is_finite()) {
                if peak.is_none_or(|(_, b)| v > b) {
                    peak = Some(((i, j), v));
                }
            }
        }
    }
    let ((pi, pj), peak_mean) = peak?;
    let rows = score.len();
    let cols = score.iter().map(Vec::len).max().unwrap_or(0);
    let at = |(i, j): (usize, usize)| {
        score
            .get(i)
            .and_then(|r| r.get(j))
            .copied()
            .flatten()
            .filter(|v| v.is_finite())
    };
    let taught = |p: &(usize, usize)| !unrewarded.contains(p);
    let (mut rising, mut steps) = (0, 0);
    let mut largest: Option<(f64, [(usize, usize); 2])> = None;
    // Each neighbouring pair is compared once: the point farther from the peak with the one
    // nearer, which for the pairs that cross the peak's row or column is in it.
    let mut compare = |near: (usize, usize), far: (usize, usize)| {
        if let (Some(n), Some(f)) = (at(near), at(far)) {
            steps += 1;
            rising += usize::from(n > f);
            let d = (n - f).abs();
            if taught(&near) && taught(&far) && largest.is_none_or(|l| d > l.0) {
                largest = Some((d, [far, near]));
            }
        }
    };
    for i in 0..rows {
        for j in 0..cols {
            // Each point against its neighbour one step nearer the peak, along w1 and w2.
            if i != pi {
                let near = if i < pi { i + 1 } else { i - 1 };
                compare((near, j), (i, j));
            }
            if j != pj {
                let near = if j < pj { j + 1 } else { j - 1 };
                compare((i, near), (i, j));
            }
        }
    }
    // A point never rewarded learned nothing, so its speed (often a fall at full tilt) says
    // nothing of whether its row's weights teach standing.
    let standing_rows = (0..rows)
        .filter(|&i| {
            let r = speed.get(i).map(Vec::as_slice).unwrap_or(&[]);
            let taught: Vec<usize> = (0..cols)
                .filter(|&j| !unrewarded.contains(&(i, j)))
                .collect();
            !taught.is_empty()
                && taught.iter().all(|&j| {
                    r.get(j)
                        .copied()
                        .flatten()
                        .is_some_and(|v| v < STANDING_SPEED)
                })
        })
        .collect();
    let rewarded: Vec<f64> = (0..rows)
        .flat_map(|i| (0..cols).map(move |j| (i, j)))
        .filter(taught)
        .filter_map(at)
        .collect();
    let range = rewarded.iter().copied().fold(f64::MIN, f64::max)
        - rewarded.iter().copied().fold(f64::MAX, f64::min);
    Some(Shape {
        peak: (pi, pj),
        peak_mean,
        interior: pi > 0 && pj > 0 && pi + 1 < rows && pj + 1 < cols,
        rising,
        steps,
        largest_step: largest
            .filter(|l| l.0 > 0.0 && range > 0.0)
            .map(|(d, points)| Step {
                share: d / range,
                points,
            }),
        standing_rows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn grid(f: impl Fn(usize, usize) -> Option<f64>, rows: usize, cols: usize) -> GridValues {
        (0..rows)
            .map(|i| (0..cols).map(|j| f(i, j)).collect())
            .collect()
    }

    #[test]
    fn an_interior_hill_rises_towards_its_peak_on_every_step() {
        // The paper's ANYmal picture: one hill inside a 4 x 7 grid.
        let hill = grid(
            |i, j| Some(1.0 - (i as f64 - 2.0).powi(2) * 0.1 - (j as f64 - 4.0).powi(2) * 0.05),
            4,
            7,
        );
        let s = shape(&hill, &grid(|_, _| Some(1.0), 4, 7), &[]).unwrap();
        assert_eq!((s.peak, s.interior), ((2, 4), true));
        assert_eq!(s.rising, s.steps);
        // Every point but the peak's row and column has one step each way; 4 x 7 has
        // 3 x 7 steps along w1 and 4 x 6 along w2, all towards the peak.
        assert_eq!(s.steps, 3 * 7 + 4 * 6);
        assert!(s.standing_rows.is_empty());
        // Range 0.4 + 0.8 = 1.2 (corner (0, 0) is lowest); the steepest step is at the w2
        // edge, 0.05 x (16 - 9) = 0.35 (the w1 edge's is 0.1 x (4 - 1) = 0.3).
        let step = s.largest_step.clone().unwrap();
        assert!((step.share - 0.35 / 1.2).abs() < 1e-9, "{s:?}");
        let [far, near] = step.points;
        assert_eq!(
            (far.0, far.1, near.1),
            (near.0, 0, 1),
            "a step from w2's edge"
        );
        assert!(step.share < 0.5, "a hill climbs in several steps");
    }

    #[test]
    fn a_cliff_peaks_on_the_edge_and_its_low_row_stands() {
        // The paper's heavy robot: w1 = 2 stands in every column, the score climbs to the
        // grid's edge.
        let cliff = grid(
            |i, j| {
                Some(if i == 0 {
                    -0.3
                } else {
                    0.2 * i as f64 + 0.01 * j as f64
                })
            },
            4,
            4,
        );
        let speed = grid(|i, _| Some(if i == 0 { 0.05 } else { 0.9 }), 4, 4);
        let s = shape(&cliff, &speed, &[]).unwrap();
        assert_eq!((s.peak, s.interior), ((3, 3), false));
        assert_eq!(s.standing_rows, vec![0]);
        // The standing row is flat along w2: its 3 steps are ties, which do not rise.
        assert_eq!((s.rising, s.steps), (21, 24));
        // From the standing row (-0.3) to the next (0.2 + 0.01 j), 0.53 at j = 3, of the
        // range 0.93 (-0.3 to 0.63).
        let step = s.largest_step.clone().unwrap();
        assert!((step.share - 0.53 / 0.93).abs() < 1e-9, "{s:?}");
        assert_eq!(step.points, [(0, 3), (1, 3)]);
        // With the standing row never rewarded, the steepest step is one row up (0.2 of
        // the rewarded rows' range 0.2 to 0.63), and that row no longer stands.
        let row0: Vec<_> = (0..4).map(|j| (0, j)).collect();
        let taught = shape(&cliff, &speed, &row0).unwrap();
        let step = taught.largest_step.clone().unwrap();
        assert!((step.share - 0.2 / 0.43).abs() < 1e-9, "{step:?}");
        let [far, near] = step.points;
        assert_eq!((far.0 + 1, far.1), near, "a step along w1");
        assert!(taught.standing_rows.is_empty());
        assert_eq!(
            (taught.rising, taught.steps),
            (21, 24),
            "rising counts every point"
        );
        // A row with an unscored point is not called standing.
        let mut partial = speed.clone();
        partial[0][2] = None;
        assert!(shape(&cliff, &partial, &[])
            .unwrap()
            .standing_rows
            .is_empty());
        // A point never rewarded runs (falls) at 4 m/s: it is left out of its row, unless
        // it is all the row has.
        let mut flailing = speed.clone();
        flailing[0][3] = Some(4.0);
        assert!(shape(&cliff, &flailing, &[])
            .unwrap()
            .standing_rows
            .is_empty());
        assert_eq!(
            shape(&cliff, &flailing, &[(0, 3)]).unwrap().standing_rows,
            vec![0]
        );
        let whole_row: Vec<_> = (0..4).map(|j| (0, j)).collect();
        assert!(shape(&cliff, &flailing, &whole_row)
            .unwrap()
            .standing_rows
            .is_empty());
    }

    #[test]
    fn missing_points_are_skipped_and_an_empty_grid_has_no_shape() {
        assert_eq!(shape(&grid(|_, _| None, 2, 2), &[], &[]), None);
        let holes = grid(|i, j| ((i + j) % 2 == 0).then_some((i + j) as f64), 3, 3);
        let s = shape(&holes, &[], &[]).unwrap();
        assert_eq!(s.peak, (2, 2));
        // No two neighbours are both scored on a checkerboard.
        assert_eq!((s.steps, s.largest_step), (0, None));
        // Ties only, the range widened by a point with no neighbour: no step to speak of.
        let ties = grid(
            |i, j| match (i, j) {
                (0, 0) | (0, 1) => Some(0.5),
                (2, 3) => Some(-0.5),
                _ => None,
            },
            3,
            4,
        );
        let s = shape(&ties, &[], &[]).unwrap();
        assert_eq!((s.steps, s.largest_step), (1, None));
        // A NaN point is no point: not a step, not the peak.
        let mut nan = ties.clone();
        nan[1][0] = Some(f64::NAN);
        let s = shape(&nan, &[], &[]).unwrap();
        assert_eq!((s.steps, s.peak), (1, (0, 0)));
        nan[0][0] = Some(f64::INFINITY);
        assert_eq!(
            shape(&nan, &[], &[]).unwrap().peak,
            (0, 1),
            "nor is an infinite one"
        );
    }

    proptest! {
        #[test]
        fn the_peak_is_the_best_point_and_rising_never_exceeds_steps(
            v in proptest::collection::vec(proptest::option::of(-1.0f64..1.0), 12),
        ) {
            let g = grid(|i, j| v[i * 4 + j], 3, 4);
            match shape(&g, &[], &[]) {
                None => prop_assert!(v.iter().all(Option::is_none)),
                Some(s) => {
                    let best = v.iter().flatten().cloned().fold(f64::MIN, f64::max);
                    prop_assert_eq!(s.peak_mean, best);
                    prop_assert_eq!(g[s.peak.0][s.peak.1], Some(best));
                    prop_assert!(s.rising <= s.steps);
                    if let Some(l) = s.largest_step {
                        prop_assert!(l.share > 0.0 && l.share <= 1.0 + 1e-12, "{:?}", l);
                    }
                }
            }
        }
    }
}
