//! `coordinator report SWEEP --data-dir DIR --out OUT`: the pictures of a sweep, read
//! straight from the coordinator's database (SQLite read-only, or PostgreSQL; the coordinator may be
//! running) and drawn with plotters:
//!
//! - `score_<terrain>.{png,svg}`: heatmap of the gait score over (w1, w2), best cell marked;
//! - `surface_<terrain>.{png,svg}`: the same as a 3D surface;
//! - `<component>_<terrain>.{png,svg}` for track, effort, tilt and progress;
//! - `torque_share_<terrain>.{png,svg}`: the torque penalty against the tracking reward in
//!   each cell's training ([`ReportCell::torque_share`]), where w2 shapes the reward;
//! - `overlap.{png,svg}`: grid points whose mean is in the top quartile on every terrain
//!   (more than one terrain);
//! - `curves_<terrain>.{png,svg}`: learning curves (mean reward per step and mean return);
//! - `findings.md`: the paper's findings beside the sweep's, one column per terrain
//!   (grid sweeps; several robots' sweeps in one table: `coordinator findings`, [`study`]);
//! - `gait.gif`: the promoted policy walking (`worker render`, run from the `worker` binary
//!   next to this executable);
//! - `index.html`: all of it with the table of cells, and per terrain the spread of one run
//!   read from the runs of nearly the same reward ([`ReportData::same_reward_rows`]) and the
//!   points not told apart from the best ([`ReportData::near_best`], labelled "near best"
//!   in the score heatmap), on each terrain and on every terrain at once.
//!
//! Loading ([`load`]) is the only part that touches the database; everything else is a
//! function of a [`ReportData`], so it is tested on synthetic data.

mod data;
mod findings;
mod html;
mod load;
pub mod machines;
mod paragraphs;
mod plots;
mod spread;
pub mod study;
pub mod tensorboard;
mod text;

use crate::error::io;
use crate::Result;
use std::path::{Path, PathBuf};

pub use data::{Promotion, ReportCell, ReportData};
pub use load::load;
pub use plots::{colormap, register_fonts};
pub use spread::SameRewardRow;
pub use text::{budget_text, eval_text};

/// Metrics drawn as learning curves, in the order they are looked for.
pub const CURVE_METRICS: [&str; 3] = ["mean_step_reward", "mean_return", "eval/score"];

/// The per-step reward terms, logged every epoch, that the torque weight is read against
/// ([`ReportCell::torque_share`]).
pub const SHARE_METRICS: [&str; 2] = ["reward/torques", "reward/tracking_lin_vel"];

/// A torque penalty under this share of the tracking reward shapes a cell's reward by less
/// than 1%: at such w2 the weights give nearly the same reward, and cells differ by their
/// runs' spread more than by w2.
pub const NEGLIGIBLE_TORQUE_SHARE: f64 = 0.01;

/// The paper's findings beside a grid sweep's, in Markdown ([`findings::markdown`]).
pub const FINDINGS_FILE: &str = "findings.md";

/// What happened to the gait GIF.
#[derive(Debug, Clone, PartialEq)]
pub enum GifStatus {
    /// Written under this file name in the output dir.
    Written(String),
    /// Not made, and why (shown in index.html).
    NotMade(String),
}

/// The files a report wrote.
#[derive(Debug, Clone, Default)]
pub struct ReportFiles {
    /// Every picture, page, Markdown file and GIF written, in the output dir.
    pub files: Vec<PathBuf>,
}

/// Draws every picture of `data` into `out`, writes `findings.md` for a grid and
/// `index.html` (with `gif` as the gait section).
pub fn write_report(data: &ReportData, out: &Path, gif: &GifStatus) -> Result<ReportFiles> {
    std::fs::create_dir_all(out).map_err(io(format!("create {}", out.display())))?;
    let mut files = plots::draw_all(data, out)?;
    if let Some(md) = findings::markdown(data) {
        let path = out.join(FINDINGS_FILE);
        std::fs::write(&path, md).map_err(io(format!("write {}", path.display())))?;
        files.push(path);
    }
    let index = out.join("index.html");
    std::fs::write(&index, html::index(data, &files, gif))
        .map_err(io(format!("write {}", index.display())))?;
    files.push(index);
    Ok(ReportFiles { files })
}

/// Safe file-name part for a terrain.
pub fn slug(s: &str) -> String {
    let s: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "terrain".into()
    } else {
        s
    }
}

