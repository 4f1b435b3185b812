//! The one place that converts between wire messages (`pb`) and domain types.

use crate::pb;
use crate::records::{
    CellRecord, CheckpointRecord, PromotionRecord, RungDecisionRecord, SweepRecord,
};
use crate::spec::{Axis, EvalSpec, ResolvedSpec, Search, SearchSpec, SweepSpec};
use crate::{CellState, Error, Place, Result, SweepState};
use gaitsweep_model::{EvalSettings, GaitScore, LevelScore, TerrainKind};

impl From<&Axis> for pb::Axis {
    fn from(a: &Axis) -> Self {
        let kind = match a {
            Axis::Range { min, max, count } => pb::axis::Kind::Range(pb::Range {
                min: *min,
                max: *max,
                count: *count as u32,
            }),
            Axis::Values { values } => pb::axis::Kind::Values(pb::Values {
                values: values.clone(),
            }),
        };
        pb::Axis { kind: Some(kind) }
    }
}

fn axis_from_wire(a: Option<pb::Axis>) -> Option<Axis> {
    match a?.kind? {
        pb::axis::Kind::Range(r) => Some(Axis::Range {
            min: r.min,
            max: r.max,
            count: r.count as usize,
        }),
        pb::axis::Kind::Values(v) => Some(Axis::Values { values: v.values }),
    }
}

impl From<pb::SweepSpec> for SweepSpec {
    fn from(s: pb::SweepSpec) -> Self {
        let nonzero = |v: u32| (v != 0).then_some(v);
        SweepSpec {
            name: s.name,
            robot: s.robot,
            terrains: s.terrains,
            difficulty: s.difficulty,
            preset_grid: s.preset_grid,
            w1: axis_from_wire(s.w1),
            w2: axis_from_wire(s.w2),
            agents_per_cell: nonzero(s.agents_per_cell).map(|v| v as usize),
            epochs: nonzero(s.epochs),
            checkpoint_every: s.checkpoint_every,
            seed: s.seed,
            seeds: nonzero(s.seeds),
            ppo: s.ppo_overrides,
            eval: EvalSpec {
                robots: nonzero(s.eval_robots).map(|v| v as usize),
                seconds: (s.eval_seconds != 0.0).then_some(s.eval_seconds),
                every: nonzero(s.eval_every),
                levels: (!s.eval_levels.is_empty()).then_some(s.eval_levels),
                score: (!s.score.is_empty()).then_some(s.score),
            },
            search: s.search.and_then(search_from_wire),
            finalists: (s.finalists_top != 0 || s.finalists_seeds != 0).then_some(
                crate::finalists::FinalistsSpec {
                    top: s.finalists_top,
                    seeds: s.finalists_seeds,
                },
            ),
            stop_unrewarded: (s.stop_unrewarded != 0.0).then_some(s.stop_unrewarded),
        }
    }
}

/// The resolved spec a wire spec stands for, as the coordinator sends it (every default
/// filled in, its axes as values): it resolves to itself, its own axes standing for the
/// robot's grid, so a client can ask the search what it is without the robot's preset.
pub fn resolved_from_wire(spec: pb::SweepSpec) -> Result<ResolvedSpec> {
    let axis =
        |a: &Option<pb::Axis>| axis_from_wire(a.clone()).unwrap_or(Axis::Values { values: vec![] });
    let grid = crate::spec::PresetGrid {
        w1: axis(&spec.w1),
        w2: axis(&spec.w2),
        agents_per_cell: spec.agents_per_cell as usize,
        epochs: spec.epochs,
    };
    SweepSpec::from(spec).resolve_with(|_| Ok((grid, None)))
}

