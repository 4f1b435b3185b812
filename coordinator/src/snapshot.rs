//! `coordinator snapshot`: a SQLite data dir reduced to what a later sitting, on another
//! machine, needs to go on with its sweeps: the database (every score, evaluation, attempt
//! and promotion; the training metrics of every 10th epoch) and only the checkpoint files
//! that are read again.
//!
//! A recording too long for one machine (the paper's study, issue 39) lives in a snapshot
//! committed to the repository between sittings; `scripts/record-sweep.sh` restores it into
//! a fresh data dir and writes it back. The cells training when the snapshot is taken are
//! queued in it (a restore point holds no lease). The checkpoint files kept are those of
//! the cells that will train again (their latest checkpoint, which a worker resumes from),
//! the final checkpoint of each sweep's promoted cells (the latest promotion, overall and
//! per terrain), and the final checkpoints of the `keep_best` best-scored cells of each
//! sweep and terrain (the finalists a later promotion may pick).
//! The other files stay listed in `checkpoints` with their hashes; asking the restored
//! coordinator for one says that it was left out ([`crate::Error::CheckpointFileMissing`]).

use crate::error::io;
use crate::store::reader::{self, DB_FILE};
use crate::{Error, Result};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Arguments of `coordinator snapshot`.
#[derive(clap::Args, Debug)]
pub struct SnapshotArgs {
    /// The coordinator's data dir (SQLite); the coordinator may be running.
    #[arg(long)]
    pub data_dir: PathBuf,
    /// The snapshot dir to write (created; a previous snapshot there is replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Final checkpoints kept of the best-scored cells of each sweep and terrain.
    #[arg(long, default_value_t = 12)]
    pub keep_best: u32,
    /// Training metrics kept at every N-th epoch (and each cell's first and last); 1: all.
    /// Scores, evaluations and promotions are always kept whole.
    #[arg(long, default_value_t = 10)]
    pub metrics_every: u32,
}

/// What a snapshot holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SnapshotSummary {
    /// Checkpoint files copied.
    pub kept: usize,
    /// Checkpoints listed in the database whose files were left out.
    pub left_out: usize,
    /// Bytes of the database file plus the checkpoint files.
    pub bytes: u64,
}

/// The error of an attempt that was running when its snapshot was taken.
pub const RELEASED_BY_SNAPSHOT: &str =
    "released: the snapshot was taken while this attempt ran; a coordinator restored from it queues the cell again";

/// The checkpoints a snapshot keeps: (sha256, data-dir-relative path), sorted.
const KEPT_SQL: &str = "SELECT sha256, path FROM checkpoints WHERE sha256 IN ( \
     SELECT last_checkpoint_sha256 FROM cells \
       WHERE state IN ('queued', 'running') AND last_checkpoint_sha256 IS NOT NULL \
     UNION SELECT s.final_checkpoint_sha256 FROM promotions p JOIN scores s ON s.cell_id = p.cell_id \
       WHERE p.id IN (SELECT MAX(id) FROM promotions GROUP BY sweep_id, terrain) \
     UNION SELECT sha FROM ( \
       SELECT s.final_checkpoint_sha256 AS sha, ROW_NUMBER() OVER ( \
         PARTITION BY c.sweep_id, c.terrain ORDER BY s.score DESC, c.id) AS rank \
       FROM scores s JOIN cells c ON c.id = s.cell_id) ranked WHERE rank <= $1 \
   ) ORDER BY sha256";

