use super::*;

/// A 4 x 7 grid with a smooth score field (best at w1 12, w2 -6) and three noisy
/// replicates per point, evaluated every 10 epochs on the way to 90 (a learning curve
/// that rises towards the final score).
fn synthetic(noise: f64) -> Recording {
    let w1: Vec<f64> = vec![2.0, 5.33, 8.67, 12.0];
    let w2: Vec<f64> = (0..7).map(|k| -10.0 + 4.0 / 3.0 * k as f64).collect();
    let mut rng = StdRng::seed_from_u64(1);
    let mut points = Vec::new();
    for (i, a) in w1.iter().enumerate() {
        for (j, b) in w2.iter().enumerate() {
            let truth = 0.8 - ((a - 12.0) / 10.0).powi(2) - ((b + 6.0) / 6.0).powi(2);
            let runs = (0..3)
                .map(|r| {
                    let score = truth + noise * rng.random_range(-1.0..1.0);
                    let evals = (1..=9)
                        .map(|k| {
                            let e = 10 * k;
                            (
                                e,
                                score * f64::from(e) / 90.0 + noise * rng.random_range(-0.5..0.5),
                            )
                        })
                        .collect();
                    RecordedRun {
                        seed: r,
                        score,
                        evals,
                        gait: None,
                    }
                })
                .collect();
            points.push(RecordedPoint {
                w1_index: i,
                w2_index: j,
                runs,
            });
        }
    }
    Recording {
        source: "synthetic".into(),
        terrain: "flat".into(),
        epochs: 90,
        w1_values: w1,
        w2_values: w2,
        points,
        spec: None,
    }
}

/// Reads and validates a recording kept in the repository, checks its shape (w1 points,
/// w2 points, epochs), grid best and successive-halving rungs from `min_epochs` with
/// `reduction`, and summarises 20 ASHA replays on 4 workers.
fn replay_kept_recording(
    json: &str,
    shape: (usize, usize, u32),
    best_point: (usize, usize),
    best_mean: f64,
    (min_epochs, reduction): (u32, u32),
    rungs: &[u32],
) -> Summary {
    let rec: Recording = serde_json::from_str(json).unwrap();
    rec.validate().unwrap();
    assert_eq!(
        (rec.w1_values.len(), rec.w2_values.len(), rec.epochs),
        shape
    );
    let (best, mean) = rec.best();
    assert_eq!(best, best_point);
    assert!((mean - best_mean).abs() < 1e-3, "{mean}");
    let s = AshaSetup {
        min_epochs,
        reduction,
        workers: 4,
    };
    assert_eq!(asha_rungs(&rec, &s).unwrap(), rungs);
    let runs: Vec<Replay> = (0..20).map(|k| replay_asha(&rec, &s, k).unwrap()).collect();
    summarise(&runs)
}

/// The real recording kept in the repository (BENCHMARKS.md, "Search benchmark")
/// reads, validates and replays: its grid best is the recorded one and halving stays
/// at its rungs' share of the epochs.
#[test]
fn the_recorded_anymal_grid_replays() {
    let sum = replay_kept_recording(
        include_str!("../../tests/data/search-grid-anymal-flat-4x7.json"),
        (4, 7, 180),
        (1, 3),
        0.3316,
        (20, 3),
        &[20, 60, 180],
    );
    assert!(sum.epoch_fraction < 0.4, "{sum:?}");
}

/// The recording at a budget where the policies walk (4 x 4, 90 epochs, evaluations
/// every 10 epochs; BENCHMARKS.md, "Search benchmark") replays at rungs 10 / 30 / 90,
/// its grid best is the recorded one, and halving stays under a third of the epochs.
#[test]
fn the_walking_anymal_grid_replays() {
    let sum = replay_kept_recording(
        include_str!("../../tests/data/search-grid-anymal-flat-4x4-walking.json"),
        (4, 4, 90),
        (3, 3),
        0.7701,
        (10, 3),
        &[10, 30, 90],
    );
    assert!(sum.epoch_fraction < 1.0 / 3.0, "{sum:?}");
}