impl From<&ResolvedSpec> for pb::SweepSpec {
    fn from(s: &ResolvedSpec) -> Self {
        pb::SweepSpec {
            name: s.name.clone(),
            robot: s.robot.clone(),
            terrains: s.terrains.iter().map(|t| t.to_string()).collect(),
            difficulty: s.difficulty.map(u32::from),
            preset_grid: false,
            w1: Some(
                (&Axis::Values {
                    values: s.w1_values.clone(),
                })
                    .into(),
            ),
            w2: Some(
                (&Axis::Values {
                    values: s.w2_values.clone(),
                })
                    .into(),
            ),
            agents_per_cell: s.agents_per_cell as u32,
            epochs: s.epochs,
            checkpoint_every: Some(s.checkpoint_every),
            seed: s.seed,
            ppo_overrides: s.ppo_overrides.clone(),
            eval_robots: s.eval.robots as u32,
            eval_seconds: s.eval.seconds,
            seeds: s.replicates,
            eval_every: s.eval.every,
            eval_levels: s.eval.levels.iter().map(|l| u32::from(*l)).collect(),
            score: s.eval.score.to_string(),
            finalists_top: s.finalists.map_or(0, |f| f.top),
            finalists_seeds: s.finalists.map_or(0, |f| f.seeds),
            search: Some(search_to_wire(&s.search, s.budget_epochs())),
            stop_unrewarded: s.stop_unrewarded.unwrap_or(0.0),
        }
    }
}

/// The name of a wire spec's search method, as a spec writes it ("grid" when unset).
pub fn search_method(spec: &pb::SweepSpec) -> String {
    spec.search
        .and_then(search_from_wire)
        .map_or_else(|| "grid".to_string(), |s| s.method)
}

/// A user's `[search]` as the wire's `oneof`: each method's own options (an unset one 0);
/// `None` for a message without a method.
fn search_from_wire(s: pb::Search) -> Option<SearchSpec> {
    use pb::search::Method;
    let nonzero = |v: u32| (v != 0).then_some(v);
    let budget = |v: u64| (v != 0).then_some(v);
    let spec = |method: &str| SearchSpec {
        method: method.into(),
        ..SearchSpec::default()
    };
    Some(match s.method? {
        Method::Grid(_) => spec("grid"),
        Method::Asha(a) => SearchSpec {
            min_epochs: nonzero(a.min_epochs),
            reduction: nonzero(a.reduction),
            ..spec("asha")
        },
        Method::Cmaes(c) => SearchSpec {
            population: nonzero(c.population),
            sigma: (c.sigma != 0.0).then_some(c.sigma),
            budget_epochs: budget(c.budget_epochs),
            min_epochs: nonzero(c.min_epochs),
            reduction: nonzero(c.reduction),
            ..spec("cmaes")
        },
        Method::Genetic(g) => SearchSpec {
            population: nonzero(g.population),
            budget_epochs: budget(g.budget_epochs),
            min_epochs: nonzero(g.min_epochs),
            reduction: nonzero(g.reduction),
            ..spec("genetic")
        },
        Method::Random(r) => SearchSpec {
            budget_epochs: budget(r.budget_epochs),
            ..spec("random")
        },
    })
}

/// A resolved search as the wire's `oneof`, every option concrete (`budget_epochs`: what
/// the spec trains in all, for the methods with a fixed budget).
fn search_to_wire(s: &Search, budget_epochs: Option<u64>) -> pb::Search {
    use pb::search::Method;
    let budget_epochs = budget_epochs.unwrap_or(0);
    let (min_epochs, reduction) = s.halving().unwrap_or((0, 0));
    let method = match *s {
        Search::Grid => Method::Grid(pb::GridSearch {}),
        Search::Asha { .. } => Method::Asha(pb::AshaSearch {
            min_epochs,
            reduction,
        }),
        Search::Cmaes {
            population, sigma, ..
        } => Method::Cmaes(pb::CmaesSearch {
            population,
            sigma,
            budget_epochs,
            min_epochs,
            reduction,
        }),
        Search::Genetic { population, .. } => Method::Genetic(pb::GeneticSearch {
            population,
            budget_epochs,
            min_epochs,
            reduction,
        }),
        Search::Random { .. } => Method::Random(pb::RandomSearch { budget_epochs }),
    };
    pb::Search {
        method: Some(method),
    }
}

