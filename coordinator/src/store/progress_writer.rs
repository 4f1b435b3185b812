//! Group commit of epoch metrics: every `ReportProgress` call waits on one queue, one task
//! drains whatever is queued and writes it in one transaction (one multi-row `INSERT` per
//! few hundred rows), then answers every call. With many workers, one commit carries many
//! reports instead of one each; a report is answered only after its rows are committed.
//! The queue's depth and the wait of its oldest report are the coordinator's write lag,
//! logged when it grows and exposed through [`WriteStats`].

use super::backend::{self, Backend};
use super::search::record_periodic_eval;
use super::tx::{lease_cell, refuse_closed};
use crate::{validate, Error, Result};
use gaitsweep_core::{CellId, LeaseId, SweepId};
use sqlx::AnyPool;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, oneshot};

/// Reports written in one transaction at most (bounds a transaction's time and memory).
pub const MAX_BATCH: usize = 512;
/// Rows per multi-row `INSERT` (5 parameters each, well below SQLite's 32,766 and
/// PostgreSQL's 65,535).
const ROWS_PER_INSERT: usize = 400;
/// Reports that may wait before callers wait to enqueue (the backpressure a worker sees
/// as a slower answer, never as an error).
const QUEUE: usize = 16_384;
/// A write lag above this is logged as a warning (at most every 10 s).
const LAG_WARN: Duration = Duration::from_secs(1);

/// What a stored progress report answers: rows written, the cell and its sweep.
pub type ProgressAck = (usize, CellId, SweepId);

/// Counters of the metric writer, shared with whoever reports them.
#[derive(Debug, Default)]
pub struct WriteStats {
    /// Reports queued and not yet written.
    pub queued: AtomicU64,
    /// How long the oldest report of the last batch waited, microseconds.
    pub last_lag_us: AtomicU64,
    /// Metric rows written since start.
    pub rows: AtomicU64,
    /// Reports written since start.
    pub reports: AtomicU64,
    /// Transactions committed since start.
    pub batches: AtomicU64,
}

/// A snapshot of [`WriteStats`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WriteSnapshot {
    /// Reports queued and not yet written.
    pub queued: u64,
    /// Wait of the oldest report of the last batch, milliseconds.
    pub lag_ms: f64,
    /// Metric rows written since start.
    pub rows: u64,
    /// Reports written since start.
    pub reports: u64,
    /// Transactions committed since start.
    pub batches: u64,
}

impl WriteStats {
    /// The counters now.
    pub fn snapshot(&self) -> WriteSnapshot {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        WriteSnapshot {
            queued: g(&self.queued),
            lag_ms: g(&self.last_lag_us) as f64 / 1000.0,
            rows: g(&self.rows),
            reports: g(&self.reports),
            batches: g(&self.batches),
        }
    }
}

struct Job {
    lease: LeaseId,
    epochs: Vec<(u32, BTreeMap<String, f64>)>,
    queued: Instant,
    reply: oneshot::Sender<Result<ProgressAck>>,
}

/// The sending side of the metric writer; cheap to clone.
#[derive(Clone)]
pub struct ProgressWriter {
    tx: mpsc::Sender<Job>,
    stats: Arc<WriteStats>,
}

impl ProgressWriter {
    /// Starts the writer task on the current runtime, writing through `pool` (the
    /// store's one writer connection).
    pub fn start(backend: Backend, pool: AnyPool) -> Self {
        let (tx, rx) = mpsc::channel(QUEUE);
        let stats = Arc::new(WriteStats::default());
        tokio::spawn(run(backend, pool, rx, stats.clone()));
        ProgressWriter { tx, stats }
    }

    /// Queues a report and waits until it is committed (or refused).
    pub async fn write(
        &self,
        lease: LeaseId,
        epochs: &[(u32, BTreeMap<String, f64>)],
    ) -> Result<ProgressAck> {
        let (reply, rx) = oneshot::channel();
        self.stats.queued.fetch_add(1, Ordering::Relaxed);
        let job = Job {
            lease,
            epochs: epochs.to_vec(),
            queued: Instant::now(),
            reply,
        };
        if self.tx.send(job).await.is_err() {
            self.stats.queued.fetch_sub(1, Ordering::Relaxed);
            return Err(Error::Server("the metric writer has stopped".into()));
        }
        rx.await
            .map_err(|_| Error::Server("the metric writer stopped before answering".into()))?
    }

    /// The writer's counters.
    pub fn stats(&self) -> &Arc<WriteStats> {
        &self.stats
    }
}