/// The recording trained to 600 epochs (4 x 4, 2 replicates, evaluations every 50
/// epochs; BENCHMARKS.md, "Search benchmark"): its grid best is the recorded one, and
/// successive halving at rungs 50 / 100 / 200 / 400 / 600 (the real ASHA sweep's) meets
/// issue 10's target on it: under a third of the grid's epochs, within 5% of the best
/// mean in at least 90% of the replays.
#[test]
fn the_600_epoch_anymal_grid_meets_the_halving_target() {
    let sum = replay_kept_recording(
        include_str!("../../tests/data/search-grid-anymal-flat-4x4-600.json"),
        (4, 4, 600),
        (2, 0),
        0.9078,
        (50, 2),
        &[50, 100, 200, 400, 600],
    );
    assert!(sum.epoch_fraction < 1.0 / 3.0, "{sum:?}");
    assert!(sum.p_within_5pct >= 0.9, "{sum:?}");
}

/// The same recording meets issue 10's target for the evolutionary search too with the
/// genetic algorithm over the grid's points (population 8, halving at 100 / 300 / 600
/// inside each generation, a third of the grid's epochs; the real sweep's spec
/// tests/data/search-genetic-anymal-flat-4x4-600.toml): within 5% of the best mean in at
/// least 90% of 200 replays. CMA-ES at the same settings does not (86.5%: its
/// candidates fall between grid points, where the interpolated surface is lower; see
/// BENCHMARKS.md), which this test pins too, so that a change to either shows.
#[test]
fn the_600_epoch_anymal_grid_meets_the_evolutionary_target_with_the_genetic_algorithm() {
    let rec: Recording = serde_json::from_str(include_str!(
        "../../tests/data/search-grid-anymal-flat-4x4-600.json"
    ))
    .unwrap();
    rec.validate().unwrap();
    let setup = |genetic| EvolutionSetup {
        genetic,
        population: 8,
        sigma: 0.5,
        budget_fraction: 1.0 / 3.0,
        halving: Some(AshaSetup {
            min_epochs: 100,
            reduction: 3,
            workers: 4,
        }),
    };
    let replay = |s: &EvolutionSetup| {
        let runs: Vec<Replay> = (0..200)
            .map(|k| replay_evolution(&rec, s, k).unwrap())
            .collect();
        summarise(&runs)
    };
    let ga = replay(&setup(true));
    assert!(ga.epoch_fraction <= 1.0 / 3.0, "{ga:?}");
    assert!(ga.p_within_5pct >= 0.9, "{ga:?}");
    let cmaes = replay(&setup(false));
    assert!(cmaes.p_within_5pct < 0.9, "{cmaes:?}");
}

#[test]
fn a_single_seed_grid_is_only_as_sure_as_its_runs() {
    // Without noise the grid with one run per point always finds the best point.
    let exact = synthetic(0.0);
    let r = replay_grid_single(&exact, 5).unwrap();
    assert!(
        r.found_best && r.regret == 0.0 && r.epoch_fraction == 1.0,
        "{r:?}"
    );
    // Two points, the better one's replicates 1.0 and 0.5, the other's 0.7 and 0.7: the
    // single-seed grid finds the better one only when it draws its 1.0 (half the time).
    let run = |score| RecordedRun {
        seed: 0,
        score,
        evals: BTreeMap::new(),
        gait: None,
    };
    let rec = Recording {
        source: "two points".into(),
        terrain: "flat".into(),
        epochs: 10,
        w1_values: vec![1.0],
        w2_values: vec![1.0, 2.0],
        points: vec![
            RecordedPoint {
                w1_index: 0,
                w2_index: 0,
                runs: vec![run(1.0), run(0.5)],
            },
            RecordedPoint {
                w1_index: 0,
                w2_index: 1,
                runs: vec![run(0.7), run(0.7)],
            },
        ],
        spec: None,
    };
    let sum = summarise(
        &(0..400)
            .map(|k| replay_grid_single(&rec, k).unwrap())
            .collect::<Vec<_>>(),
    );
    assert!((sum.p_best - 0.5).abs() < 0.1, "{sum:?}");
}

