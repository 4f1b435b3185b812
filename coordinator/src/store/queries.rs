//! The reads that several parts of the coordinator share (the store's transactions, the
//! report, the live API, the search benchmark): each query is written here once, typed.

use super::rows::{spec_of, PlaceRow, PLACE_COLUMNS};
use crate::across::ScoredCell;
use crate::{Error, Result};
use gaitsweep_core::{CellId, CellState, Place, ResolvedSpec, SweepId};
use gaitsweep_search::CellView;
use sqlx::{Any, Executor};
use std::collections::BTreeMap;
use std::str::FromStr;

/// A sweep's name, state and spec (its defaults filled in).
#[derive(Debug, Clone)]
pub struct SweepSpecRow {
    /// Name.
    pub name: String,
    /// State (`running`, `done`, ...).
    pub state: String,
    /// The stored spec.
    pub spec: ResolvedSpec,
}

/// The name, state and spec of `sweep`; an unknown sweep is [`Error::UnknownSweep`].
pub async fn sweep_spec<'e>(
    db: impl Executor<'e, Database = Any>,
    sweep: SweepId,
) -> Result<SweepSpecRow> {
    let row: Option<(String, String, String)> =
        sqlx::query_as("SELECT name, state, spec_json FROM sweeps WHERE id = $1")
            .bind(sweep.0)
            .fetch_optional(db)
            .await?;
    let (name, state, spec_json) = row.ok_or(Error::UnknownSweep(sweep))?;
    Ok(SweepSpecRow {
        name,
        state,
        spec: spec_of(&spec_json)?,
    })
}

/// One evaluation of a cell (a rung's, or a periodic one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvalPoint {
    /// The cell.
    pub cell_id: i64,
    /// Its grid point, or its generation and number as a candidate.
    pub place: Place,
    /// Epoch of the evaluation.
    pub epoch: i64,
    /// Score.
    pub score: f64,
    /// Fall rate (unknown for evaluations stored by old workers).
    pub fall_rate: Option<f64>,
}

/// Which evaluations [`evaluations`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EvalKinds {
    /// Rungs of successive halving only.
    Rungs,
    /// Every evaluation: rungs and periodic ones.
    All,
}

/// The evaluations of `sweep`'s cells in epoch order (then by cell), so that a map filled
/// from them in order keeps each cell's (or point's) latest.
pub async fn evaluations<'e>(
    db: impl Executor<'e, Database = Any>,
    sweep: SweepId,
    kinds: EvalKinds,
) -> Result<Vec<EvalPoint>> {
    let filter = match kinds {
        EvalKinds::Rungs => " AND e.kind = 'rung'",
        EvalKinds::All => "",
    };
    let sql = format!(
        "SELECT e.cell_id, {PLACE_COLUMNS}, e.epoch, e.score, e.fall_rate FROM evaluations e \
         JOIN cells c ON c.id = e.cell_id WHERE c.sweep_id = $1{filter} ORDER BY e.epoch, e.cell_id"
    );
    #[derive(sqlx::FromRow)]
    struct Row {
        cell_id: i64,
        #[sqlx(flatten)]
        place: PlaceRow,
        epoch: i64,
        score: f64,
        fall_rate: Option<f64>,
    }
    let rows: Vec<Row> = sqlx::query_as(&sql).bind(sweep.0).fetch_all(db).await?;
    rows.into_iter()
        .map(|r| {
            Ok(EvalPoint {
                cell_id: r.cell_id,
                place: r.place.place()?,
                epoch: r.epoch,
                score: r.score,
                fall_rate: r.fall_rate,
            })
        })
        .collect()
}

/// The two columns that hold a place of this kind (`w1_index, w2_index` of a grid point,
/// `generation, candidate` of a candidate), for a filter on it.
pub(super) fn place_filter(place: Place) -> (&'static str, &'static str) {
    match place {
        Place::Point { .. } => ("w1_index", "w2_index"),
        Place::Candidate { .. } => ("generation", "candidate"),
    }
}

/// The sweep's done cells that were never rewarded: `mean_step_reward` logged, and 0 at
/// every epoch (the report's [`crate::report::ReportCell::never_rewarded`]), in id order.
pub(super) async fn never_rewarded<'e>(
    db: impl Executor<'e, Database = Any>,
    sweep: SweepId,
) -> Result<Vec<CellId>> {
    // A rewarded cell is answered by its first epochs' rows; only a cell never rewarded
    // is read to its end, and those are few.
    let ids: Vec<i64> = sqlx::query_scalar(
        "SELECT c.id FROM cells c WHERE c.sweep_id = $1 AND c.state = 'done' \
         AND EXISTS (SELECT 1 FROM epoch_metrics m WHERE m.cell_id = c.id AND m.name = 'mean_step_reward') \
         AND NOT EXISTS (SELECT 1 FROM epoch_metrics m WHERE m.cell_id = c.id \
             AND m.name = 'mean_step_reward' AND m.value <> 0) \
         ORDER BY c.id",
    )
    .bind(sweep.0)
    .fetch_all(db)
    .await?;
    Ok(ids.into_iter().map(CellId).collect())
}

