//! `search-bench`: the offline search benchmark (see `gaitsweep_coordinator::searchbench`).
//!
//! `search-bench export --data-dir DIR --sweep N > grid.json` writes a recorded full-grid
//! sweep (every replicate's final score and intermediate evaluations) from a coordinator's
//! database; `search-bench run --data grid.json --replays 200` replays the grid, successive
//! halving and CMA-ES over it and prints what each spends and finds.

use anyhow::{bail, Context};
use clap::{Parser, Subcommand};
use gaitsweep_coordinator::searchbench::{
    self, AshaSetup, EvolutionSetup, RecordedGait, RecordedLevel, RecordedPoint, RecordedRun,
    Recording, Summary,
};
use gaitsweep_coordinator::store::queries;
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "search-bench",
    about = "replay search strategies offline over a recorded full-grid sweep"
)]
struct Args {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Write a recorded grid sweep as JSON (stdout) from a coordinator's data dir.
    Export {
        /// The coordinator's data dir (holds gaitsweep.sqlite); not needed with --database.
        #[arg(long, required_unless_present = "database")]
        data_dir: Option<PathBuf>,
        /// The coordinator's database when it is not the data dir's SQLite file.
        #[arg(long, env = "GAITSWEEP_DATABASE", hide_env_values = true)]
        database: Option<String>,
        /// Sweep id (a full grid, every point scored).
        #[arg(long)]
        sweep: i64,
        /// Terrain (default: the sweep's first).
        #[arg(long)]
        terrain: Option<String>,
    },
    /// Replay the strategies over a recording and print their figures.
    Run {
        /// The recording (`export`'s output).
        #[arg(long)]
        data: PathBuf,
        /// Replays per strategy (seeds 0..replays).
        #[arg(long, default_value_t = 200)]
        replays: u64,
        /// Simulated workers for successive halving.
        #[arg(long, default_value_t = 4)]
        workers: usize,
        /// First rung of successive halving, epochs (default: the smallest evaluated epoch
        /// with a rung sequence that is evaluated everywhere).
        #[arg(long)]
        min_epochs: Option<u32>,
        /// Reduction factor of successive halving.
        #[arg(long, default_value_t = 3)]
        reduction: u32,
        /// Candidates per generation of CMA-ES and the genetic algorithm.
        #[arg(long, default_value_t = 6)]
        population: usize,
        /// CMA-ES initial step, a fraction of each axis' range.
        #[arg(long, default_value_t = 0.3)]
        sigma: f64,
        /// Epoch budget of CMA-ES and the genetic algorithm, a fraction of the grid's.
        #[arg(long, default_value_t = 1.0 / 3.0)]
        budget_fraction: f64,
    },
}

fn main() -> std::process::ExitCode {
    gaitsweep_core::error::exit(
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(anyhow::Error::from)
            .and_then(|rt| rt.block_on(run())),
    )
}

