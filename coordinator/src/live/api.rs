//! The live page's JSON and event stream, read from the coordinator's own database (the
//! store's reader pool) and event bus.

use super::Live;
use crate::service::now_ms;
use crate::store::queries::{self, EvalKinds};
use crate::store::Store;
use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Json, Response};
use futures::stream::Stream;
use gaitsweep_core::pb::{self, sweep_event::Kind};
use gaitsweep_core::SweepId;
use serde::Serialize;
use serde_json::{json, Value};
use sqlx::Row;
use std::collections::BTreeMap;
use std::convert::Infallible;
use std::time::Duration;
use tokio_stream::wrappers::BroadcastStream;
use tokio_stream::StreamExt;

/// An error as the page shows it: a status and a lowercase message.
pub(crate) struct ApiError(StatusCode, String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, Json(json!({ "error": self.1 }))).into_response()
    }
}

impl<E: std::fmt::Display> From<E> for ApiError {
    fn from(e: E) -> Self {
        ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string())
    }
}

type ApiResult<T> = std::result::Result<T, ApiError>;

/// One sweep in the list, with progress and an ETA from the measured epoch rate.
#[derive(Serialize)]
struct SweepSummary {
    id: i64,
    name: String,
    robot: String,
    state: String,
    search: &'static str,
    created_unix_ms: i64,
    cells: BTreeMap<&'static str, u32>,
    epochs_done: i64,
    epochs_total: i64,
    /// Epochs a second at the speed its workers train now ([`super::rate::epochs_per_second`]).
    epochs_per_second: Option<f64>,
    eta_seconds: Option<f64>,
    /// Cells the finalist stage will add once the first pass ends (0 once it has queued
    /// them, or without finalists): counted in `epochs_total`, so the ETA covers them.
    finalists_to_come: u32,
}

/// A sweep's epochs by its cells' states, for its progress.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct EpochCounts {
    /// Epochs trained by every cell.
    done: i64,
    /// Cells that train no more (done, failed, cancelled, stopped).
    closed: i64,
    /// Epochs those cells trained.
    closed_done: i64,
    /// What they fell short of the epoch they were training to (`target_epochs`).
    short_of_target: i64,
}

impl EpochCounts {
    /// The epochs the sweep will have trained when it ends. A closed cell counts at the
    /// epochs it trained (one stopped early as never rewarded, one failed for good, one a
    /// rung stopped), so a finished sweep reads full. An evolutionary search's cells appear
    /// generation by generation: its total is its budget, less what closed cells fell short
    /// of their stage (the budget already leaves out what its halving stops).
    fn total(&self, epochs: u32, cells: u32, budget: Option<u64>) -> i64 {
        match budget {
            Some(b) => (b as i64 - self.short_of_target).max(self.done),
            None => {
                let untrained = (self.closed * i64::from(epochs) - self.closed_done).max(0);
                i64::from(cells) * i64::from(epochs) - untrained
            }
        }
    }
}

/// Cells a running sweep's finalist stage will still queue, which the count of cells and
/// the epochs to go would otherwise leave out: during the first pass, the finalists' seeds
/// (known from the spec); after it, `confirmation`, the seeds that confirming the point
/// best across terrains would queue as the scores stand
/// ([`crate::store::confirmation_to_come`]).
fn finalists_to_come(
    running: bool,
    cells_total: u32,
    spec: &gaitsweep_core::ResolvedSpec,
    confirmation: usize,
) -> u32 {
    if !running || spec.finalists.is_none() {
        0
    } else if cells_total as usize == spec.cell_count() {
        spec.finalist_cell_count() as u32
    } else {
        confirmation as u32
    }
}

