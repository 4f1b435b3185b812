//! Search strategies in the store: results at successive-halving rungs and the rung
//! decisions of [`crate::asha`], and the generations of the evolutionary search
//! ([`crate::evolution`]), applied inside the transaction that records a result or ends an
//! attempt.

use super::promotion::finish_if_done;
use super::queries::{self, EvalKinds};
use super::score_sql::ScoreTable;
use super::sql::Tx;
use super::tx::{cell_tx, end_winning_attempt, refuse_closed, require_uploaded};
use super::ResultOutcome;
use crate::evolution::{self, EvolutionParams, NextStep, Optimizer};
use crate::{asha, Error, Result};
use gaitsweep_core::records::RungDecisionRecord;
use gaitsweep_core::spec::CellPlan;
use gaitsweep_core::{CellId, CellState, LeaseId, ResolvedSpec, Search, SweepId};
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
    let decisions = apply_asha(tx, sweep, now_ms).await?;
    apply_evolution(tx, sweep).await?;
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
    let spec = queries::sweep_spec(&mut **tx, sweep).await?.spec;
    let Some(reduction) = spec.halving_reduction() else {
        return Ok(vec![]);
    };
    let rungs = spec.rungs();
    // An evolutionary search halves inside each generation (w1_index): its candidates
    // compete with each other, not with earlier generations, and synchronously (a rung is
    // decided once none of the generation trains): the next generation waits for the whole
    // one anyway, and the budget buys generations at synchronous halving's cost, which
    // asynchronous promotion could overrun.
    let generations = spec.search.generations().is_some();
    let states: Vec<(i64, String, i64)> =
        sqlx::query_as("SELECT id, state, w1_index FROM cells WHERE sweep_id = $1 ORDER BY id")
            .bind(sweep.0)
            .fetch_all(&mut **tx)
            .await?;
    let evals = queries::evaluations(&mut **tx, sweep, EvalKinds::Rungs).await?;
    let mut at: BTreeMap<(i64, i64), f64> = BTreeMap::new();
    for e in evals {
        at.insert((e.cell_id, e.epoch), e.score);
    }
    let mut groups: BTreeMap<i64, Vec<asha::AshaCell>> = BTreeMap::new();
    for (id, state, generation) in &states {
        let cell = {
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
        };
        groups
            .entry(if generations { *generation } else { 0 })
            .or_default()
            .push(cell);
    }
    let due: Vec<asha::Decision> = groups
        .values()
        .filter(|cells| !generations || asha::no_cell_training(cells))
        .flat_map(|cells| asha::decide(cells, rungs.len(), reduction))
        .collect();
    let mut out = Vec::new();
    for d in due {
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
            sqlx::query("UPDATE cells SET state = 'queued', target_epochs = $1 WHERE id = $2 AND state = 'paused'")
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

/// The evolutionary search's parameters for a spec, or `None` for other searches.
pub(super) fn evolution_params(spec: &ResolvedSpec) -> Option<EvolutionParams> {
    let (population, generations) = spec.search.generations()?;
    let optimizer = match spec.search {
        Search::Cmaes { sigma, .. } => Optimizer::Cmaes { sigma },
        _ => Optimizer::genetic(&spec.w1_values, &spec.w2_values),
    };
    let (lo, hi) = spec.bounds();
    Some(EvolutionParams {
        bounds: evolution::Bounds { lo, hi },
        population: population as usize,
        optimizer,
        generations,
        seed: spec.seed,
    })
}

/// Inserts `cells` into a sweep, queued, each training to `target` epochs first.
pub(super) async fn insert_cells(
    tx: &mut Tx,
    sweep: SweepId,
    cells: &[CellPlan],
    target: u32,
) -> Result<()> {
    for c in cells {
        sqlx::query(
            "INSERT INTO cells (sweep_id, terrain_index, terrain, w1_index, w2_index, w1, w2, replicate, seed, state, target_epochs) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, 'queued', $10)",
        )
        .bind(sweep.0)
        .bind(c.terrain_index as i64)
        .bind(c.terrain.to_string())
        .bind(c.w1_index as i64)
        .bind(c.w2_index as i64)
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

/// The first generation of an evolutionary search.
pub(super) fn first_generation(spec: &ResolvedSpec) -> Result<Vec<[f64; 2]>> {
    let params = evolution_params(spec)
        .ok_or_else(|| Error::BadRequest("the spec's search is not evolutionary".into()))?;
    match evolution::next_step(&params, &[]).map_err(Error::BadRequest)? {
        NextStep::Generation(c) => Ok(c),
        NextStep::Done(why) => Err(Error::BadRequest(format!(
            "the evolutionary search has nothing to train: {why}"
        ))),
    }
}

/// Once every cell of an evolutionary search's latest generation has ended, asks CMA-ES for
/// the next one (replaying the stored generations, see [`crate::evolution`]) and queues its
/// cells; returns the new generation's number and size. A candidate's score is the mean of
/// its scored replicates; one with none (failed for good) ranks below its generation.
/// Nothing for other searches, an open generation or a sweep that is not running.
pub(super) async fn apply_evolution(tx: &mut Tx, sweep: SweepId) -> Result<Option<(u32, usize)>> {
    let queries::SweepSpecRow { spec, state, .. } = queries::sweep_spec(&mut **tx, sweep).await?;
    let Some(params) = evolution_params(&spec) else {
        return Ok(None);
    };
    if state != "running" {
        return Ok(None);
    }
    let rows: Vec<(i64, i64, String, Option<f64>)> = sqlx::query_as(
        "SELECT c.w1_index, c.w2_index, c.state, s.score FROM cells c LEFT JOIN scores s ON s.cell_id = c.id \
         WHERE c.sweep_id = $1 ORDER BY c.w1_index, c.w2_index, c.replicate",
    )
    .bind(sweep.0)
    .fetch_all(&mut **tx)
    .await?;
    if rows
        .iter()
        .any(|r| matches!(r.2.as_str(), "queued" | "running" | "paused"))
    {
        return Ok(None);
    }
    let generations = rows.iter().map(|r| r.0 + 1).max().unwrap_or(0) as usize;
    let mut sums: Vec<Vec<(f64, u32)>> = vec![vec![(0.0, 0); params.population]; generations];
    for (g, k, _, score) in &rows {
        let slot = &mut sums[*g as usize][*k as usize];
        if let Some(s) = score {
            slot.0 += s;
            slot.1 += 1;
        }
    }
    // With successive halving inside generations, a candidate stopped at a rung is ranked
    // by how far it got, then by its score there.
    let halted = if spec.halving_reduction().is_some() {
        let rungs = spec.rungs();
        let evals = queries::evaluations(&mut **tx, sweep, EvalKinds::Rungs).await?;
        let mut deepest: BTreeMap<(i64, i64), (usize, f64)> = BTreeMap::new();
        for queries::EvalPoint {
            w1_index: g,
            w2_index: k,
            epoch,
            score,
            ..
        } in evals
        {
            if let Some(depth) = rungs.iter().position(|r| i64::from(*r) == epoch) {
                deepest.insert((g, k), (depth, score));
            }
        }
        Some((rungs.len() - 1, deepest))
    } else {
        None
    };
    let history: Vec<Vec<f64>> = sums
        .iter()
        .enumerate()
        .map(|(g, cands)| {
            let values: Vec<Option<f64>> = cands
                .iter()
                .enumerate()
                .map(|(k, (sum, n))| {
                    let fin = (*n > 0).then(|| sum / f64::from(*n));
                    match &halted {
                        None => fin,
                        Some((last, deepest)) => match fin {
                            Some(v) => Some(evolution::halving_fitness(*last, v)),
                            None => deepest
                                .get(&(g as i64, k as i64))
                                .map(|(d, v)| evolution::halving_fitness(*d, *v)),
                        },
                    }
                })
                .collect();
            evolution::failed_fitness(&values)
        })
        .collect();
    match evolution::next_step(&params, &history).map_err(Error::BadRequest)? {
        NextStep::Generation(candidates) => {
            let generation = generations as u32;
            let cells = spec.candidate_cells(generation, &candidates);
            insert_cells(tx, sweep, &cells, spec.rungs()[0]).await?;
            let n = cells.len();
            tracing::info!(
                sweep = sweep.0,
                generation,
                cells = n,
                "evolutionary search: next generation queued"
            );
            Ok(Some((generation, n)))
        }
        NextStep::Done(why) => {
            tracing::info!(sweep = sweep.0, generations, reason = %why, "evolutionary search done");
            Ok(None)
        }
    }
}