/// A gait score with the numeric components the wire and domain types share (the same
/// names on both sides), then the given fields: the one list of both conversions.
macro_rules! score_with_components {
    ($($ty:ident)::+, $g:expr, { $($rest:tt)* }) => {
        $($ty)::+ {
            score: $g.score,
            track: $g.track,
            effort: $g.effort,
            tilt: $g.tilt,
            progress: $g.progress,
            progress_bounded: $g.progress_bounded,
            fall_rate: $g.fall_rate,
            mean_vel_error: $g.mean_vel_error,
            mean_speed: $g.mean_speed,
            overspeed: $g.overspeed,
            mean_abs_torque: $g.mean_abs_torque,
            cost_of_transport: $g.cost_of_transport,
            $($rest)*
        }
    };
}

impl From<&GaitScore> for pb::GaitScore {
    fn from(g: &GaitScore) -> Self {
        score_with_components!(pb::GaitScore, g, {
            robots: g.robots as u32,
            levels: g
                .levels
                .iter()
                .map(|l| pb::LevelScore {
                    level: u32::from(l.level),
                    score: Some((&l.score).into()),
                })
                .collect(),
        })
    }
}

impl From<&pb::GaitScore> for GaitScore {
    fn from(g: &pb::GaitScore) -> Self {
        score_with_components!(GaitScore, g, {
            robots: g.robots as usize,
            levels: g
                .levels
                .iter()
                .map(|l| LevelScore {
                    level: l.level.min(u32::from(u8::MAX)) as u8,
                    score: l.score.as_ref().map(GaitScore::from).unwrap_or_default(),
                })
                .collect(),
        })
    }
}

impl From<CellState> for pb::CellState {
    fn from(s: CellState) -> Self {
        match s {
            CellState::Queued => pb::CellState::Queued,
            CellState::Running => pb::CellState::Running,
            CellState::Done => pb::CellState::Done,
            CellState::Failed => pb::CellState::Failed,
            CellState::Cancelled => pb::CellState::Cancelled,
            CellState::Paused => pb::CellState::Paused,
            CellState::Stopped => pb::CellState::Stopped,
        }
    }
}

impl TryFrom<pb::CellState> for CellState {
    type Error = Error;
    fn try_from(s: pb::CellState) -> Result<Self> {
        Ok(match s {
            pb::CellState::Queued => CellState::Queued,
            pb::CellState::Running => CellState::Running,
            pb::CellState::Done => CellState::Done,
            pb::CellState::Failed => CellState::Failed,
            pb::CellState::Cancelled => CellState::Cancelled,
            pb::CellState::Paused => CellState::Paused,
            pb::CellState::Stopped => CellState::Stopped,
            pb::CellState::Unspecified => {
                return Err(Error::UnknownValue {
                    what: "cell state",
                    value: "unspecified".into(),
                })
            }
        })
    }
}

impl From<SweepState> for pb::SweepState {
    fn from(s: SweepState) -> Self {
        match s {
            SweepState::Running => pb::SweepState::Running,
            SweepState::Done => pb::SweepState::Done,
            SweepState::Cancelled => pb::SweepState::Cancelled,
        }
    }
}

impl From<&CheckpointRecord> for pb::CheckpointRef {
    fn from(c: &CheckpointRecord) -> Self {
        pb::CheckpointRef {
            sha256: c.sha256.clone(),
            size: c.size,
            epoch: c.epoch,
        }
    }
}

impl From<&pb::CheckpointRef> for CheckpointRecord {
    fn from(c: &pb::CheckpointRef) -> Self {
        CheckpointRecord {
            sha256: c.sha256.clone(),
            size: c.size,
            epoch: c.epoch,
        }
    }
}