async fn run(backend: Backend, pool: AnyPool, mut rx: mpsc::Receiver<Job>, stats: Arc<WriteStats>) {
    let mut warned: Option<Instant> = None;
    while let Some(first) = rx.recv().await {
        let mut jobs = vec![first];
        while jobs.len() < MAX_BATCH {
            match rx.try_recv() {
                Ok(j) => jobs.push(j),
                Err(_) => break,
            }
        }
        stats.queued.fetch_sub(jobs.len() as u64, Ordering::Relaxed);
        let lag = jobs
            .iter()
            .map(|j| j.queued.elapsed())
            .max()
            .unwrap_or_default();
        stats
            .last_lag_us
            .store(lag.as_micros() as u64, Ordering::Relaxed);
        if lag > LAG_WARN && warned.is_none_or(|w| w.elapsed() > Duration::from_secs(10)) {
            warned = Some(Instant::now());
            tracing::warn!(
                lag_ms = lag.as_millis() as u64,
                batch = jobs.len(),
                queued = stats.queued.load(Ordering::Relaxed),
                "metric writes are falling behind; workers batch their epochs meanwhile"
            );
        }
        let outcomes = match write_batch(backend, &pool, &jobs).await {
            Ok(o) => o,
            Err(e) => {
                tracing::error!(error = %e, reports = jobs.len(), "a batch of metric reports failed");
                let disk_full = e.is_disk_full();
                let message = e.to_string();
                jobs.iter()
                    .map(|_| {
                        Err(Error::Write {
                            message: message.clone(),
                            disk_full,
                        })
                    })
                    .collect()
            }
        };
        stats.batches.fetch_add(1, Ordering::Relaxed);
        for (job, out) in jobs.into_iter().zip(outcomes) {
            if let Ok((rows, ..)) = &out {
                stats.rows.fetch_add(*rows as u64, Ordering::Relaxed);
                stats.reports.fetch_add(1, Ordering::Relaxed);
            }
            // The caller may have gone (its call was cancelled); its rows are stored.
            let _ = job.reply.send(out);
        }
    }
}

/// Writes a batch in one transaction. A report that is refused (unknown lease, closed
/// cell, a bad value) gets its own error and writes nothing; a database error fails the
/// whole batch (the caller answers every report with it).
async fn write_batch(
    backend: Backend,
    pool: &AnyPool,
    jobs: &[Job],
) -> Result<Vec<Result<ProgressAck>>> {
    let mut tx = pool.begin_with(backend.begin_write()).await?;
    let now_ms = backend::now_ms();
    let mut out = Vec::with_capacity(jobs.len());
    let mut rows: Vec<(i64, i64, &str, f64, i64)> = Vec::new();
    for job in jobs {
        let l = match lease_cell(&mut tx, backend, job.lease).await {
            Ok(l) => l,
            // A database error ends the transaction on PostgreSQL: the batch fails whole.
            Err(e @ Error::Db(_)) => return Err(e),
            Err(e) => {
                out.push(Err(e));
                continue;
            }
        };
        if let Err(e) =
            refuse_closed(l.cell, l.state).and_then(|()| validate::progress(l.total, &job.epochs))
        {
            out.push(Err(e));
            continue;
        }
        let mut n = 0;
        let mut last = 0;
        for (epoch, values) in &job.epochs {
            last = last.max(*epoch);
            for (name, value) in values {
                rows.push((l.cell.0, i64::from(*epoch), name, *value, job.lease.0));
                n += 1;
            }
            if let Some(score) = values.get("eval/score") {
                record_periodic_eval(&mut tx, l.cell, job.lease, *epoch, *score, values, now_ms)
                    .await?;
            }
        }
        sqlx::query("UPDATE cells SET epochs_done = CASE WHEN epochs_done > $1 THEN epochs_done ELSE $1 END WHERE id = $2")
            .bind(i64::from(last))
            .bind(l.cell.0)
            .execute(&mut *tx)
            .await?;
        out.push(Ok((n, l.cell, l.sweep)));
    }
    // A batch may carry the same (cell, epoch, metric) twice (a retried report next to its
    // first try); the later row wins, as it would row by row. PostgreSQL refuses one INSERT
    // that updates a row twice, so the earlier copies are dropped first.
    let mut last: std::collections::HashMap<(i64, i64, &str), usize> =
        std::collections::HashMap::with_capacity(rows.len());
    for (i, r) in rows.iter().enumerate() {
        last.insert((r.0, r.1, r.2), i);
    }
    if last.len() < rows.len() {
        let mut i = 0;
        rows.retain(|r| {
            let keep = last[&(r.0, r.1, r.2)] == i;
            i += 1;
            keep
        });
    }
    for chunk in rows.chunks(ROWS_PER_INSERT) {
        let sql = metric_insert(chunk.len());
        let mut q = sqlx::query(&sql);
        for r in chunk {
            q = q.bind(r.0).bind(r.1).bind(r.2).bind(r.3).bind(r.4);
        }
        q.execute(&mut *tx).await?;
    }
    tx.commit().await?;
    Ok(out)
}

/// The multi-row insert of `rows` metric rows, numbered placeholders (both backends).
fn metric_insert(rows: usize) -> String {
    let mut sql =
        String::from("INSERT INTO epoch_metrics (cell_id, epoch, name, value, attempt_id) VALUES ");
    for r in 0..rows {
        let p = 5 * r;
        if r > 0 {
            sql.push_str(", ");
        }
        sql.push_str(&format!(
            "(${}, ${}, ${}, ${}, ${})",
            p + 1,
            p + 2,
            p + 3,
            p + 4,
            p + 5
        ));
    }
    sql.push_str(
        " ON CONFLICT (cell_id, epoch, name) DO UPDATE SET value = excluded.value, attempt_id = excluded.attempt_id",
    );
    sql
}
