//! The store on SQL: one implementation of [`Store`] for SQLite (the default: one file in
//! the data dir) and PostgreSQL, through sqlx's `Any` driver. Both run every write on one
//! writer connection, so write transactions never interleave (SQLite's own rule, kept on
//! PostgreSQL so the two behave alike), and reads on a pool of their own. SQLite runs in WAL
//! mode and opens write transactions with `BEGIN IMMEDIATE` (so they never fail on a busy
//! snapshot). The SQL is the dialect both share ([`super::backend`]); each backend has its
//! migrations (`migrations/` for SQLite, `migrations/postgres/`).

use super::backend::{writer_pool, Backend, DatabaseUrl};
use super::progress_writer::{ProgressWriter, WriteSnapshot};
use super::promotion::{finish_if_done, promote_point};
use super::queries;
use super::rows::{CELL_COLUMNS, CELL_ORDER, SWEEP_COLUMNS};
use super::score_sql::ScoreTable;
use super::search::{self, rung_result};
use super::tx::{
    cell_from_row, cell_tx, checkpoint_of, drop_epochs_after, end_winning_attempt, lease_cell,
    refuse_closed, require_uploaded, sweep_from_row, sweep_tx, LeaseCell,
};
use super::{
    AttemptEnd, AttemptOutcome, LeaseGrant, ResultOutcome, RunningLease, Store, WorkerInfo,
};
use crate::sched::{self, Candidate};
use crate::{validate, Error, Result};
use gaitsweep_core::records::{CellRecord, CheckpointRecord, PromotionRecord, SweepRecord};
use gaitsweep_core::{CellId, CellState, LeaseId, ResolvedSpec, SweepId, WorkerId};
use gaitsweep_model::GaitScore;
use sqlx::any::{AnyConnectOptions, AnyPoolOptions};
use sqlx::sqlite::SqliteConnectOptions;
use sqlx::{Any, AnyConnection, AnyPool, ConnectOptions, Connection, Executor, Transaction};
use std::collections::BTreeMap;
use std::path::Path;
use std::str::FromStr;

/// The embedded SQLite migrations of `migrations/`.
pub static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("../migrations");
/// The embedded PostgreSQL migrations of `migrations/postgres/`.
pub static PG_MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("../migrations/postgres");

/// Per-connection SQLite settings (the journal mode is stored in the file; the rest is not).
const SQLITE_PRAGMAS: &str = "PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL; \
     PRAGMA foreign_keys = ON; PRAGMA busy_timeout = 10000;";

/// The coordinator's storage: a SQLite file or a PostgreSQL database.
#[derive(Clone)]
pub struct SqlStore {
    backend: Backend,
    write: AnyPool,
    read: AnyPool,
    progress: ProgressWriter,
}

pub(super) type Tx = Transaction<'static, Any>;

impl SqlStore {
    /// Opens (creating if needed) the SQLite database file and applies the migrations.
    pub async fn open(path: &Path) -> Result<Self> {
        Self::connect(&DatabaseUrl::Sqlite(path.to_path_buf())).await
    }

    /// Opens the database `url` names and applies its backend's migrations. A SQLite file
    /// is created if missing; a PostgreSQL database must exist.
    pub async fn connect(url: &DatabaseUrl) -> Result<Self> {
        sqlx::any::install_default_drivers();
        match url {
            DatabaseUrl::Sqlite(path) => Self::open_sqlite(path).await,
            DatabaseUrl::Postgres(u) => Self::open_postgres(u).await,
        }
    }

