//! Client subcommands: create, list, show, watch, cancel, fetch-best.

use anyhow::{bail, Context};
use gaitsweep_core::client::{self, Auth};
use gaitsweep_core::pb::{self, sweep_event::Kind, sweep_service_client::SweepServiceClient};
use std::path::PathBuf;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::Channel;

mod show;
use show::{cell_state, render_show, sweep_state};

/// How to reach the coordinator.
#[derive(clap::Args, Clone)]
pub struct Conn {
    /// Coordinator URL (http://HOST:PORT, or https:// with TLS).
    #[arg(long, env = "GAITSWEEP_URL", default_value = "http://127.0.0.1:50051")]
    connect: String,
    /// Access token.
    #[arg(long, env = "GAITSWEEP_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// PEM CA certificate to trust for https:// (e.g. a self-signed coordinator certificate).
    #[arg(long)]
    tls_ca: Option<PathBuf>,
}

/// Client subcommands.
#[derive(clap::Subcommand)]
pub enum ClientCmd {
    /// Create a sweep from a TOML spec file.
    Create {
        #[command(flatten)]
        conn: Conn,
        /// The sweep spec (TOML).
        spec: PathBuf,
    },
    /// List sweeps.
    List {
        #[command(flatten)]
        conn: Conn,
    },
    /// The coordinator's load: running leases, queued metric reports and write lag.
    Status {
        #[command(flatten)]
        conn: Conn,
    },
    /// Show a sweep: its state and the grid of gait scores (rows w1, columns w2, best marked).
    Show {
        #[command(flatten)]
        conn: Conn,
        /// Sweep id.
        sweep: i64,
    },
    /// Follow a sweep's events until it ends.
    Watch {
        #[command(flatten)]
        conn: Conn,
        /// Sweep id.
        sweep: i64,
        /// Print a cell's training progress every N epochs (0: never).
        #[arg(long, default_value_t = 10)]
        every: u32,
    },
    /// Cancel a sweep.
    Cancel {
        #[command(flatten)]
        conn: Conn,
        /// Sweep id.
        sweep: i64,
    },
    /// Download the promoted (best) model of a sweep as a .safetensors checkpoint.
    FetchBest {
        #[command(flatten)]
        conn: Conn,
        /// Sweep id.
        sweep: i64,
        /// Best on this terrain only (default: over all terrains).
        #[arg(long)]
        terrain: Option<String>,
        /// Output file.
        #[arg(long, default_value = "best.safetensors")]
        out: PathBuf,
        /// Also export the actor (TorchScript, safetensors, JSON) into this directory, by
        /// running `worker export` (the `worker` binary next to this one, or on PATH).
        #[arg(long)]
        export: Option<PathBuf>,
    },
}

type Client = SweepServiceClient<InterceptedService<Channel, Auth>>;

/// A sweep and its cells as they are now.
async fn sweep_and_cells(c: &mut Client, sweep: i64) -> anyhow::Result<(pb::Sweep, Vec<pb::Cell>)> {
    let s = c
        .get_sweep(pb::GetSweepRequest { sweep_id: sweep })
        .await?
        .into_inner();
    let cells = c
        .list_cells(pb::ListCellsRequest { sweep_id: sweep })
        .await?
        .into_inner()
        .cells;
    Ok((s, cells))
}

async fn connect(c: &Conn) -> anyhow::Result<Client> {
    let ep = client::endpoint(&c.connect, c.tls_ca.as_deref()).map_err(anyhow::Error::msg)?;
    let auth = Auth::new(c.token.as_deref()).map_err(anyhow::Error::msg)?;
    let channel = match ep.connect().await {
        Ok(ch) => ch,
        Err(e) => match gaitsweep_core::reason::tls_problem(&e) {
            Some(tls) => anyhow::bail!("cannot connect to {}: {tls}", c.connect),
            None => {
                return Err(anyhow::Error::new(e).context(format!(
                    "cannot reach the coordinator at {}: is it running?",
                    c.connect
                )))
            }
        },
    };
    Ok(SweepServiceClient::with_interceptor(channel, auth)
        .max_decoding_message_size(client::MAX_MESSAGE))
}