/// What a worker needs to train `cell` of a sweep with `spec`: every value concrete (the
/// spec's defaults were decided when the sweep was created).
pub fn cell_task(cell: &CellRecord, spec: &ResolvedSpec) -> pb::CellTask {
    let eval = spec.eval_for(&cell.terrain);
    pb::CellTask {
        cell: Some(cell.into()),
        robot: spec.robot.clone(),
        difficulty: spec.difficulty.map(u32::from),
        agents: spec.agents_per_cell as u32,
        epochs: cell.target_epochs,
        checkpoint_every: spec.checkpoint_every,
        ppo_overrides: spec.ppo_overrides.clone(),
        budget_epochs: spec.epochs,
        // The wire keeps the cell's evaluation settings as loose fields.
        eval_robots: eval.robots as u32,
        eval_seconds: eval.seconds,
        eval_every: eval.every,
        eval_levels: eval.levels.iter().map(|l| u32::from(*l)).collect(),
        score: eval.score.to_string(),
        stop_unrewarded_after: spec.stop_unrewarded_after(),
    }
}

/// How the worker scores a task's cell on `terrain`: the task's loose evaluation fields
/// as one value (levels clamped to 0-9; a fixed difficulty without levels is evaluated at
/// that difficulty, as [`crate::defaults::eval_levels`] says). An unknown score variant is
/// an error naming it.
pub fn task_eval(
    task: &pb::CellTask,
    terrain: TerrainKind,
) -> std::result::Result<EvalSettings, String> {
    let levels: Vec<u8> = task.eval_levels.iter().map(|l| (*l).min(9) as u8).collect();
    Ok(EvalSettings {
        robots: task.eval_robots as usize,
        seconds: task.eval_seconds,
        levels: crate::defaults::eval_levels(
            terrain,
            task.difficulty.map(|d| d.min(9) as u8),
            &levels,
        ),
        score: task.score.parse()?,
        every: task.eval_every,
    })
}

impl From<&CellRecord> for pb::Cell {
    fn from(c: &CellRecord) -> Self {
        pb::Cell {
            cell_id: c.id.0,
            sweep_id: c.sweep_id.0,
            terrain_index: c.terrain_index,
            terrain: c.terrain.clone(),
            w1_index: c.place.grid().map_or(0, |p| p.0),
            w2_index: c.place.grid().map_or(0, |p| p.1),
            candidate: place_to_wire(c.place),
            w1: c.w1,
            w2: c.w2,
            state: pb::CellState::from(c.state) as i32,
            attempts: c.attempts,
            epochs_done: c.epochs_done,
            score: c.score.as_ref().map(Into::into),
            last_error: c.last_error.clone().unwrap_or_default(),
            seed: c.seed,
            replicate: c.replicate,
            target_epochs: c.target_epochs,
            rung_score: c.rung_score,
            // Read from the cell's metrics, not its record: ListCells sets it.
            never_rewarded: false,
        }
    }
}

impl From<&SweepRecord> for pb::Sweep {
    fn from(s: &SweepRecord) -> Self {
        pb::Sweep {
            sweep_id: s.id.0,
            spec: Some((&s.spec).into()),
            state: pb::SweepState::from(s.state) as i32,
            created_unix_ms: s.created_unix_ms,
            cells_total: s.cells_total,
            cells_queued: s.cells_queued,
            cells_running: s.cells_running,
            cells_done: s.cells_done,
            cells_failed: s.cells_failed,
            cells_paused: s.cells_paused,
            cells_stopped: s.cells_stopped,
            w1_values: s.spec.w1_values.clone(),
            w2_values: s.spec.w2_values.clone(),
            best_cell_id: s.best_cell.map_or(0, |c| c.0),
        }
    }
}

impl From<&PromotionRecord> for pb::Promotion {
    fn from(p: &PromotionRecord) -> Self {
        pb::Promotion {
            sweep_id: p.sweep_id.0,
            terrain: p.terrain.clone().unwrap_or_default(),
            cell: Some((&p.cell).into()),
            checkpoint: p.checkpoint.as_ref().map(Into::into),
            promoted_unix_ms: p.promoted_unix_ms,
        }
    }
}

