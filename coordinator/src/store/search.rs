//! Search strategies in the store: results at successive-halving rungs and the rung
//! decisions of [`crate::asha`], applied inside the transaction that records a result or
//! ends an attempt.

use super::rows::spec_of;
use super::sqlite::{
    cell_tx, end_winning_attempt, finish_if_done, refuse_closed, require_uploaded, Tx,
};
use super::ResultOutcome;
use crate::{asha, Error, Result};
use gaitsweep_core::records::RungDecisionRecord;
use gaitsweep_core::{CellId, CellState, LeaseId, Search, SweepId};
use gaitsweep_model::GaitScore;
use std::collections::BTreeMap;

/// Stores a result at a successive-halving rung (the caller has checked it is not a retry):
/// the evaluation, the attempt done, the cell paused at its rung, then the decisions that are due (see [`crate::asha`]).
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
    sqlx::query(
        "INSERT INTO evaluations (cell_id, epoch, kind, attempt_id, score, track, effort, tilt, progress, \
         fall_rate, mean_vel_error, robots, reported_unix_ms) VALUES (?, ?, 'rung', ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) \
         ON CONFLICT (cell_id, epoch) DO UPDATE SET kind = 'rung', attempt_id = excluded.attempt_id, \
         score = excluded.score, track = excluded.track, effort = excluded.effort, tilt = excluded.tilt, \
         progress = excluded.progress, fall_rate = excluded.fall_rate, mean_vel_error = excluded.mean_vel_error, \
         robots = excluded.robots, reported_unix_ms = excluded.reported_unix_ms",
    )
    .bind(cell_id.0)
    .bind(i64::from(target))
    .bind(lease.0)
    .bind(score.score)
    .bind(score.track)
    .bind(score.effort)
    .bind(score.tilt)
    .bind(score.progress)
    .bind(score.fall_rate)
    .bind(score.mean_vel_error)
    .bind(score.robots as i64)
    .bind(now_ms)
    .execute(&mut **tx)
    .await?;
    end_winning_attempt(
        tx,
        lease,
        cell_id,
        now_ms,
        "rung reached by another attempt",
    )
    .await?;
    sqlx::query(
        "UPDATE cells SET state = 'paused', epochs_done = MAX(epochs_done, ?) WHERE id = ?",
    )
    .bind(i64::from(target))
    .bind(cell_id.0)
    .execute(&mut **tx)
    .await?;
    let decisions = apply_asha(tx, sweep, now_ms).await?;
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

/// Takes the successive-halving decisions that are due in a sweep ([`asha::decide`]) and
/// records them: `rung_decisions` rows, continued cells queued for their next rung (they
/// resume from their rung checkpoint), stopped cells `stopped`. Nothing for a grid.
pub(super) async fn apply_asha(
    tx: &mut Tx,
    sweep: SweepId,
    now_ms: i64,
) -> Result<Vec<RungDecisionRecord>> {
    let spec_json: String = sqlx::query_scalar("SELECT spec_json FROM sweeps WHERE id = ?")
        .bind(sweep.0)
        .fetch_one(&mut **tx)
        .await?;
    let spec = spec_of(&spec_json)?;
    let Search::Asha { reduction, .. } = spec.search else {
        return Ok(vec![]);
    };
    let rungs = spec.rungs();
    let states: Vec<(i64, String)> =
        sqlx::query_as("SELECT id, state FROM cells WHERE sweep_id = ? ORDER BY id")
            .bind(sweep.0)
            .fetch_all(&mut **tx)
            .await?;
    let evals: Vec<(i64, i64, f64)> = sqlx::query_as(
        "SELECT e.cell_id, e.epoch, e.score FROM evaluations e JOIN cells c ON c.id = e.cell_id \
         WHERE c.sweep_id = ? AND e.kind = 'rung'",
    )
    .bind(sweep.0)
    .fetch_all(&mut **tx)
    .await?;
    let mut at: BTreeMap<(i64, i64), f64> = BTreeMap::new();
    for (c, e, v) in evals {
        at.insert((c, e), v);
    }
    let cells: Vec<asha::AshaCell> = states
        .iter()
        .map(|(id, state)| {
            let scores = rungs[..rungs.len() - 1]
                .iter()
                .map_while(|r| at.get(&(*id, i64::from(*r))).copied())
                .collect();
            let standing = match state.as_str() {
                "queued" | "running" => asha::Standing::Training,
                "paused" => asha::Standing::Paused,
                _ => asha::Standing::Closed,
            };
            asha::AshaCell {
                cell: CellId(*id),
                scores,
                standing,
            }
        })
        .collect();
    let mut out = Vec::new();
    for d in asha::decide(&cells, rungs.len(), reduction) {
        let epoch = rungs[d.rung];
        sqlx::query(
            "INSERT INTO rung_decisions (cell_id, rung, epoch, score, decision, decided_unix_ms) VALUES (?, ?, ?, ?, ?, ?)",
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
            sqlx::query("UPDATE cells SET state = 'queued', target_epochs = ? WHERE id = ? AND state = 'paused'")
                .bind(i64::from(rungs[d.rung + 1]))
                .bind(d.cell.0)
                .execute(&mut **tx)
                .await?;
        } else {
            sqlx::query("UPDATE cells SET state = 'stopped' WHERE id = ? AND state = 'paused'")
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
        out.push(RungDecisionRecord {
            cell: cell_tx(tx, d.cell).await?,
            rung: d.rung as u32,
            epoch,
            score: d.score,
            continued: d.continued,
        });
    }
    Ok(out)
}

/// Stores an intermediate evaluation a worker logged as the metrics `eval/*` at `epoch`
/// (a spec's `eval.every`) in `evaluations`; a rung's evaluation at the same epoch wins.
pub(super) async fn record_periodic_eval(
    tx: &mut Tx,
    cell: CellId,
    lease: LeaseId,
    epoch: u32,
    score: f64,
    values: &BTreeMap<String, f64>,
) -> Result<()> {
    let v = |k: &str| values.get(&format!("eval/{k}")).copied();
    sqlx::query(
        "INSERT INTO evaluations (cell_id, epoch, kind, attempt_id, score, track, effort, tilt, progress, \
         fall_rate, mean_vel_error, robots, reported_unix_ms) VALUES (?, ?, 'periodic', ?, ?, ?, ?, ?, ?, ?, ?, ?, \
         CAST(strftime('%s', 'now') AS INTEGER) * 1000) ON CONFLICT (cell_id, epoch) DO NOTHING",
    )
    .bind(cell.0)
    .bind(i64::from(epoch))
    .bind(lease.0)
    .bind(score)
    .bind(v("track"))
    .bind(v("effort"))
    .bind(v("tilt"))
    .bind(v("progress"))
    .bind(v("fall_rate"))
    .bind(v("mean_vel_error"))
    .bind(v("robots").map(|r| r as i64))
    .execute(&mut **tx)
    .await?;
    Ok(())
}