/// Writes the snapshot of `data_dir` into `out`: `out/gaitsweep.sqlite` (a consistent copy,
/// also while the coordinator writes, with the training metrics thinned to every
/// `metrics_every`-th epoch) and `out/checkpoints/..` as in the data dir. Files of an
/// earlier snapshot in `out` that are no longer kept are removed.
pub async fn snapshot(
    data_dir: &Path,
    out: &Path,
    keep_best: u32,
    metrics_every: u32,
) -> Result<SnapshotSummary> {
    if metrics_every == 0 {
        return Err(Error::BadRequest(
            "--metrics-every must be at least 1 (1 keeps every epoch)".into(),
        ));
    }
    let db = reader::open(data_dir, None).await?;
    check_apart(&real(data_dir)?, &real(out)?)?;
    std::fs::create_dir_all(out).map_err(io(format!("create {}", out.display())))?;
    let tmp = out.join(format!("{DB_FILE}.tmp"));
    remove_if_present(&tmp)?;
    let target = absolute(&tmp)?;
    // VACUUM INTO reads one transaction's view (WAL), so a running coordinator's writes
    // either are in the copy whole or not at all.
    sqlx::query("VACUUM INTO $1")
        .bind(target.to_string_lossy().into_owned())
        .execute(&db)
        .await?;
    db.close().await;
    // What to keep is read from the copy: a checkpoint the coordinator records after the
    // copy was taken is not one the copy resumes from.
    let (kept, listed) = trim_copy(&target, keep_best, metrics_every).await?;
    // The files first, the database last, the old files after it: at every moment the
    // snapshot's database finds the checkpoints it resumes from.
    let mut bytes = 0;
    let mut wanted = BTreeSet::new();
    for (sha, rel) in &kept {
        let rel = safe_relative(rel)?;
        let (src, dst) = (data_dir.join(&rel), out.join(&rel));
        if !src.is_file() {
            return Err(Error::CheckpointFileMissing {
                sha256: sha.clone(),
                path: src.display().to_string(),
            });
        }
        if !dst.is_file() || file_len(&dst)? != file_len(&src)? {
            if let Some(parent) = dst.parent() {
                std::fs::create_dir_all(parent)
                    .map_err(io(format!("create {}", parent.display())))?;
            }
            let part = dst.with_extension("part");
            std::fs::copy(&src, &part).map_err(io(format!(
                "copy {} to {}",
                src.display(),
                part.display()
            )))?;
            std::fs::rename(&part, &dst).map_err(io(format!("move {}", part.display())))?;
        }
        bytes += file_len(&dst)?;
        wanted.insert(dst);
    }
    let final_db = out.join(DB_FILE);
    std::fs::rename(&tmp, &final_db).map_err(io(format!(
        "move {} to {}",
        tmp.display(),
        final_db.display()
    )))?;
    bytes += file_len(&final_db)?;
    prune(&out.join("checkpoints"), &wanted)?;
    Ok(SnapshotSummary {
        kept: kept.len(),
        left_out: usize::try_from(listed)
            .unwrap_or(0)
            .saturating_sub(kept.len()),
        bytes,
    })
}

/// In the copy `db_file`: queues the cells that were running; keeps the training metrics
/// of every `every`-th epoch and of each cell's first and last reported epoch (a snapshot
/// is committed to a repository, and a 1,200-epoch cell's ~40 metrics an epoch are ~2 MB a
/// cell); returns the checkpoints to keep (sha256, data-dir-relative path) and how many
/// checkpoints the copy lists.
async fn trim_copy(
    db_file: &Path,
    keep_best: u32,
    every: u32,
) -> Result<(Vec<(String, String)>, i64)> {
    use sqlx::{ConnectOptions, Connection};
    let mut conn = sqlx::sqlite::SqliteConnectOptions::new()
        .filename(db_file)
        .connect()
        .await?;
    // The copy is a restore point, and no worker holds its leases any more: its running
    // attempts end released (not counted towards the attempt limit) and their cells are
    // queued, so a restored coordinator hands them out at once, resuming from their latest
    // checkpoint, instead of after each lease expires as a counted failure.
    sqlx::query(
        "UPDATE attempts SET state = 'released', ended_unix_ms = $1, error = $2 WHERE state = 'running'",
    )
    .bind(crate::store::backend::now_ms())
    .bind(RELEASED_BY_SNAPSHOT)
    .execute(&mut conn)
    .await?;
    sqlx::query("UPDATE cells SET state = 'queued' WHERE state = 'running'")
        .execute(&mut conn)
        .await?;
    let kept: Vec<(String, String)> = sqlx::query_as(KEPT_SQL)
        .bind(i64::from(keep_best))
        .fetch_all(&mut conn)
        .await?;
    let listed: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM checkpoints")
        .fetch_one(&mut conn)
        .await?;
    if every == 1 {
        conn.close().await?;
        return Ok((kept, listed));
    }
    sqlx::query(
        "DELETE FROM epoch_metrics WHERE epoch % $1 != 0 AND (cell_id, epoch) NOT IN ( \
           SELECT cell_id, MIN(epoch) FROM epoch_metrics GROUP BY cell_id \
           UNION SELECT cell_id, MAX(epoch) FROM epoch_metrics GROUP BY cell_id)",
    )
    .bind(i64::from(every))
    .execute(&mut conn)
    .await?;
    sqlx::query("VACUUM").execute(&mut conn).await?;
    conn.close().await?;
    Ok((kept, listed))
}

/// Runs `coordinator snapshot`.
pub async fn run(a: SnapshotArgs) -> Result<()> {
    let s = snapshot(&a.data_dir, &a.out, a.keep_best, a.metrics_every).await?;
    println!(
        "snapshot of {} in {}: the database (training metrics every {} epochs) and {} checkpoint files ({:.1} MiB); {} checkpoints left out",
        a.data_dir.display(),
        a.out.display(),
        a.metrics_every,
        s.kept,
        s.bytes as f64 / (1u64 << 20) as f64,
        s.left_out
    );
    Ok(())
}

