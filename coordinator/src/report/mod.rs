//! `coordinator report SWEEP --data-dir DIR --out OUT`: the pictures of a sweep, read
//! straight from the coordinator's database (SQLite read-only, or PostgreSQL; the coordinator may be
//! running) and drawn with plotters:
//!
//! - `score_<terrain>.{png,svg}`: heatmap of the gait score over (w1, w2), best cell marked;
//! - `surface_<terrain>.{png,svg}`: the same as a 3D surface;
//! - `<component>_<terrain>.{png,svg}` for track, effort, tilt and progress;
//! - `torque_share_<terrain>.{png,svg}`: the torque penalty against the tracking reward in
//!   each cell's training ([`ReportCell::torque_share`]), where w2 shapes the reward;
//! - `overlap.{png,svg}`: cells in the top quartile on every terrain (more than one terrain);
//! - `curves_<terrain>.{png,svg}`: learning curves (mean reward per step and mean return);
//! - `gait.gif`: the promoted policy walking (`worker render`, run from the `worker` binary
//!   next to this executable);
//! - `index.html`: all of it with the table of cells, and per terrain the spread of one run
//!   read from the runs of nearly the same reward ([`ReportData::same_reward_rows`]) and the
//!   points not told apart from the best ([`ReportData::near_best`], labelled "near best"
//!   in the score heatmap), on each terrain and on every terrain at once.
//!
//! Loading ([`load`]) is the only part that touches the database; everything else is a
//! function of a [`ReportData`], so it is tested on synthetic data.

mod html;
pub mod machines;
mod plots;
pub mod tensorboard;
mod text;

use crate::error::io;
use crate::near_best::{NearBest, SpreadSource};
use crate::shape::GridValues;
use crate::store::queries::{self, EvalKinds};
use crate::store::rows::{CellRow, CELL_COLUMNS, CELL_ORDER};
use crate::Result;
use gaitsweep_core::records::CellRecord;
use gaitsweep_core::stats::Summary;
use gaitsweep_core::{Place, SweepId};
use gaitsweep_model::GaitScore;
use gaitsweep_search::Layout;
use sqlx::{FromRow, Row};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use plots::{colormap, register_fonts};
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

/// One cell of the sweep with its score (if it has one).
#[derive(Debug, Clone)]
pub struct ReportCell {
    /// Cell id.
    pub id: i64,
    /// Index of its terrain in [`ReportData::terrains`].
    pub terrain_index: usize,
    /// Terrain name.
    pub terrain: String,
    /// Its grid point (indices into [`ReportData::w1_values`] and
    /// [`ReportData::w2_values`]), or its generation and number as a candidate.
    pub place: Place,
    /// Replicate number within its grid point (`seeds = k` in the spec).
    pub replicate: u32,
    /// Velocity-tracking weight.
    pub w1: f64,
    /// log10 of the torque-penalty weight.
    pub w2: f64,
    /// queued, running, done, failed or cancelled.
    pub state: String,
    /// Attempts so far.
    pub attempts: u32,
    /// Epochs trained.
    pub epochs_done: u32,
    /// Last error, if any.
    pub last_error: Option<String>,
    /// The gait score and its components (done cells).
    pub score: Option<GaitScore>,
    /// The final (or latest) checkpoint, relative to the data dir.
    pub checkpoint: Option<String>,
    /// Learning curves: metric name -> (epoch, value), epochs ascending.
    pub curves: BTreeMap<String, Vec<(u32, f64)>>,
    /// Its deepest successive-halving rung evaluation (epoch, gait score), if any.
    pub rung: Option<(u32, f64)>,
    /// The CPUs that trained its epochs, in epoch order ([`machines::cpu_spans`]).
    pub trained_on: Vec<machines::CpuSpan>,
}

impl ReportCell {
    /// Its grid point as `(row, column)`; `None` for an evolutionary candidate.
    pub fn grid(&self) -> Option<(usize, usize)> {
        self.place.grid().map(|(i, j)| (i as usize, j as usize))
    }

