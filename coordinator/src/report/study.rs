//! `coordinator findings SOURCE...`: the paper's findings beside several grid sweeps' in one
//! Markdown table, one column per robot and terrain (issue 39 item 5, "The paper's study").
//! A study records one sweep per robot, each in its own database (a recording snapshot:
//! `studies/recordings/ROBOT`), so each source is a data dir, with the sweep named after a
//! colon or by the dir's `sweep.id` file (written by `scripts/record-sweep.sh`).

use super::findings::study_markdown;
use super::{load, ReportData};
use crate::error::io;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// The file in a recording's data dir that names its sweep.
pub const SWEEP_ID_FILE: &str = "sweep.id";

/// `coordinator findings`.
#[derive(clap::Args, Debug, Clone)]
pub struct FindingsArgs {
    /// Each sweep, in the order of the table's columns: DATA_DIR:SWEEP_ID, or DATA_DIR alone
    /// when it holds a `sweep.id` file (a recording snapshot). The database is the data
    /// dir's gaitsweep.sqlite, opened read-only.
    #[arg(required = true, value_name = "DATA_DIR[:SWEEP_ID]")]
    pub sweeps: Vec<String>,
    /// Write the Markdown to this file instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Where one sweep of a study is read from.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// The data dir holding its database.
    pub data_dir: PathBuf,
    /// Its id there.
    pub sweep: i64,
}

/// Reads `DATA_DIR:SWEEP_ID`, or `DATA_DIR` with the id from its `sweep.id` file.
pub fn parse_source(arg: &str) -> Result<Source> {
    if let Some((dir, id)) = arg.rsplit_once(':') {
        if let Ok(sweep) = id.trim().parse::<i64>() {
            return Ok(Source {
                data_dir: dir.into(),
                sweep,
            });
        }
    }
    let data_dir = PathBuf::from(arg);
    let file = data_dir.join(SWEEP_ID_FILE);
    let text = match std::fs::read_to_string(&file) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Error::BadRequest(format!(
                "{arg} names no sweep: write it as DATA_DIR:SWEEP_ID (`coordinator list` shows the ids), \
                 or give a recording's data dir, which holds {SWEEP_ID_FILE}"
            )))
        }
        Err(e) => return Err(io(format!("read {}", file.display()))(e)),
    };
    let sweep = text.trim().parse::<i64>().map_err(|_| {
        Error::BadRequest(format!(
            "{} should hold a sweep id (a whole number) but reads {:?}: write the source as DATA_DIR:SWEEP_ID instead",
            file.display(),
            text.trim()
        ))
    })?;
    Ok(Source { data_dir, sweep })
}

/// Loads one source's sweep; refuses an evolutionary search, which has no grid to hold
/// against the paper's.
async fn load_source(s: &Source) -> Result<ReportData> {
    let db = crate::store::reader::open(&s.data_dir, None).await?;
    let data = load(&db, s.sweep).await;
    db.close().await;
    let data = data?;
    if data.evolution.is_some() {
        return Err(Error::BadRequest(format!(
            "sweep {} in {} is a {}, not a grid: the paper's findings are read from grids",
            s.sweep,
            s.data_dir.display(),
            data.search_title
        )));
    }
    Ok(data)
}

/// Runs `coordinator findings`.
pub async fn run(a: FindingsArgs) -> Result<()> {
    let sources: Vec<Source> = a
        .sweeps
        .iter()
        .map(|s| parse_source(s))
        .collect::<Result<_>>()?;
    let mut sweeps = Vec::with_capacity(sources.len());
    for s in &sources {
        sweeps.push((s.data_dir.display().to_string(), load_source(s).await?));
    }
    let md = study_markdown(&sweeps);
    match &a.out {
        Some(path) => {
            write(path, &md)?;
            tracing::info!(file = %path.display(), sweeps = sweeps.len(), "findings written");
        }
        None => print!("{md}"),
    }
    Ok(())
}

fn write(path: &Path, md: &str) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io(format!("create {}", dir.display())))?;
    }
    std::fs::write(path, md).map_err(io(format!("write {}", path.display())))
}