#[test]
fn asha_spends_less_than_the_grid_and_finds_a_good_point() {
    let rec = synthetic(0.02);
    rec.validate().unwrap();
    let s = AshaSetup {
        min_epochs: 10,
        reduction: 3,
        workers: 4,
    };
    assert_eq!(asha_rungs(&rec, &s).unwrap(), vec![10, 30, 90]);
    let runs: Vec<Replay> = (0..50).map(|k| replay_asha(&rec, &s, k).unwrap()).collect();
    let sum = summarise(&runs);
    assert!(sum.epoch_fraction < 0.5, "{sum:?}");
    assert!(sum.p_within_5pct > 0.8, "{sum:?}");
    // A replay is a function of its seed.
    assert_eq!(replay_asha(&rec, &s, 3).unwrap(), runs[3]);
}

#[test]
fn cmaes_uses_its_budget_and_closes_in() {
    let rec = synthetic(0.02);
    // A third of a 4 x 7 grid pays for one generation of six: the budget is respected.
    let third = EvolutionSetup {
        genetic: false,
        population: 6,
        sigma: 0.3,
        budget_fraction: 1.0 / 3.0,
        halving: None,
    };
    let r = replay_evolution(&rec, &third, 0).unwrap();
    assert!((r.epoch_fraction - 6.0 / 28.0).abs() < 1e-9, "{r:?}");
    // The grid's budget in generations of four: the search closes in on the best.
    let full = EvolutionSetup {
        genetic: false,
        population: 4,
        sigma: 0.3,
        budget_fraction: 1.0,
        halving: None,
    };
    let runs: Vec<Replay> = (0..30)
        .map(|k| replay_evolution(&rec, &full, k).unwrap())
        .collect();
    let sum = summarise(&runs);
    assert!(sum.epoch_fraction <= 1.0 + 1e-9, "{sum:?}");
    assert!(sum.p_within_5pct > 0.5 && sum.mean_regret < 0.05, "{sum:?}");
    // Successive halving inside generations buys more generations from a third.
    let halved = EvolutionSetup {
        genetic: false,
        population: 6,
        sigma: 0.3,
        budget_fraction: 1.0 / 3.0,
        halving: Some(AshaSetup {
            min_epochs: 10,
            reduction: 3,
            workers: 4,
        }),
    };
    let runs: Vec<Replay> = (0..30)
        .map(|k| replay_evolution(&rec, &halved, k).unwrap())
        .collect();
    let sum = summarise(&runs);
    // 6x10 + 2x20 + 1x60 = 160 epochs a generation: 5 of them in 840.
    assert!(
        (sum.epoch_fraction - 5.0 * 160.0 / 2520.0).abs() < 1e-9,
        "{sum:?}"
    );
}

#[test]
fn interpolation_hits_grid_points_and_rungs_need_evaluations() {
    let rec = synthetic(0.0);
    let (p, best) = rec.best();
    let at = rec.interpolate(12.0, rec.w2_values[p.1], &mut |i, j| rec.mean(i, j));
    assert!((at - best).abs() < 1e-12);
    let mid = rec.interpolate(10.335, rec.w2_values[p.1], &mut |i, j| rec.mean(i, j));
    assert!((mid - (rec.mean(2, p.1) + rec.mean(3, p.1)) / 2.0).abs() < 1e-9);
    let bad = AshaSetup {
        min_epochs: 15,
        reduction: 3,
        workers: 2,
    };
    assert!(asha_rungs(&rec, &bad).unwrap_err().contains("epoch 15"));
    let mut holes = rec.clone();
    holes.points.pop();
    assert!(holes.validate().unwrap_err().contains("no scored run"));
}

