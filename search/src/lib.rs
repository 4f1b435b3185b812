//! How a sweep spends its epochs: the search methods, pure functions over a snapshot of a
//! sweep (no database, no clock, no network). The coordinator's store loads the snapshot
//! and applies the [`Action`]s a [`SearchMethod`] returns; search-bench replays the same
//! decisions on a recording.
//!
//! - [`asha`]: successive halving's rung decisions;
//! - [`evolution`]: CMA-ES and the genetic algorithm ([`genetic`]), generation by generation;
//! - [`method`]: the [`SearchMethod`] trait and its implementations (the grid, successive
//!   halving, the evolutionary searches and random search).

pub mod asha;
pub mod evolution;
pub mod genetic;
pub mod method;
pub mod random;

pub use method::{describe, method_for, Action, CellView, Description, Layout, SearchMethod};