/// The spec of a create request: TOML text or structured.
pub fn spec_from_request(req: pb::CreateSweepRequest) -> Result<SweepSpec> {
    match req.spec {
        Some(pb::create_sweep_request::Spec::Toml(text)) => SweepSpec::from_toml(&text),
        Some(pb::create_sweep_request::Spec::Structured(s)) => Ok(s.into()),
        None => Err(Error::MissingField {
            message: "CreateSweepRequest",
            field: "spec",
        }),
    }
}

impl From<&RungDecisionRecord> for pb::RungDecision {
    fn from(d: &RungDecisionRecord) -> Self {
        pb::RungDecision {
            cell_id: d.cell.id.0,
            rung: d.rung,
            epoch: d.epoch,
            score: d.score,
            continued: d.continued,
        }
    }
}

/// A candidate's place on the wire (`None` for a grid point).
fn place_to_wire(p: Place) -> Option<pb::CandidatePlace> {
    p.generation()
        .map(|(generation, number)| pb::CandidatePlace { generation, number })
}

/// Where a wire cell stands: its candidate place if set, else its grid point.
pub fn place_of(c: &pb::Cell) -> Place {
    match &c.candidate {
        Some(k) => Place::candidate(k.generation, k.number),
        None => Place::point(c.w1_index, c.w2_index),
    }
}

/// The cells' grid points (terrain, w1, w2 index) summarised over their replicates, in
/// order of first appearance: mean, sd and 95% CI of the score and of every component.
pub fn point_results(cells: &[pb::Cell]) -> Vec<pb::PointResult> {
    let mut order: Vec<(u32, Place)> = Vec::new();
    let mut groups: std::collections::BTreeMap<(u32, Place), Vec<&pb::Cell>> =
        std::collections::BTreeMap::new();
    for c in cells {
        let key = (c.terrain_index, place_of(c));
        if !groups.contains_key(&key) {
            order.push(key);
        }
        groups.entry(key).or_default().push(c);
    }
    order
        .into_iter()
        .map(|key| {
            let group = &groups[&key];
            let scored: Vec<&pb::GaitScore> =
                group.iter().filter_map(|c| c.score.as_ref()).collect();
            let stat = |f: fn(&pb::GaitScore) -> f64| {
                let v: Vec<f64> = scored.iter().map(|g| f(g)).collect();
                crate::stats::Summary::of(&v).map(|s| pb::Stat {
                    mean: s.mean,
                    sd: s.sd,
                    ci95: s.ci95,
                    n: s.n as u32,
                })
            };
            pb::PointResult {
                terrain_index: key.0,
                w1_index: key.1.grid().map_or(0, |p| p.0),
                w2_index: key.1.grid().map_or(0, |p| p.1),
                candidate: place_to_wire(key.1),
                w1: group[0].w1,
                w2: group[0].w2,
                replicates: group.len() as u32,
                scored: scored.len() as u32,
                score: stat(|g| g.score),
                fall_rate: stat(|g| g.fall_rate),
                mean_vel_error: stat(|g| g.mean_vel_error),
                track: stat(|g| g.track),
                effort: stat(|g| g.effort),
                tilt: stat(|g| g.tilt),
                progress: stat(|g| g.progress),
            }
        })
        .collect()
}

#[cfg(test)]
mod point_tests {
    use super::*;

