//! `coordinator tensorboard SWEEP --data-dir DIR --out OUT`: every metric every cell of a
//! sweep reported, as one TensorBoard log dir with one run per cell
//! (`<terrain>_w1=<w1>_w2=<w2>_seed=<seed>`), read from the database (read-only).

use crate::error::io;
use crate::{Error, Result};
use gaitsweep_core::tensorboard::EventWriter;
use gaitsweep_core::SweepId;
use sqlx::Row;
use std::path::{Path, PathBuf};

/// Arguments of `coordinator tensorboard`.
#[derive(clap::Args, Debug)]
pub struct TensorboardArgs {
    /// Sweep id.
    pub sweep: i64,
    /// The coordinator's data dir (holds gaitsweep.sqlite); not needed with --database.
    #[arg(long, required_unless_present = "database")]
    pub data_dir: Option<PathBuf>,
    /// The coordinator's database when it is not the data dir's SQLite file (as `serve
    /// --database`).
    #[arg(long, env = "GAITSWEEP_DATABASE", hide_env_values = true)]
    pub database: Option<String>,
    /// The log dir to write (`tensorboard --logdir OUT`).
    #[arg(long, default_value = "tensorboard")]
    pub out: PathBuf,
}

/// The run name of a cell: terrain, weights and seed, safe as a directory name.
pub fn run_name(terrain: &str, w1: f64, w2: f64, seed: u64) -> String {
    format!("{terrain}_w1={w1:.3}_w2={w2:.3}_seed={seed}")
}

/// Writes the log dir; returns the number of runs and of scalars written.
pub async fn export(db: &sqlx::AnyPool, sweep: i64, out: &Path) -> Result<(usize, usize)> {
    let cells =
        sqlx::query("SELECT id, terrain, w1, w2, seed FROM cells WHERE sweep_id = $1 ORDER BY id")
            .bind(sweep)
            .fetch_all(db)
            .await?;
    if cells.is_empty() {
        return Err(Error::UnknownSweep(SweepId(sweep)));
    }
    let (mut runs, mut scalars) = (0, 0);
    for c in cells {
        let id: i64 = c.try_get("id")?;
        let name = run_name(
            &c.try_get::<String, _>("terrain")?,
            c.try_get("w1")?,
            c.try_get("w2")?,
            c.try_get::<i64, _>("seed")? as u64,
        );
        let rows = sqlx::query(
            "SELECT epoch, name, value FROM epoch_metrics WHERE cell_id = $1 ORDER BY epoch, name",
        )
        .bind(id)
        .fetch_all(db)
        .await?;
        if rows.is_empty() {
            continue;
        }
        let dir = out.join(&name);
        let mut w = EventWriter::create(&dir)
            .map_err(io(format!("start an event file in {}", dir.display())))?;
        let mut epoch = None;
        let mut values: Vec<(String, f64)> = Vec::new();
        let mut flush = |w: &mut EventWriter, e: Option<u32>, v: &mut Vec<(String, f64)>| {
            if let Some(e) = e {
                w.scalars(e, v.iter().map(|(k, x)| (k.as_str(), *x)))?;
                scalars += v.len();
            }
            v.clear();
            std::io::Result::Ok(())
        };
        for r in rows {
            let e = r.try_get::<i64, _>("epoch")? as u32;
            if epoch != Some(e) {
                flush(&mut w, epoch, &mut values)
                    .map_err(io(format!("write {}", dir.display())))?;
                epoch = Some(e);
            }
            values.push((r.try_get("name")?, r.try_get("value")?));
        }
        flush(&mut w, epoch, &mut values)
            .and_then(|()| w.flush())
            .map_err(io(format!("write {}", dir.display())))?;
        runs += 1;
    }
    Ok((runs, scalars))
}

/// Runs `coordinator tensorboard`.
pub async fn run(a: TensorboardArgs) -> Result<()> {
    let dir = a.data_dir.clone().unwrap_or_default();
    let db = crate::store::reader::open(&dir, a.database.as_deref()).await?;
    let (runs, scalars) = export(&db, a.sweep, &a.out).await?;
    db.close().await;
    println!(
        "sweep {}: {runs} runs, {scalars} scalars in {}; open with `tensorboard --logdir {}`",
        a.sweep,
        a.out.display(),
        a.out.display()
    );
    Ok(())
}