    async fn open_sqlite(path: &Path) -> Result<Self> {
        let path = &super::backend::absolute(path)?;
        let url = SqliteConnectOptions::new()
            .filename(path)
            .create_if_missing(true)
            .to_url_lossy();
        let opts = AnyConnectOptions::from_url(&url)?;
        // Migrations that rebuild a table (SQLite's only way to change a constraint) need
        // foreign keys off while they run; they are checked once the migrations are done.
        let mut mig = AnyConnection::connect_with(&opts).await?;
        mig.execute(
            "PRAGMA journal_mode = WAL; PRAGMA foreign_keys = OFF; PRAGMA busy_timeout = 10000;",
        )
        .await?;
        MIGRATOR.run(&mut mig).await?;
        let broken = sqlx::query("PRAGMA foreign_key_check")
            .fetch_all(&mut mig)
            .await?;
        mig.close().await?;
        if !broken.is_empty() {
            return Err(Error::Server(format!(
                "{}: {} rows break a foreign key after the migrations; restore a backup of the data dir",
                path.display(),
                broken.len()
            )));
        }
        let write = writer_pool()
            .after_connect(|conn, _| {
                Box::pin(async move { conn.execute(SQLITE_PRAGMAS).await.map(|_| ()) })
            })
            .connect_with(opts.clone())
            .await?;
        let read_url = SqliteConnectOptions::new()
            .filename(path)
            .read_only(true)
            .to_url_lossy();
        let read = AnyPoolOptions::new()
            .max_connections(4)
            .after_connect(|conn, _| {
                Box::pin(async move {
                    conn.execute("PRAGMA busy_timeout = 10000;")
                        .await
                        .map(|_| ())
                })
            })
            .connect_with(AnyConnectOptions::from_url(&read_url)?)
            .await?;
        Ok(Self::with_pools(Backend::Sqlite, write, read))
    }

    async fn open_postgres(url: &str) -> Result<Self> {
        let opts = AnyConnectOptions::from_str(url).map_err(|e| {
            Error::BadRequest(format!(
                "--database: {e}; expected postgres://user:password@host:port/database"
            ))
        })?;
        let mut mig = AnyConnection::connect_with(&opts).await?;
        PG_MIGRATOR.run(&mut mig).await?;
        mig.close().await?;
        let write = writer_pool().connect_with(opts.clone()).await?;
        let read = AnyPoolOptions::new()
            .max_connections(4)
            .connect_with(opts)
            .await?;
        Ok(Self::with_pools(Backend::Postgres, write, read))
    }

    fn with_pools(backend: Backend, write: AnyPool, read: AnyPool) -> Self {
        let progress = ProgressWriter::start(backend, write.clone());
        Self {
            backend,
            write,
            read,
            progress,
        }
    }

    /// The database behind the store.
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// The pool of read connections (the live page reads through it).
    pub fn reader(&self) -> &AnyPool {
        &self.read
    }

    /// The writer pool, for tests that reach the connection (e.g. to fill the database).
    #[cfg(test)]
    pub(crate) fn writer(&self) -> &AnyPool {
        &self.write
    }

    async fn begin(&self) -> Result<Tx> {
        Ok(self.write.begin_with(self.backend.begin_write()).await?)
    }
}

impl Store for SqlStore {
    async fn create_sweep(&self, spec: &ResolvedSpec, now_ms: i64) -> Result<SweepRecord> {
        let mut tx = self.begin().await?;
        let id: i64 = sqlx::query_scalar(
            "INSERT INTO sweeps (name, robot, spec_json, state, created_unix_ms) VALUES ($1, $2, $3, 'running', $4) RETURNING id",
        )
        .bind(&spec.name)
        .bind(&spec.robot)
        .bind(serde_json::to_string(spec)?)
        .bind(now_ms)
        .fetch_one(&mut *tx)
        .await?;
        // A grid is stored whole; an evolutionary search starts with its first generation.
        let cells = gaitsweep_search::method_for(spec)
            .initial_cells(spec)
            .map_err(Error::BadRequest)?;
        search::insert_cells(&mut tx, SweepId(id), &cells, spec.rungs()[0]).await?;
        let rec = sweep_tx(&mut tx, SweepId(id)).await?;
        tx.commit().await?;
        Ok(rec)
    }

    async fn list_sweeps(&self) -> Result<Vec<SweepRecord>> {
        let sql = format!("SELECT {SWEEP_COLUMNS} FROM sweeps w ORDER BY w.id DESC");
        sqlx::query(&sql)
            .fetch_all(&self.read)
            .await?
            .iter()
            .map(sweep_from_row)
            .collect()
    }

    async fn sweep(&self, id: SweepId) -> Result<SweepRecord> {
        let sql = format!("SELECT {SWEEP_COLUMNS} FROM sweeps w WHERE w.id = $1");
        let row = sqlx::query(&sql)
            .bind(id.0)
            .fetch_optional(&self.read)
            .await?;
        sweep_from_row(&row.ok_or(Error::UnknownSweep(id))?)
    }

    async fn never_rewarded(&self, id: SweepId) -> Result<Vec<CellId>> {
        super::queries::never_rewarded(&self.read, id).await
    }