#[test]
fn random_search_spends_its_share_and_finds_the_best_as_often_as_it_draws_it() {
    let rec = synthetic(0.0);
    let n = rec.w1_values.len() * rec.w2_values.len();
    // Every point drawn: the single-run grid's answer, at the grid's cost.
    let all = replay_random(&rec, n, 3).unwrap();
    assert_eq!(all.epoch_fraction, 1.0);
    assert!(all.found_best && all.regret.abs() < 1e-12);
    // One point: its share of the epochs, and the best only when it is drawn (1 in n).
    let one: Vec<Replay> = (0..2000)
        .map(|k| replay_random(&rec, 1, k).unwrap())
        .collect();
    let s = summarise(&one);
    assert!((s.epoch_fraction - 1.0 / n as f64).abs() < 1e-12);
    assert!((s.p_best - 1.0 / n as f64).abs() < 0.03, "{s:?}");
    assert!(replay_random(&rec, 0, 1).is_err() && replay_random(&rec, n + 1, 1).is_err());
}

/// The study recordings kept in `tests/data/` (`scripts/study-docs.sh`, issue 39) each sit
/// beside the spec they were recorded with, and are that spec's full grid on one of its
/// terrains: the spec beside it resolves to the spec the coordinator stored when the sweep
/// was created (carried in the export), as the study's own (`studies/ROBOT.toml`) does, and
/// the recording's axes, budget, terrain and sweep name are that spec's.
#[test]
fn the_kept_study_recordings_are_their_specs_grids() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data");
    let mut seen = 0;
    for entry in std::fs::read_dir(&data).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let Some(stem) = name
            .strip_prefix("study-")
            .and_then(|n| n.strip_suffix(".json"))
        else {
            continue;
        };
        let (robot, terrain) = stem.rsplit_once('-').expect("study-ROBOT-TERRAIN.json");
        let spec_path = data.join(format!("study-{robot}.toml"));
        let spec_text = std::fs::read_to_string(&spec_path)
            .unwrap_or_else(|e| panic!("{name} has no spec beside it ({spec_path:?}): {e}"));
        let resolve = |text: &str| {
            crate::presets::resolve(&gaitsweep_core::SweepSpec::from_toml(text).unwrap()).unwrap()
        };
        let r = resolve(&spec_text);
        let rec: Recording =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let stored = rec.spec.as_ref().unwrap_or_else(|| {
            panic!("{name} carries no stored spec: run scripts/study-docs.sh {robot}")
        });
        assert_eq!(
            &r, stored,
            "{spec_path:?} is not the spec {name} was recorded with"
        );
        let study = data.join(format!("../../studies/{robot}.toml"));
        assert_eq!(
            &resolve(&std::fs::read_to_string(&study).unwrap()),
            stored,
            "{study:?} no longer resolves to the spec its recording ran with: record again, or keep a new study under a new name"
        );
        rec.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(rec.terrain, terrain, "{name}");
        assert!(
            r.terrains.iter().any(|t| t.to_string() == terrain),
            "{name}: {:?}",
            r.terrains
        );
        assert_eq!(rec.epochs, r.epochs, "{name}");
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
        };
        assert!(
            close(&rec.w1_values, &r.w1_values),
            "{name}: {:?}",
            rec.w1_values
        );
        assert!(
            close(&rec.w2_values, &r.w2_values),
            "{name}: {:?}",
            rec.w2_values
        );
        assert!(
            rec.source.contains(&format!("\"{}\"", r.name)),
            "{name}: {}",
            rec.source
        );
        assert!(
            rec.points
                .iter()
                .flat_map(|p| &p.runs)
                .all(|run| run.score.is_finite()),
            "{name}: a run without a finite score"
        );
        // Each run says how it walked at every level the spec evaluates.
        let levels: Vec<u32> = r
            .eval_levels_for(terrain)
            .into_iter()
            .map(u32::from)
            .collect();
        for run in rec.points.iter().flat_map(|p| &p.runs) {
            let gait = run.gait.as_ref().unwrap_or_else(|| {
                panic!("{name}: a run without its gait: run scripts/study-docs.sh {robot}")
            });
            assert_eq!(
                gait.levels.iter().map(|l| l.level).collect::<Vec<_>>(),
                levels,
                "{name}"
            );
            assert!((0.0..=1.0).contains(&gait.fall_rate), "{name}");
        }
        seen += 1;
    }
    assert!(seen >= 1, "no study recording in {data:?}");
}