/// Every scored cell of `sweep` with its final score, in id order: what promotion across
/// terrains and the finalists rank.
pub(super) async fn scored_cells<'e>(
    db: impl Executor<'e, Database = Any>,
    sweep: SweepId,
) -> Result<Vec<ScoredCell>> {
    #[derive(sqlx::FromRow)]
    struct Row {
        id: i64,
        terrain_index: i64,
        #[sqlx(flatten)]
        place: PlaceRow,
        score: f64,
    }
    let rows: Vec<Row> = sqlx::query_as(&format!(
        "SELECT c.id, c.terrain_index, {PLACE_COLUMNS}, s.score FROM cells c \
         JOIN scores s ON s.cell_id = c.id WHERE c.sweep_id = $1 ORDER BY c.id"
    ))
    .bind(sweep.0)
    .fetch_all(db)
    .await?;
    rows.into_iter()
        .map(|r| {
            Ok(ScoredCell {
                cell: CellId(r.id),
                terrain: r.terrain_index.max(0) as usize,
                place: r.place.place()?,
                score: r.score,
            })
        })
        .collect()
}

/// Every cell of `sweep` as its search method sees it ([`SearchMethod::react`]), in id
/// order: indices, state, final score and rung evaluations.
///
/// [`SearchMethod::react`]: gaitsweep_search::SearchMethod::react
pub(super) async fn search_view(tx: &mut super::sql::Tx, sweep: SweepId) -> Result<Vec<CellView>> {
    #[derive(sqlx::FromRow)]
    struct Row {
        id: i64,
        #[sqlx(flatten)]
        place: PlaceRow,
        state: String,
        score: Option<f64>,
    }
    let rows: Vec<Row> = sqlx::query_as(&format!(
        "SELECT c.id, {PLACE_COLUMNS}, c.state, s.score FROM cells c \
         LEFT JOIN scores s ON s.cell_id = c.id WHERE c.sweep_id = $1 ORDER BY c.id"
    ))
    .bind(sweep.0)
    .fetch_all(&mut **tx)
    .await?;
    let mut rungs: BTreeMap<i64, BTreeMap<u32, f64>> = BTreeMap::new();
    for e in evaluations(&mut **tx, sweep, EvalKinds::Rungs).await? {
        rungs
            .entry(e.cell_id)
            .or_default()
            .insert(e.epoch as u32, e.score);
    }
    rows.into_iter()
        .map(|r| {
            Ok(CellView {
                id: CellId(r.id),
                place: r.place.place()?,
                state: CellState::from_str(&r.state)?,
                score: r.score,
                rungs: rungs.remove(&r.id).unwrap_or_default(),
            })
        })
        .collect()
}

/// One attempt at a cell as the machines' record reads it: the CPU model its worker
/// reported (empty for workers older than that field) and the epoch it resumed from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AttemptCpu {
    /// CPU model of the attempt's worker (`workers.cpu`).
    pub cpu: String,
    /// The epoch the attempt resumed from (0: it started fresh).
    pub resumed_from: u32,
}

/// Every attempt at `sweep`'s cells with its worker's CPU, by cell, in the order the
/// attempts started: which machines trained a cell ([`crate::report::machines::cpu_spans`]).
pub async fn attempt_cpus<'e>(
    db: impl Executor<'e, Database = Any>,
    sweep: SweepId,
) -> Result<BTreeMap<i64, Vec<AttemptCpu>>> {
    let rows: Vec<(i64, String, i64)> = sqlx::query_as(
        "SELECT a.cell_id, w.cpu, a.resumed_from_epoch FROM attempts a \
         JOIN workers w ON w.id = a.worker_id JOIN cells c ON c.id = a.cell_id \
         WHERE c.sweep_id = $1 ORDER BY a.cell_id, a.started_unix_ms, a.id",
    )
    .bind(sweep.0)
    .fetch_all(db)
    .await?;
    let mut by_cell: BTreeMap<i64, Vec<AttemptCpu>> = BTreeMap::new();
    for (cell, cpu, from) in rows {
        by_cell.entry(cell).or_default().push(AttemptCpu {
            cpu,
            resumed_from: from.max(0) as u32,
        });
    }
    Ok(by_cell)
}

/// One lease of a cell as the live page's speed reads it ([`crate::live`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AttemptSpan {
    /// When it was leased.
    pub started_ms: i64,
    /// When it ended; `None` while it runs.
    pub ended_ms: Option<i64>,
    /// Epochs it trained: its last epoch less the one it resumed from.
    pub epochs: i64,
}

/// `sweep`'s attempts running now, and those done or released after `since_ms` (an expired
/// lease's end is when the coordinator noticed, not when its worker stopped), in the order
/// they started.
pub async fn attempt_spans<'e>(
    db: impl Executor<'e, Database = Any>,
    sweep: SweepId,
    since_ms: i64,
) -> Result<Vec<AttemptSpan>> {
    // An ended attempt's last epoch is its newest metric row.
    let rows: Vec<(i64, Option<i64>, i64)> = sqlx::query_as(
        "SELECT a.started_unix_ms, a.ended_unix_ms, CAST(CASE WHEN a.state = 'running' THEN c.epochs_done \
             ELSE COALESCE((SELECT m.epoch FROM epoch_metrics m WHERE m.cell_id = a.cell_id \
                 AND m.attempt_id = a.id ORDER BY m.epoch DESC LIMIT 1), a.resumed_from_epoch) \
             END - a.resumed_from_epoch AS BIGINT) \
         FROM attempts a JOIN cells c ON c.id = a.cell_id WHERE c.sweep_id = $1 \
         AND (a.state = 'running' OR (a.state IN ('done', 'released') AND a.ended_unix_ms > $2)) \
         ORDER BY a.started_unix_ms, a.id",
    )
    .bind(sweep.0)
    .bind(since_ms)
    .fetch_all(db)
    .await?;
    Ok(rows
        .into_iter()
        .map(|(started_ms, ended_ms, epochs)| AttemptSpan {
            started_ms,
            ended_ms,
            epochs,
        })
        .collect())
}