    async fn cells(&self, id: SweepId) -> Result<Vec<CellRecord>> {
        self.sweep(id).await?;
        let sql = format!(
            "SELECT {CELL_COLUMNS} FROM cells c LEFT JOIN scores s ON s.cell_id = c.id WHERE c.sweep_id = $1 \
             ORDER BY {CELL_ORDER}"
        );
        let mut cells = sqlx::query(&sql)
            .bind(id.0)
            .fetch_all(&self.read)
            .await?
            .iter()
            .map(cell_from_row)
            .collect::<Result<Vec<_>>>()?;
        let mut levels = super::levels::final_levels(&self.read, id).await?;
        for c in &mut cells {
            if let (Some(s), Some(l)) = (c.score.as_mut(), levels.remove(&c.id.0)) {
                s.levels = l;
            }
        }
        Ok(cells)
    }

    async fn cancel_sweep(&self, id: SweepId, now_ms: i64) -> Result<(SweepRecord, Vec<LeaseId>)> {
        let mut tx = self.begin().await?;
        sweep_tx(&mut tx, id).await?;
        let leases: Vec<i64> = sqlx::query_scalar(
            "SELECT a.id FROM attempts a JOIN cells c ON c.id = a.cell_id WHERE c.sweep_id = $1 AND a.state = 'running'",
        )
        .bind(id.0)
        .fetch_all(&mut *tx)
        .await?;
        sqlx::query("UPDATE sweeps SET state = 'cancelled', finished_unix_ms = $1 WHERE id = $2 AND state = 'running'")
            .bind(now_ms)
            .bind(id.0)
            .execute(&mut *tx)
            .await?;
        sqlx::query("UPDATE cells SET state = 'cancelled' WHERE sweep_id = $1 AND state IN ('queued', 'running', 'paused')")
            .bind(id.0)
            .execute(&mut *tx)
            .await?;
        sqlx::query(
            "UPDATE attempts SET state = 'cancelled', ended_unix_ms = $1 WHERE state = 'running' \
             AND cell_id IN (SELECT id FROM cells WHERE sweep_id = $2)",
        )
        .bind(now_ms)
        .bind(id.0)
        .execute(&mut *tx)
        .await?;
        let rec = sweep_tx(&mut tx, id).await?;
        tx.commit().await?;
        Ok((rec, leases.into_iter().map(LeaseId).collect()))
    }

    async fn register_worker(&self, id: &WorkerId, info: &WorkerInfo, now_ms: i64) -> Result<()> {
        let mut tx = self.begin().await?;
        sqlx::query(
            "INSERT INTO workers (id, hostname, cores, device, slots, version, registered_unix_ms, last_seen_unix_ms, cpu) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9)",
        )
        .bind(&id.0)
        .bind(&info.hostname)
        .bind(info.cores as i64)
        .bind(&info.device)
        .bind(info.slots as i64)
        .bind(&info.version)
        .bind(now_ms)
        .bind(now_ms)
        .bind(&info.cpu)
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(())
    }

    async fn touch_workers(&self, ids: &[WorkerId], now_ms: i64) -> Result<()> {
        if ids.is_empty() {
            return Ok(());
        }
        let mut tx = self.begin().await?;
        for id in ids {
            sqlx::query("UPDATE workers SET last_seen_unix_ms = $1 WHERE id = $2")
                .bind(now_ms)
                .bind(&id.0)
                .execute(&mut *tx)
                .await?;
        }
        tx.commit().await?;
        Ok(())
    }

