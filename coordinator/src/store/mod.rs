//! Storage behind one trait: everything the coordinator persists. [`sql::SqlStore`]
//! implements it on SQLite (the default) and PostgreSQL.

pub mod backend;
mod finalists;
pub mod levels;
pub mod progress_writer;
mod promotion;
pub mod queries;
pub mod reader;
pub mod rows;
mod score_sql;
mod search;
pub mod sql;
#[cfg(test)]
mod tests;
mod tx;

use crate::Result;
use gaitsweep_core::records::{
    CellRecord, CheckpointRecord, PromotionRecord, RungDecisionRecord, SweepRecord,
};
use gaitsweep_core::{CellId, LeaseId, ResolvedSpec, SweepId, WorkerId};
use gaitsweep_model::GaitScore;
use std::collections::BTreeMap;
use std::future::Future;

pub use backend::{Backend, DatabaseUrl};
pub use finalists::confirmation_to_come;
pub use progress_writer::WriteSnapshot;
pub use reader::DB_FILE;
pub use sql::SqlStore;

/// What a worker says about itself when it registers.
#[derive(Debug, Clone)]
pub struct WorkerInfo {
    /// Host name.
    pub hostname: String,
    /// CPU cores.
    pub cores: u32,
    /// Training device.
    pub device: String,
    /// Concurrent cells.
    pub slots: u32,
    /// Worker version.
    pub version: String,
    /// CPU model (empty if the worker did not say).
    pub cpu: String,
}

/// A cell leased to a worker slot.
#[derive(Debug, Clone)]
pub struct LeaseGrant {
    /// The lease (attempt) id.
    pub lease: LeaseId,
    /// The cell, in state running.
    pub cell: CellRecord,
    /// Its sweep's spec.
    pub spec: ResolvedSpec,
    /// The checkpoint to resume from, if an earlier attempt uploaded one.
    pub resume: Option<CheckpointRecord>,
}

/// A lease that is running according to the database.
#[derive(Debug, Clone)]
pub struct RunningLease {
    /// Lease id.
    pub lease: LeaseId,
    /// Its cell.
    pub cell: CellId,
    /// Its sweep.
    pub sweep: SweepId,
    /// The worker holding it.
    pub worker: WorkerId,
}

/// What storing a result changed.
#[derive(Debug, Clone)]
pub struct ResultOutcome {
    /// True if the cell already had a score (a retried report); nothing was written.
    pub duplicate: bool,
    /// The cell after the report.
    pub cell: CellRecord,
    /// New promotions (overall and per terrain).
    pub promotions: Vec<PromotionRecord>,
    /// Successive-halving decisions this result made due.
    pub decisions: Vec<RungDecisionRecord>,
    /// The sweep, if this report finished it.
    pub finished: Option<SweepRecord>,
}

impl ResultOutcome {
    /// The answer to a retried report: nothing written, nothing changed.
    pub fn duplicate(cell: CellRecord) -> Self {
        ResultOutcome {
            duplicate: true,
            cell,
            promotions: vec![],
            decisions: vec![],
            finished: None,
        }
    }
}

/// What ending an attempt changed.
#[derive(Debug, Clone)]
pub struct AttemptOutcome {
    /// The cell after the attempt ended.
    pub cell: CellRecord,
    /// Successive-halving decisions the end of the attempt made due (a cell that failed
    /// for good can close a rung).
    pub decisions: Vec<RungDecisionRecord>,
    /// The sweep, if this finished it.
    pub finished: Option<SweepRecord>,
}

/// How an attempt ended without a result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AttemptEnd {
    /// The worker reported an error.
    Failed,
    /// Its lease expired (missed heartbeats).
    Expired,
    /// The worker gave the cell back (it is stopping): not a failure, the cell is queued
    /// again at once and the attempt does not count towards the attempt limit.
    Released,
}

impl AttemptEnd {
    /// The stored attempt state.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Failed => "failed",
            Self::Expired => "expired",
            Self::Released => "released",
        }
    }
}