/// The snapshot replaces files in `out`: it must not be the data dir, nor inside it, nor hold it.
fn check_apart(data_dir: &Path, out: &Path) -> Result<()> {
    if out.starts_with(data_dir) || data_dir.starts_with(out) {
        return Err(Error::BadRequest(format!(
            "the snapshot dir {} and the data dir {} overlap: write the snapshot to a dir of its own",
            out.display(),
            data_dir.display()
        )));
    }
    Ok(())
}

/// A stored path must stay inside the data dir.
fn safe_relative(rel: &str) -> Result<PathBuf> {
    let p = PathBuf::from(rel);
    if p.is_absolute()
        || p.components()
            .any(|c| !matches!(c, std::path::Component::Normal(_)))
    {
        return Err(Error::BadRequest(format!(
            "checkpoint path {rel:?} in the database is not inside the data dir"
        )));
    }
    Ok(p)
}

/// `p` with its symbolic links and `..` resolved, also when it does not exist yet (its
/// nearest existing ancestor is resolved and the rest appended).
fn real(p: &Path) -> Result<PathBuf> {
    use std::path::Component;
    let mut p = absolute(p)?
        .components()
        .fold(PathBuf::new(), |mut acc, c| {
            match c {
                Component::ParentDir => {
                    acc.pop();
                }
                Component::CurDir => {}
                c => acc.push(c),
            }
            acc
        });
    if p.as_os_str().is_empty() {
        p.push("/");
    }
    let mut rest = Vec::new();
    let mut base = p.as_path();
    loop {
        match std::fs::canonicalize(base) {
            Ok(mut r) => {
                r.extend(rest.iter().rev());
                return Ok(r);
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => match base.parent() {
                Some(parent) => {
                    rest.push(base.file_name().unwrap_or_default().to_os_string());
                    base = parent;
                }
                None => return Err(io(format!("resolve {}", p.display()))(e)),
            },
            Err(e) => return Err(io(format!("resolve {}", p.display()))(e)),
        }
    }
}

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).map_err(io(format!("resolve {}", p.display())))
}

fn file_len(p: &Path) -> Result<u64> {
    Ok(std::fs::metadata(p)
        .map_err(io(format!("stat {}", p.display())))?
        .len())
}

fn remove_if_present(p: &Path) -> Result<()> {
    match std::fs::remove_file(p) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(io(format!("remove {}", p.display()))(e))
        }
        _ => Ok(()),
    }
}

/// Removes the files under `dir` that are not in `keep`, and the folders left empty.
fn prune(dir: &Path, keep: &BTreeSet<PathBuf>) -> Result<()> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    for e in entries {
        let path = e.map_err(io(format!("list {}", dir.display())))?.path();
        if path.is_dir() {
            prune(&path, keep)?;
            if std::fs::read_dir(&path)
                .map(|mut d| d.next().is_none())
                .unwrap_or(false)
            {
                std::fs::remove_dir(&path).map_err(io(format!("remove {}", path.display())))?;
            }
        } else if !keep.contains(&path) {
            remove_if_present(&path)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_snapshot_dir_stays_apart_from_the_data_dir() {
        let ok = check_apart(
            Path::new("/w/data"),
            Path::new("/repo/studies/recordings/a"),
        );
        assert!(ok.is_ok());
        for out in ["/w/data", "/w/data/snap", "/w"] {
            let e = check_apart(Path::new("/w/data"), Path::new(out)).unwrap_err();
            assert!(e.to_string().contains("overlap"), "{e}");
        }
        // Resolved before comparing, also where the snapshot dir does not exist yet.
        let tmp = tempfile::tempdir().unwrap();
        let data = tmp.path().join("data");
        std::fs::create_dir(&data).unwrap();
        let out = real(&tmp.path().join("other/../data/new/snap")).unwrap();
        assert_eq!(out, real(&data).unwrap().join("new/snap"));
        assert!(check_apart(&real(&data).unwrap(), &out).is_err());
        // A sibling whose name extends the data dir's is apart.
        assert!(check_apart(Path::new("/w/data"), Path::new("/w/data-snap")).is_ok());
    }

    #[test]
    fn stored_paths_stay_inside_the_data_dir() {
        assert!(safe_relative("checkpoints/ab/abcd.safetensors").is_ok());
        for bad in [
            "/etc/passwd",
            "../x",
            "checkpoints/../../x",
            "./checkpoints/a",
        ] {
            assert!(safe_relative(bad).is_err(), "{bad}");
        }
    }
}