    /// Whether a scored cell trained without ever being rewarded: its mean reward per step
    /// was exactly 0 at every epoch logged, i.e. every step's reward sum was clipped to 0
    /// (`only_positive_rewards`, legged_gym's) because the penalties, the torque's at a
    /// large w2, outweighed every positive term. PPO then had no reward to learn from, and
    /// the score is that of a policy its weights taught nothing. A cell without a score
    /// may yet be rewarded: `false`.
    pub fn never_rewarded(&self) -> bool {
        self.score.is_some()
            && self
                .curves
                .get("mean_step_reward")
                .is_some_and(|c| !c.is_empty() && c.iter().all(|&(_, v)| v == 0.0))
    }

    /// How much the torque penalty weighs against velocity tracking in the cell's training:
    /// the mean over its logged epochs of the torque penalty per step (its magnitude) over
    /// the mean tracking reward per step. The paper contrasts these two terms (w2 against
    /// w1); this says where on the grid the contrast exists. `None` without both metrics or
    /// without a positive tracking reward.
    pub fn torque_share(&self) -> Option<f64> {
        let mean = |name: &str| {
            let c = self.curves.get(name).filter(|c| !c.is_empty())?;
            Some(c.iter().map(|p| p.1).sum::<f64>() / c.len() as f64)
        };
        let (torque, track) = (mean(SHARE_METRICS[0])?, mean(SHARE_METRICS[1])?);
        (track > 0.0).then(|| torque.abs() / track)
    }

    /// The composite score, if the cell has a finite one.
    pub fn value(&self) -> Option<f64> {
        self.score
            .as_ref()
            .map(|s| s.score)
            .filter(|v| v.is_finite())
    }
}

/// One row's first-seed runs of nearly the same reward ([`ReportData::same_reward_rows`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SameRewardRow {
    /// The row (index into [`ReportData::w1_values`]).
    pub w1_index: usize,
    /// `(w2_index, score)` of each run, w2 ascending.
    pub runs: Vec<(usize, f64)>,
    /// Mean score of the runs.
    pub mean: f64,
    /// Sample standard deviation of the runs' scores (n - 1).
    pub sd: f64,
}

impl SameRewardRow {
    /// The rows' pooled standard deviation: each row's variance weighted by its degrees of
    /// freedom, so that rows at different levels of score share one estimate of a run's
    /// spread. `Some((sd, degrees of freedom))`, `None` without rows.
    pub fn pooled(rows: &[SameRewardRow]) -> Option<(f64, usize)> {
        let scores: Vec<Vec<f64>> = rows
            .iter()
            .map(|r| r.runs.iter().map(|run| run.1).collect())
            .collect();
        crate::near_best::pooled_sd(scores.iter().map(Vec::as_slice))
    }
}

/// A promoted (best) cell.
#[derive(Debug, Clone, PartialEq)]
pub struct Promotion {
    /// Terrain it is best on; empty: over all terrains.
    pub terrain: String,
    /// The cell.
    pub cell_id: i64,
    /// Its score.
    pub score: f64,
}

/// Everything a report shows, loaded once from SQL.
#[derive(Debug, Clone)]
pub struct ReportData {
    /// Sweep id.
    pub sweep_id: i64,
    /// Sweep name.
    pub name: String,
    /// Robot preset.
    pub robot: String,
    /// running, done or cancelled.
    pub state: String,
    /// Fixed difficulty of the sweep, if any.
    pub difficulty: Option<u8>,
    /// Terrains in grid order.
    pub terrains: Vec<String>,
    /// w1 values (grid rows).
    pub w1_values: Vec<f64>,
    /// w2 values (grid columns).
    pub w2_values: Vec<f64>,
    /// Every cell.
    pub cells: Vec<ReportCell>,
    /// Latest promotion per terrain ('' = overall).
    pub promotions: Vec<Promotion>,
    /// For an evolutionary search, the (w1, w2) rectangle it searched
    /// (`([w1_lo, w2_lo], [w1_hi, w2_hi])`): its cells are candidates, not grid points,
    /// and the report draws them instead of grid pictures.
    pub evolution: Option<([f64; 2], [f64; 2])>,
    /// The search method as a spec writes it (`grid`, `asha`, `cmaes`, `genetic`, `random`).
    pub search: String,
    /// The search method in words, for titles ([`gaitsweep_search::Description::title`]).
    pub search_title: String,
    /// What the sweep was given to spend: robots, epochs, search, seeds, evaluation.
    pub budget: String,
    /// Whether the sweep has a finalist stage (`[finalists]`): its points' first seeds were
    /// picked for scoring high ([`ReportData::near_best`]).
    pub finalists: bool,
}