pub(crate) async fn sweeps(State(live): State<Live>) -> ApiResult<Json<Value>> {
    let records = live.coord.store.list_sweeps().await?;
    let counts: BTreeMap<i64, EpochCounts> = sqlx::query_as(
        "SELECT sweep_id, CAST(SUM(epochs_done) AS BIGINT), \
         CAST(SUM(CASE WHEN state IN ('done', 'failed', 'cancelled', 'stopped') THEN 1 ELSE 0 END) AS BIGINT), \
         CAST(SUM(CASE WHEN state IN ('done', 'failed', 'cancelled', 'stopped') THEN epochs_done ELSE 0 END) AS BIGINT), \
         CAST(SUM(CASE WHEN state IN ('done', 'failed', 'cancelled', 'stopped') AND target_epochs > epochs_done \
             THEN target_epochs - epochs_done ELSE 0 END) AS BIGINT) \
         FROM cells GROUP BY sweep_id",
    )
    .fetch_all(&live.db)
    .await?
    .into_iter()
    .map(|(id, done, closed, closed_done, short_of_target): (i64, i64, i64, i64, i64)| {
        (id, EpochCounts { done, closed, closed_done, short_of_target })
    })
    .collect();
    let now = now_ms();
    let mut speeds = BTreeMap::new();
    let mut confirmations = BTreeMap::new();
    for s in &records {
        if s.state == gaitsweep_core::SweepState::Running {
            if s.cells_total as usize > s.spec.cell_count() {
                confirmations.insert(
                    s.id.0,
                    crate::store::confirmation_to_come(&live.db, s.id, &s.spec).await?,
                );
            }
            speeds.insert(
                s.id.0,
                super::rate::epochs_per_second(
                    &queries::attempt_spans(&live.db, s.id, now - super::rate::WINDOW_MS).await?,
                    now,
                ),
            );
        }
    }
    let out: Vec<SweepSummary> = records
        .iter()
        .map(|s| {
            let c = counts.get(&s.id.0).copied().unwrap_or_default();
            let epochs_done = c.done;
            let running = s.state == gaitsweep_core::SweepState::Running;
            let confirmation = confirmations.get(&s.id.0).copied().unwrap_or(0);
            let finalists_to_come =
                finalists_to_come(running, s.cells_total, &s.spec, confirmation);
            let epochs_total = c.total(s.spec.epochs, s.cells_total, s.spec.budget_epochs())
                + i64::from(finalists_to_come) * i64::from(s.spec.epochs);
            let rate = speeds.get(&s.id.0).copied().flatten();
            let search = gaitsweep_search::describe(&s.spec);
            SweepSummary {
                id: s.id.0,
                name: s.spec.name.clone(),
                robot: s.spec.robot.clone(),
                state: s.state.as_str().to_string(),
                search: search.name,
                created_unix_ms: s.created_unix_ms,
                cells: BTreeMap::from([
                    ("total", s.cells_total),
                    ("queued", s.cells_queued),
                    ("running", s.cells_running),
                    ("done", s.cells_done),
                    ("failed", s.cells_failed),
                    ("paused", s.cells_paused),
                    ("stopped", s.cells_stopped),
                ]),
                epochs_done,
                epochs_total,
                epochs_per_second: rate,
                // Successive halving never trains every epoch: no ETA from the grid's total.
                eta_seconds: rate
                    .filter(|_| search.known_total)
                    .map(|r| (epochs_total - epochs_done).max(0) as f64 / r),
                finalists_to_come,
            }
        })
        .collect();
    Ok(Json(json!({ "sweeps": out })))
}