    #[test]
    fn points_summarise_their_replicates() {
        let cell = |w1_index: u32, score: Option<f64>| pb::Cell {
            w1_index,
            w1: f64::from(w1_index),
            score: score.map(|s| pb::GaitScore {
                score: s,
                fall_rate: s / 10.0,
                ..Default::default()
            }),
            ..Default::default()
        };
        let cells = [
            cell(0, Some(0.4)),
            cell(1, Some(0.9)),
            cell(0, Some(0.6)),
            cell(0, None),
        ];
        let p = point_results(&cells);
        assert_eq!(p.len(), 2);
        assert_eq!((p[0].w1_index, p[0].replicates, p[0].scored), (0, 3, 2));
        let s = p[0].score.unwrap();
        assert!((s.mean - 0.5).abs() < 1e-12 && s.n == 2);
        // sd of (0.4, 0.6) is 0.1414; t(0.975, 1) = 12.706: ci = 12.706 * 0.1414 / sqrt(2).
        assert!((s.ci95 - 12.706 * 0.1).abs() < 1e-9, "{s:?}");
        assert!((p[0].fall_rate.unwrap().mean - 0.05).abs() < 1e-12);
        assert_eq!((p[1].scored, p[1].score.unwrap().ci95), (1, 0.0));
    }
}

#[cfg(test)]
mod eval_tests {
    use super::*;
    use crate::spec::PresetGrid;
    use crate::{CellId, SweepId};

    #[test]
    fn a_score_crosses_the_wire_unchanged() {
        let mut g = GaitScore {
            robots: 64,
            ..Default::default()
        };
        for (i, (_, v)) in g.components_mut().into_iter().enumerate() {
            *v = 0.5 + i as f64;
        }
        g.levels = vec![LevelScore {
            level: 3,
            score: g.clone(),
        }];
        let wire = pb::GaitScore::from(&g);
        assert_eq!(GaitScore::from(&wire), g);
    }

    /// Cell 1 of sweep 1 on `terrain`, queued, training to epoch 10.
    fn queued_cell(terrain: &str) -> CellRecord {
        CellRecord {
            id: CellId(1),
            sweep_id: SweepId(1),
            terrain_index: 0,
            terrain: terrain.into(),
            place: Place::point(0, 0),
            w1: 1.0,
            w2: -6.0,
            seed: 1,
            replicate: 0,
            state: CellState::Queued,
            attempts: 0,
            epochs_done: 0,
            target_epochs: 10,
            score: None,
            rung_score: None,
            last_error: None,
        }
    }

    #[test]
    fn a_task_carries_its_cells_evaluation_and_back() {
        let grid = PresetGrid {
            w1: Axis::Values { values: vec![1.0] },
            w2: Axis::Values { values: vec![-6.0] },
            agents_per_cell: 8,
            epochs: 10,
        };
        let spec = SweepSpec::from_toml(
            "robot = \"anymal\"\nterrains = [\"flat\", \"rough\"]\npreset_grid = true\n\
             [eval]\nrobots = 32\nlevels = [2, 4]\nscore = \"bounded\"\nevery = 5\n",
        )
        .unwrap()
        .resolve_with(|_| Ok((grid, None)))
        .unwrap();
        for (terrain, kind, levels) in [
            ("flat", TerrainKind::Flat, vec![0]),
            ("rough", TerrainKind::Rough, vec![2, 4]),
        ] {
            let cell = queued_cell(terrain);
            let task = cell_task(&cell, &spec);
            assert_eq!(task.stop_unrewarded_after, 0, "off unless the spec asks");
            let e = task_eval(&task, kind).unwrap();
            assert_eq!(e, spec.eval_for(terrain));
            assert_eq!((e.robots, e.levels, e.every), (32, levels, 5));
            assert_eq!(e.score, gaitsweep_model::ScoreVariant::Bounded);
        }
        let bad = pb::CellTask {
            score: "eq5".into(),
            ..Default::default()
        };
        assert!(task_eval(&bad, TerrainKind::Flat)
            .unwrap_err()
            .contains("eq5"));
        let stopping = ResolvedSpec {
            stop_unrewarded: Some(0.25),
            ..spec.clone()
        };
        let cell = queued_cell("rough");
        assert_eq!(cell_task(&cell, &stopping).stop_unrewarded_after, 3);
    }
}