impl ReportData {
    /// The grid point best across the sweep's terrains ([`crate::across`]); `None` for one
    /// terrain or an evolutionary search.
    pub fn across(&self) -> Option<crate::across::AcrossTerrains> {
        if self.evolution.is_some() {
            return None;
        }
        let cells: Vec<crate::across::ScoredCell> = self
            .cells
            .iter()
            .filter_map(|c| {
                Some(crate::across::ScoredCell {
                    cell: gaitsweep_core::CellId(c.id),
                    terrain: c.terrain_index,
                    place: c.place,
                    score: c.value()?,
                })
            })
            .collect();
        crate::across::best_across(&cells, self.terrains.len())
    }

    /// The cell with this id.
    pub fn cell(&self, id: i64) -> Option<&ReportCell> {
        self.cells.iter().find(|c| c.id == id)
    }

    /// The cells of terrain `t`.
    pub fn cells_of(&self, t: usize) -> impl Iterator<Item = &ReportCell> {
        self.cells.iter().filter(move |c| c.terrain_index == t)
    }

    /// The promoted cell over all terrains: the latest overall promotion, else the best
    /// scored cell.
    pub fn promoted(&self) -> Option<&ReportCell> {
        self.promotions
            .iter()
            .find(|p| p.terrain.is_empty())
            .and_then(|p| self.cell(p.cell_id))
            .or_else(|| self.best_cell(None))
    }

    /// The best scored cell (highest score; ties: lowest id) of terrain `t`, or overall.
    pub fn best_cell(&self, t: Option<usize>) -> Option<&ReportCell> {
        self.cells
            .iter()
            .filter(|c| t.is_none_or(|t| c.terrain_index == t))
            .filter_map(|c| c.value().map(|v| (c, v)))
            .fold(None::<(&ReportCell, f64)>, |b, (c, v)| match b {
                Some((bc, bv)) if bv > v || (bv == v && bc.id < c.id) => Some((bc, bv)),
                _ => Some((c, v)),
            })
            .map(|b| b.0)
    }

    /// Grid `[w1_index][w2_index]` of terrain `t` filled with `f(cell)`.
    pub fn grid<T: Clone>(&self, t: usize, empty: T, f: impl Fn(&ReportCell) -> T) -> Vec<Vec<T>> {
        let mut g = vec![vec![empty; self.w2_values.len()]; self.w1_values.len()];
        for c in self.cells_of(t) {
            if let Some(slot) = c.grid().and_then(|(i, j)| g.get_mut(i)?.get_mut(j)) {
                *slot = f(c);
            }
        }
        g
    }

    /// Grid `[w1_index][w2_index]` of terrain `t`: per grid point the mean of `f` over its
    /// replicates that have a value (`seeds = k` trains each point k times).
    pub fn grid_mean(&self, t: usize, f: impl Fn(&ReportCell) -> Option<f64>) -> GridValues {
        let mut sum = vec![vec![(0.0, 0usize); self.w2_values.len()]; self.w1_values.len()];
        for c in self.cells_of(t) {
            if let (Some(v), Some(slot)) =
                (f(c), c.grid().and_then(|(i, j)| sum.get_mut(i)?.get_mut(j)))
            {
                slot.0 += v;
                slot.1 += 1;
            }
        }
        sum.into_iter()
            .map(|r| {
                r.into_iter()
                    .map(|(s, n)| (n > 0).then(|| s / n as f64))
                    .collect()
            })
            .collect()
    }

    /// Grid points `(w1_index, w2_index)` of terrain `t` that have a scored cell and whose
    /// every scored cell was never rewarded ([`ReportCell::never_rewarded`]), in grid order.
    pub fn unrewarded_points(&self, t: usize) -> Vec<(usize, usize)> {
        let mut points: BTreeMap<(usize, usize), bool> = BTreeMap::new();
        for c in self.cells_of(t).filter(|c| c.score.is_some()) {
            if let Some(p) = c.grid() {
                *points.entry(p).or_insert(true) &= c.never_rewarded();
            }
        }
        points
            .into_iter()
            .filter_map(|(p, none)| none.then_some(p))
            .collect()
    }

