//! `gaitsweep.v1.WorkerService`: register, lease, heartbeat, progress, checkpoints,
//! results and failures.

use super::{now_ms, Coordinator};
use crate::leases::Beat;
use crate::store::{AttemptEnd, Store, WorkerInfo};
use crate::Error;
use gaitsweep_core::pb::{self, sweep_event::Kind, worker_service_server::WorkerService};
use gaitsweep_core::records::CheckpointRecord;
use gaitsweep_core::{LeaseId, WorkerId};
use std::sync::Arc;
use tokio_stream::wrappers::ReceiverStream;
use tokio_stream::StreamExt;
use tonic::{Request, Response, Status, Streaming};

/// The worker-facing service.
pub struct WorkerApi<S>(pub Arc<Coordinator<S>>);

#[tonic::async_trait]
impl<S: Store> WorkerService for WorkerApi<S> {
    async fn register(
        &self,
        req: Request<pb::RegisterRequest>,
    ) -> Result<Response<pb::RegisterResponse>, Status> {
        let r = req.into_inner();
        let id = WorkerId(format!("w-{:016x}", rand::random::<u64>()));
        let info = WorkerInfo {
            hostname: r.hostname,
            cores: r.cores,
            device: r.device,
            slots: r.slots,
            version: r.version,
            cpu: r.cpu,
        };
        self.0.store.register_worker(&id, &info, now_ms()).await?;
        tracing::info!(worker = %id, host = %info.hostname, slots = info.slots, device = %info.device, cpu = %info.cpu, "worker registered");
        Ok(Response::new(pb::RegisterResponse {
            worker_id: id.0,
            heartbeat_interval_ms: (self.0.limits.lease_ms / 4).max(100) as u32,
        }))
    }

    async fn lease(
        &self,
        req: Request<pb::LeaseRequest>,
    ) -> Result<Response<pb::LeaseResponse>, Status> {
        let r = req.into_inner();
        let worker = WorkerId(r.worker_id);
        let now = now_ms();
        let Some(g) = self.0.store.lease_next(&worker, r.slot, now).await? else {
            return Ok(Response::new(pb::LeaseResponse {
                lease: None,
                retry_after_ms: 1000,
            }));
        };
        let deadline = now + self.0.limits.lease_ms;
        self.0.leases.insert(
            g.lease,
            g.cell.id,
            g.cell.sweep_id,
            worker.clone(),
            deadline,
        );
        tracing::info!(lease = g.lease.0, cell = g.cell.id.0, worker = %worker, resume_epoch = g.resume.as_ref().map(|c| c.epoch), "cell leased");
        let cell: pb::Cell = (&g.cell).into();
        self.0.emit(g.cell.sweep_id.0, Kind::Cell(cell.clone()));
        Ok(Response::new(pb::LeaseResponse {
            lease: Some(pb::Lease {
                lease_id: g.lease.0,
                task: Some(gaitsweep_core::convert::cell_task(&g.cell, &g.spec)),
                deadline_unix_ms: deadline,
                resume_from: g.resume.as_ref().map(Into::into),
            }),
            retry_after_ms: 0,
        }))
    }

    async fn heartbeat(
        &self,
        req: Request<pb::HeartbeatRequest>,
    ) -> Result<Response<pb::HeartbeatResponse>, Status> {
        let r = req.into_inner();
        let ids: Vec<LeaseId> = r.lease_ids.iter().map(|&i| LeaseId(i)).collect();
        let beats = self.0.leases.heartbeat(
            &WorkerId(r.worker_id),
            &ids,
            now_ms(),
            self.0.limits.lease_ms,
        );
        let leases = ids
            .iter()
            .zip(beats)
            .map(|(id, b)| {
                let (status, deadline) = match b {
                    Beat::Active(d) => (pb::LeaseStatus::Active, d),
                    Beat::Lost => (pb::LeaseStatus::Lost, 0),
                    Beat::Cancelled => (pb::LeaseStatus::Cancelled, 0),
                };
                pb::LeaseState {
                    lease_id: id.0,
                    status: status as i32,
                    deadline_unix_ms: deadline,
                }
            })
            .collect();
        Ok(Response::new(pb::HeartbeatResponse { leases }))
    }

    async fn report_progress(
        &self,
        req: Request<pb::ReportProgressRequest>,
    ) -> Result<Response<pb::ReportProgressResponse>, Status> {
        let r = req.into_inner();
        let lease = LeaseId(r.lease_id);
        let epochs: Vec<(u32, _)> = r.epochs.into_iter().map(|e| (e.epoch, e.values)).collect();
        let (stored, cell, sweep) = self.0.store.record_progress(lease, &epochs).await?;
        if let Some((epoch, values)) = epochs.iter().max_by_key(|e| e.0) {
            self.0.emit(
                sweep.0,
                Kind::Progress(pb::CellProgress {
                    cell_id: cell.0,
                    epoch: *epoch,
                    mean_return: values.get("mean_return").copied(),
                }),
            );
        }
        Ok(Response::new(pb::ReportProgressResponse {
            stored: stored as u32,
        }))
    }

