//! `coordinator serve`: opens the data dir, restores leases, serves both services with
//! health and reflection (v1 and v1alpha), token check and optional TLS, and runs the
//! lease-expiry loop.

use crate::auth::TokenCheck;
use crate::blobs::Blobs;
use crate::error::io;
use crate::service::{now_ms, sweeps::SweepApi, worker::WorkerApi, Coordinator, Limits};
use crate::store::{AttemptEnd, DatabaseUrl, SqlStore, Store};
use crate::{Error, Result};
use gaitsweep_core::pb::{self, sweep_event::Kind};
use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tonic::transport::{Identity, Server, ServerTlsConfig};

/// Name of the file in the data dir that holds the bound address.
pub const ADDR_FILE: &str = "coordinator.addr";

/// Settings of `coordinator serve`.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// Address to listen on (port 0: any free port).
    pub listen: SocketAddr,
    /// Directory of the checkpoints (and of the SQLite database unless `database` is set).
    pub data_dir: PathBuf,
    /// The database (`--database`); `None`: `gaitsweep.sqlite` in the data dir.
    pub database: Option<DatabaseUrl>,
    /// Access token; `None` disables access control.
    pub token: Option<String>,
    /// PEM certificate chain and private key for TLS.
    pub tls: Option<(PathBuf, PathBuf)>,
    /// Attempts before a cell fails.
    pub max_attempts: u32,
    /// Lease duration without heartbeat.
    pub lease: Duration,
    /// Largest checkpoint accepted, bytes.
    pub max_checkpoint_bytes: u64,
    /// Address of the live page (HTTP), if it is served.
    pub http: Option<SocketAddr>,
}

/// How long open calls (e.g. `watch` streams) may run on after the shutdown signal.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(3);