pub(crate) async fn sweep(State(live): State<Live>, Path(id): Path<i64>) -> ApiResult<Json<Value>> {
    let data = crate::report::load(&live.db, id)
        .await
        .map_err(|e| ApiError(StatusCode::NOT_FOUND, e.to_string()))?;
    let cells: Vec<Value> = data
        .cells
        .iter()
        .map(|c| {
            let last = |name: &str| c.curves.get(name).and_then(|v| v.last()).map(|p| p.1);
            json!({
                "id": c.id,
                "terrain_index": c.terrain_index,
                "w1_index": c.place.grid().map(|p| p.0),
                "w2_index": c.place.grid().map(|p| p.1),
                "generation": c.place.generation().map(|p| p.0),
                "candidate": c.place.generation().map(|p| p.1),
                "w1": c.w1,
                "w2": c.w2,
                "replicate": c.replicate,
                "state": c.state,
                "epochs_done": c.epochs_done,
                "attempts": c.attempts,
                "score": c.score.as_ref().map(|s| s.score),
                "fall_rate": c.score.as_ref().map(|s| s.fall_rate),
                "mean_vel_error": c.score.as_ref().map(|s| s.mean_vel_error),
                "overspeed": c.score.as_ref().map(|s| s.overspeed).filter(|v| v.is_finite()),
                "levels": c.score.as_ref().map(|s| s.levels.iter().map(|l| json!({
                    "level": l.level,
                    "score": l.score.score,
                    "fall_rate": l.score.fall_rate,
                    "mean_vel_error": l.score.mean_vel_error,
                })).collect::<Vec<_>>()).unwrap_or_default(),
                "mean_return": last("mean_return"),
                // Scored without ever being rewarded: its score says nothing of its weights.
                "never_rewarded": c.never_rewarded(),
                "last_error": c.last_error,
            })
        })
        .collect();
    // The latest evaluation of each cell (a rung or `eval.every`): what a paused or stopped
    // cell of a successive-halving sweep is ranked by.
    let mut latest: BTreeMap<i64, (i64, f64, Option<f64>)> = BTreeMap::new();
    for e in queries::evaluations(&live.db, SweepId(id), EvalKinds::All).await? {
        latest.insert(e.cell_id, (e.epoch, e.score, e.fall_rate));
    }
    let cells: Vec<Value> = cells
        .into_iter()
        .map(|mut c| {
            let id = c["id"].as_i64().unwrap_or(0);
            if let Some((epoch, score, fall)) = latest.get(&id) {
                c["eval_epoch"] = json!(epoch);
                c["eval_score"] = json!(score);
                c["eval_fall_rate"] = json!(fall);
            }
            c
        })
        .collect();
    let epochs = queries::sweep_spec(&live.db, SweepId(id))
        .await?
        .spec
        .epochs;
    Ok(Json(json!({
        "id": data.sweep_id,
        "search": data.search,
        "search_title": data.search_title,
        // Grid points, or an evolutionary search's candidates (rows generations).
        "layout": if data.evolution.is_some() {
            gaitsweep_search::Layout::Candidates
        } else {
            gaitsweep_search::Layout::Grid
        }
        .as_str(),
        "name": data.name,
        "robot": data.robot,
        "state": data.state,
        "epochs": epochs,
        "terrains": data.terrains,
        "terrain_files": data.terrains.iter().map(|t| crate::report::slug(t)).collect::<Vec<_>>(),
        "w1_values": data.w1_values,
        "w2_values": data.w2_values,
        "promotions": data.promotions.iter().map(|p| json!({
            "terrain": p.terrain, "cell_id": p.cell_id, "score": p.score,
        })).collect::<Vec<_>>(),
        "cells": cells,
        "across": data.across().map(|a| json!({
            "rule": crate::across::RULE,
            "w1": data.w1_values.get(a.w1_index as usize),
            "w2": data.w2_values.get(a.w2_index as usize),
            "value": a.value,
            "ci95": a.ci95,
            "interval": a.interval_text(),
            "weakest": data.terrains.get(a.weakest),
            "relative": a.relative,
        })),
    })))
}