    async fn upload_checkpoint(
        &self,
        req: Request<Streaming<pb::UploadCheckpointRequest>>,
    ) -> Result<Response<pb::UploadCheckpointResponse>, Status> {
        use pb::upload_checkpoint_request::Part;
        let mut stream = req.into_inner();
        let header = match stream.next().await {
            Some(Ok(pb::UploadCheckpointRequest {
                part: Some(Part::Header(h)),
            })) => h,
            Some(Err(e)) => return Err(e),
            _ => {
                return Err(
                    Error::BadRequest("the first upload message must be the header".into()).into(),
                )
            }
        };
        let lease = LeaseId(header.lease_id);
        self.0.store.open_lease(lease).await?;
        let mut up = self.0.blobs.begin(&header.sha256, header.size).await?;
        while let Some(msg) = stream.next().await {
            let res = match msg {
                Ok(pb::UploadCheckpointRequest {
                    part: Some(Part::Chunk(c)),
                }) => up.write(&c.data).await,
                Ok(_) => Err(Error::BadRequest(
                    "only the first upload message may be a header".into(),
                )),
                Err(e) => {
                    self.0.blobs.abort(up).await;
                    return Err(e);
                }
            };
            if let Err(e) = res {
                self.0.blobs.abort(up).await;
                tracing::warn!(lease = lease.0, error = %e, "checkpoint upload refused");
                return Err(e.into());
            }
        }
        let rel = self.0.blobs.finish(up).await.inspect_err(|e| {
            tracing::warn!(lease = lease.0, error = %e, "checkpoint upload refused");
        })?;
        let ckpt = CheckpointRecord {
            sha256: header.sha256,
            size: header.size,
            epoch: header.epoch,
        };
        self.0
            .store
            .record_checkpoint(lease, &ckpt, &rel, now_ms())
            .await?;
        tracing::info!(lease = lease.0, epoch = ckpt.epoch, sha256 = %ckpt.sha256, size = ckpt.size, "checkpoint stored");
        Ok(Response::new(pb::UploadCheckpointResponse {
            checkpoint: Some((&ckpt).into()),
        }))
    }

    async fn report_result(
        &self,
        req: Request<pb::ReportResultRequest>,
    ) -> Result<Response<pb::ReportResultResponse>, Status> {
        let r = req.into_inner();
        let score = r
            .score
            .as_ref()
            .ok_or(gaitsweep_core::Error::MissingField {
                message: "ReportResultRequest",
                field: "score",
            })
            .map_err(Error::from)?;
        let sha =
            (!r.final_checkpoint_sha256.is_empty()).then_some(r.final_checkpoint_sha256.as_str());
        let out = self
            .0
            .store
            .report_result(LeaseId(r.lease_id), &score.into(), r.epochs, sha, now_ms())
            .await?;
        self.0.leases.remove_cell(out.cell.id);
        if !out.duplicate {
            tracing::info!(
                lease = r.lease_id,
                cell = out.cell.id.0,
                score = score.score,
                state = %out.cell.state,
                "cell result stored"
            );
            let sweep = out.cell.sweep_id.0;
            self.0.emit(sweep, Kind::Cell((&out.cell).into()));
            self.0.emit_decisions(sweep, &out.decisions);
            for p in &out.promotions {
                tracing::info!(
                    sweep,
                    cell = p.cell.id.0,
                    terrain = p.terrain.as_deref().unwrap_or("all"),
                    "cell promoted"
                );
                self.0.emit(sweep, Kind::Promotion(p.into()));
            }
            if let Some(s) = &out.finished {
                tracing::info!(sweep, "sweep finished");
                self.0.emit(sweep, Kind::Finished(s.into()));
            }
        }
        Ok(Response::new(pb::ReportResultResponse {
            duplicate: out.duplicate,
        }))
    }

    async fn fail_cell(
        &self,
        req: Request<pb::FailCellRequest>,
    ) -> Result<Response<pb::FailCellResponse>, Status> {
        let r = req.into_inner();
        let lease = LeaseId(r.lease_id);
        self.0.leases.remove(lease);
        let out = self
            .0
            .store
            .end_attempt(
                lease,
                AttemptEnd::Failed,
                &r.error,
                self.0.limits.max_attempts,
                now_ms(),
            )
            .await?;
        tracing::warn!(lease = lease.0, cell = out.cell.id.0, error = %r.error, state = %out.cell.state, "attempt failed");
        let sweep = out.cell.sweep_id.0;
        self.0.emit(sweep, Kind::Cell((&out.cell).into()));
        self.0.emit_decisions(sweep, &out.decisions);
        if let Some(s) = &out.finished {
            self.0.emit(sweep, Kind::Finished(s.into()));
        }
        Ok(Response::new(pb::FailCellResponse {
            requeued: out.cell.state == gaitsweep_core::CellState::Queued,
        }))
    }

    async fn release_lease(
        &self,
        req: Request<pb::ReleaseLeaseRequest>,
    ) -> Result<Response<pb::ReleaseLeaseResponse>, Status> {
        let r = req.into_inner();
        let lease = LeaseId(r.lease_id);
        self.0.leases.remove(lease);
        let reason = if r.reason.trim().is_empty() {
            "released by its worker".to_string()
        } else {
            format!("released: {}", r.reason.trim())
        };
        let out = self
            .0
            .store
            .end_attempt(
                lease,
                AttemptEnd::Released,
                &reason,
                self.0.limits.max_attempts,
                now_ms(),
            )
            .await?;
        tracing::info!(lease = lease.0, cell = out.cell.id.0, state = %out.cell.state, "lease released");
        let sweep = out.cell.sweep_id.0;
        self.0.emit(sweep, Kind::Cell((&out.cell).into()));
        self.0.emit_decisions(sweep, &out.decisions);
        if let Some(s) = &out.finished {
            self.0.emit(sweep, Kind::Finished(s.into()));
        }
        Ok(Response::new(pb::ReleaseLeaseResponse {
            requeued: out.cell.state == gaitsweep_core::CellState::Queued,
        }))
    }

    type DownloadCheckpointStream = ReceiverStream<Result<pb::CheckpointChunk, Status>>;

    async fn download_checkpoint(
        &self,
        req: Request<pb::DownloadCheckpointRequest>,
    ) -> Result<Response<Self::DownloadCheckpointStream>, Status> {
        Ok(Response::new(
            self.0.download(&req.into_inner().sha256).await?,
        ))
    }
}
