//! The database rows the coordinator reads, as `sqlx::FromRow` structs, and their one
//! conversion to domain records. The store and the report both read through them, so a
//! column is mapped in exactly one place.

use crate::{Error, Result};
use gaitsweep_core::records::{CellRecord, SweepRecord};
use gaitsweep_core::{CellId, CellState, Place, ResolvedSpec, SweepId, SweepState};
use gaitsweep_model::GaitScore;
use std::str::FromStr;

/// The score columns of a cell joined with `scores` (all NULL for a cell without one).
#[derive(Debug, Clone, sqlx::FromRow)]
pub struct ScoreRow {
    /// Composite score J.
    pub score: Option<f64>,
    /// Tracking term.
    pub track: Option<f64>,
    /// Effort term.
    pub effort: Option<f64>,
    /// Tilt term.
    pub tilt: Option<f64>,
    /// Progress term.
    pub progress: Option<f64>,
    /// Fraction of robots that fell.
    pub fall_rate: Option<f64>,
    /// Mean |v_cmd - v|.
    pub mean_vel_error: Option<f64>,
    /// Mean absolute torque.
    pub mean_abs_torque: Option<f64>,
    /// Cost of transport.
    pub cost_of_transport: Option<f64>,
    /// Robots evaluated.
    pub robots: Option<i64>,
    /// Bounded progress term (NULL in scores stored before it existed).
    pub progress_bounded: Option<f64>,
    /// Mean speed.
    pub mean_speed: Option<f64>,
    /// Mean speed above the command.
    pub overspeed: Option<f64>,
}

impl ScoreRow {
    /// The gait score, if the cell has one.
    pub fn into_score(self) -> Option<GaitScore> {
        let v = |x: Option<f64>| x.unwrap_or(f64::NAN);
        Some(GaitScore {
            score: self.score?,
            track: v(self.track),
            effort: v(self.effort),
            tilt: v(self.tilt),
            progress: v(self.progress),
            fall_rate: v(self.fall_rate),
            mean_vel_error: v(self.mean_vel_error),
            mean_abs_torque: v(self.mean_abs_torque),
            cost_of_transport: v(self.cost_of_transport),
            robots: self.robots.unwrap_or(0) as usize,
            progress_bounded: v(self.progress_bounded),
            mean_speed: v(self.mean_speed),
            overspeed: v(self.overspeed),
            levels: vec![],
        })
    }
}

/// The columns a cell's [`Place`] is stored in ([`PLACE_COLUMNS`]).
#[derive(Debug, Clone, Copy, sqlx::FromRow)]
pub struct PlaceRow {
    /// Row of the grid (NULL for a candidate).
    pub w1_index: Option<i64>,
    /// Column of the grid (NULL for a candidate).
    pub w2_index: Option<i64>,
    /// A candidate's generation (NULL for a grid point).
    pub generation: Option<i64>,
    /// A candidate's number in its generation (NULL for a grid point).
    pub candidate: Option<i64>,
}

/// The columns [`PlaceRow`] reads, of `cells c`.
pub const PLACE_COLUMNS: &str = "c.w1_index, c.w2_index, c.generation, c.candidate";

impl PlaceRow {
    /// The place the columns hold; a row with both pairs or neither is an error.
    pub fn place(self) -> Result<Place> {
        Ok(Place::from_columns(
            self.w1_index,
            self.w2_index,
            self.generation,
            self.candidate,
        )?)
    }
}

/// A `cells` row with its score ([`CELL_COLUMNS`]).
#[derive(Debug, Clone, sqlx::FromRow)]
pub struct CellRow {
    /// Cell id.
    pub id: i64,
    /// Sweep id.
    pub sweep_id: i64,
    /// Index of the terrain in the sweep's list.
    pub terrain_index: i64,
    /// Terrain name.
    pub terrain: String,
    /// Its grid point or candidate.
    #[sqlx(flatten)]
    pub place: PlaceRow,
    /// Velocity-tracking weight.
    pub w1: f64,
    /// log10 of the torque weight.
    pub w2: f64,
    /// The cell's seed (stored as a signed 64-bit integer).
    pub seed: i64,
    /// Replicate number within its grid point.
    pub replicate: i64,
    /// queued, running, done, failed, cancelled.
    pub state: String,
    /// Leases so far.
    pub attempts: i64,
    /// Epochs trained.
    pub epochs_done: i64,
    /// Epochs to train to before the next decision.
    pub target_epochs: i64,
    /// Last error.
    pub last_error: Option<String>,
    /// Score of the latest rung decision.
    pub rung_score: Option<f64>,
    /// The score columns.
    #[sqlx(flatten)]
    pub score: ScoreRow,
}

/// The order cells are listed in everywhere (`show`, the report, the live API): by terrain,
/// then by place (a grid point's indices or a candidate's generation and number), then by
/// replicate; one of the two place pairs is always NULL, so both can be named.
pub const CELL_ORDER: &str =
    "c.terrain_index, c.w1_index, c.w2_index, c.generation, c.candidate, c.replicate";