async fn run() -> anyhow::Result<()> {
    match Args::parse().cmd {
        Cmd::Export {
            data_dir,
            database,
            sweep,
            terrain,
        } => {
            let rec = export(
                &data_dir.unwrap_or_default(),
                database.as_deref(),
                sweep,
                terrain.as_deref(),
            )
            .await?;
            rec.validate().map_err(anyhow::Error::msg)?;
            println!("{}", serde_json::to_string_pretty(&rec)?);
            Ok(())
        }
        Cmd::Run {
            data,
            replays,
            workers,
            min_epochs,
            reduction,
            population,
            sigma,
            budget_fraction,
        } => {
            let text = std::fs::read_to_string(&data)
                .with_context(|| format!("read {}", data.display()))?;
            let rec: Recording = serde_json::from_str(&text)
                .with_context(|| format!("{} is not a search-bench recording", data.display()))?;
            rec.validate().map_err(anyhow::Error::msg)?;
            let min_epochs = match min_epochs {
                Some(m) => m,
                None => default_min_epochs(&rec, reduction)?,
            };
            let asha = AshaSetup {
                min_epochs,
                reduction,
                workers,
            };
            let rungs = searchbench::asha_rungs(&rec, &asha).map_err(anyhow::Error::msg)?;
            let cmaes = EvolutionSetup {
                genetic: false,
                population,
                sigma,
                budget_fraction,
                halving: None,
            };
            // The same search with successive halving inside each generation, at ASHA's
            // rungs.
            let halved = EvolutionSetup {
                halving: Some(asha),
                ..cmaes
            };
            let ga = EvolutionSetup {
                genetic: true,
                ..cmaes
            };
            let ga_halved = EvolutionSetup {
                genetic: true,
                ..halved
            };
            let points = rec.w1_values.len() * rec.w2_values.len();
            // Random search at the evolutionary searches' budget: as many points as it buys.
            let random_points =
                ((budget_fraction * points as f64).round() as usize).clamp(1, points);
            let (best_point, best) = rec.best();
            let runs: usize = rec.points.iter().map(|p| p.runs.len()).sum();
            println!(
                "recording: {} ({} on {}, {} x {} points, {runs} runs, {} epochs); grid best: w1 {}, w2 {}, mean {best:.4}",
                data.display(),
                rec.source,
                rec.terrain,
                rec.w1_values.len(),
                rec.w2_values.len(),
                rec.epochs,
                rec.w1_values[best_point.0],
                rec.w2_values[best_point.1],
            );
            let replay_all = |one: &dyn Fn(u64) -> Result<searchbench::Replay, String>| {
                (0..replays).map(one).collect::<Result<Vec<_>, String>>()
            };
            let g = replay_all(&|seed| searchbench::replay_grid_single(&rec, seed))
                .map_err(anyhow::Error::msg)?;
            let a = replay_all(&|seed| searchbench::replay_asha(&rec, &asha, seed))
                .map_err(anyhow::Error::msg)?;
            let r = replay_all(&|seed| searchbench::replay_random(&rec, random_points, seed))
                .map_err(anyhow::Error::msg)?;
            // A CMA-ES setting whose budget pays for no generation (a small grid, a large
            // population) gets a row that says so; the other strategies still print.
            let c = replay_all(&|seed| searchbench::replay_evolution(&rec, &cmaes, seed));
            let h = replay_all(&|seed| searchbench::replay_evolution(&rec, &halved, seed));
            let gc = replay_all(&|seed| searchbench::replay_evolution(&rec, &ga, seed));
            let gh = replay_all(&|seed| searchbench::replay_evolution(&rec, &ga_halved, seed));
            println!(
                "{:<58} {:>8} {:>8} {:>12} {:>10} {:>12} {:>10}",
                "strategy", "replays", "epochs", "mean regret", "max regret", "P(best)", "P(<= 5%)"
            );
            let grid = Summary {
                replays: 1,
                epoch_fraction: 1.0,
                mean_regret: 0.0,
                max_regret: 0.0,
                p_best: 1.0,
                p_within_5pct: 1.0,
            };
            for (name, s) in [
                ("grid (every point to the end)".to_string(), Ok(grid)),
                (
                    "grid, one replicate drawn per point".to_string(),
                    Ok(searchbench::summarise(&g)),
                ),
                (
                    format!("random search, {random_points} of {points} points"),
                    Ok(searchbench::summarise(&r)),
                ),
                (
                    format!("asha rungs {rungs:?}, eta {reduction}, {workers} workers"),
                    Ok(searchbench::summarise(&a)),
                ),
                (
                    format!("cma-es pop {population}, sigma {sigma}, budget {budget_fraction:.3}"),
                    c.map(|c| searchbench::summarise(&c)),
                ),
                (
                    format!(
                        "cma-es pop {population} + halving at asha's rungs, budget {budget_fraction:.3}"
                    ),
                    h.map(|h| searchbench::summarise(&h)),
                ),
                (
                    format!("genetic pop {population}, budget {budget_fraction:.3}"),
                    gc.map(|g| searchbench::summarise(&g)),
                ),
                (
                    format!(
                        "genetic pop {population} + halving at asha's rungs, budget {budget_fraction:.3}"
                    ),
                    gh.map(|g| searchbench::summarise(&g)),
                ),
            ] {
                let s = match s {
                    Ok(s) => s,
                    Err(why) => {
                        println!("{name:<58} not replayed: {why}");
                        continue;
                    }
                };
                println!(
                    "{name:<58} {:>8} {:>7.1}% {:>12.4} {:>10.4} {:>11.1}% {:>9.1}%",
                    s.replays,
                    100.0 * s.epoch_fraction,
                    s.mean_regret,
                    s.max_regret,
                    100.0 * s.p_best,
                    100.0 * s.p_within_5pct
                );
            }
            Ok(())
        }
    }
}

/// The smallest evaluated epoch from which every rung is evaluated in every run.
fn default_min_epochs(rec: &Recording, reduction: u32) -> anyhow::Result<u32> {
    for m in rec.common_eval_epochs() {
        let s = AshaSetup {
            min_epochs: m,
            reduction,
            workers: 1,
        };
        if searchbench::asha_rungs(rec, &s).is_ok() {
            return Ok(m);
        }
    }
    bail!(
        "no rung sequence with reduction {reduction} is evaluated in every run: give --min-epochs"
    )
}

