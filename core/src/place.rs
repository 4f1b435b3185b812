//! Where a cell stands in its sweep's layout: a point of the grid, or a candidate of an
//! evolutionary search (CMA-ES, the genetic algorithm). Stored in columns of their own
//! (`cells.w1_index`/`w2_index` or `cells.generation`/`candidate`), never one pair
//! standing for the other.

use crate::{Error, Result};

/// Where a cell stands in its sweep: the replicates of one place share it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Place {
    /// A grid point: indices into the spec's w1 and w2 axes.
    Point {
        /// Row: index into the w1 axis.
        w1_index: u32,
        /// Column: index into the w2 axis.
        w2_index: u32,
    },
    /// An evolutionary search's candidate, at its own (w1, w2).
    Candidate {
        /// Its generation, from 0.
        generation: u32,
        /// Its number within the generation, from 0.
        candidate: u32,
    },
}

impl Place {
    /// A grid point.
    pub fn point(w1_index: u32, w2_index: u32) -> Self {
        Place::Point { w1_index, w2_index }
    }

    /// A candidate of a generation.
    pub fn candidate(generation: u32, candidate: u32) -> Self {
        Place::Candidate {
            generation,
            candidate,
        }
    }

    /// (row, column) of a grid point; `None` for a candidate.
    pub fn grid(self) -> Option<(u32, u32)> {
        match self {
            Place::Point { w1_index, w2_index } => Some((w1_index, w2_index)),
            Place::Candidate { .. } => None,
        }
    }

    /// (generation, number) of a candidate; `None` for a grid point.
    pub fn generation(self) -> Option<(u32, u32)> {
        match self {
            Place::Candidate {
                generation,
                candidate,
            } => Some((generation, candidate)),
            Place::Point { .. } => None,
        }
    }

    /// The place's two coordinates in its layout's order: (row, column) of a point,
    /// (generation, number) of a candidate. Only places of one layout compare.
    pub fn pair(self) -> (u32, u32) {
        match self {
            Place::Point { w1_index, w2_index } => (w1_index, w2_index),
            Place::Candidate {
                generation,
                candidate,
            } => (generation, candidate),
        }
    }

    /// The stored columns `w1_index`, `w2_index`, `generation`, `candidate` (NULL: `None`).
    pub fn columns(self) -> [Option<i64>; 4] {
        match self {
            Place::Point { w1_index, w2_index } => {
                [Some(w1_index.into()), Some(w2_index.into()), None, None]
            }
            Place::Candidate {
                generation,
                candidate,
            } => [None, None, Some(generation.into()), Some(candidate.into())],
        }
    }

    /// From the stored columns: exactly one pair set, neither negative.
    pub fn from_columns(
        w1_index: Option<i64>,
        w2_index: Option<i64>,
        generation: Option<i64>,
        candidate: Option<i64>,
    ) -> Result<Self> {
        let index = |v: i64| u32::try_from(v).ok();
        match (w1_index, w2_index, generation, candidate) {
            (Some(i), Some(j), None, None) => {
                index(i).zip(index(j)).map(|(i, j)| Place::point(i, j))
            }
            (None, None, Some(g), Some(k)) => {
                index(g).zip(index(k)).map(|(g, k)| Place::candidate(g, k))
            }
            _ => None,
        }
        .ok_or_else(|| Error::UnknownValue {
            what: "cell place (w1_index, w2_index, generation, candidate)",
            value: format!("{w1_index:?}, {w2_index:?}, {generation:?}, {candidate:?}"),
        })
    }
}

impl std::fmt::Display for Place {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Place::Point { w1_index, w2_index } => write!(f, "point ({w1_index}, {w2_index})"),
            Place::Candidate {
                generation,
                candidate,
            } => write!(f, "generation {generation} candidate {candidate}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_place_round_trips_through_its_columns_and_a_row_with_both_or_neither_pair_is_refused() {
        for p in [Place::point(3, 6), Place::candidate(0, 5)] {
            let [a, b, c, d] = p.columns();
            assert_eq!(Place::from_columns(a, b, c, d).unwrap(), p);
        }
        assert!(Place::from_columns(Some(1), Some(2), Some(0), Some(0)).is_err());
        assert!(Place::from_columns(None, None, None, None).is_err());
        assert!(Place::from_columns(Some(1), None, None, None).is_err());
        let err = Place::from_columns(Some(-1), Some(2), None, None).unwrap_err();
        assert!(err.to_string().contains("Some(-1)"), "{err}");
    }
}