    /// The columns (w2 indices) of terrain `t` where the torque penalty is negligible: some
    /// cell there has a [`ReportCell::torque_share`] and every such cell's is under
    /// [`NEGLIGIBLE_TORQUE_SHARE`].
    pub fn negligible_torque_columns(&self, t: usize) -> Vec<usize> {
        let mut cols: BTreeMap<usize, bool> = BTreeMap::new();
        for c in self.cells_of(t) {
            if let (Some((_, j)), Some(share)) = (c.grid(), c.torque_share()) {
                *cols.entry(j).or_insert(true) &= share < NEGLIGIBLE_TORQUE_SHARE;
            }
        }
        cols.into_iter()
            .filter_map(|(j, small)| small.then_some(j))
            .collect()
    }

    /// Per row of terrain `t`, the first-seed runs whose weights give nearly the same reward:
    /// scored cells of replicate 0 whose [`ReportCell::torque_share`] is under
    /// [`NEGLIGIBLE_TORQUE_SHARE`]. Across them only w2 differs, and it shapes their reward
    /// by under 1%, so their scores are draws of one reward that differ by their seeds: the
    /// spread of a single run, measured without spending replicates. Rows with fewer than two
    /// such runs are left out. It picks cells, not columns
    /// ([`ReportData::negligible_torque_columns`] needs every cell of a column under 1%).
    pub fn same_reward_rows(&self, t: usize) -> Vec<SameRewardRow> {
        let mut rows: BTreeMap<usize, Vec<(usize, f64)>> = BTreeMap::new();
        for c in self.cells_of(t).filter(|c| c.replicate == 0) {
            if let (Some((i, j)), Some(v), Some(share)) = (c.grid(), c.value(), c.torque_share()) {
                if share < NEGLIGIBLE_TORQUE_SHARE {
                    rows.entry(i).or_default().push((j, v));
                }
            }
        }
        rows.into_iter()
            .filter(|(_, runs)| runs.len() > 1)
            .filter_map(|(w1_index, mut runs)| {
                runs.sort_by_key(|r| r.0);
                let s = Summary::of(&runs.iter().map(|r| r.1).collect::<Vec<_>>())?;
                Some(SameRewardRow {
                    w1_index,
                    runs,
                    mean: s.mean,
                    sd: s.sd,
                })
            })
            .collect()
    }

    /// The points of terrain `t` not told apart from its best point at 95%
    /// ([`crate::near_best`]), over every replicate's score. One run's spread is pooled over
    /// the points trained on more than one seed once every one of their cells has ended
    /// (scored, failed, cancelled or stopped); until then a finalist stage would give a
    /// degree of freedom or two, whose t quantile widens the set several times over, and the
    /// spread is read from the rows' runs of nearly the same reward
    /// ([`ReportData::same_reward_rows`]) instead. After a finalist stage only the seeds
    /// drawn after the selection count: the first was picked for scoring high, so with it
    /// the spread would come out wider than a run's. `None` before either gives a degree
    /// of freedom.
    pub fn near_best(&self, t: usize) -> Option<NearBest> {
        let mut scores: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
        let mut unselected: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
        // Per point: (trained more than once, every one of its cells ended).
        let mut stage: BTreeMap<(usize, usize), (bool, bool)> = BTreeMap::new();
        for c in self.cells_of(t) {
            let Some(p) = c.grid() else { continue };
            if let Some(v) = c.value() {
                scores.entry(p).or_default().push(v);
                if !self.finalists || c.replicate > 0 {
                    unselected.entry(p).or_default().push(v);
                }
            }
            let (replicated, ended) = stage.entry(p).or_insert((false, true));
            *replicated |= c.replicate > 0;
            *ended &= c
                .state
                .parse::<gaitsweep_core::CellState>()
                .is_ok_and(gaitsweep_core::CellState::is_terminal);
        }
        let mut replicated = stage.values().filter(|s| s.0).peekable();
        let stage_ended = replicated.peek().is_some() && replicated.all(|s| s.1);
        let replicates = stage_ended
            .then(|| crate::near_best::pooled_sd(unselected.values().map(Vec::as_slice)))
            .flatten()
            .map(|(sd, dof)| (sd, dof, SpreadSource::Replicates));
        let (sd, dof, source) = replicates.or_else(|| {
            SameRewardRow::pooled(&self.same_reward_rows(t))
                .map(|(sd, dof)| (sd, dof, SpreadSource::SameReward))
        })?;
        crate::near_best::near_best(&scores, sd, dof, source)
    }

