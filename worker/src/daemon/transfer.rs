//! Checkpoint transfer: chunked uploads and sha256-checked downloads.

use super::*;
use gaitsweep_core::client::{collect_checkpoint, upload_messages, DownloadError};

pub(super) enum UploadError {
    /// The coordinator refused the upload for good.
    Refused(Status),
    /// The file could not be read.
    Local(Error),
}

/// Uploads one checkpoint file (header, then chunks) with retries; returns its sha256 and size.
pub(super) async fn upload(
    ctx: &Ctx,
    lease: i64,
    epoch: u32,
    path: &Path,
) -> std::result::Result<(String, u64), UploadError> {
    let bytes = tokio::fs::read(path).await.map_err(|e| {
        UploadError::Local(Error::io(format!("read checkpoint {}", path.display()))(e))
    })?;
    let sha = hex::encode(Sha256::digest(&bytes));
    let bytes = Arc::new(bytes);
    let header = pb::UploadHeader {
        lease_id: lease,
        epoch,
        sha256: sha.clone(),
        size: bytes.len() as u64,
    };
    retry("upload_checkpoint", &ctx.backoff, None, || {
        let mut c = ctx.client.clone();
        let msgs = upload_messages(header.clone(), &bytes);
        async move { c.upload_checkpoint(tokio_stream::iter(msgs)).await }
    })
    .await
    .map_err(UploadError::Refused)?;
    tracing::info!(lease, epoch, sha256 = %sha, size = bytes.len(), "checkpoint uploaded");
    Ok((sha, bytes.len() as u64))
}

/// Downloads the checkpoint a lease resumes from into the cache (verifying its sha256).
pub(super) async fn download(
    ctx: &Ctx,
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
        let mut c = ctx.client.clone();
        let res = async {
            let mut s = c
                .download_checkpoint(pb::DownloadCheckpointRequest {
                    sha256: ck.sha256.clone(),
                })
                .await
                .map_err(DownloadError::Call)?
                .into_inner();
            collect_checkpoint(&mut s, &ck.sha256, ck.size).await
        }
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
        tokio::time::sleep(ctx.backoff.delay(attempt)).await;
        attempt += 1;
    }
}