    async fn lease_next(
        &self,
        worker: &WorkerId,
        slot: u32,
        now_ms: i64,
    ) -> Result<Option<LeaseGrant>> {
        let mut tx = self.begin().await?;
        let slots: Option<i64> = sqlx::query_scalar("SELECT slots FROM workers WHERE id = $1")
            .bind(&worker.0)
            .fetch_optional(&mut *tx)
            .await?;
        let Some(slots) = slots else {
            return Err(Error::UnknownWorker(worker.0.clone()));
        };
        validate::slot(slot, slots as u32)?;
        let heads: Vec<(i64, i64)> = sqlx::query_as(
            "SELECT MIN(c.id), c.sweep_id FROM cells c JOIN sweeps w ON w.id = c.sweep_id \
             WHERE c.state = 'queued' AND w.state = 'running' GROUP BY c.sweep_id",
        )
        .fetch_all(&mut *tx)
        .await?;
        if heads.is_empty() {
            return Ok(None);
        }
        let running: BTreeMap<i64, i64> = sqlx::query_as::<_, (i64, i64)>(
            "SELECT sweep_id, COUNT(*) FROM cells WHERE state = 'running' GROUP BY sweep_id",
        )
        .fetch_all(&mut *tx)
        .await?
        .into_iter()
        .collect();
        let candidates: Vec<Candidate> = heads
            .iter()
            .map(|&(cell, sweep)| Candidate {
                cell: CellId(cell),
                sweep: SweepId(sweep),
                running: running.get(&sweep).copied().unwrap_or(0) as u32,
            })
            .collect();
        let Some(cell_id) = sched::pick_next(&candidates) else {
            return Ok(None);
        };
        let (sha, epoch): (Option<String>, Option<i64>) = sqlx::query_as(
            "SELECT last_checkpoint_sha256, last_checkpoint_epoch FROM cells WHERE id = $1",
        )
        .bind(cell_id.0)
        .fetch_one(&mut *tx)
        .await?;
        let resume = checkpoint_of(&mut tx, sha, epoch).await?;
        let lease: i64 = sqlx::query_scalar(
            "INSERT INTO attempts (cell_id, worker_id, slot, state, resumed_from_epoch, started_unix_ms) \
             VALUES ($1, $2, $3, 'running', $4, $5) RETURNING id",
        )
        .bind(cell_id.0)
        .bind(&worker.0)
        .bind(slot as i64)
        .bind(resume.as_ref().map_or(0, |c| c.epoch as i64))
        .bind(now_ms)
        .fetch_one(&mut *tx)
        .await?;
        sqlx::query("UPDATE cells SET state = 'running', attempts = attempts + 1 WHERE id = $1")
            .bind(cell_id.0)
            .execute(&mut *tx)
            .await?;
        let cell = cell_tx(&mut tx, cell_id).await?;
        let spec = queries::sweep_spec(&mut *tx, cell.sweep_id).await?.spec;
        tx.commit().await?;
        Ok(Some(LeaseGrant {
            lease: LeaseId(lease),
            cell,
            spec,
            resume,
        }))
    }

    async fn running_leases(&self) -> Result<Vec<RunningLease>> {
        let rows: Vec<(i64, i64, i64, String)> = sqlx::query_as(
            "SELECT a.id, a.cell_id, c.sweep_id, a.worker_id FROM attempts a JOIN cells c ON c.id = a.cell_id \
             WHERE a.state = 'running'",
        )
        .fetch_all(&self.read)
        .await?;
        Ok(rows
            .into_iter()
            .map(|(l, c, s, w)| RunningLease {
                lease: LeaseId(l),
                cell: CellId(c),
                sweep: SweepId(s),
                worker: WorkerId(w),
            })
            .collect())
    }

    async fn open_lease(&self, lease: LeaseId) -> Result<(CellId, SweepId)> {
        let mut tx = self.read.begin().await?;
        let l = lease_cell(&mut tx, self.backend, lease).await?;
        refuse_closed(l.cell, l.state)?;
        Ok((l.cell, l.sweep))
    }

    async fn record_progress(
        &self,
        lease: LeaseId,
        epochs: &[(u32, BTreeMap<String, f64>)],
    ) -> Result<(usize, CellId, SweepId)> {
        self.progress.write(lease, epochs).await
    }

    fn write_stats(&self) -> WriteSnapshot {
        self.progress.stats().snapshot()
    }

