//! `gaitsweep.v1.SweepService`: create, list, inspect, watch, cancel sweeps and fetch
//! promoted models.

use super::{now_ms, Coordinator};
use crate::store::Store;
use crate::Error;
use gaitsweep_core::convert::spec_from_request;
use gaitsweep_core::pb::{self, sweep_event::Kind, sweep_service_server::SweepService};
use gaitsweep_core::{SweepId, SweepState};
use std::sync::Arc;
use tokio::sync::{broadcast, mpsc};
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

/// The user-facing service.
pub struct SweepApi<S>(pub Arc<Coordinator<S>>);

#[tonic::async_trait]
impl<S: Store> SweepService for SweepApi<S> {
    async fn create_sweep(
        &self,
        req: Request<pb::CreateSweepRequest>,
    ) -> Result<Response<pb::Sweep>, Status> {
        let spec = spec_from_request(req.into_inner()).map_err(Error::from)?;
        let resolved = tokio::task::spawn_blocking(move || crate::presets::resolve(&spec))
            .await
            .map_err(|e| Status::internal(format!("spec validation panicked: {e}")))?
            .map_err(Error::from)?;
        let rec = self.0.store.create_sweep(&resolved, now_ms()).await?;
        tracing::info!(sweep = rec.id.0, name = %rec.spec.name, cells = rec.cells_total, "sweep created");
        Ok(Response::new((&rec).into()))
    }

    async fn list_sweeps(
        &self,
        _: Request<pb::ListSweepsRequest>,
    ) -> Result<Response<pb::ListSweepsResponse>, Status> {
        let sweeps = self.0.store.list_sweeps().await?;
        Ok(Response::new(pb::ListSweepsResponse {
            sweeps: sweeps.iter().map(Into::into).collect(),
        }))
    }

    async fn get_sweep(
        &self,
        req: Request<pb::GetSweepRequest>,
    ) -> Result<Response<pb::Sweep>, Status> {
        let rec = self
            .0
            .store
            .sweep(SweepId(req.into_inner().sweep_id))
            .await?;
        Ok(Response::new((&rec).into()))
    }

    async fn list_cells(
        &self,
        req: Request<pb::ListCellsRequest>,
    ) -> Result<Response<pb::ListCellsResponse>, Status> {
        let sweep = SweepId(req.into_inner().sweep_id);
        let cells = self.0.store.cells(sweep).await?;
        let unrewarded = self.0.store.never_rewarded(sweep).await?;
        let cells: Vec<pb::Cell> = cells
            .iter()
            .map(|c| pb::Cell {
                never_rewarded: unrewarded.contains(&c.id),
                ..c.into()
            })
            .collect();
        Ok(Response::new(pb::ListCellsResponse {
            points: gaitsweep_core::convert::point_results(&cells),
            cells,
        }))
    }

    type WatchSweepStream = ReceiverStream<Result<pb::SweepEvent, Status>>;

    async fn watch_sweep(
        &self,
        req: Request<pb::WatchSweepRequest>,
    ) -> Result<Response<Self::WatchSweepStream>, Status> {
        let id = req.into_inner().sweep_id;
        let mut rx = self.0.events.subscribe();
        let rec = self.0.store.sweep(SweepId(id)).await?;
        let (tx, out) = mpsc::channel(64);
        if rec.state != SweepState::Running {
            let ev = pb::SweepEvent {
                sweep_id: id,
                unix_ms: now_ms(),
                kind: Some(Kind::Finished((&rec).into())),
            };
            let _ = tx.send(Ok(ev)).await;
            return Ok(Response::new(ReceiverStream::new(out)));
        }
        tokio::spawn(async move {
            loop {
                match rx.recv().await {
                    Ok(ev) if ev.sweep_id == id => {
                        let last = matches!(ev.kind, Some(Kind::Finished(_)));
                        if tx.send(Ok(ev)).await.is_err() || last {
                            break;
                        }
                    }
                    Ok(_) => {}
                    Err(broadcast::error::RecvError::Lagged(n)) => {
                        tracing::warn!(sweep = id, skipped = n, "watcher too slow, events skipped");
                    }
                    Err(broadcast::error::RecvError::Closed) => break,
                }
            }
        });
        Ok(Response::new(ReceiverStream::new(out)))
    }

    async fn get_promoted(
        &self,
        req: Request<pb::GetPromotedRequest>,
    ) -> Result<Response<pb::Promotion>, Status> {
        let r = req.into_inner();
        let terrain = (!r.terrain.is_empty()).then_some(r.terrain.as_str());
        let p = self.0.store.promoted(SweepId(r.sweep_id), terrain).await?;
        Ok(Response::new((&p).into()))
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

    async fn cancel_sweep(
        &self,
        req: Request<pb::CancelSweepRequest>,
    ) -> Result<Response<pb::Sweep>, Status> {
        let id = SweepId(req.into_inner().sweep_id);
        let (rec, leases) = self.0.store.cancel_sweep(id, now_ms()).await?;
        self.0.leases.cancel_sweep(id);
        tracing::info!(
            sweep = id.0,
            running_leases = leases.len(),
            "sweep cancelled"
        );
        let sweep: pb::Sweep = (&rec).into();
        self.0.emit(id.0, Kind::Finished(sweep.clone()));
        Ok(Response::new(sweep))
    }

    async fn get_status(
        &self,
        _: Request<pb::GetStatusRequest>,
    ) -> Result<Response<pb::CoordinatorStatus>, Status> {
        let w = self.0.store.write_stats();
        Ok(Response::new(pb::CoordinatorStatus {
            leases_running: self.0.leases.len() as u32,
            metric_reports_queued: w.queued,
            metric_write_lag_ms: w.lag_ms,
            metric_rows_written: w.rows,
            metric_reports_written: w.reports,
            metric_batches: w.batches,
            uptime_seconds: self.0.started.elapsed().as_secs_f64(),
        }))
    }
}