    /// Cells `(w1_index, w2_index)` whose score is in the top quartile of their terrain's
    /// scored cells on every terrain, and per grid position the number of terrains where
    /// it is in the top quartile (none where a terrain has not scored it yet: a 0 there
    /// would claim a comparison that has not been made).
    pub fn overlap(&self) -> (Vec<(usize, usize)>, GridValues) {
        let mut count = vec![vec![Some(0.0); self.w2_values.len()]; self.w1_values.len()];
        for (i, row) in count.iter_mut().enumerate() {
            for (j, n) in row.iter_mut().enumerate() {
                let scored_everywhere = (0..self.terrains.len()).all(|t| {
                    self.cells_of(t)
                        .any(|c| c.grid() == Some((i, j)) && c.value().is_some())
                });
                if !scored_everywhere {
                    *n = None;
                }
            }
        }
        for t in 0..self.terrains.len() {
            let mut v: Vec<f64> = self.cells_of(t).filter_map(|c| c.value()).collect();
            if v.is_empty() {
                continue;
            }
            v.sort_by(|a, b| b.total_cmp(a));
            let threshold = v[v.len().div_ceil(4) - 1];
            for c in self.cells_of(t) {
                if c.value().is_some_and(|x| x >= threshold) {
                    if let Some(Some(n)) = c.grid().and_then(|(i, j)| count.get_mut(i)?.get_mut(j))
                    {
                        *n += 1.0;
                    }
                }
            }
        }
        let all = self.terrains.len() as f64;
        let mut cells = Vec::new();
        for (i, row) in count.iter().enumerate() {
            for (j, n) in row.iter().enumerate() {
                if all > 0.0 && *n == Some(all) {
                    cells.push((i, j));
                }
            }
        }
        (cells, count)
    }
}