    async fn record_checkpoint(
        &self,
        lease: LeaseId,
        ckpt: &CheckpointRecord,
        rel_path: &str,
        now_ms: i64,
    ) -> Result<()> {
        let mut tx = self.begin().await?;
        let l = lease_cell(&mut tx, self.backend, lease).await?;
        let cell = l.cell;
        refuse_closed(cell, l.state)?;
        validate::checkpoint_epoch(l.epochs, ckpt.epoch)?;
        sqlx::query("INSERT INTO checkpoints (sha256, size, path, created_unix_ms) VALUES ($1, $2, $3, $4) ON CONFLICT (sha256) DO NOTHING")
            .bind(&ckpt.sha256)
            .bind(ckpt.size as i64)
            .bind(rel_path)
            .bind(now_ms)
            .execute(&mut *tx)
            .await?;
        sqlx::query(
            "INSERT INTO cell_checkpoints (cell_id, epoch, sha256, attempt_id, unix_ms) VALUES ($1, $2, $3, $4, $5) \
             ON CONFLICT (cell_id, epoch) DO UPDATE SET sha256 = excluded.sha256, attempt_id = excluded.attempt_id",
        )
        .bind(cell.0)
        .bind(ckpt.epoch as i64)
        .bind(&ckpt.sha256)
        .bind(lease.0)
        .bind(now_ms)
        .execute(&mut *tx)
        .await?;
        sqlx::query(
            "UPDATE cells SET last_checkpoint_sha256 = $1, last_checkpoint_epoch = $2 \
             WHERE id = $3 AND (last_checkpoint_epoch IS NULL OR last_checkpoint_epoch <= $4)",
        )
        .bind(&ckpt.sha256)
        .bind(ckpt.epoch as i64)
        .bind(cell.0)
        .bind(ckpt.epoch as i64)
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(())
    }

    async fn checkpoint_path(&self, sha256: &str) -> Result<(u64, String)> {
        let row: Option<(i64, String)> =
            sqlx::query_as("SELECT size, path FROM checkpoints WHERE sha256 = $1")
                .bind(sha256)
                .fetch_optional(&self.read)
                .await?;
        let (size, path) = row.ok_or_else(|| Error::UnknownCheckpoint(sha256.to_string()))?;
        Ok((size as u64, path))
    }

    async fn report_result(
        &self,
        lease: LeaseId,
        score: &GaitScore,
        epochs: u32,
        final_sha256: Option<&str>,
        now_ms: i64,
    ) -> Result<ResultOutcome> {
        validate::score(score)?;
        let mut tx = self.begin().await?;
        let LeaseCell {
            cell: cell_id,
            sweep,
            state,
            epochs: target,
            total,
            ..
        } = lease_cell(&mut tx, self.backend, lease).await?;
        let rung_seen: Option<i64> =
            sqlx::query_scalar("SELECT 1 FROM evaluations WHERE attempt_id = $1 AND kind = 'rung'")
                .bind(lease.0)
                .fetch_optional(&mut *tx)
                .await?;
        let scored: Option<i64> = sqlx::query_scalar("SELECT 1 FROM scores WHERE cell_id = $1")
            .bind(cell_id.0)
            .fetch_optional(&mut *tx)
            .await?;
        if rung_seen.is_some() || (target == total && scored.is_some()) {
            // A retried report: answered, nothing written.
            return Ok(ResultOutcome::duplicate(cell_tx(&mut tx, cell_id).await?));
        }
        if target < total {
            let out = rung_result(
                &mut tx,
                lease,
                cell_id,
                sweep,
                state,
                target,
                score,
                epochs,
                final_sha256,
                now_ms,
            )
            .await?;
            tx.commit().await?;
            return Ok(out);
        }
        refuse_closed(cell_id, state)?;
        validate::result_epochs(target, epochs)?;
        require_uploaded(&mut tx, final_sha256, epochs, "final").await?;
        let t = ScoreTable::Final;
        let sql = format!(
            "INSERT INTO scores (cell_id, attempt_id, epochs, final_checkpoint_sha256, reported_unix_ms, {}) \
             VALUES ($1, $2, $3, $4, $5, {})",
            t.columns(),
            t.placeholders(6)
        );
        let q = sqlx::query(&sql)
            .bind(cell_id.0)
            .bind(lease.0)
            .bind(epochs as i64)
            .bind(final_sha256)
            .bind(now_ms);
        t.bind(q, score).execute(&mut *tx).await?;
        super::levels::write(&mut tx, cell_id, lease, epochs, &score.levels).await?;
        drop_epochs_after(&mut tx, cell_id, epochs).await?;
        end_winning_attempt(
            &mut tx,
            lease,
            cell_id,
            now_ms,
            "cell finished by another attempt",
        )
        .await?;
        sqlx::query("UPDATE cells SET state = 'done', epochs_done = $1 WHERE id = $2")
            .bind(epochs as i64)
            .bind(cell_id.0)
            .execute(&mut *tx)
            .await?;
        let cell = cell_tx(&mut tx, cell_id).await?;
        let promotions = promote_point(&mut tx, &cell, now_ms).await?;
        search::apply_search(&mut tx, sweep, now_ms).await?;
        let finished = finish_if_done(&mut tx, sweep, now_ms).await?;
        tx.commit().await?;
        Ok(ResultOutcome {
            duplicate: false,
            cell,
            promotions,
            decisions: vec![],
            finished,
        })
    }