/// The columns [`CellRow`] reads: `cells c LEFT JOIN scores s`.
pub const CELL_COLUMNS: &str =
    "c.id, c.sweep_id, c.terrain_index, c.terrain, c.w1_index, c.w2_index, c.generation, \
     c.candidate, c.w1, c.w2, \
     c.seed, c.replicate, c.state, c.attempts, c.epochs_done, c.target_epochs, c.last_error, \
     (SELECT d.score FROM rung_decisions d WHERE d.cell_id = c.id ORDER BY d.rung DESC LIMIT 1) AS rung_score, s.score, s.track, s.effort, s.tilt, \
     s.progress, s.fall_rate, s.mean_vel_error, s.mean_abs_torque, s.cost_of_transport, s.robots, \
     s.progress_bounded, s.mean_speed, s.overspeed";

impl TryFrom<CellRow> for CellRecord {
    type Error = Error;
    fn try_from(r: CellRow) -> Result<Self> {
        Ok(CellRecord {
            id: CellId(r.id),
            sweep_id: SweepId(r.sweep_id),
            terrain_index: r.terrain_index as u32,
            terrain: r.terrain,
            place: r.place.place()?,
            w1: r.w1,
            w2: r.w2,
            seed: r.seed as u64,
            replicate: r.replicate as u32,
            state: CellState::from_str(&r.state)?,
            attempts: r.attempts as u32,
            epochs_done: r.epochs_done as u32,
            target_epochs: r.target_epochs as u32,
            score: r.score.into_score(),
            rung_score: r.rung_score,
            last_error: r.last_error,
        })
    }
}

/// A `sweeps` row with its cell counts and best cell ([`SWEEP_COLUMNS`]).
#[derive(Debug, Clone, sqlx::FromRow)]
pub struct SweepRow {
    /// Sweep id.
    pub id: i64,
    /// The resolved spec as JSON.
    pub spec_json: String,
    /// running, done, cancelled.
    pub state: String,
    /// Creation time.
    pub created_unix_ms: i64,
    /// Cells in total.
    pub total: i64,
    /// Cells queued.
    pub queued: i64,
    /// Cells running.
    pub running: i64,
    /// Cells done.
    pub done: i64,
    /// Cells failed.
    pub failed: i64,
    /// Cells paused at a rung.
    pub paused: i64,
    /// Cells stopped by successive halving.
    pub stopped: i64,
    /// The promoted cell over all terrains.
    pub best: Option<i64>,
}

/// The columns [`SweepRow`] reads: `sweeps w` with counts from `cells` and `promotions`.
pub const SWEEP_COLUMNS: &str = "w.id, w.spec_json, w.state, w.created_unix_ms, \
     (SELECT COUNT(*) FROM cells c WHERE c.sweep_id = w.id) AS total, \
     (SELECT COUNT(*) FROM cells c WHERE c.sweep_id = w.id AND c.state = 'queued') AS queued, \
     (SELECT COUNT(*) FROM cells c WHERE c.sweep_id = w.id AND c.state = 'running') AS running, \
     (SELECT COUNT(*) FROM cells c WHERE c.sweep_id = w.id AND c.state = 'done') AS done, \
     (SELECT COUNT(*) FROM cells c WHERE c.sweep_id = w.id AND c.state = 'failed') AS failed, \
     (SELECT COUNT(*) FROM cells c WHERE c.sweep_id = w.id AND c.state = 'paused') AS paused, \
     (SELECT COUNT(*) FROM cells c WHERE c.sweep_id = w.id AND c.state = 'stopped') AS stopped, \
     (SELECT p.cell_id FROM promotions p WHERE p.sweep_id = w.id AND p.terrain = '' ORDER BY p.id DESC LIMIT 1) AS best";

/// The spec stored with a sweep, typed, with every default filled in (specs stored by
/// earlier versions left some at 0).
pub fn spec_of(spec_json: &str) -> Result<ResolvedSpec> {
    Ok(serde_json::from_str::<ResolvedSpec>(spec_json)?.with_defaults())
}

impl TryFrom<SweepRow> for SweepRecord {
    type Error = Error;
    fn try_from(r: SweepRow) -> Result<Self> {
        Ok(SweepRecord {
            id: SweepId(r.id),
            spec: spec_of(&r.spec_json)?,
            state: SweepState::from_str(&r.state)?,
            created_unix_ms: r.created_unix_ms,
            cells_total: r.total as u32,
            cells_queued: r.queued as u32,
            cells_running: r.running as u32,
            cells_done: r.done as u32,
            cells_failed: r.failed as u32,
            cells_paused: r.paused as u32,
            cells_stopped: r.stopped as u32,
            best_cell: r.best.map(CellId),
        })
    }
}
