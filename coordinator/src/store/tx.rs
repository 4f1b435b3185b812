//! Transaction helpers shared by the store's writes: rows to records, the cell and sweep a
//! transaction sees, what a lease refers to, and the checks a report passes.

use super::backend::Backend;
use super::rows::{CellRow, SweepRow, CELL_COLUMNS, SWEEP_COLUMNS};
use super::sql::Tx;
use crate::{Error, Result};
use gaitsweep_core::records::{CellRecord, CheckpointRecord, SweepRecord};
use gaitsweep_core::{CellId, CellState, LeaseId, SweepId};
use sqlx::any::AnyRow;
use sqlx::{FromRow, Row};
use std::str::FromStr;

pub(super) fn cell_from_row(r: &AnyRow) -> Result<CellRecord> {
    CellRow::from_row(r)?.try_into()
}

pub(super) fn sweep_from_row(r: &AnyRow) -> Result<SweepRecord> {
    SweepRow::from_row(r)?.try_into()
}

pub(super) async fn cell_tx(tx: &mut Tx, id: CellId) -> Result<CellRecord> {
    let sql = format!(
        "SELECT {CELL_COLUMNS} FROM cells c LEFT JOIN scores s ON s.cell_id = c.id WHERE c.id = $1"
    );
    let row = sqlx::query(&sql)
        .bind(id.0)
        .fetch_optional(&mut **tx)
        .await?;
    cell_from_row(&row.ok_or(Error::UnknownCell(id))?)
}

pub(super) async fn sweep_tx(tx: &mut Tx, id: SweepId) -> Result<SweepRecord> {
    let sql = format!("SELECT {SWEEP_COLUMNS} FROM sweeps w WHERE w.id = $1");
    let row = sqlx::query(&sql)
        .bind(id.0)
        .fetch_optional(&mut **tx)
        .await?;
    sweep_from_row(&row.ok_or(Error::UnknownSweep(id))?)
}

/// What a lease id refers to.
pub(super) struct LeaseCell {
    pub(super) cell: CellId,
    pub(super) sweep: SweepId,
    /// The cell's state.
    pub(super) state: CellState,
    /// The attempt's state.
    pub(super) attempt_state: String,
    /// The epochs the cell trains to in this attempt (its target: a rung or the end).
    pub(super) epochs: u32,
    /// The spec's epochs: a result at fewer is a rung result.
    pub(super) total: u32,
}

/// The cell, its state and its epochs for a lease id.
pub(super) async fn lease_cell(tx: &mut Tx, backend: Backend, lease: LeaseId) -> Result<LeaseCell> {
    let sql = format!(
        "SELECT a.cell_id, c.sweep_id, c.state, a.state AS attempt_state, \
         c.target_epochs AS epochs, {} AS total FROM attempts a \
         JOIN cells c ON c.id = a.cell_id JOIN sweeps w ON w.id = c.sweep_id WHERE a.id = $1",
        backend.json_int("w.spec_json", "epochs")
    );
    let row = sqlx::query(&sql)
        .bind(lease.0)
        .fetch_optional(&mut **tx)
        .await?
        .ok_or(Error::UnknownLease(lease))?;
    Ok(LeaseCell {
        cell: CellId(row.try_get("cell_id")?),
        sweep: SweepId(row.try_get("sweep_id")?),
        state: CellState::from_str(row.try_get("state")?)?,
        attempt_state: row.try_get("attempt_state")?,
        epochs: row.try_get::<i64, _>("epochs")? as u32,
        total: row.try_get::<i64, _>("total")? as u32,
    })
}

/// Refuses reports for cells that are finished, cancelled or failed for good (a late
/// report must not revive a failed cell).
pub(super) fn refuse_closed(cell: CellId, state: CellState) -> Result<()> {
    if matches!(
        state,
        CellState::Done
            | CellState::Cancelled
            | CellState::Failed
            | CellState::Paused
            | CellState::Stopped
    ) {
        return Err(Error::CellClosed {
            cell,
            state: state.to_string(),
        });
    }
    Ok(())
}

pub(super) async fn checkpoint_of(
    ex: &mut Tx,
    sha: Option<String>,
    epoch: Option<i64>,
) -> Result<Option<CheckpointRecord>> {
    let Some(sha) = sha else { return Ok(None) };
    let size: Option<i64> = sqlx::query_scalar("SELECT size FROM checkpoints WHERE sha256 = $1")
        .bind(&sha)
        .fetch_optional(&mut **ex)
        .await?;
    Ok(size.map(|size| CheckpointRecord {
        sha256: sha,
        size: size as u64,
        epoch: epoch.unwrap_or(0) as u32,
    }))
}

/// Refuses a result whose checkpoint (`what`: final or rung) was named but not uploaded.
pub(super) async fn require_uploaded(
    tx: &mut Tx,
    sha: Option<&str>,
    epochs: u32,
    what: &str,
) -> Result<()> {
    if let Some(sha) = sha {
        if checkpoint_of(tx, Some(sha.to_string()), Some(epochs as i64))
            .await?
            .is_none()
        {
            return Err(Error::BadRequest(format!(
                "{what} checkpoint {sha} was not uploaded: upload it before reporting the result"
            )));
        }
    }
    Ok(())
}

/// Marks the attempt that delivered a result done and cancels the cell's other running
/// attempts with `why`.
pub(super) async fn end_winning_attempt(
    tx: &mut Tx,
    lease: LeaseId,
    cell: CellId,
    now_ms: i64,
    why: &str,
) -> Result<()> {
    sqlx::query("UPDATE attempts SET state = 'done', ended_unix_ms = $1 WHERE id = $2")
        .bind(now_ms)
        .bind(lease.0)
        .execute(&mut **tx)
        .await?;
    sqlx::query(
        "UPDATE attempts SET state = 'cancelled', ended_unix_ms = $1, error = $2 WHERE cell_id = $3 AND state = 'running'",
    )
    .bind(now_ms)
    .bind(why)
    .bind(cell.0)
    .execute(&mut **tx)
    .await?;
    Ok(())
}

/// Removes a cell's metrics and periodic evaluations (with their levels) past `epochs`,
/// the epoch its result was trained to. Only an earlier attempt, killed after it had
/// trained further than the run that finished (one stopped early as never rewarded), leaves
/// such rows; kept, they would describe a run that was cut off, not the cell's policy.
pub(super) async fn drop_epochs_after(tx: &mut Tx, cell: CellId, epochs: u32) -> Result<()> {
    for sql in [
        "DELETE FROM epoch_metrics WHERE cell_id = $1 AND epoch > $2",
        "DELETE FROM evaluations WHERE cell_id = $1 AND epoch > $2 AND kind = 'periodic'",
        "DELETE FROM level_scores WHERE cell_id = $1 AND epoch > $2",
    ] {
        sqlx::query(sql)
            .bind(cell.0)
            .bind(epochs as i64)
            .execute(&mut **tx)
            .await?;
    }
    Ok(())
}
