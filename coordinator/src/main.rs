//! `coordinator`: serve the sweep coordinator, or talk to one as a client.

mod cli;

use clap::{Parser, Subcommand};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Parser)]
#[command(
    name = "coordinator",
    version,
    about = "gaitsweep coordinator: serve sweeps or query a running coordinator"
)]
struct Args {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Serve the coordinator (gRPC) with its SQLite database in the data dir (or PostgreSQL: --database).
    Serve(ServeArgs),
    /// Write a sweep's report (heatmaps, 3D surface, learning curves, gait GIF, index.html) from the data dir's database.
    Report(gaitsweep_coordinator::report::ReportArgs),
    /// Write the paper's findings beside several grid sweeps' (one per robot) as one Markdown table.
    Findings(gaitsweep_coordinator::report::study::FindingsArgs),
    /// Write every metric of a sweep's cells as a TensorBoard log dir (one run per cell).
    Tensorboard(gaitsweep_coordinator::report::tensorboard::TensorboardArgs),
    /// Copy a SQLite data dir's database and the checkpoints a later sitting resumes from
    /// into a snapshot dir (for a recording that moves between machines).
    Snapshot(gaitsweep_coordinator::snapshot::SnapshotArgs),
    /// Client commands against a running coordinator.
    #[command(flatten)]
    Client(cli::ClientCmd),
}

#[derive(clap::Args)]
struct ServeArgs {
    /// Address to listen on; port 0 picks a free port (written to DATA_DIR/coordinator.addr).
    #[arg(long, default_value = "127.0.0.1:50051")]
    listen: SocketAddr,
    /// Directory for the checkpoints and, by default, the SQLite database.
    #[arg(long)]
    data_dir: PathBuf,
    /// The database: a PostgreSQL URL (postgres://user:password@host:port/db) or a SQLite
    /// file path; default DATA_DIR/gaitsweep.sqlite.
    #[arg(long, env = "GAITSWEEP_DATABASE", hide_env_values = true)]
    database: Option<String>,
    /// Require this access token on every RPC.
    #[arg(long, env = "GAITSWEEP_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// PEM certificate chain for TLS (with --tls-key).
    #[arg(long, requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// PEM private key for TLS (with --tls-cert).
    #[arg(long, requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// Attempts (failures or expired leases) before a cell is marked failed.
    #[arg(long, default_value_t = 3)]
    max_attempts: u32,
    /// Seconds a lease lives without a heartbeat.
    #[arg(long, default_value_t = 30.0)]
    lease_seconds: f64,
    /// Largest checkpoint upload accepted, MiB.
    #[arg(long, default_value_t = 512)]
    max_checkpoint_mb: u64,
    /// Also serve the live page (HTTP) on this address; port 0 picks a free port (written
    /// to DATA_DIR/http.addr). The token, if any, applies to it too.
    #[arg(long)]
    http: Option<SocketAddr>,
}

fn main() -> std::process::ExitCode {
    gaitsweep_core::error::exit(run())
}

fn run() -> anyhow::Result<()> {
    let args = Args::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let rt = tokio::runtime::Runtime::new()?;
    rt.block_on(async move {
        match args.cmd {
            Cmd::Serve(a) => {
                let database = a
                    .database
                    .as_deref()
                    .map(gaitsweep_coordinator::store::DatabaseUrl::parse)
                    .transpose()?;
                let cfg = gaitsweep_coordinator::serve::ServeConfig {
                    listen: a.listen,
                    database,
                    data_dir: a.data_dir,
                    token: a.token,
                    tls: a.tls_cert.zip(a.tls_key),
                    max_attempts: a.max_attempts,
                    lease: Duration::from_secs_f64(a.lease_seconds),
                    max_checkpoint_bytes: a.max_checkpoint_mb << 20,
                    http: a.http,
                };
                let shutdown = async {
                    gaitsweep_core::shutdown_signal().await;
                    tracing::info!("shutting down");
                };
                gaitsweep_coordinator::serve::serve(cfg, shutdown).await?;
                Ok(())
            }
            Cmd::Report(a) => Ok(gaitsweep_coordinator::report::run(a).await?),
            Cmd::Findings(a) => Ok(gaitsweep_coordinator::report::study::run(a).await?),
            Cmd::Tensorboard(a) => Ok(gaitsweep_coordinator::report::tensorboard::run(a).await?),
            Cmd::Snapshot(a) => Ok(gaitsweep_coordinator::snapshot::run(a).await?),
            Cmd::Client(c) => cli::run(c).await,
        }
    })
}