/// `coordinator report`.
#[derive(clap::Args, Debug, Clone)]
pub struct ReportArgs {
    /// Sweep id.
    pub sweep: i64,
    /// The coordinator's data dir (holds gaitsweep.sqlite and the checkpoints).
    #[arg(long)]
    pub data_dir: PathBuf,
    /// The coordinator's database when it is not the data dir's SQLite file (as `serve
    /// --database`).
    #[arg(long, env = "GAITSWEEP_DATABASE", hide_env_values = true)]
    pub database: Option<String>,
    /// Output directory of the report.
    #[arg(long, default_value = "report")]
    pub out: PathBuf,
    /// The `worker` binary that renders the gait GIF (default: next to this executable).
    #[arg(long)]
    pub worker: Option<PathBuf>,
    /// Do not render the gait GIF.
    #[arg(long)]
    pub no_gif: bool,
    /// Seconds of walking in the gait GIF.
    #[arg(long, default_value_t = 6.0)]
    pub gif_seconds: f32,
}

/// Runs `coordinator report`.
pub async fn run(a: ReportArgs) -> Result<()> {
    let db = crate::store::reader::open(&a.data_dir, a.database.as_deref()).await?;
    let data = load(&db, a.sweep).await?;
    db.close().await;
    std::fs::create_dir_all(&a.out).map_err(io(format!("create {}", a.out.display())))?;
    let gif = if a.no_gif {
        GifStatus::NotMade("not rendered (--no-gif)".into())
    } else {
        render_gif(&data, &a).await
    };
    match &gif {
        GifStatus::Written(f) => {
            tracing::info!(file = %a.out.join(f).display(), "gait GIF written")
        }
        GifStatus::NotMade(why) => tracing::warn!("no gait GIF: {why}"),
    }
    let files = write_report(&data, &a.out, &gif)?;
    let done = data.cells.iter().filter(|c| c.score.is_some()).count();
    println!(
        "report of sweep {} ({} of {} cells scored): {} files in {}; open {}",
        data.sweep_id,
        done,
        data.cells.len(),
        files.files.len(),
        a.out.display(),
        a.out.join("index.html").display()
    );
    Ok(())
}

/// The `worker` binary next to this executable.
pub fn sibling_worker() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let p = exe.parent()?.join(if cfg!(windows) {
        "worker.exe"
    } else {
        "worker"
    });
    p.is_file().then_some(p)
}

/// Renders the promoted cell's checkpoint with `worker render`; never fails the report.
pub(crate) async fn render_gif(data: &ReportData, a: &ReportArgs) -> GifStatus {
    let Some(best) = data.promoted() else {
        return GifStatus::NotMade(
            "no cell has a score yet, so there is no promoted policy to render".into(),
        );
    };
    let Some(rel) = &best.checkpoint else {
        return GifStatus::NotMade(format!(
            "the promoted cell {} has no checkpoint in the database",
            best.id
        ));
    };
    let ckpt = a.data_dir.join(rel);
    if !ckpt.is_file() {
        return GifStatus::NotMade(format!(
            "the promoted cell's checkpoint {} is missing",
            ckpt.display()
        ));
    }
    let worker = match a.worker.clone().or_else(sibling_worker) {
        Some(w) if w.is_file() => w,
        Some(w) => {
            return GifStatus::NotMade(format!("the worker binary {} does not exist", w.display()))
        }
        None => {
            let dir = std::env::current_exe()
                .ok()
                .and_then(|e| e.parent().map(Path::to_path_buf))
                .unwrap_or_default();
            return GifStatus::NotMade(format!(
                "the worker binary was not found next to the coordinator (in {}); build it or pass --worker PATH, then run `worker render --checkpoint {} --out gait.gif`",
                dir.display(),
                ckpt.display()
            ));
        }
    };
    let name = "gait.gif";
    let mut cmd = tokio::process::Command::new(&worker);
    cmd.arg("render")
        .arg("--checkpoint")
        .arg(&ckpt)
        .arg("--out")
        .arg(a.out.join(name))
        .arg("--terrain")
        .arg(&best.terrain)
        .arg("--seconds")
        .arg(a.gif_seconds.to_string());
    if let Some(d) = data.difficulty {
        cmd.arg("--difficulty").arg(d.to_string());
    }
    tracing::info!(worker = %worker.display(), checkpoint = %ckpt.display(), cell = best.id, "rendering the promoted policy's gait");
    match cmd.kill_on_drop(true).output().await {
        Ok(o) if o.status.success() && a.out.join(name).is_file() => {
            GifStatus::Written(name.into())
        }
        Ok(o) => {
            let err = String::from_utf8_lossy(&o.stderr);
            let last = err
                .lines()
                .rev()
                .find(|l| !l.trim().is_empty())
                .unwrap_or("")
                .trim()
                .to_string();
            GifStatus::NotMade(format!(
                "`{} render` failed ({}): {last}",
                worker.display(),
                o.status
            ))
        }
        Err(e) => GifStatus::NotMade(format!("could not run {}: {e}", worker.display())),
    }
}

#[cfg(test)]
mod tests;
