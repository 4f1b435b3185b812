//! Search strategies in the store: results at successive-halving rungs and the rung
//! decisions of [`gaitsweep_search::asha`], and the generations of the evolutionary search
//! ([`gaitsweep_search::evolution`]), applied inside the transaction that records a result or ends an
//! attempt.

use super::promotion::finish_if_done;
use super::queries;
use super::score_sql::ScoreTable;
use super::sql::Tx;
use super::tx::{cell_tx, end_winning_attempt, refuse_closed, require_uploaded};
use super::ResultOutcome;
use crate::{Error, Result};
use gaitsweep_core::records::RungDecisionRecord;
use gaitsweep_core::spec::CellPlan;
use gaitsweep_core::{CellId, CellState, LeaseId, SweepId};
use gaitsweep_model::GaitScore;
use gaitsweep_search::asha::Decision;
use gaitsweep_search::Action;
use std::collections::BTreeMap;

/// Stores a result at a successive-halving rung (the caller has checked it is not a retry):
/// the evaluation, the attempt done, the cell paused at its rung, then the decisions that are due (see [`gaitsweep_search::asha`]).
#[allow(clippy::too_many_arguments)]
pub(super) async fn rung_result(
    tx: &mut Tx,
    lease: LeaseId,
    cell_id: CellId,
    sweep: SweepId,
    state: CellState,
    target: u32,
    score: &GaitScore,
    epochs: u32,
    final_sha256: Option<&str>,
    now_ms: i64,
) -> Result<ResultOutcome> {
    refuse_closed(cell_id, state)?;
    if epochs != target {
        return Err(Error::BadRequest(format!(
            "result at epoch {epochs} does not match the cell's rung at epoch {target}: the lease is stale, drop the result"
        )));
    }
    require_uploaded(tx, final_sha256, epochs, "rung").await?;
    let t = ScoreTable::Evaluation;
    let sql = format!(
        "INSERT INTO evaluations (cell_id, epoch, kind, attempt_id, reported_unix_ms, {}) \
         VALUES ($1, $2, 'rung', $3, $4, {}) \
         ON CONFLICT (cell_id, epoch) DO UPDATE SET kind = 'rung', attempt_id = excluded.attempt_id, \
         reported_unix_ms = excluded.reported_unix_ms, {}",
        t.columns(),
        t.placeholders(5),
        t.upserts()
    );
    let q = sqlx::query(&sql)
        .bind(cell_id.0)
        .bind(i64::from(target))
        .bind(lease.0)
        .bind(now_ms);
    t.bind(q, score).execute(&mut **tx).await?;
    super::levels::write(tx, cell_id, lease, target, &score.levels).await?;
    end_winning_attempt(
        tx,
        lease,
        cell_id,
        now_ms,
        "rung reached by another attempt",
    )
    .await?;
    sqlx::query(
        "UPDATE cells SET state = 'paused', epochs_done = CASE WHEN epochs_done > $1 THEN epochs_done ELSE $1 END WHERE id = $2",
    )
    .bind(i64::from(target))
    .bind(cell_id.0)
    .execute(&mut **tx)
    .await?;
    let decisions = apply_search(tx, sweep, now_ms).await?;
    let cell = cell_tx(tx, cell_id).await?;
    let finished = finish_if_done(tx, sweep, now_ms).await?;
    Ok(ResultOutcome {
        duplicate: false,
        cell,
        promotions: vec![],
        decisions,
        finished,
    })
}

/// Asks the sweep's search method ([`gaitsweep_search::method`]) what is due, given its cells,
/// and applies it: rung decisions recorded (`rung_decisions`), continued cells queued for
/// their next rung (they resume from their rung checkpoint), stopped cells `stopped`, a new
/// generation's cells queued (only while the sweep runs). Returns the rung decisions.
pub(super) async fn apply_search(
    tx: &mut Tx,
    sweep: SweepId,
    now_ms: i64,
) -> Result<Vec<RungDecisionRecord>> {
    let queries::SweepSpecRow { spec, state, .. } = queries::sweep_spec(&mut **tx, sweep).await?;
    let method = gaitsweep_search::method_for(&spec);
    if !method.reacts() {
        return Ok(vec![]);
    }
    let cells = queries::search_view(tx, sweep).await?;
    let actions = method.react(&spec, &cells).map_err(Error::BadRequest)?;
    let rungs = spec.rungs();
    let mut out = Vec::new();
    for action in actions {
        match action {
            Action::Rung(d) => out.push(apply_rung_decision(tx, &rungs, d, now_ms).await?),
            Action::Queue {
                generation,
                cells,
                target,
            } if state == "running" => {
                insert_cells(tx, sweep, &cells, target).await?;
                tracing::info!(
                    sweep = sweep.0,
                    method = method.name(),
                    generation,
                    cells = cells.len(),
                    "next generation queued"
                );
            }
            Action::Queue { .. } => {}
        }
    }
    Ok(out)
}