/// Loads everything the report of `sweep` shows.
pub async fn load(db: &sqlx::AnyPool, sweep: i64) -> Result<ReportData> {
    let row = queries::sweep_spec(db, SweepId(sweep)).await?;
    let spec = row.spec;
    let search = gaitsweep_search::describe(&spec);
    let mut data = ReportData {
        sweep_id: sweep,
        name: row.name,
        robot: spec.robot.clone(),
        state: row.state,
        difficulty: spec.difficulty,
        terrains: spec.terrains.iter().map(|t| t.to_string()).collect(),
        w1_values: spec.w1_values.clone(),
        w2_values: spec.w2_values.clone(),
        cells: Vec::new(),
        promotions: Vec::new(),
        evolution: (search.layout == Layout::Candidates).then(|| spec.bounds()),
        search: search.name.to_string(),
        search_title: search.title.to_string(),
        budget: budget_text(&spec),
        finalists: spec.finalists.is_some(),
    };

    let sql = format!(
        "SELECT {CELL_COLUMNS}, COALESCE(fk.path, lk.path) AS ckpt_path \
         FROM cells c LEFT JOIN scores s ON s.cell_id = c.id \
         LEFT JOIN checkpoints fk ON fk.sha256 = s.final_checkpoint_sha256 \
         LEFT JOIN checkpoints lk ON lk.sha256 = c.last_checkpoint_sha256 \
         WHERE c.sweep_id = $1 \
         ORDER BY {CELL_ORDER}"
    );
    for r in sqlx::query(&sql).bind(sweep).fetch_all(db).await? {
        let checkpoint: Option<String> = r.try_get("ckpt_path")?;
        let c: CellRecord = CellRow::from_row(&r)?.try_into()?;
        data.cells.push(ReportCell {
            id: c.id.0,
            terrain_index: c.terrain_index as usize,
            terrain: c.terrain,
            place: c.place,
            replicate: c.replicate,
            w1: c.w1,
            w2: c.w2,
            state: c.state.to_string(),
            attempts: c.attempts,
            epochs_done: c.epochs_done,
            last_error: c.last_error,
            score: c.score,
            checkpoint,
            curves: BTreeMap::new(),
            rung: None,
            trained_on: Vec::new(),
        });
    }
    let mut attempts = queries::attempt_cpus(db, SweepId(sweep)).await?;
    for c in &mut data.cells {
        let a = attempts.remove(&c.id).unwrap_or_default();
        c.trained_on = machines::cpu_spans(&a, c.epochs_done);
    }
    let mut levels = crate::store::levels::final_levels(db, gaitsweep_core::SweepId(sweep)).await?;
    for c in &mut data.cells {
        if let (Some(s), Some(l)) = (c.score.as_mut(), levels.remove(&c.id)) {
            s.levels = l;
        }
    }
    let rungs = queries::evaluations(db, SweepId(sweep), EvalKinds::Rungs).await?;
    let mut deepest: BTreeMap<i64, (u32, f64)> = BTreeMap::new();
    for e in rungs {
        deepest.insert(e.cell_id, (e.epoch as u32, e.score));
    }
    for c in &mut data.cells {
        c.rung = deepest.get(&c.id).copied();
    }

    let names = CURVE_METRICS
        .iter()
        .chain(&SHARE_METRICS)
        .map(|n| format!("'{n}'"))
        .collect::<Vec<_>>()
        .join(", ");
    let sql = format!(
        "SELECT m.cell_id, m.epoch, m.name, m.value FROM epoch_metrics m JOIN cells c ON c.id = m.cell_id \
         WHERE c.sweep_id = $1 AND m.name IN ({names}) ORDER BY m.cell_id, m.epoch"
    );
    let mut by_cell: BTreeMap<i64, BTreeMap<String, Vec<(u32, f64)>>> = BTreeMap::new();
    for r in sqlx::query(&sql).bind(sweep).fetch_all(db).await? {
        let v: f64 = r.try_get("value")?;
        if v.is_finite() {
            by_cell
                .entry(r.try_get("cell_id")?)
                .or_default()
                .entry(r.try_get("name")?)
                .or_default()
                .push((r.try_get::<i64, _>("epoch")? as u32, v));
        }
    }
    for c in &mut data.cells {
        c.curves = by_cell.remove(&c.id).unwrap_or_default();
    }

    let mut latest: BTreeMap<String, Promotion> = BTreeMap::new();
    for r in sqlx::query(
        "SELECT terrain, cell_id, score FROM promotions WHERE sweep_id = $1 ORDER BY id",
    )
    .bind(sweep)
    .fetch_all(db)
    .await?
    {
        let p = Promotion {
            terrain: r.try_get("terrain")?,
            cell_id: r.try_get("cell_id")?,
            score: r.try_get("score")?,
        };
        latest.insert(p.terrain.clone(), p);
    }
    data.promotions = latest.into_values().collect();
    fill_axes(&mut data);
    Ok(data)
}

/// Fills terrains and grid values the spec did not give from the cells themselves.
fn fill_axes(d: &mut ReportData) {
    let n_t = d
        .cells
        .iter()
        .map(|c| c.terrain_index + 1)
        .max()
        .unwrap_or(0);
    if d.terrains.len() < n_t {
        d.terrains.resize(n_t, String::new());
    }
    let points = || d.cells.iter().filter_map(|c| Some((c, c.grid()?)));
    let n1 = points().map(|(_, (i, _))| i + 1).max().unwrap_or(0);
    let n2 = points().map(|(_, (_, j))| j + 1).max().unwrap_or(0);
    if d.w1_values.len() < n1 {
        d.w1_values.resize(n1, f64::NAN);
    }
    if d.w2_values.len() < n2 {
        d.w2_values.resize(n2, f64::NAN);
    }
    for c in &d.cells {
        if d.terrains[c.terrain_index].is_empty() {
            d.terrains[c.terrain_index] = c.terrain.clone();
        }
        let Some((i, j)) = c.grid() else {
            continue;
        };
        if d.w1_values[i].is_nan() {
            d.w1_values[i] = c.w1;
        }
        if d.w2_values[j].is_nan() {
            d.w2_values[j] = c.w2;
        }
    }
}

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
    /// Every picture, page and GIF written, in the output dir.
    pub files: Vec<PathBuf>,
}

/// Draws every picture of `data` into `out` and writes `index.html` (with `gif` as the
/// gait section).
pub fn write_report(data: &ReportData, out: &Path, gif: &GifStatus) -> Result<ReportFiles> {
    std::fs::create_dir_all(out).map_err(io(format!("create {}", out.display())))?;
    let mut files = plots::draw_all(data, out)?;
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
