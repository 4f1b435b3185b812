//! The gRPC services: [`worker::WorkerApi`] for worker daemons and [`sweeps::SweepApi`]
//! for users, over one shared [`Coordinator`] state.

pub mod sweeps;
pub mod worker;

use crate::blobs::Blobs;
use crate::leases::LeaseTable;
use crate::store::Store;
use crate::Result;
use gaitsweep_core::pb;
use gaitsweep_core::records::RungDecisionRecord;
use std::sync::Arc;
use tokio::sync::{broadcast, mpsc};
use tokio_stream::wrappers::ReceiverStream;

/// Bytes per message when streaming a checkpoint.
pub const CHUNK_BYTES: usize = 256 * 1024;

/// Tunables of a running coordinator.
#[derive(Debug, Clone)]
pub struct Limits {
    /// Lease duration without a heartbeat, milliseconds.
    pub lease_ms: i64,
    /// Attempts before a cell is marked failed.
    pub max_attempts: u32,
}

/// State shared by both services and the background tasks.
pub struct Coordinator<S> {
    /// Storage.
    pub store: S,
    /// Live leases.
    pub leases: LeaseTable,
    /// Checkpoint files.
    pub blobs: Blobs,
    /// Sweep events for watchers.
    pub events: broadcast::Sender<pb::SweepEvent>,
    /// Tunables.
    pub limits: Limits,
    /// When this coordinator started.
    pub started: std::time::Instant,
}

pub use crate::store::backend::now_ms;

impl<S: Store> Coordinator<S> {
    /// Builds the shared state and loads the running leases from storage, each with a
    /// fresh deadline (so workers that outlived a restart can keep their cells).
    pub async fn new(store: S, blobs: Blobs, limits: Limits) -> Result<Arc<Self>> {
        let leases = LeaseTable::default();
        let now = now_ms();
        let running = store.running_leases().await?;
        for l in &running {
            leases.insert(
                l.lease,
                l.cell,
                l.sweep,
                l.worker.clone(),
                now + limits.lease_ms,
            );
        }
        if !running.is_empty() {
            tracing::info!(leases = running.len(), "restored running leases");
        }
        let (events, _) = broadcast::channel(4096);
        Ok(Arc::new(Self {
            store,
            leases,
            blobs,
            events,
            limits,
            started: std::time::Instant::now(),
        }))
    }

    /// Publishes an event to watchers (dropped if nobody listens).
    pub fn emit(&self, sweep_id: i64, kind: pb::sweep_event::Kind) {
        let _ = self.events.send(pb::SweepEvent {
            sweep_id,
            unix_ms: now_ms(),
            kind: Some(kind),
        });
    }

    /// Sends successive halving's decisions: each as a decision and as its cell's new
    /// state.
    pub fn emit_decisions(&self, sweep_id: i64, decisions: &[RungDecisionRecord]) {
        for d in decisions {
            self.emit(sweep_id, pb::sweep_event::Kind::Decision(d.into()));
            self.emit(sweep_id, pb::sweep_event::Kind::Cell((&d.cell).into()));
        }
    }

    /// Streams a stored checkpoint in chunks.
    pub async fn download(
        &self,
        sha256: &str,
    ) -> Result<ReceiverStream<Result<pb::CheckpointChunk, tonic::Status>>> {
        let (_, rel) = self.store.checkpoint_path(sha256).await?;
        let path = self.blobs.absolute(&rel);
        let mut file = match tokio::fs::File::open(&path).await {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(crate::Error::CheckpointFileMissing {
                    sha256: sha256.to_string(),
                    path: path.display().to_string(),
                })
            }
            r => r.map_err(crate::error::io(format!(
                "open checkpoint {}",
                path.display()
            )))?,
        };
        let (tx, rx) = mpsc::channel(4);
        tokio::spawn(async move {
            use tokio::io::AsyncReadExt;
            let mut buf = vec![0u8; CHUNK_BYTES];
            loop {
                match file.read(&mut buf).await {
                    Ok(0) => break,
                    Ok(n) => {
                        if tx
                            .send(Ok(pb::CheckpointChunk {
                                data: buf[..n].to_vec(),
                            }))
                            .await
                            .is_err()
                        {
                            break;
                        }
                    }
                    Err(e) => {
                        let _ = tx
                            .send(Err(tonic::Status::internal(format!(
                                "read checkpoint: {e}"
                            ))))
                            .await;
                        break;
                    }
                }
            }
        });
        Ok(ReceiverStream::new(rx))
    }
}