pub(crate) async fn cell(State(live): State<Live>, Path(id): Path<i64>) -> ApiResult<Json<Value>> {
    let head = sqlx::query(
        "SELECT c.id, c.terrain, c.w1, c.w2, c.replicate, c.seed, c.state, c.epochs_done, \
         COALESCE(s.final_checkpoint_sha256, c.last_checkpoint_sha256) AS sha \
         FROM cells c LEFT JOIN scores s ON s.cell_id = c.id WHERE c.id = $1",
    )
    .bind(id)
    .fetch_optional(&live.db)
    .await?
    .ok_or_else(|| ApiError(StatusCode::NOT_FOUND, format!("no cell {id}")))?;
    let mut curves: BTreeMap<String, Vec<(i64, f64)>> = BTreeMap::new();
    for r in sqlx::query(
        "SELECT epoch, name, value FROM epoch_metrics WHERE cell_id = $1 ORDER BY epoch",
    )
    .bind(id)
    .fetch_all(&live.db)
    .await?
    {
        let v: f64 = r.try_get("value")?;
        if v.is_finite() {
            curves
                .entry(r.try_get("name")?)
                .or_default()
                .push((r.try_get("epoch")?, v));
        }
    }
    type AttemptRow = (
        i64,
        String,
        Option<String>,
        Option<String>,
        String,
        i64,
        i64,
        Option<i64>,
        Option<String>,
    );
    let attempts: Vec<Value> = sqlx::query_as::<_, AttemptRow>(
        "SELECT a.id, a.worker_id, w.hostname, w.cpu, a.state, a.resumed_from_epoch, a.started_unix_ms, \
         a.ended_unix_ms, a.error FROM attempts a LEFT JOIN workers w ON w.id = a.worker_id \
         WHERE a.cell_id = $1 ORDER BY a.id",
    )
    .bind(id)
    .fetch_all(&live.db)
    .await?
    .into_iter()
    .map(
        |(id, worker, host, cpu, state, resumed, started, ended, error)| {
            json!({
                "id": id,
                "worker": worker,
                "host": host,
                "cpu": cpu.unwrap_or_default(),
                "state": state,
                "resumed_from_epoch": resumed,
                "started_unix_ms": started,
                "ended_unix_ms": ended,
                "error": error,
            })
        },
    )
    .collect();
    let evaluations: Vec<Value> =
        sqlx::query_as::<_, (i64, String, f64, Option<f64>, Option<f64>)>(
            "SELECT epoch, kind, score, fall_rate, mean_vel_error FROM evaluations WHERE cell_id = $1 \
             ORDER BY epoch",
        )
        .bind(id)
        .fetch_all(&live.db)
        .await?
        .into_iter()
        .map(|(epoch, kind, score, fall_rate, mean_vel_error)| {
            json!({
                "epoch": epoch,
                "kind": kind,
                "score": score,
                "fall_rate": fall_rate,
                "mean_vel_error": mean_vel_error,
            })
        })
        .collect();
    Ok(Json(json!({
        "id": head.try_get::<i64, _>("id")?,
        "terrain": head.try_get::<String, _>("terrain")?,
        "w1": head.try_get::<f64, _>("w1")?,
        "w2": head.try_get::<f64, _>("w2")?,
        "replicate": head.try_get::<i64, _>("replicate")?,
        "state": head.try_get::<String, _>("state")?,
        "epochs_done": head.try_get::<i64, _>("epochs_done")?,
        "checkpoint": head.try_get::<Option<String>, _>("sha")?,
        "curves": curves,
        "attempts": attempts,
        "evaluations": evaluations,
    })))
}

pub(crate) async fn workers(State(live): State<Live>) -> ApiResult<Json<Value>> {
    let mut running: BTreeMap<String, Vec<i64>> = BTreeMap::new();
    for (w, c) in sqlx::query_as::<_, (String, i64)>(
        "SELECT worker_id, cell_id FROM attempts WHERE state = 'running' ORDER BY cell_id",
    )
    .fetch_all(&live.db)
    .await?
    {
        running.entry(w).or_default().push(c);
    }
    let rows = sqlx::query_as::<_, (String, String, i64, String, String, i64, i64)>(
        "SELECT id, hostname, cores, cpu, device, slots, last_seen_unix_ms FROM workers ORDER BY last_seen_unix_ms DESC",
    )
    .fetch_all(&live.db)
    .await?;
    let out: Vec<Value> = rows
        .into_iter()
        .map(|(id, host, cores, cpu, device, slots, last_seen)| {
            json!({
                "cells": running.get(&id).cloned().unwrap_or_default(),
                "id": id,
                "host": host,
                "cores": cores,
                "cpu": cpu,
                "device": device,
                "slots": slots,
                "last_seen_unix_ms": last_seen,
            })
        })
        .collect();
    Ok(Json(json!({ "workers": out, "now_unix_ms": now_ms() })))
}

