//! Loading a report's data from the coordinator's database: the only part of the report
//! that touches SQL.

use super::{
    budget_text, machines, Promotion, ReportCell, ReportData, CURVE_METRICS, SHARE_METRICS,
};
use crate::store::queries::{self, EvalKinds};
use crate::store::rows::{CellRow, CELL_COLUMNS, CELL_ORDER};
use crate::Result;
use gaitsweep_core::records::CellRecord;
use gaitsweep_core::SweepId;
use gaitsweep_search::Layout;
use sqlx::{FromRow, Row};
use std::collections::BTreeMap;

/// Loads everything the report of `sweep` shows.
pub async fn load(db: &sqlx::AnyPool, sweep: i64) -> Result<ReportData> {
    let row = queries::sweep_spec(db, SweepId(sweep)).await?;
    let spec = row.spec;
    let search = gaitsweep_search::describe(&spec);
    let mut data = ReportData {
        sweep_id: sweep,
        name: row.name,
        robot: spec.robot.clone(),
        state: row.state,
        difficulty: spec.difficulty,
        terrains: spec.terrains.iter().map(|t| t.to_string()).collect(),
        w1_values: spec.w1_values.clone(),
        w2_values: spec.w2_values.clone(),
        cells: Vec::new(),
        promotions: Vec::new(),
        evolution: (search.layout == Layout::Candidates).then(|| spec.bounds()),
        search: search.name.to_string(),
        search_title: search.title.to_string(),
        budget: budget_text(&spec),
        finalists: spec.finalists.is_some(),
    };

    let sql = format!(
        "SELECT {CELL_COLUMNS}, COALESCE(fk.path, lk.path) AS ckpt_path \
         FROM cells c LEFT JOIN scores s ON s.cell_id = c.id \
         LEFT JOIN checkpoints fk ON fk.sha256 = s.final_checkpoint_sha256 \
         LEFT JOIN checkpoints lk ON lk.sha256 = c.last_checkpoint_sha256 \
         WHERE c.sweep_id = $1 \
         ORDER BY {CELL_ORDER}"
    );
    for r in sqlx::query(&sql).bind(sweep).fetch_all(db).await? {
        let checkpoint: Option<String> = r.try_get("ckpt_path")?;
        let c: CellRecord = CellRow::from_row(&r)?.try_into()?;
        data.cells.push(ReportCell {
            id: c.id.0,
            terrain_index: c.terrain_index as usize,
            terrain: c.terrain,
            place: c.place,
            replicate: c.replicate,
            w1: c.w1,
            w2: c.w2,
            state: c.state.to_string(),
            attempts: c.attempts,
            epochs_done: c.epochs_done,
            last_error: c.last_error,
            score: c.score,
            checkpoint,
            curves: BTreeMap::new(),
            rung: None,
            trained_on: Vec::new(),
        });
    }
    let mut attempts = queries::attempt_cpus(db, SweepId(sweep)).await?;
    for c in &mut data.cells {
        let a = attempts.remove(&c.id).unwrap_or_default();
        c.trained_on = machines::cpu_spans(&a, c.epochs_done);
    }
    let mut levels = crate::store::levels::final_levels(db, gaitsweep_core::SweepId(sweep)).await?;
    for c in &mut data.cells {
        if let (Some(s), Some(l)) = (c.score.as_mut(), levels.remove(&c.id)) {
            s.levels = l;
        }
    }
    let rungs = queries::evaluations(db, SweepId(sweep), EvalKinds::Rungs).await?;
    let mut deepest: BTreeMap<i64, (u32, f64)> = BTreeMap::new();
    for e in rungs {
        deepest.insert(e.cell_id, (e.epoch as u32, e.score));
    }
    for c in &mut data.cells {
        c.rung = deepest.get(&c.id).copied();
    }

    let names = CURVE_METRICS
        .iter()
        .chain(&SHARE_METRICS)
        .map(|n| format!("'{n}'"))
        .collect::<Vec<_>>()
        .join(", ");
    let sql = format!(
        "SELECT m.cell_id, m.epoch, m.name, m.value FROM epoch_metrics m JOIN cells c ON c.id = m.cell_id \
         WHERE c.sweep_id = $1 AND m.name IN ({names}) ORDER BY m.cell_id, m.epoch"
    );
    let mut by_cell: BTreeMap<i64, BTreeMap<String, Vec<(u32, f64)>>> = BTreeMap::new();
    for r in sqlx::query(&sql).bind(sweep).fetch_all(db).await? {
        let v: f64 = r.try_get("value")?;
        if v.is_finite() {
            by_cell
                .entry(r.try_get("cell_id")?)
                .or_default()
                .entry(r.try_get("name")?)
                .or_default()
                .push((r.try_get::<i64, _>("epoch")? as u32, v));
        }
    }
    for c in &mut data.cells {
        c.curves = by_cell.remove(&c.id).unwrap_or_default();
    }

    let mut latest: BTreeMap<String, Promotion> = BTreeMap::new();
    for r in sqlx::query(
        "SELECT terrain, cell_id, score FROM promotions WHERE sweep_id = $1 ORDER BY id",
    )
    .bind(sweep)
    .fetch_all(db)
    .await?
    {
        let p = Promotion {
            terrain: r.try_get("terrain")?,
            cell_id: r.try_get("cell_id")?,
            score: r.try_get("score")?,
        };
        latest.insert(p.terrain.clone(), p);
    }
    data.promotions = latest.into_values().collect();
    fill_axes(&mut data);
    Ok(data)
}

/// Fills terrains and grid values the spec did not give from the cells themselves.
fn fill_axes(d: &mut ReportData) {
    let n_t = d
        .cells
        .iter()
        .map(|c| c.terrain_index + 1)
        .max()
        .unwrap_or(0);
    if d.terrains.len() < n_t {
        d.terrains.resize(n_t, String::new());
    }
    let points = || d.cells.iter().filter_map(|c| Some((c, c.grid()?)));
    let n1 = points().map(|(_, (i, _))| i + 1).max().unwrap_or(0);
    let n2 = points().map(|(_, (_, j))| j + 1).max().unwrap_or(0);
    if d.w1_values.len() < n1 {
        d.w1_values.resize(n1, f64::NAN);
    }
    if d.w2_values.len() < n2 {
        d.w2_values.resize(n2, f64::NAN);
    }
    for c in &d.cells {
        if d.terrains[c.terrain_index].is_empty() {
            d.terrains[c.terrain_index] = c.terrain.clone();
        }
        let Some((i, j)) = c.grid() else {
            continue;
        };
        if d.w1_values[i].is_nan() {
            d.w1_values[i] = c.w1;
        }
        if d.w2_values[j].is_nan() {
            d.w2_values[j] = c.w2;
        }
    }
}
