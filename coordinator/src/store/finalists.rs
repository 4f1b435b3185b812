//! The store's side of a grid's finalist stage ([`crate::finalists`]): queueing more seeds
//! of the best points when the single-seed pass closes, then of the point best across
//! terrains, and promoting among them when they close.

use std::collections::BTreeSet;

use gaitsweep_core::finalists::Point;
use gaitsweep_core::{CellId, CellPlan, ResolvedSpec, SweepId};
use sqlx::{Any, AnyConnection, Executor};

use super::queries::{never_rewarded, scored_cells};
use super::search::insert_cells;
use super::sql::Tx;
use crate::finalists;
use crate::Result;

/// The points that have cells past the first pass (replicate > 0): the finalists.
async fn finalist_points<'e>(
    db: impl Executor<'e, Database = Any>,
    sweep: SweepId,
) -> Result<BTreeSet<Point>> {
    let rows: Vec<(i64, i64, i64)> = sqlx::query_as(
        "SELECT DISTINCT terrain_index, w1_index, w2_index FROM cells \
         WHERE sweep_id = $1 AND replicate > 0 AND w1_index IS NOT NULL",
    )
    .bind(sweep.0)
    .fetch_all(db)
    .await?;
    Ok(rows
        .into_iter()
        .map(|(t, i, j)| (t as usize, i as usize, j as usize))
        .collect())
}

/// The cells that confirming the point best across terrains would queue if the scores
/// stood as they are now ([`finalists::across_to_confirm`]): a forecast for the live page,
/// since the seeds still training may move the pick. 0 before the finalist stage has
/// begun (its own cells are counted from the spec) and once the pick is a finalist on
/// every terrain.
pub async fn confirmation_to_come(
    db: &sqlx::AnyPool,
    sweep: SweepId,
    spec: &ResolvedSpec,
) -> Result<usize> {
    if spec.finalists.is_none() || spec.terrains.len() < 2 {
        return Ok(0);
    }
    let mut conn = db.acquire().await?;
    let points = finalist_points(&mut *conn, sweep).await?;
    if points.is_empty() {
        return Ok(0);
    }
    Ok(confirmation(&mut conn, sweep, spec, &points).await?.1.len())
}

/// The point best across terrains on each terrain where it is no finalist yet
/// ([`finalists::across_to_confirm`]), and the cells that would confirm it there: what
/// [`queue_across`] queues and [`confirmation_to_come`] forecasts.
async fn confirmation(
    conn: &mut AnyConnection,
    sweep: SweepId,
    spec: &ResolvedSpec,
    finalist_points: &BTreeSet<Point>,
) -> Result<(Vec<Point>, Vec<CellPlan>)> {
    let missing = finalists::across_to_confirm(
        &scored_cells(&mut *conn, sweep).await?,
        spec.terrains.len(),
        finalist_points,
    );
    let cells = spec.finalist_cells(&missing);
    Ok((missing, cells))
}

/// Called when no cell of a running sweep is open: queues the finalists' further seeds if
/// the spec has a finalist stage that has not started, and after it, over several
/// terrains, those of the point best across them where it is no finalist yet
/// ([`finalists::across_to_confirm`]). Returns how many cells it queued (0: the sweep may
/// finish).
pub(super) async fn queue(tx: &mut Tx, sweep: SweepId, spec: &ResolvedSpec) -> Result<usize> {
    let Some(f) = spec.finalists else {
        return Ok(0);
    };
    let points = finalist_points(&mut **tx, sweep).await?;
    if !points.is_empty() {
        return queue_across(tx, sweep, spec, &points).await;
    }
    // A point whose weights taught nothing (no reward at any epoch) scores a policy that
    // learned nothing: more seeds of it would say nothing of its weights.
    let unrewarded: BTreeSet<CellId> = never_rewarded(&mut **tx, sweep)
        .await?
        .into_iter()
        .collect();
    let rewarded: Vec<_> = scored_cells(&mut **tx, sweep)
        .await?
        .into_iter()
        .filter(|c| !unrewarded.contains(&c.cell))
        .collect();
    let picked = finalists::pick(&rewarded, f.top);
    let cells = spec.finalist_cells(&picked);
    insert_cells(tx, sweep, &cells, spec.epochs).await?;
    tracing::info!(%sweep, points = picked.len(), cells = cells.len(), seeds = f.seeds,
        "grid pass done: queued the finalists' further seeds");
    Ok(cells.len())
}

/// After the finalists of a grid over several terrains: queues the seeds of the point best
/// across them on the terrains where it is no finalist yet; returns how many cells.
async fn queue_across(
    tx: &mut Tx,
    sweep: SweepId,
    spec: &ResolvedSpec,
    finalist_points: &BTreeSet<Point>,
) -> Result<usize> {
    let (missing, cells) = confirmation(tx, sweep, spec, finalist_points).await?;
    let Some(&(_, i, j)) = missing.first().filter(|_| !cells.is_empty()) else {
        return Ok(0);
    };
    insert_cells(tx, sweep, &cells, spec.epochs).await?;
    tracing::info!(%sweep, w1 = spec.w1_values[i], w2 = spec.w2_values[j], terrains = missing.len(),
        cells = cells.len(), "queued the further seeds of the point best across terrains");
    Ok(cells.len())
}

/// Called once when a sweep with a finalist stage finishes: promotes the finalist with
/// the best mean over its seeds, over all terrains and on each terrain, with its interval.
/// These rows come last, so they are the sweep's promoted models whatever single runs of
/// the first pass were promoted while it ran.
pub(super) async fn promote(
    tx: &mut Tx,
    sweep: SweepId,
    spec: &ResolvedSpec,
    now_ms: i64,
) -> Result<()> {
    if spec.finalists.is_none() {
        return Ok(());
    }
    let points = finalist_points(&mut **tx, sweep).await?;
    let (overall, per_terrain) =
        finalists::winners(&scored_cells(&mut **tx, sweep).await?, &points);
    let mut rows: Vec<(String, finalists::Winner)> = per_terrain
        .into_iter()
        .filter_map(|(t, w)| Some((spec.terrains.get(t)?.to_string(), w)))
        .collect();
    if let Some(w) = overall {
        rows.push((String::new(), w));
    }
    for (terrain, w) in rows {
        sqlx::query(
            "INSERT INTO promotions (sweep_id, terrain, cell_id, score, promoted_unix_ms, ci95) \
             VALUES ($1, $2, $3, $4, $5, $6)",
        )
        .bind(sweep.0)
        .bind(&terrain)
        .bind(w.cell.0)
        .bind(w.stats.mean)
        .bind(now_ms)
        .bind(w.stats.ci95)
        .execute(&mut **tx)
        .await?;
        tracing::info!(%sweep, terrain = %terrain, w1 = spec.w1_values[w.point.1], w2 = spec.w2_values[w.point.2],
            mean = w.stats.mean, ci95 = w.stats.ci95, seeds = w.stats.n, "promoted the best finalist");
    }
    Ok(())
}