/// The event bus as server-sent events: one JSON object per event, `sweep_id` and `kind`
/// with the cell, epoch or decision it is about. A watcher that falls behind gets a
/// `lagged` event and reloads.
pub(crate) async fn events(
    State(live): State<Live>,
) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    let rx = live.coord.events.subscribe();
    let stream = BroadcastStream::new(rx).map(|ev| {
        let v = match ev {
            Ok(e) => event_json(&e),
            Err(_) => json!({ "kind": "lagged" }),
        };
        Ok(Event::default().data(v.to_string()))
    });
    Sse::new(stream).keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
}

fn event_json(e: &pb::SweepEvent) -> Value {
    let mut v = match &e.kind {
        Some(Kind::Cell(c)) => {
            json!({ "kind": "cell", "cell_id": c.cell_id, "epochs_done": c.epochs_done })
        }
        Some(Kind::Progress(p)) => {
            json!({ "kind": "progress", "cell_id": p.cell_id, "epoch": p.epoch, "mean_return": p.mean_return })
        }
        Some(Kind::Promotion(p)) => {
            json!({ "kind": "promotion", "cell_id": p.cell.as_ref().map(|c| c.cell_id), "terrain": p.terrain })
        }
        Some(Kind::Finished(_)) => json!({ "kind": "finished" }),
        Some(Kind::Decision(d)) => {
            json!({ "kind": "decision", "cell_id": d.cell_id, "rung": d.rung, "continued": d.continued })
        }
        None => json!({ "kind": "none" }),
    };
    v["sweep_id"] = json!(e.sweep_id);
    v["unix_ms"] = json!(e.unix_ms);
    v
}

pub(crate) async fn checkpoint(
    State(live): State<Live>,
    Path(sha): Path<String>,
) -> ApiResult<Response> {
    if sha.len() != 64 || !sha.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(ApiError(
            StatusCode::BAD_REQUEST,
            format!("{sha:?} is not a sha256"),
        ));
    }
    let path: Option<String> = sqlx::query_scalar("SELECT path FROM checkpoints WHERE sha256 = $1")
        .bind(&sha)
        .fetch_optional(&live.db)
        .await?;
    let path =
        path.ok_or_else(|| ApiError(StatusCode::NOT_FOUND, format!("no checkpoint {sha}")))?;
    let bytes = tokio::fs::read(live.data_dir.join(&path)).await?;
    Ok((
        [
            (header::CONTENT_TYPE, "application/octet-stream".to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{sha}.safetensors\""),
            ),
        ],
        Body::from(bytes),
    )
        .into_response())
}