/// Runs one client subcommand.
pub async fn run(cmd: ClientCmd) -> anyhow::Result<()> {
    match cmd {
        ClientCmd::Create { conn, spec } => {
            let text = std::fs::read_to_string(&spec)
                .with_context(|| format!("read spec {}", spec.display()))?;
            let mut c = connect(&conn).await?;
            let s = c
                .create_sweep(pb::CreateSweepRequest {
                    spec: Some(pb::create_sweep_request::Spec::Toml(text)),
                })
                .await?
                .into_inner();
            println!("created sweep {} ({} cells)", s.sweep_id, s.cells_total);
        }
        ClientCmd::Status { conn } => {
            let mut c = connect(&conn).await?;
            let s = c.get_status(pb::GetStatusRequest {}).await?.into_inner();
            println!("uptime                  {:.0} s", s.uptime_seconds);
            println!("leases running          {}", s.leases_running);
            println!("metric reports queued   {}", s.metric_reports_queued);
            println!("metric write lag        {:.1} ms", s.metric_write_lag_ms);
            println!(
                "metrics written         {} rows in {} reports, {} transactions",
                s.metric_rows_written, s.metric_reports_written, s.metric_batches
            );
        }
        ClientCmd::List { conn } => {
            let mut c = connect(&conn).await?;
            let list = c.list_sweeps(pb::ListSweepsRequest {}).await?.into_inner();
            println!(
                "{:>5}  {:<24} {:<10} {:>6} {:>6} {:>6} {:>6}",
                "id", "name", "state", "cells", "done", "run", "failed"
            );
            for s in list.sweeps {
                let name = s.spec.as_ref().map_or("", |p| p.name.as_str());
                println!(
                    "{:>5}  {:<24} {:<10} {:>6} {:>6} {:>6} {:>6}",
                    s.sweep_id,
                    name,
                    sweep_state(s.state),
                    s.cells_total,
                    s.cells_done,
                    s.cells_running,
                    s.cells_failed
                );
            }
        }
        ClientCmd::Show { conn, sweep } => {
            let mut c = connect(&conn).await?;
            let (s, cells) = sweep_and_cells(&mut c, sweep).await?;
            print!("{}", render_show(&s, &cells));
        }
        ClientCmd::Watch { conn, sweep, every } => {
            use std::io::IsTerminal;
            let mut c = connect(&conn).await?;
            let mut stream = c
                .watch_sweep(pb::WatchSweepRequest { sweep_id: sweep })
                .await?
                .into_inner();
            if std::io::stdout().is_terminal() && std::io::stderr().is_terminal() {
                let (s, cells) = sweep_and_cells(&mut c, sweep).await?;
                let mut bars = gaitsweep_coordinator::watch::WatchBars::new(&s, &cells, false);
                while let Some(ev) = stream.message().await? {
                    if bars.event(&ev) {
                        break;
                    }
                }
                return Ok(());
            }
            while let Some(ev) = stream.message().await? {
                match ev.kind {
                    Some(Kind::Cell(cell)) => println!(
                        "cell {} (w1 {:.3}, w2 {:.3}, {}) {} attempts {}{}",
                        cell.cell_id,
                        cell.w1,
                        cell.w2,
                        cell.terrain,
                        cell_state(cell.state),
                        cell.attempts,
                        cell.score
                            .map(|s| format!(" score {:.4}", s.score))
                            .unwrap_or_default()
                    ),
                    Some(Kind::Progress(p)) if every > 0 && p.epoch % every == 0 => println!(
                        "cell {} epoch {}{}",
                        p.cell_id,
                        p.epoch,
                        p.mean_return
                            .map(|r| format!(" mean return {r:.4}"))
                            .unwrap_or_default()
                    ),
                    Some(Kind::Progress(_)) => {}
                    Some(Kind::Promotion(p)) => {
                        let cell = p.cell.unwrap_or_default();
                        let on = if p.terrain.is_empty() {
                            "overall".to_string()
                        } else {
                            format!("on {}", p.terrain)
                        };
                        println!(
                            "promoted cell {} {on} (score {:.4})",
                            cell.cell_id,
                            cell.score.map_or(f64::NAN, |s| s.score)
                        );
                    }
                    Some(Kind::Decision(d)) => {
                        println!("{}", gaitsweep_coordinator::watch::decision_line(&d))
                    }
                    Some(Kind::Finished(s)) => {
                        println!("sweep {} {}", s.sweep_id, sweep_state(s.state));
                        break;
                    }
                    None => {}
                }
            }
        }
        ClientCmd::Cancel { conn, sweep } => {
            let mut c = connect(&conn).await?;
            let s = c
                .cancel_sweep(pb::CancelSweepRequest { sweep_id: sweep })
                .await?
                .into_inner();
            println!("sweep {} {}", s.sweep_id, sweep_state(s.state));
        }
        ClientCmd::FetchBest {
            conn,
            sweep,
            terrain,
            out,
            export,
        } => {
            let mut c = connect(&conn).await?;
            let p = c
                .get_promoted(pb::GetPromotedRequest {
                    sweep_id: sweep,
                    terrain: terrain.unwrap_or_default(),
                })
                .await?
                .into_inner();
            let Some(ck) = p.checkpoint else {
                bail!("the promoted cell has no checkpoint: its worker sent none")
            };
            let mut stream = c
                .download_checkpoint(pb::DownloadCheckpointRequest {
                    sha256: ck.sha256.clone(),
                })
                .await?
                .into_inner();
            let bytes = match client::collect_checkpoint(&mut stream, &ck.sha256, ck.size).await {
                Ok(b) => b,
                Err(client::DownloadError::Call(s)) => return Err(s.into()),
                Err(client::DownloadError::Corrupt { got }) => bail!(
                    "downloaded checkpoint is corrupt (sha256 {got}, expected {}): try again",
                    ck.sha256
                ),
            };
            std::fs::write(&out, &bytes).with_context(|| format!("write {}", out.display()))?;
            let cell = p.cell.unwrap_or_default();
            println!(
                "wrote {} (cell {}, w1 {:.3}, w2 {:.3}, score {:.4})",
                out.display(),
                cell.cell_id,
                cell.w1,
                cell.w2,
                cell.score.map_or(f64::NAN, |s| s.score)
            );
            match export {
                Some(dir) => {
                    let sibling = std::env::current_exe()?.with_file_name("worker");
                    let worker = if sibling.is_file() {
                        sibling
                    } else {
                        PathBuf::from("worker")
                    };
                    let status = std::process::Command::new(&worker)
                        .arg("export")
                        .arg("--out")
                        .arg(&dir)
                        .arg(&out)
                        .status()
                        .with_context(|| {
                            format!(
                                "run {} export: is the worker binary installed?",
                                worker.display()
                            )
                        })?;
                    if !status.success() {
                        bail!("worker export failed ({status}): see its message above");
                    }
                    println!("exported the actor to {}", dir.display());
                }
                None => println!(
                    "export it with `worker export --out DIR {}` or pass --export DIR",
                    out.display()
                ),
            }
        }
    }
    Ok(())
}