/// Everything the coordinator persists. Methods that change several rows do so in one
/// write transaction. Results, checkpoints and metrics are idempotent: a retried call
/// never duplicates a row.
pub trait Store: Send + Sync + 'static {
    /// Stores a new sweep and its expanded grid.
    fn create_sweep(
        &self,
        spec: &ResolvedSpec,
        now_ms: i64,
    ) -> impl Future<Output = Result<SweepRecord>> + Send;
    /// All sweeps, newest first.
    fn list_sweeps(&self) -> impl Future<Output = Result<Vec<SweepRecord>>> + Send;
    /// One sweep.
    fn sweep(&self, id: SweepId) -> impl Future<Output = Result<SweepRecord>> + Send;
    /// The cells of a sweep in grid order.
    fn cells(&self, id: SweepId) -> impl Future<Output = Result<Vec<CellRecord>>> + Send;
    /// The sweep's done cells that were never rewarded: `mean_step_reward` logged, and 0 at
    /// every epoch.
    fn never_rewarded(&self, id: SweepId) -> impl Future<Output = Result<Vec<CellId>>> + Send;
    /// Cancels a sweep; returns it and the leases that were running.
    fn cancel_sweep(
        &self,
        id: SweepId,
        now_ms: i64,
    ) -> impl Future<Output = Result<(SweepRecord, Vec<LeaseId>)>> + Send;
    /// Registers a worker under a new id.
    fn register_worker(
        &self,
        id: &WorkerId,
        info: &WorkerInfo,
        now_ms: i64,
    ) -> impl Future<Output = Result<()>> + Send;
    /// Records that workers were seen.
    fn touch_workers(
        &self,
        ids: &[WorkerId],
        now_ms: i64,
    ) -> impl Future<Output = Result<()>> + Send;
    /// Leases the next queued cell (see [`crate::sched::pick_next`]) to a worker slot.
    fn lease_next(
        &self,
        worker: &WorkerId,
        slot: u32,
        now_ms: i64,
    ) -> impl Future<Output = Result<Option<LeaseGrant>>> + Send;
    /// Leases that are running according to the database (used at start-up).
    fn running_leases(&self) -> impl Future<Output = Result<Vec<RunningLease>>> + Send;
    /// The cell and sweep of a lease, refusing leases whose cell is closed.
    fn open_lease(&self, lease: LeaseId) -> impl Future<Output = Result<(CellId, SweepId)>> + Send;
    /// Stores (or replaces) epoch metrics of a lease's cell; returns rows written and the
    /// cell and sweep. Concurrent calls may be committed together (group commit); a call
    /// returns once its rows are committed.
    fn record_progress(
        &self,
        lease: LeaseId,
        epochs: &[(u32, BTreeMap<String, f64>)],
    ) -> impl Future<Output = Result<(usize, CellId, SweepId)>> + Send;
    /// The metric writer's queue, lag and counters.
    fn write_stats(&self) -> WriteSnapshot;
    /// Records an uploaded checkpoint file (already in place under the data dir).
    fn record_checkpoint(
        &self,
        lease: LeaseId,
        ckpt: &CheckpointRecord,
        rel_path: &str,
        now_ms: i64,
    ) -> impl Future<Output = Result<()>> + Send;
    /// Size and data-dir-relative path of a stored checkpoint.
    fn checkpoint_path(&self, sha256: &str) -> impl Future<Output = Result<(u64, String)>> + Send;
    /// Stores the result of a cell and promotes it if it is the best.
    fn report_result(
        &self,
        lease: LeaseId,
        score: &GaitScore,
        epochs: u32,
        final_sha256: Option<&str>,
        now_ms: i64,
    ) -> impl Future<Output = Result<ResultOutcome>> + Send;
    /// Ends an attempt without a result; the cell is requeued or failed (failed once the
    /// failed and expired attempts reach `max_attempts`; released ones do not count).
    fn end_attempt(
        &self,
        lease: LeaseId,
        end: AttemptEnd,
        error: &str,
        max_attempts: u32,
        now_ms: i64,
    ) -> impl Future<Output = Result<AttemptOutcome>> + Send;
    /// The latest promotion of a sweep (terrain `None`: over all terrains).
    fn promoted(
        &self,
        id: SweepId,
        terrain: Option<&str>,
    ) -> impl Future<Output = Result<PromotionRecord>> + Send;
}
