//! Promotion: a grid point once its replicates close, the finalists and the point best
//! across terrains when a sweep ends, and the sweep's end itself.

use super::finalists;
use super::queries;
use super::sql::Tx;
use super::tx::{cell_tx, checkpoint_of, sweep_tx};
use crate::across;
use crate::sched;
use crate::Result;
use gaitsweep_core::records::{CellRecord, CheckpointRecord, PromotionRecord, SweepRecord};
use gaitsweep_core::{CellId, CellState, ResolvedSpec, SweepId, SweepState};

/// Marks the sweep done if no cell is open any more; returns it if so.
pub(super) async fn finish_if_done(
    tx: &mut Tx,
    sweep: SweepId,
    now_ms: i64,
) -> Result<Option<SweepRecord>> {
    let open: i64 = sqlx::query_scalar(
        "SELECT COUNT(*) FROM cells WHERE sweep_id = $1 AND state IN ('queued', 'running', 'paused')",
    )
    .bind(sweep.0)
    .fetch_one(&mut **tx)
    .await?;
    if !sched::sweep_finished(open as u32) {
        return Ok(None);
    }
    let queries::SweepSpecRow { spec, state, .. } = queries::sweep_spec(&mut **tx, sweep).await?;
    if state == SweepState::Running.as_str() && finalists::queue(tx, sweep, &spec).await? > 0 {
        return Ok(None);
    }
    let changed = sqlx::query(
        "UPDATE sweeps SET state = 'done', finished_unix_ms = $1 WHERE id = $2 AND state = 'running'",
    )
    .bind(now_ms)
    .bind(sweep.0)
    .execute(&mut **tx)
    .await?
    .rows_affected();
    if changed == 0 {
        return Ok(None);
    }
    finalists::promote(tx, sweep, &spec, now_ms).await?;
    promote_across_terrains(tx, sweep, &spec, now_ms).await?;
    Ok(Some(sweep_tx(tx, sweep).await?))
}

/// When a grid over several terrains ends, promotes the point best across them
/// ([`crate::across`]) as a `promotions` row with terrain `'*'`.
async fn promote_across_terrains(
    tx: &mut Tx,
    sweep: SweepId,
    spec: &ResolvedSpec,
    now_ms: i64,
) -> Result<()> {
    if spec.terrains.len() < 2 || spec.search.generations().is_some() {
        return Ok(());
    }
    let cells = queries::scored_cells(&mut **tx, sweep).await?;
    let Some(a) = across::best_across(&cells, spec.terrains.len()) else {
        tracing::info!(%sweep, "no grid point is scored on every terrain with a positive best: nothing promoted across terrains");
        return Ok(());
    };
    sqlx::query(
        "INSERT INTO promotions (sweep_id, terrain, cell_id, score, promoted_unix_ms, ci95) \
         VALUES ($1, $2, $3, $4, $5, $6)",
    )
    .bind(sweep.0)
    .bind(across::ACROSS)
    .bind(a.cell.0)
    .bind(a.value)
    .bind(now_ms)
    .bind(a.ci95)
    .execute(&mut **tx)
    .await?;
    tracing::info!(%sweep, w1 = spec.w1_values[a.w1_index as usize], w2 = spec.w2_values[a.w2_index as usize],
        value = a.value, ci95 = a.ci95, "promoted the grid point best across terrains");
    Ok(())
}

/// Promotes the grid point (or candidate) of `cell` once all its replicates are closed:
/// ranked by the mean of their scores, represented by its best replicate (whose checkpoint
/// is the model). With one replicate this is the cell and its score.
pub(super) async fn promote_point(
    tx: &mut Tx,
    cell: &CellRecord,
    now_ms: i64,
) -> Result<Vec<PromotionRecord>> {
    if cell.replicate > 0 {
        // A finalist's further seeds are promoted together when the sweep ends.
        if queries::sweep_spec(&mut **tx, cell.sweep_id)
            .await?
            .spec
            .finalists
            .is_some()
        {
            return Ok(vec![]);
        }
    }
    let (a, b) = queries::place_filter(cell.place);
    let (i, j) = cell.place.pair();
    let rows: Vec<(i64, String, Option<f64>)> = sqlx::query_as(&format!(
        "SELECT c.id, c.state, s.score FROM cells c LEFT JOIN scores s ON s.cell_id = c.id \
         WHERE c.sweep_id = $1 AND c.terrain_index = $2 AND c.{a} = $3 AND c.{b} = $4 ORDER BY c.id"
    ))
    .bind(cell.sweep_id.0)
    .bind(i64::from(cell.terrain_index))
    .bind(i64::from(i))
    .bind(i64::from(j))
    .fetch_all(&mut **tx)
    .await?;
    let open = rows
        .iter()
        .filter(|r| r.1 == CellState::Queued.as_str() || r.1 == CellState::Running.as_str())
        .count();
    let replicates: Vec<(CellId, Option<f64>)> = rows.iter().map(|r| (CellId(r.0), r.2)).collect();
    let Some(point) = sched::point_result(&replicates, open) else {
        return Ok(vec![]);
    };
    let best = if point.cell == cell.id {
        cell.clone()
    } else {
        cell_tx(tx, point.cell).await?
    };
    let (sha, epochs): (Option<String>, i64) =
        sqlx::query_as("SELECT final_checkpoint_sha256, epochs FROM scores WHERE cell_id = $1")
            .bind(point.cell.0)
            .fetch_one(&mut **tx)
            .await?;
    let ckpt = checkpoint_of(tx, sha, Some(epochs)).await?;
    promote(tx, &best, point.stats.mean, ckpt, now_ms).await
}

/// Promotes `cell` over all terrains and on its terrain if it beats the current best.
async fn promote(
    tx: &mut Tx,
    cell: &CellRecord,
    score: f64,
    final_ckpt: Option<CheckpointRecord>,
    now_ms: i64,
) -> Result<Vec<PromotionRecord>> {
    let mut out = Vec::new();
    for terrain in ["", cell.terrain.as_str()] {
        let best: Option<(i64, f64)> = sqlx::query_as(
            "SELECT cell_id, score FROM promotions WHERE sweep_id = $1 AND terrain = $2 ORDER BY id DESC LIMIT 1",
        )
        .bind(cell.sweep_id.0)
        .bind(terrain)
        .fetch_optional(&mut **tx)
        .await?;
        if sched::beats((cell.id, score), best.map(|(c, s)| (CellId(c), s))) {
            sqlx::query("INSERT INTO promotions (sweep_id, terrain, cell_id, score, promoted_unix_ms) VALUES ($1, $2, $3, $4, $5)")
                .bind(cell.sweep_id.0)
                .bind(terrain)
                .bind(cell.id.0)
                .bind(score)
                .bind(now_ms)
                .execute(&mut **tx)
                .await?;
            out.push(PromotionRecord {
                sweep_id: cell.sweep_id,
                terrain: (!terrain.is_empty()).then(|| terrain.to_string()),
                cell: cell.clone(),
                checkpoint: final_ckpt.clone(),
                promoted_unix_ms: now_ms,
            });
        }
    }
    Ok(out)
}
