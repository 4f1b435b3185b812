//! Domain records the coordinator stores and serves: sweeps, cells, checkpoints,
//! promotions. Their wire forms are built in [`crate::convert`].

use crate::{CellId, CellState, Place, ResolvedSpec, SweepId, SweepState};
use gaitsweep_model::GaitScore;

/// A stored checkpoint: content-addressed file with its epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckpointRecord {
    /// Hex sha256 of the file.
    pub sha256: String,
    /// Size in bytes.
    pub size: u64,
    /// Epoch it was taken at.
    pub epoch: u32,
}

/// One cell as stored.
#[derive(Debug, Clone)]
pub struct CellRecord {
    /// Cell id.
    pub id: CellId,
    /// Sweep id.
    pub sweep_id: SweepId,
    /// Index into the sweep's terrains.
    pub terrain_index: u32,
    /// Terrain name.
    pub terrain: String,
    /// Grid point or evolutionary candidate.
    pub place: Place,
    /// Velocity tracking weight.
    pub w1: f64,
    /// Torque penalty exponent.
    pub w2: f64,
    /// The cell's seed.
    pub seed: u64,
    /// Replicate number within its grid point, from 0.
    pub replicate: u32,
    /// State.
    pub state: CellState,
    /// Attempts started.
    pub attempts: u32,
    /// Last epoch reported.
    pub epochs_done: u32,
    /// Epochs the cell trains to before its next decision (the spec's epochs for a grid,
    /// the next rung under successive halving).
    pub target_epochs: u32,
    /// Score once done.
    pub score: Option<GaitScore>,
    /// The gait score of its latest successive-halving rung decision (a stopped cell's
    /// score is the one it stopped with).
    pub rung_score: Option<f64>,
    /// Last error of a failed attempt.
    pub last_error: Option<String>,
}

/// One sweep as stored, with cell counts.
#[derive(Debug, Clone)]
pub struct SweepRecord {
    /// Sweep id.
    pub id: SweepId,
    /// Resolved spec.
    pub spec: ResolvedSpec,
    /// State.
    pub state: SweepState,
    /// Creation time, unix ms.
    pub created_unix_ms: i64,
    /// Cells in total.
    pub cells_total: u32,
    /// Cells queued.
    pub cells_queued: u32,
    /// Cells running.
    pub cells_running: u32,
    /// Cells done.
    pub cells_done: u32,
    /// Cells failed.
    pub cells_failed: u32,
    /// Cells paused at a successive-halving rung.
    pub cells_paused: u32,
    /// Cells stopped by successive halving.
    pub cells_stopped: u32,
    /// Promoted cell over all terrains.
    pub best_cell: Option<CellId>,
}

/// A promoted cell.
#[derive(Debug, Clone)]
pub struct PromotionRecord {
    /// Sweep id.
    pub sweep_id: SweepId,
    /// Terrain, `None` for the best over all terrains.
    pub terrain: Option<String>,
    /// The cell with its score.
    pub cell: CellRecord,
    /// Its final checkpoint.
    pub checkpoint: Option<CheckpointRecord>,
    /// Promotion time, unix ms.
    pub promoted_unix_ms: i64,
}

/// A successive-halving decision on a cell at a rung, as stored in `rung_decisions`.
#[derive(Debug, Clone)]
pub struct RungDecisionRecord {
    /// The cell after the decision.
    pub cell: CellRecord,
    /// Rung index, from 0.
    pub rung: u32,
    /// Epochs of the rung.
    pub epoch: u32,
    /// The cell's score at the rung.
    pub score: f64,
    /// True: it trains on to the next rung; false: it stopped.
    pub continued: bool,
}