/// A file of the sweep's report (`gait.gif`, `surface_<terrain>.svg`, ...), drawn by the
/// same code as `coordinator report` into `DATA_DIR/live-report/<sweep>/` and drawn again
/// whenever the promoted cell or the number of scored cells changed.
pub(crate) async fn report_file(
    State(live): State<Live>,
    Path((id, file)): Path<(i64, String)>,
) -> ApiResult<Response> {
    if file.is_empty()
        || file.starts_with('.')
        || !file
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
    {
        return Err(ApiError(
            StatusCode::BAD_REQUEST,
            format!("{file:?} is not a report file name"),
        ));
    }
    let data = crate::report::load(&live.db, id)
        .await
        .map_err(|e| ApiError(StatusCode::NOT_FOUND, e.to_string()))?;
    let scored = data.cells.iter().filter(|c| c.score.is_some()).count();
    let key = format!("{:?} {scored}", data.promoted().map(|c| c.id));
    let dir = live.data_dir.join("live-report").join(id.to_string());
    {
        // One drawing at a time: the page asks for the GIF and the surface together.
        let _g = live.drawing.lock().await;
        let stamp = dir.join(".stamp");
        if tokio::fs::read_to_string(&stamp).await.ok().as_deref() != Some(key.as_str()) {
            tokio::fs::create_dir_all(&dir).await?;
            let args = crate::report::ReportArgs {
                sweep: id,
                data_dir: live.data_dir.clone(),
                database: None,
                out: dir.clone(),
                worker: None,
                no_gif: false,
                gif_seconds: 6.0,
            };
            let gif = crate::report::render_gif(&data, &args).await;
            let out = dir.clone();
            tokio::task::spawn_blocking(move || crate::report::write_report(&data, &out, &gif))
                .await?
                .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("{e:#}")))?;
            tokio::fs::write(&stamp, &key).await?;
        }
    }
    let bytes = tokio::fs::read(dir.join(&file)).await.map_err(|_| {
        ApiError(
            StatusCode::NOT_FOUND,
            format!("the report of sweep {id} has no {file}"),
        )
    })?;
    let kind = match file.rsplit('.').next() {
        Some("svg") => "image/svg+xml",
        Some("gif") => "image/gif",
        Some("png") => "image/png",
        Some("html") => "text/html; charset=utf-8",
        _ => "application/octet-stream",
    };
    Ok(([(header::CONTENT_TYPE, kind)], Body::from(bytes)).into_response())
}

#[cfg(test)]
mod tests {
    use super::{finalists_to_come, EpochCounts};

    #[test]
    fn a_grid_counts_closed_cells_at_the_epochs_they_trained() {
        // 4 cells of 100 epochs: one done at 100, one stopped unrewarded at 10, one failed
        // at 30, one running at 50.
        let c = EpochCounts {
            done: 190,
            closed: 3,
            closed_done: 140,
            short_of_target: 160,
        };
        assert_eq!(c.total(100, 4, None), 400 - 160);
        let fresh = EpochCounts::default();
        assert_eq!(fresh.total(100, 4, None), 400);
        // Finished: every cell closed, the total is what they trained.
        let finished = EpochCounts {
            done: 210,
            closed: 4,
            closed_done: 210,
            short_of_target: 190,
        };
        assert_eq!(finished.total(100, 4, None), finished.done);
    }

    #[test]
    fn a_budget_loses_what_closed_cells_fell_short_of() {
        let c = EpochCounts {
            done: 1_000,
            closed: 5,
            closed_done: 900,
            short_of_target: 300,
        };
        assert_eq!(c.total(100, 12, Some(3_000)), 2_700);
        // Never below what was trained.
        assert_eq!(c.total(100, 12, Some(1_100)), 1_000);
    }

    #[test]
    fn a_first_pass_counts_the_finalists_it_will_queue() {
        let spec = gaitsweep_core::SweepSpec::from_toml(
            &std::fs::read_to_string(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../studies/anymal.toml"
            ))
            .unwrap(),
        )
        .unwrap();
        let spec = crate::presets::resolve(&spec).unwrap();
        // 2 terrains x the top 4 points x 2 more seeds, while the 56 first-pass cells run.
        assert_eq!(finalists_to_come(true, 56, &spec, 0), 16);
        assert_eq!(
            finalists_to_come(true, 72, &spec, 0),
            0,
            "queued: they are cells"
        );
        // After the first pass only the confirmation of the pick across terrains can come.
        assert_eq!(finalists_to_come(true, 72, &spec, 2), 2);
        assert_eq!(
            finalists_to_come(false, 56, &spec, 0),
            0,
            "a stopped sweep queues none"
        );
        assert_eq!(finalists_to_come(false, 72, &spec, 2), 0);
        let mut plain = spec.clone();
        plain.finalists = None;
        assert_eq!(finalists_to_come(true, 56, &plain, 0), 0);
    }
}
