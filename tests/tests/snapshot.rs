//! A recording moved between machines (`coordinator snapshot`, README "Recording over
//! several sittings"): a sweep half done on one data dir is snapshotted while its
//! coordinator runs, the snapshot keeps the database and only the checkpoints a later
//! sitting needs, and a coordinator on a copy of it finishes the sweep, the cell that was
//! training when the snapshot was taken resuming from its checkpoint at once.

mod common;

use common::*;
use gaitsweep_core::pb;
use std::path::Path;
use std::time::Duration;

const SWEEP_TIMEOUT: Duration = Duration::from_secs(600);
/// Long enough (about 0.1 s an epoch) for the second cell to be stopped mid-training.
const EPOCHS: u32 = 40;

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let dst = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &dst);
        } else {
            std::fs::copy(&p, &dst).unwrap();
        }
    }
}

fn files_under(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.extend(files_under(&p));
            } else {
                out.push(p.file_stem().unwrap().to_string_lossy().into_owned());
            }
        }
    }
    out.sort();
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_snapshot_resumes_the_sweep_on_a_fresh_data_dir() {
    let _g = heavy().await;
    let first = tempfile::tempdir().unwrap();
    let coord = Coord::start(first.path(), "127.0.0.1:0", &["--lease-seconds", "300"]).await;
    let mut c = coord.sweeps().await;
    let sweep = create(&mut c, tiny_spec(&[4.0, 6.0], &[-5.0], EPOCHS)).await;
    let mut a = start_worker(first.path(), &coord.url(), "a");
    let db = coord.db().await;
    // One cell scored and the other one training with a checkpoint.
    wait_for(
        "one cell done and the next one checkpointed",
        SWEEP_TIMEOUT,
        || {
            let db = db.clone();
            async move {
                let (done, training): (i64, i64) = sqlx::query_as(
                    "SELECT (SELECT COUNT(*) FROM scores), \
                 (SELECT COUNT(*) FROM cells c WHERE c.state = 'running' AND EXISTS \
                   (SELECT 1 FROM cell_checkpoints k WHERE k.cell_id = c.id AND k.epoch >= 1))",
                )
                .fetch_one(&db)
                .await
                .ok()?;
                (done == 1 && training == 1).then_some(())
            }
        },
    )
    .await;
    let (scored, promoted_final): (i64, String) = sqlx::query_as(
        "SELECT s.cell_id, s.final_checkpoint_sha256 FROM scores s JOIN promotions p ON p.cell_id = s.cell_id",
    )
    .fetch_one(&db)
    .await
    .unwrap();
    let left_out: String =
        sqlx::query_scalar("SELECT sha256 FROM cell_checkpoints WHERE cell_id = $1 AND epoch = 1")
            .bind(scored)
            .fetch_one(&db)
            .await
            .unwrap();
    let epochs: Vec<i64> = sqlx::query_scalar(
        "SELECT DISTINCT epoch FROM epoch_metrics WHERE cell_id = $1 ORDER BY epoch",
    )
    .bind(scored)
    .fetch_all(&db)
    .await
    .unwrap();
    assert!(epochs.len() >= 20, "{epochs:?}");
    let (first_epoch, last_epoch) = (epochs[0], *epochs.last().unwrap());
    let thinned: Vec<i64> = epochs
        .iter()
        .copied()
        .filter(|&e| e % 10 == 0 || e == first_epoch || e == last_epoch)
        .collect();

    // Snapshot while the coordinator runs and worker a trains the second cell, keeping no
    // best cells but the promoted one; then worker a goes away for good, as a machine that
    // is not coming back.
    let snap = first.path().join("snap");
    let out = snapshot(&coord.data, &snap);
    a.stop("worker a to exit").await;
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let snap_db = gaitsweep_coordinator::store::reader::open(&snap, None)
        .await
        .unwrap();
    // The running cell is queued in the snapshot and its attempt released (not a failure),
    // to resume from the latest checkpoint the snapshot holds.
    let (resume_cell, resume_sha, resume_epoch, attempt_state, attempt_error): (
        i64,
        String,
        i64,
        String,
        String,
    ) = sqlx::query_as(
        "SELECT c.id, c.last_checkpoint_sha256, k.epoch, a.state, a.error FROM cells c \
         JOIN cell_checkpoints k ON k.cell_id = c.id AND k.sha256 = c.last_checkpoint_sha256 \
         JOIN attempts a ON a.cell_id = c.id WHERE c.state = 'queued'",
    )
    .fetch_one(&snap_db)
    .await
    .unwrap();
    assert!(resume_epoch >= 1, "{}", tail(&a.log_text(), 20));
    assert_eq!(attempt_state, "released", "{attempt_error}");
    assert!(attempt_error.contains("snapshot"), "{attempt_error}");
    let listed: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM checkpoints")
        .fetch_one(&snap_db)
        .await
        .unwrap();
    assert!(
        said.contains(" 2 checkpoint files")
            && said.contains(&format!("{} checkpoints left out", listed - 2)),
        "{said}"
    );
    let mut want = vec![promoted_final.clone(), resume_sha.clone()];
    want.sort();
    assert_eq!(files_under(&snap.join("checkpoints")), want);
    let kept_epochs: Vec<i64> = sqlx::query_scalar(
        "SELECT DISTINCT epoch FROM epoch_metrics WHERE cell_id = $1 ORDER BY epoch",
    )
    .bind(scored)
    .fetch_all(&snap_db)
    .await
    .unwrap();
    assert_eq!(
        kept_epochs, thinned,
        "training metrics every 10th epoch, first and last"
    );
    let evals = |db: sqlx::AnyPool| async move {
        let n: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM evaluations WHERE cell_id = $1")
            .bind(scored)
            .fetch_one(&db)
            .await
            .unwrap();
        n
    };
    assert_eq!(
        evals(snap_db.clone()).await,
        evals(db.clone()).await,
        "every evaluation kept"
    );
    snap_db.close().await;
    drop(db);
    drop(coord);

    // Restored on a fresh data dir, the sweep goes on.
    let second = tempfile::tempdir().unwrap();
    copy_dir(&snap, &second.path().join("data"));
    let coord = Coord::start(second.path(), "127.0.0.1:0", &["--lease-seconds", "300"]).await;
    let b = start_worker(second.path(), &coord.url(), "b");
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &b]).await;
    assert_eq!((done.cells_done, done.cells_failed), (2, 0));
    let db = coord.db().await;
    let (resumed_from, scores): (i64, i64) = sqlx::query_as(
        "SELECT (SELECT resumed_from_epoch FROM attempts WHERE cell_id = $1 ORDER BY id DESC LIMIT 1), \
         (SELECT COUNT(*) FROM scores)",
    )
    .bind(resume_cell)
    .fetch_one(&db)
    .await
    .unwrap();
    assert_eq!(resumed_from, resume_epoch, "{}", tail(&b.log_text(), 30));
    // Worker b took the cell at once, not after worker a's lease (300 s) expired as a
    // counted failure.
    let failures: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM attempts WHERE state IN ('expired', 'failed')")
            .fetch_one(&db)
            .await
            .unwrap();
    assert_eq!(failures, 0, "{}", tail(&b.log_text(), 30));
    assert_eq!(
        scores, 2,
        "the first sitting's score is kept, none is duplicated"
    );

    // The left-out checkpoint says what happened to it.
    let mut w = coord.workers().await;
    let e = match w
        .download_checkpoint(pb::DownloadCheckpointRequest {
            sha256: left_out.clone(),
        })
        .await
    {
        Err(e) => e,
        Ok(stream) => {
            use tokio_stream::StreamExt;
            let mut s = stream.into_inner();
            loop {
                match s.next().await {
                    Some(Err(e)) => break e,
                    Some(Ok(_)) => continue,
                    None => panic!("left-out checkpoint {left_out} was served"),
                }
            }
        }
    };
    assert_eq!(e.code(), tonic::Code::NotFound, "{e:?}");
    assert!(
        e.message().contains("missing") && e.message().contains("snapshot"),
        "{}",
        e.message()
    );
    // A second snapshot into the same dir replaces the first one's files.
    let kept = &snap;
    let out = snapshot(&coord.data, kept);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        files_under(&kept.join("checkpoints")),
        promoted_finals(&db, sweep.sweep_id).await,
        "no cell trains any more: only the promoted model stays"
    );
}

/// The final checkpoints of the sweep's latest promotions (overall and per terrain).
/// `coordinator snapshot` of `data` into `out`, keeping no best cells but the promoted ones.
fn snapshot(data: &Path, out: &Path) -> std::process::Output {
    std::process::Command::new(bin("coordinator"))
        .args(["snapshot", "--data-dir"])
        .arg(data)
        .arg("--out")
        .arg(out)
        .args(["--keep-best", "0"])
        .output()
        .unwrap()
}

async fn promoted_finals(db: &sqlx::AnyPool, sweep: i64) -> Vec<String> {
    sqlx::query_scalar(
        "SELECT DISTINCT s.final_checkpoint_sha256 FROM promotions p JOIN scores s ON s.cell_id = p.cell_id \
         WHERE p.id IN (SELECT MAX(id) FROM promotions WHERE sweep_id = $1 GROUP BY terrain) \
         ORDER BY 1",
    )
    .bind(sweep)
    .fetch_all(db)
    .await
    .unwrap()
}
