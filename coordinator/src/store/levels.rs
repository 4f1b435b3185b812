//! Each difficulty level's score of an evaluation (`level_scores`), written in the
//! transaction that stores the evaluation itself: the final score, a rung's or a periodic
//! one.

use super::score_sql::ScoreTable;
use super::sql::Tx;
use crate::Result;
use gaitsweep_core::{CellId, LeaseId, SweepId};
use gaitsweep_model::{GaitScore, LevelScore};
use std::collections::BTreeMap;

/// Stores `levels`, the per-level scores of the cell's evaluation at `epoch`. A later
/// attempt's evaluation at the same epoch replaces an earlier one's, as the evaluation's
/// own row does.
pub(super) async fn write(
    tx: &mut Tx,
    cell: CellId,
    lease: LeaseId,
    epoch: u32,
    levels: &[LevelScore],
) -> Result<()> {
    for l in levels {
        let t = ScoreTable::Evaluation;
        let sql = format!(
            "INSERT INTO level_scores (cell_id, epoch, level, attempt_id, {}) VALUES ($1, $2, $3, $4, {}) \
             ON CONFLICT (cell_id, epoch, level) DO UPDATE SET attempt_id = excluded.attempt_id, {}",
            t.columns(),
            t.placeholders(5),
            t.upserts()
        );
        let q = sqlx::query(&sql)
            .bind(cell.0)
            .bind(i64::from(epoch))
            .bind(i64::from(l.level.min(9)))
            .bind(lease.0);
        t.bind(q, &l.score).execute(&mut **tx).await?;
    }
    Ok(())
}

/// The per-level scores of the final score of every scored cell of `sweep`, by cell id,
/// levels ascending. The store's cell list and the report read them here.
pub async fn final_levels<'e>(
    db: impl sqlx::Executor<'e, Database = sqlx::Any>,
    sweep: SweepId,
) -> Result<BTreeMap<i64, Vec<LevelScore>>> {
    type Row = (
        i64,
        i64,
        f64,
        f64,
        f64,
        f64,
        f64,
        f64,
        f64,
        f64,
        f64,
        f64,
        i64,
    );
    let rows: Vec<Row> = sqlx::query_as(
        "SELECT l.cell_id, l.level, l.score, l.track, l.effort, l.tilt, l.progress, \
         l.progress_bounded, l.fall_rate, l.mean_vel_error, l.mean_speed, l.overspeed, \
         l.robots FROM level_scores l \
         JOIN scores s ON s.cell_id = l.cell_id AND s.epochs = l.epoch \
         JOIN cells c ON c.id = l.cell_id WHERE c.sweep_id = $1 ORDER BY l.cell_id, l.level",
    )
    .bind(sweep.0)
    .fetch_all(db)
    .await?;
    let mut out: BTreeMap<i64, Vec<LevelScore>> = BTreeMap::new();
    for (
        cell,
        level,
        score,
        track,
        effort,
        tilt,
        progress,
        bounded,
        fall,
        err,
        speed,
        over,
        robots,
    ) in rows
    {
        out.entry(cell).or_default().push(LevelScore {
            level: level.clamp(0, 9) as u8,
            score: GaitScore {
                score,
                track,
                effort,
                tilt,
                progress,
                progress_bounded: bounded,
                fall_rate: fall,
                mean_vel_error: err,
                mean_speed: speed,
                overspeed: over,
                robots: robots.max(0) as usize,
                ..Default::default()
            },
        });
    }
    Ok(out)
}
