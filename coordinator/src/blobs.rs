//! Content-addressed checkpoint files under `DATA_DIR/checkpoints/ab/<sha256>.safetensors`.

use crate::error::io;
use crate::{Error, Result};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use tokio::io::AsyncWriteExt;

/// The checkpoint file store of a data dir.
#[derive(Debug, Clone)]
pub struct Blobs {
    root: PathBuf,
    limit: u64,
}

/// An upload in progress: bytes go to a temp file while they are hashed and counted.
pub struct Upload {
    file: tokio::fs::File,
    tmp: PathBuf,
    hasher: Sha256,
    written: u64,
    expected_sha: String,
    expected_size: u64,
    limit: u64,
}

impl Blobs {
    /// The store under `data_dir`, refusing files above `limit` bytes.
    pub fn new(data_dir: &Path, limit: u64) -> Result<Self> {
        for d in ["checkpoints", "tmp"] {
            std::fs::create_dir_all(data_dir.join(d))
                .map_err(io(format!("create {}", data_dir.join(d).display())))?;
        }
        Ok(Self {
            root: data_dir.to_path_buf(),
            limit,
        })
    }

    /// The path a data-dir-relative path points to.
    pub fn absolute(&self, rel: &str) -> PathBuf {
        self.root.join(rel)
    }

    /// Starts an upload announced with its hash and size.
    pub async fn begin(&self, sha256: &str, size: u64) -> Result<Upload> {
        if sha256.len() != 64
            || !sha256
                .bytes()
                .all(|b| b.is_ascii_hexdigit() && !b.is_ascii_uppercase())
        {
            return Err(Error::BadRequest(format!(
                "sha256 {sha256:?} is not 64 lowercase hex digits"
            )));
        }
        if size > self.limit {
            return Err(Error::TooLarge {
                size,
                limit: self.limit,
            });
        }
        let tmp = self
            .root
            .join("tmp")
            .join(format!("{sha256}.{:016x}.part", rand::random::<u64>()));
        let file = tokio::fs::File::create(&tmp)
            .await
            .map_err(io(format!("create {}", tmp.display())))?;
        Ok(Upload {
            file,
            tmp,
            hasher: Sha256::new(),
            written: 0,
            expected_sha: sha256.to_string(),
            expected_size: size,
            limit: self.limit,
        })
    }

    /// Verifies a finished upload and moves it into place; returns the relative path.
    pub async fn finish(&self, mut up: Upload) -> Result<String> {
        let result = async {
            up.file
                .flush()
                .await
                .map_err(io("flush checkpoint upload"))?;
            up.file
                .sync_all()
                .await
                .map_err(io("sync checkpoint upload"))?;
            if up.written != up.expected_size {
                return Err(Error::Corrupt(format!(
                    "received {} bytes, header announced {}",
                    up.written, up.expected_size
                )));
            }
            let got = hex::encode(up.hasher.clone().finalize());
            if got != up.expected_sha {
                return Err(Error::Corrupt(format!(
                    "sha256 of the bytes is {got}, header announced {}",
                    up.expected_sha
                )));
            }
            let rel = format!("checkpoints/{}/{}.safetensors", &got[..2], got);
            let dest = self.root.join(&rel);
            if let Some(dir) = dest.parent() {
                tokio::fs::create_dir_all(dir)
                    .await
                    .map_err(io(format!("create {}", dir.display())))?;
            }
            tokio::fs::rename(&up.tmp, &dest)
                .await
                .map_err(io(format!("move checkpoint to {}", dest.display())))?;
            Ok(rel)
        }
        .await;
        if result.is_err() {
            let _ = tokio::fs::remove_file(&up.tmp).await;
        }
        result
    }

    /// Removes a failed upload's temp file.
    pub async fn abort(&self, up: Upload) {
        let _ = tokio::fs::remove_file(&up.tmp).await;
    }
}

impl Upload {
    /// Appends bytes, refusing more than announced or allowed.
    pub async fn write(&mut self, data: &[u8]) -> Result<()> {
        self.written += data.len() as u64;
        if self.written > self.limit {
            return Err(Error::TooLarge {
                size: self.written,
                limit: self.limit,
            });
        }
        if self.written > self.expected_size {
            return Err(Error::Corrupt(format!(
                "more bytes than the {} the header announced",
                self.expected_size
            )));
        }
        self.hasher.update(data);
        self.file
            .write_all(data)
            .await
            .map_err(io("write checkpoint upload"))
    }
}
