//! Checkpoint transfer: chunked uploads and sha256-checked downloads.

use super::*;
use gaitsweep_core::client::{upload_messages, DownloadError};

pub(super) enum UploadError {
    /// The coordinator refused the upload for good.
    Refused(Status),
    /// The file could not be read.
    Local(Error),
}

/// Uploads one checkpoint file (header, then chunks) with retries; returns its sha256 and size.
pub(super) async fn upload<C: Coordinator>(
    ctx: &Ctx<C>,
    lease: i64,
    epoch: u32,
    path: &Path,
) -> std::result::Result<(String, u64), UploadError> {
    let bytes = tokio::fs::read(path).await.map_err(|e| {
        UploadError::Local(Error::io(format!("read checkpoint {}", path.display()))(e))
    })?;
    let sha = hex::encode(Sha256::digest(&bytes));
    let header = pb::UploadHeader {
        lease_id: lease,
        epoch,
        sha256: sha.clone(),
        size: bytes.len() as u64,
    };
    ctx.retry
        .call("upload_checkpoint", None, || {
            ctx.client
                .upload_checkpoint(upload_messages(header.clone(), &bytes))
        })
        .await
        .map_err(UploadError::Refused)?;
    tracing::info!(lease, epoch, sha256 = %sha, size = bytes.len(), "checkpoint uploaded");
    Ok((sha, bytes.len() as u64))
}

/// Downloads the checkpoint a lease resumes from into the cache (verifying its sha256).
pub(super) async fn download<C: Coordinator>(
    ctx: &Ctx<C>,
    ck: &pb::CheckpointRef,
    stop: &AtomicBool,
) -> Result<PathBuf> {
    let path = ctx
        .work_dir
        .join("cache")
        .join(format!("{}.safetensors", ck.sha256));
    if path.is_file() {
        return Ok(path);
    }
    let mut attempt = 0;
    loop {
        let res = ctx
            .client
            .download_checkpoint(ck.sha256.clone(), ck.size)
            .await;
        match res {
            Ok(bytes) => {
                let tmp = path.with_extension("part");
                std::fs::write(&tmp, &bytes)
                    .map_err(Error::io(format!("write {}", tmp.display())))?;
                std::fs::rename(&tmp, &path)
                    .map_err(Error::io(format!("move {}", path.display())))?;
                tracing::info!(sha256 = %ck.sha256, epoch = ck.epoch, "resume checkpoint downloaded");
                return Ok(path);
            }
            Err(DownloadError::Corrupt { got }) => {
                tracing::warn!(sha256 = %ck.sha256, %got, "downloaded checkpoint does not match its sha256, retrying")
            }
            Err(DownloadError::Call(s)) if !transient(&s) || stop.load(Ordering::Relaxed) => {
                return Err(Error::Config(format!(
                    "cannot download checkpoint {}: {}",
                    ck.sha256,
                    s.message()
                )))
            }
            Err(DownloadError::Call(_)) => {}
        }
        tokio::time::sleep(ctx.retry.backoff.delay(attempt)).await;
        attempt += 1;
    }
}