/// Runs the coordinator until `shutdown` resolves.
pub async fn serve(
    cfg: ServeConfig,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<()> {
    std::fs::create_dir_all(&cfg.data_dir)
        .map_err(io(format!("create data dir {}", cfg.data_dir.display())))?;
    let database = cfg
        .database
        .clone()
        .unwrap_or_else(|| DatabaseUrl::Sqlite(cfg.data_dir.join(crate::store::DB_FILE)));
    let store = SqlStore::connect(&database)
        .await
        .map_err(|e| Error::Server(format!("open the database {}: {e}", database.redacted())))?;
    tracing::info!(database = %database.redacted(), backend = %store.backend(), "database open");
    let blobs = Blobs::new(&cfg.data_dir, cfg.max_checkpoint_bytes)?;
    let limits = Limits {
        lease_ms: cfg.lease.as_millis() as i64,
        max_attempts: cfg.max_attempts,
    };
    let coord = Coordinator::new(store, blobs, limits).await?;

    let (health, health_service) = tonic_health::server::health_reporter();
    for name in [
        "",
        "gaitsweep.v1.WorkerService",
        "gaitsweep.v1.SweepService",
    ] {
        health
            .set_service_status(name, tonic_health::ServingStatus::Serving)
            .await;
    }
    let reflection = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(pb::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
    };
    let reflection_v1 = reflection()
        .build_v1()
        .map_err(|e| Error::Server(format!("reflection: {e}")))?;
    let reflection_v1alpha = reflection()
        .build_v1alpha()
        .map_err(|e| Error::Server(format!("reflection: {e}")))?;

    let mut builder = Server::builder().http2_adaptive_window(Some(true));
    if let Some((cert, key)) = &cfg.tls {
        let cert =
            std::fs::read(cert).map_err(io(format!("read tls certificate {}", cert.display())))?;
        let key = std::fs::read(key).map_err(io(format!("read tls key {}", key.display())))?;
        builder = builder
            .tls_config(ServerTlsConfig::new().identity(Identity::from_pem(cert, key)))
            .map_err(|e| Error::Server(format!("tls certificate or key is invalid: {e}")))?;
    }
    let listener = tokio::net::TcpListener::bind(cfg.listen)
        .await
        .map_err(io(format!("listen on {}: is the port free?", cfg.listen)))?;
    let addr = listener.local_addr().map_err(io("read bound address"))?;
    let addr_file = cfg.data_dir.join(ADDR_FILE);
    std::fs::write(&addr_file, addr.to_string())
        .map_err(io(format!("write {}", addr_file.display())))?;
    tracing::info!(%addr, data_dir = %cfg.data_dir.display(), tls = cfg.tls.is_some(), auth = cfg.token.is_some(), "coordinator listening");
    println!("listening on {addr}");

    let background = tokio::spawn(expiry_loop(coord.clone()));
    let page = match cfg.http {
        Some(http) => {
            let listener = tokio::net::TcpListener::bind(http)
                .await
                .map_err(io(format!(
                    "listen on {http} for the live page: is the port free?"
                )))?;
            let addr = listener
                .local_addr()
                .map_err(io("read the page's bound address"))?;
            let file = cfg.data_dir.join(crate::live::HTTP_ADDR_FILE);
            std::fs::write(&file, addr.to_string())
                .map_err(io(format!("write {}", file.display())))?;
            tracing::info!(%addr, "live page listening");
            println!("live page on http://{addr}/");
            // Server-sent event streams never end by themselves: the task is aborted when
            // the gRPC server has stopped, instead of a graceful shutdown that would wait.
            Some(tokio::spawn(crate::live::serve_http(
                listener,
                coord.clone(),
                cfg.data_dir.clone(),
                cfg.token.clone(),
                std::future::pending(),
            )))
        }
        None => None,
    };
    let incoming = tonic::transport::server::TcpIncoming::from(listener).with_nodelay(Some(true));
    // tonic's graceful shutdown waits for every open call, and a `watch` stream never ends
    // by itself: after the signal, open calls get SHUTDOWN_GRACE to finish.
    let stopping = Arc::new(tokio::sync::Notify::new());
    let notify = stopping.clone();
    let shutdown = async move {
        shutdown.await;
        notify.notify_one();
    };
    let server = builder
        .layer(tonic::service::InterceptorLayer::new(TokenCheck::new(
            cfg.token.as_deref(),
        )))
        .add_service(health_service)
        .add_service(reflection_v1)
        .add_service(reflection_v1alpha)
        .add_service(
            pb::worker_service_server::WorkerServiceServer::new(WorkerApi(coord.clone()))
                .max_decoding_message_size(8 << 20),
        )
        .add_service(pb::sweep_service_server::SweepServiceServer::new(SweepApi(
            coord.clone(),
        )))
        .serve_with_incoming_shutdown(incoming, shutdown);
    let result = tokio::select! {
        r = server => r,
        _ = async {
            stopping.notified().await;
            tokio::time::sleep(SHUTDOWN_GRACE).await;
        } => {
            tracing::info!(seconds = SHUTDOWN_GRACE.as_secs(), "open calls did not finish in time; closing them");
            Ok(())
        }
    };
    background.abort();
    if let Some(p) = page {
        p.abort();
    }
    result.map_err(|e| Error::Server(format!("serving failed: {e}")))
}

/// Expires leases whose workers stopped heartbeating and records when workers were seen.
async fn expiry_loop<S: Store>(coord: Arc<Coordinator<S>>) {
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    let mut last_touch = now_ms();
    loop {
        tick.tick().await;
        let now = now_ms();
        for (lease, cell, sweep) in coord.leases.take_expired(now) {
            let msg = format!(
                "lease expired: no heartbeat for {} s, the worker is gone or cut off",
                coord.limits.lease_ms / 1000
            );
            match coord
                .store
                .end_attempt(
                    lease,
                    AttemptEnd::Expired,
                    &msg,
                    coord.limits.max_attempts,
                    now,
                )
                .await
            {
                Ok(out) => {
                    tracing::warn!(lease = lease.0, cell = cell.0, state = %out.cell.state, "lease expired");
                    coord.emit(sweep.0, Kind::Cell((&out.cell).into()));
                    coord.emit_decisions(sweep.0, &out.decisions);
                    if let Some(s) = &out.finished {
                        coord.emit(sweep.0, Kind::Finished(s.into()));
                    }
                }
                Err(e) => tracing::error!(lease = lease.0, error = %e, "could not expire lease"),
            }
        }
        if now - last_touch > 5000 {
            last_touch = now;
            let seen = coord.leases.take_seen();
            if let Err(e) = coord.store.touch_workers(&seen, now).await {
                tracing::warn!(error = %e, "could not record worker heartbeats");
            }
        }
    }
}