async fn export(
    data_dir: &std::path::Path,
    database: Option<&str>,
    sweep: i64,
    terrain: Option<&str>,
) -> anyhow::Result<Recording> {
    let db = gaitsweep_coordinator::store::reader::open(data_dir, database).await?;
    let queries::SweepSpecRow { name, spec, .. } =
        queries::sweep_spec(&db, gaitsweep_core::SweepId(sweep))
            .await
            .with_context(|| format!("no sweep {sweep} in this database"))?;
    if spec.search != gaitsweep_core::Search::Grid {
        bail!("sweep {sweep} is not a full grid: record a grid (no [search]) with eval.every");
    }
    let terrain = terrain
        .map(str::to_string)
        .or_else(|| spec.terrains.first().map(|t| t.to_string()))
        .context("the sweep has no terrain")?;
    #[derive(sqlx::FromRow)]
    struct Row {
        id: i64,
        w1_index: i64,
        w2_index: i64,
        seed: i64,
        score: f64,
        fall_rate: f64,
        mean_vel_error: f64,
        mean_speed: Option<f64>,
        overspeed: Option<f64>,
    }
    let rows: Vec<Row> = sqlx::query_as(
        "SELECT c.id, c.w1_index, c.w2_index, c.seed, s.score, s.fall_rate, s.mean_vel_error, \
         s.mean_speed, s.overspeed FROM cells c JOIN scores s ON s.cell_id = c.id \
         WHERE c.sweep_id = $1 AND c.terrain = $2 ORDER BY c.w1_index, c.w2_index, c.replicate",
    )
    .bind(sweep)
    .bind(&terrain)
    .fetch_all(&db)
    .await?;
    // The final evaluation's levels: the rows at the epoch the score was taken.
    let level_rows: Vec<(i64, i64, f64, f64, f64, f64, f64)> = sqlx::query_as(
        "SELECT l.cell_id, l.level, l.score, l.fall_rate, l.mean_vel_error, l.mean_speed, l.overspeed \
         FROM level_scores l \
         JOIN cells c ON c.id = l.cell_id JOIN scores s ON s.cell_id = l.cell_id AND s.epochs = l.epoch \
         WHERE c.sweep_id = $1 AND c.terrain = $2 ORDER BY l.cell_id, l.level",
    )
    .bind(sweep)
    .bind(&terrain)
    .fetch_all(&db)
    .await?;
    let mut levels: BTreeMap<i64, Vec<RecordedLevel>> = BTreeMap::new();
    for (cell, level, score, fall_rate, mean_vel_error, mean_speed, overspeed) in level_rows {
        levels.entry(cell).or_default().push(RecordedLevel {
            level: level as u32,
            score,
            fall_rate,
            mean_vel_error,
            mean_speed,
            overspeed,
        });
    }
    let evals =
        queries::evaluations(&db, gaitsweep_core::SweepId(sweep), queries::EvalKinds::All).await?;
    let mut by_cell: BTreeMap<i64, BTreeMap<u32, f64>> = BTreeMap::new();
    for e in evals {
        by_cell
            .entry(e.cell_id)
            .or_default()
            .insert(e.epoch as u32, e.score);
    }
    let mut points: BTreeMap<(usize, usize), Vec<RecordedRun>> = BTreeMap::new();
    for r in rows {
        points
            .entry((r.w1_index as usize, r.w2_index as usize))
            .or_default()
            .push(RecordedRun {
                seed: r.seed as u64,
                score: r.score,
                evals: by_cell.remove(&r.id).unwrap_or_default(),
                gait: Some(RecordedGait {
                    fall_rate: r.fall_rate,
                    mean_vel_error: r.mean_vel_error,
                    mean_speed: r.mean_speed,
                    overspeed: r.overspeed,
                    levels: levels.remove(&r.id).unwrap_or_default(),
                }),
            });
    }
    let mut w1 = spec.w1_values.clone();
    let mut w2 = spec.w2_values.clone();
    // The recording's axes ascend; grids may list values in any order.
    let order = |v: &mut Vec<f64>| -> Vec<usize> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        let sorted: Vec<f64> = idx.iter().map(|&k| v[k]).collect();
        *v = sorted;
        let mut rank = vec![0; idx.len()];
        for (r, &k) in idx.iter().enumerate() {
            rank[k] = r;
        }
        rank
    };
    let (r1, r2) = (order(&mut w1), order(&mut w2));
    Ok(Recording {
        spec: Some(spec.clone()),
        source: format!("sweep {sweep} {name:?}, seeds {}", spec.replicates),
        terrain,
        epochs: spec.epochs,
        w1_values: w1,
        w2_values: w2,
        points: points
            .into_iter()
            .map(|((i, j), runs)| RecordedPoint {
                w1_index: r1[i],
                w2_index: r2[j],
                runs,
            })
            .collect(),
    })
}
