//! gaitsweep-core: the domain types shared by the coordinator, the workers and the tools
//! (ids, cell and sweep states, the sweep spec with its validation and grid expansion), the
//! generated gRPC code of `gaitsweep.v1`, and the one place that converts between them.

pub mod client;
pub mod convert;
pub mod error;
pub mod finalists;
pub mod ids;
pub mod place;
pub mod reason;
pub mod records;
pub mod search;
pub mod spec;
pub mod state;
pub mod stats;
pub mod tensorboard;

pub use error::{Error, Result};
/// Every default, decided once (`gaitsweep_model::defaults`).
pub use gaitsweep_model::defaults;
pub use ids::{CellId, LeaseId, SweepId, WorkerId};
pub use place::Place;
pub use spec::{Axis, CellPlan, ResolvedSpec, Search, SearchSpec, SweepSpec};
pub use state::{CellState, SweepState};

/// Generated protobuf messages and tonic clients/servers of package `gaitsweep.v1`.
#[allow(missing_docs, clippy::all)]
pub mod pb {
    tonic::include_proto!("gaitsweep.v1");

    /// Encoded file descriptor set of `gaitsweep.v1`, for server reflection.
    pub const FILE_DESCRIPTOR_SET: &[u8] =
        tonic::include_file_descriptor_set!("gaitsweep_v1_descriptor");
}

/// Metadata key that carries the access token (`authorization: Bearer TOKEN`).
pub const AUTH_HEADER: &str = "authorization";

/// The value of the authorization header for a token.
pub fn bearer(token: &str) -> String {
    format!("Bearer {token}")
}

/// Resolves when the process is asked to stop: Ctrl-C (SIGINT) or SIGTERM (systemd,
/// Kubernetes and Slurm stop services with SIGTERM).
pub async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}