/// Records one successive-halving decision and moves its cell on or stops it.
async fn apply_rung_decision(
    tx: &mut Tx,
    rungs: &[u32],
    d: Decision,
    now_ms: i64,
) -> Result<RungDecisionRecord> {
    let epoch = rungs[d.rung];
    sqlx::query(
        "INSERT INTO rung_decisions (cell_id, rung, epoch, score, decision, decided_unix_ms) VALUES ($1, $2, $3, $4, $5, $6)",
    )
    .bind(d.cell.0)
    .bind(d.rung as i64)
    .bind(i64::from(epoch))
    .bind(d.score)
    .bind(if d.continued { "continue" } else { "stop" })
    .bind(now_ms)
    .execute(&mut **tx)
    .await?;
    if d.continued {
        sqlx::query(
            "UPDATE cells SET state = 'queued', target_epochs = $1 WHERE id = $2 AND state = 'paused'",
        )
        .bind(i64::from(rungs[d.rung + 1]))
        .bind(d.cell.0)
        .execute(&mut **tx)
        .await?;
    } else {
        sqlx::query("UPDATE cells SET state = 'stopped' WHERE id = $1 AND state = 'paused'")
            .bind(d.cell.0)
            .execute(&mut **tx)
            .await?;
    }
    tracing::info!(
        cell = d.cell.0,
        rung = d.rung,
        epoch,
        score = d.score,
        continued = d.continued,
        "rung decision"
    );
    Ok(RungDecisionRecord {
        cell: cell_tx(tx, d.cell).await?,
        rung: d.rung as u32,
        epoch,
        score: d.score,
        continued: d.continued,
    })
}

/// Stores an intermediate evaluation a worker logged as the metrics `eval/*` at `epoch`
/// (a spec's `eval.every`) in `evaluations`; a rung's evaluation at the same epoch wins.
/// A later attempt's evaluation replaces an earlier attempt's, as its metrics do in
/// `epoch_metrics`: a cell resumed from a checkpoint before that epoch trains it again, and
/// its curve must be the run that goes on, not the one that was cut off.
pub(super) async fn record_periodic_eval(
    tx: &mut Tx,
    cell: CellId,
    lease: LeaseId,
    epoch: u32,
    score: f64,
    values: &BTreeMap<String, f64>,
    now_ms: i64,
) -> Result<()> {
    let v = |k: &str| values.get(&format!("eval/{k}")).copied();
    let t = ScoreTable::Evaluation;
    let sql = format!(
        "INSERT INTO evaluations (cell_id, epoch, kind, attempt_id, reported_unix_ms, {}) \
         VALUES ($1, $2, 'periodic', $3, $4, {}) \
         ON CONFLICT (cell_id, epoch) DO UPDATE SET attempt_id = excluded.attempt_id, \
         reported_unix_ms = excluded.reported_unix_ms, {} \
         WHERE evaluations.kind = 'periodic' AND evaluations.attempt_id <= excluded.attempt_id",
        t.columns(),
        t.placeholders(5),
        t.upserts()
    );
    let q = sqlx::query(&sql)
        .bind(cell.0)
        .bind(i64::from(epoch))
        .bind(lease.0)
        .bind(now_ms);
    let written = t
        .bind_by_name(q, |k| if k == "score" { Some(score) } else { v(k) })
        .execute(&mut **tx)
        .await?;
    // The levels go with the evaluation's row: not over a rung's, nor an earlier attempt's
    // over a later one's.
    if written.rows_affected() > 0 {
        if let Some(s) = GaitScore::from_eval_metrics(values) {
            super::levels::write(tx, cell, lease, epoch, &s.levels).await?;
        }
    }
    Ok(())
}

/// Inserts `cells` into a sweep, queued, each training to `target` epochs first.
pub(super) async fn insert_cells(
    tx: &mut Tx,
    sweep: SweepId,
    cells: &[CellPlan],
    target: u32,
) -> Result<()> {
    for c in cells {
        let query = sqlx::query(
            "INSERT INTO cells (sweep_id, terrain_index, terrain, w1_index, w2_index, generation, candidate, w1, w2, replicate, seed, state, target_epochs) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, 'queued', $12)",
        )
        .bind(sweep.0)
        .bind(c.terrain_index as i64)
        .bind(c.terrain.to_string());
        let query = c.place.columns().into_iter().fold(query, |q, v| q.bind(v));
        query
            .bind(c.w1)
            .bind(c.w2)
            .bind(i64::from(c.replicate))
            .bind(c.seed as i64)
            .bind(i64::from(target))
            .execute(&mut **tx)
            .await?;
    }
    Ok(())
}