    async fn end_attempt(
        &self,
        lease: LeaseId,
        end: AttemptEnd,
        error: &str,
        max_attempts: u32,
        now_ms: i64,
    ) -> Result<AttemptOutcome> {
        let mut tx = self.begin().await?;
        let LeaseCell {
            cell: cell_id,
            sweep,
            state,
            attempt_state,
            ..
        } = lease_cell(&mut tx, self.backend, lease).await?;
        if attempt_state != "running" {
            let cell = cell_tx(&mut tx, cell_id).await?;
            return Ok(AttemptOutcome {
                cell,
                decisions: vec![],
                finished: None,
            });
        }
        sqlx::query("UPDATE attempts SET state = $1, ended_unix_ms = $2, error = $3 WHERE id = $4")
            .bind(end.as_str())
            .bind(now_ms)
            .bind(error)
            .bind(lease.0)
            .execute(&mut *tx)
            .await?;
        let others: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM attempts WHERE cell_id = $1 AND state = 'running'",
        )
        .bind(cell_id.0)
        .fetch_one(&mut *tx)
        .await?;
        if state == CellState::Running && others == 0 {
            let failures: i64 = sqlx::query_scalar(
                "SELECT COUNT(*) FROM attempts WHERE cell_id = $1 AND state IN ('failed', 'expired')",
            )
            .bind(cell_id.0)
            .fetch_one(&mut *tx)
            .await?;
            let next = match end {
                AttemptEnd::Released => CellState::Queued,
                AttemptEnd::Failed | AttemptEnd::Expired => {
                    sched::after_failure(failures as u32, max_attempts)
                }
            };
            sqlx::query("UPDATE cells SET state = $1, last_error = $2 WHERE id = $3")
                .bind(next.as_str())
                .bind(error)
                .bind(cell_id.0)
                .execute(&mut *tx)
                .await?;
        }
        // A cell that failed for good may close a rung others wait at, or the last open
        // cell of an evolutionary search's generation.
        let decisions = search::apply_search(&mut tx, sweep, now_ms).await?;
        let cell = cell_tx(&mut tx, cell_id).await?;
        let finished = finish_if_done(&mut tx, sweep, now_ms).await?;
        tx.commit().await?;
        Ok(AttemptOutcome {
            cell,
            decisions,
            finished,
        })
    }

    async fn promoted(&self, id: SweepId, terrain: Option<&str>) -> Result<PromotionRecord> {
        let mut tx = self.read.begin().await?;
        let sweep = sweep_tx(&mut tx, id).await?;
        if let Some(t) = terrain {
            if !sweep.spec.terrains.iter().any(|k| k.to_string() == t) {
                let have: Vec<String> = sweep.spec.terrains.iter().map(|k| k.to_string()).collect();
                return Err(Error::BadRequest(format!(
                    "sweep {id} has no terrain {t:?}: its terrains are {}",
                    have.join(", ")
                )));
            }
        }
        let row: Option<(i64, i64)> = sqlx::query_as(
            "SELECT cell_id, promoted_unix_ms FROM promotions WHERE sweep_id = $1 AND terrain = $2 ORDER BY id DESC LIMIT 1",
        )
        .bind(id.0)
        .bind(terrain.unwrap_or(""))
        .fetch_optional(&mut *tx)
        .await?;
        let (cell_id, at) = row.ok_or(Error::NothingPromoted(id))?;
        let cell = cell_tx(&mut tx, CellId(cell_id)).await?;
        let (sha, epochs): (Option<String>, i64) =
            sqlx::query_as("SELECT final_checkpoint_sha256, epochs FROM scores WHERE cell_id = $1")
                .bind(cell_id)
                .fetch_one(&mut *tx)
                .await?;
        let checkpoint = checkpoint_of(&mut tx, sha, Some(epochs)).await?;
        Ok(PromotionRecord {
            sweep_id: id,
            terrain: terrain.map(str::to_string),
            cell,
            checkpoint,
            promoted_unix_ms: at,
        })
    }
}
