//! `worker`: trains gait policies. `worker train` runs one cell locally; `worker export`
//! turns a checkpoint into TorchScript; `worker bench-train` measures throughput.

use clap::{Parser, Subcommand};
use gaitsweep_worker::cli;

/// gaitsweep worker.
#[derive(Parser, Debug)]
#[command(
    name = "worker",
    version,
    about,
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Daemon mode (`worker --connect URL ...`): train cells leased from a coordinator.
    #[command(flatten)]
    daemon: Option<gaitsweep_worker::daemon::DaemonArgs>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Train one cell locally, without a coordinator.
    Train(cli::TrainArgs),
    /// Export a checkpoint's actor (TorchScript, safetensors, JSON).
    Export(cli::ExportArgs),
    /// Measure end-to-end training throughput on the simulator.
    BenchTrain(cli::BenchArgs),
    /// Score a checkpoint with the evaluation rollout (deterministic or stochastic policy).
    Eval(gaitsweep_worker::evaluate::EvalArgs),
    /// Render a checkpoint's gait (deterministic policy, one robot) as an animated GIF.
    Render(gaitsweep_worker::render::RenderArgs),
}

fn main() -> std::process::ExitCode {
    gaitsweep_core::error::exit(run())
}

fn run() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Train(a)) => cli::train(a)?,
        Some(Command::Export(a)) => cli::export(a)?,
        Some(Command::BenchTrain(a)) => cli::bench(a)?,
        Some(Command::Eval(a)) => gaitsweep_worker::evaluate::run(a)?,
        Some(Command::Render(a)) => gaitsweep_worker::render::run(a)?,
        None => match cli.daemon {
            Some(d) => gaitsweep_worker::daemon::run_blocking(d)?,
            None => anyhow::bail!(
                "give --connect URL (daemon mode) or a subcommand (train, export, bench-train)"
            ),
        },
    }
    Ok(())
}
