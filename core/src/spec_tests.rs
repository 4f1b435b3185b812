//! Tests of the sweep spec: validation, defaults and grid expansion.

use super::*;

fn grid() -> PresetGrid {
    PresetGrid {
        w1: Axis::Range {
            min: 2.0,
            max: 12.0,
            count: 4,
        },
        w2: Axis::Range {
            min: -10.0,
            max: -2.0,
            count: 7,
        },
        agents_per_cell: 146,
        epochs: 3000,
    }
}

fn ok(_: &str) -> std::result::Result<(PresetGrid, Option<String>), String> {
    Ok((grid(), None))
}

#[test]
fn asha_rungs_grow_by_the_reduction_up_to_the_budget() {
    let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
    let r = SweepSpec::from_toml(&format!(
        "{base}eval = {{ every = 50 }}\n[search]\nmethod = \"asha\"\nmin_epochs = 100\nreduction = 3\n"
    ))
    .unwrap()
    .resolve_with(ok)
    .unwrap();
    assert_eq!(
        r.search,
        Search::Asha {
            min_epochs: 100,
            reduction: 3
        }
    );
    assert_eq!(r.rungs(), vec![100, 300, 900, 2700, 3000]);
    assert_eq!(r.eval.every, 50);
    // Defaults: reduction 3, first rung at epochs / 27.
    let d = SweepSpec::from_toml(&format!("{base}[search]\nmethod = \"asha\"\n"))
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(d.rungs(), vec![111, 333, 999, 2997, 3000]);
    // A grid has one rung, the end; a stored spec without `search` reads as a grid.
    let g = SweepSpec::from_toml(base)
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!((g.search, g.rungs()), (Search::Grid, vec![3000]));
    let mut json = serde_json::to_value(&g).unwrap();
    json.as_object_mut().unwrap().remove("search");
    json.as_object_mut().unwrap().remove("eval_every");
    let old: ResolvedSpec = serde_json::from_value(json).unwrap();
    assert_eq!((old.search, old.eval.every), (Search::Grid, 0));
    // The wire form round-trips.
    let wire = crate::pb::SweepSpec::from(&r);
    let back = SweepSpec::from(wire).resolve_with(ok).unwrap();
    assert_eq!((back.search, back.eval.every), (r.search, 50));
}

#[test]
fn bad_searches_are_named() {
    let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
    let err = |extra: &str| {
        SweepSpec::from_toml(&format!("{base}{extra}"))
            .unwrap()
            .resolve_with(ok)
            .unwrap_err()
            .to_string()
    };
    assert!(err("[search]\nmethod = \"bayes\"\n").contains("search.method \"bayes\" is unknown"));
    assert!(err("[search]\nmethod = \"asha\"\nreduction = 1\n").contains("search.reduction is 1"));
    assert!(err("[search]\nmethod = \"asha\"\nmin_epochs = 3000\n")
        .contains("search.min_epochs is 3000"));
    assert!(err("seeds = 2\n[search]\nmethod = \"asha\"\n").contains("use seeds = 1"));
    assert!(err("[search]\nmethod = \"grid\"\nreduction = 3\n").contains("belong to method"));
}

#[test]
fn cmaes_searches_inside_the_axes_with_a_budget_of_generations() {
    // The preset's Table-1 grid: 4 x 7 cells x 3000 epochs = 84,000 epochs.
    let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
    let parse = |extra: &str| {
        SweepSpec::from_toml(&format!("{base}{extra}"))
            .unwrap()
            .resolve_with(ok)
    };
    let d = parse("[search]\nmethod = \"cmaes\"\n").unwrap();
    // Default budget: a third of the grid's epochs, 28,000 = 1.5 generations of 6 x 3000.
    assert_eq!(
        d.search,
        Search::Cmaes {
            population: DEFAULT_POPULATION,
            sigma: DEFAULT_SIGMA,
            generations: 1,
            min_epochs: 0,
            reduction: 0
        }
    );
    let r = parse("seeds = 2\n[search]\nmethod = \"cmaes\"\npopulation = 4\nsigma = 0.2\nbudget_epochs = 72000\n")
        .unwrap();
    assert_eq!(
        r.search,
        Search::Cmaes {
            population: 4,
            sigma: 0.2,
            generations: 3,
            min_epochs: 0,
            reduction: 0
        }
    );
    let (lo, hi) = r.bounds();
    assert_eq!((lo[0], hi[0]), (2.0, 12.0));
    let cells = r.candidate_cells(2, &[[3.0, -5.0], [4.0, -6.0]]);
    assert_eq!(cells.len(), 4, "two candidates x two replicates");
    assert_eq!(
        (cells[3].place, cells[3].replicate),
        (crate::Place::candidate(2, 1), 1)
    );
    assert_eq!((cells[3].w1, cells[3].w2), (4.0, -6.0));
    let seeds: std::collections::BTreeSet<u64> = cells.iter().map(|c| c.seed).collect();
    assert_eq!(seeds.len(), 4);
    // The wire form round-trips.
    let back = SweepSpec::from(crate::pb::SweepSpec::from(&r))
        .resolve_with(ok)
        .unwrap();
    assert_eq!(back.search, r.search);

    let err = |extra: &str| parse(extra).unwrap_err().to_string();
    assert!(err("[search]\nmethod = \"cmaes\"\nbudget_epochs = 100\n")
        .contains("one generation of 6 candidates x 1 replicates needs 18000 epochs"));
    // Successive halving inside each generation: rungs 100, 300, 900, 2700, 3000; a
    // generation of 6 costs 6x100 + 2x200 + 1x600 + 1x1800 + 1x300 = 3700 epochs.
    let h =
        parse("[search]\nmethod = \"cmaes\"\nmin_epochs = 100\nbudget_epochs = 28000\n").unwrap();
    assert_eq!(h.rungs(), vec![100, 300, 900, 2700, 3000]);
    assert_eq!(halving_cost(6, &h.rungs(), 3), 3700);
    assert_eq!(
        h.search,
        Search::Cmaes {
            population: 6,
            sigma: DEFAULT_SIGMA,
            generations: 7,
            min_epochs: 100,
            reduction: 3
        }
    );
    assert_eq!(h.budget_epochs(), Some(25900));
    let back = SweepSpec::from(crate::pb::SweepSpec::from(&h))
        .resolve_with(ok)
        .unwrap();
    assert_eq!(back.search, h.search);
    assert!(
        err("seeds = 2\n[search]\nmethod = \"cmaes\"\nmin_epochs = 100\n")
            .contains("use seeds = 1")
    );
    assert!(
        err("[search]\nmethod = \"cmaes\"\npopulation = 1\n").contains("search.population is 1")
    );
    assert!(err("[search]\nmethod = \"cmaes\"\nsigma = 0\n").contains("search.sigma is 0"));
    assert!(
        err("w2 = { values = [-6.0] }\n[search]\nmethod = \"cmaes\"\n")
            .contains("give w1 and w2 a range")
    );
    let two = SweepSpec::from_toml(
        "robot = \"anymal\"\nterrains = [\"flat\", \"rough\"]\npreset_grid = true\n[search]\nmethod = \"cmaes\"\n",
    )
    .unwrap()
    .resolve_with(ok)
    .unwrap_err()
    .to_string();
    assert!(two.contains("searches one terrain"), "{two}");
    assert!(err("[search]\nmethod = \"asha\"\npopulation = 6\n")
        .contains("belongs to method = \"cmaes\""));
    assert!(err("[search]\nmethod = \"grid\"\nmin_epochs = 6\n")
        .contains("belong to method = \"asha\", \"cmaes\" or \"genetic\""));
}

/// The specs of the real search sweeps kept beside their recording resolve to the
/// searches BENCHMARKS.md reports them with.
#[test]
fn the_kept_search_specs_resolve() {
    let resolve = |text: &str| {
        SweepSpec::from_toml(text)
            .unwrap()
            .resolve_with(ok)
            .unwrap()
    };
    let asha = resolve(include_str!(
        "../../tests/data/search-asha-anymal-flat-4x4-600.toml"
    ));
    assert_eq!(asha.rungs(), vec![50, 100, 200, 400, 600]);
    let cmaes = resolve(include_str!(
        "../../tests/data/search-cmaes-anymal-flat-4x4-600.toml"
    ));
    assert_eq!(
        (
            cmaes.search.method(),
            cmaes.search.generations(),
            cmaes.rungs()
        ),
        ("cmaes", Some((8, 2)), vec![100, 300, 600])
    );
    let genetic = resolve(include_str!(
        "../../tests/data/search-genetic-anymal-flat-4x4-600.toml"
    ));
    assert_eq!(
        (
            genetic.search.method(),
            genetic.search.generations(),
            genetic.rungs()
        ),
        ("genetic", Some((8, 2)), vec![100, 300, 600])
    );
    assert_eq!(genetic.budget_epochs(), Some(3000));
}

#[test]
fn genetic_breeds_grid_points_with_a_budget_no_larger_than_the_grid() {
    // The 600-epoch recording's 4 x 4 grid (9,600 epochs): halving at 100 / 300 / 600
    // costs 8x100 + 2x200 + 1x300 = 1500 epochs a generation of 8, so 3200 epochs pay
    // for 2 generations; the 16 points are spent after 2 as well.
    let base = "robot = \"anymal\"\nterrains = [\"flat\"]\nepochs = 600\nagents_per_cell = 64\n\
                w1 = { min = 2.0, max = 12.0, count = 4 }\nw2 = { min = -10.0, max = -2.0, count = 4 }\n";
    let parse = |extra: &str| {
        SweepSpec::from_toml(&format!("{base}{extra}"))
            .unwrap()
            .resolve_with(ok)
    };
    let g = parse("[search]\nmethod = \"genetic\"\npopulation = 8\nmin_epochs = 100\nreduction = 3\nbudget_epochs = 3200\n")
        .unwrap();
    let want = Search::Genetic {
        population: 8,
        generations: 2,
        min_epochs: 100,
        reduction: 3,
    };
    assert_eq!(g.search, want);
    assert_eq!(g.rungs(), vec![100, 300, 600]);
    assert_eq!(g.budget_epochs(), Some(3000));
    assert_eq!(
        (g.search.method(), g.search.generations()),
        ("genetic", Some((8, 2)))
    );
    let back = SweepSpec::from(crate::pb::SweepSpec::from(&g))
        .resolve_with(ok)
        .unwrap();
    assert_eq!(back.search, g.search);
    // A budget the size of the grid still stops when every point is trained: 16 points
    // in generations of 6 are 3 generations.
    let big = parse("[search]\nmethod = \"genetic\"\nbudget_epochs = 1000000\n").unwrap();
    assert_eq!(big.search.generations(), Some((DEFAULT_POPULATION, 3)));

    let err = |extra: &str| parse(extra).unwrap_err().to_string();
    assert!(err("[search]\nmethod = \"genetic\"\npopulation = 20\n")
        .contains("search.population is 20 but the grid has 16 points"));
    assert!(err("[search]\nmethod = \"genetic\"\nsigma = 0.3\n")
        .contains("search.sigma belongs to method = \"cmaes\""));
    assert!(
        err("seeds = 2\n[search]\nmethod = \"genetic\"\nmin_epochs = 100\n")
            .contains("use seeds = 1")
    );
    let one = SweepSpec::from_toml(
        "robot = \"anymal\"\nagents_per_cell = 64\nepochs = 600\nw1 = { values = [3.0] }\nw2 = { values = [-6.0] }\n[search]\nmethod = \"genetic\"\n",
    )
    .unwrap()
    .resolve_with(ok)
    .unwrap_err()
    .to_string();
    assert!(one.contains("at least 2 points"), "{one}");
    assert!(err("[search]\nmethod = \"evolve\"\n").contains("\"genetic\""));
}

#[test]
fn preset_grid_is_one_flag_away() {
    let spec =
        SweepSpec::from_toml("robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n")
            .unwrap();
    let r = spec.resolve_with(ok).unwrap();
    assert_eq!(r.cell_count(), 28);
    assert_eq!(r.agents_per_cell, 146);
    assert!((r.w1_values[1] - 5.3333).abs() < 1e-3);
}

#[test]
fn explicit_lists_and_ranges() {
    let text = r#"
        robot = "anymal"
        terrains = ["flat", "rough"]
        w1 = { min = 2.0, max = 4.0, count = 2 }
        w2 = { values = [-6.0, -4.0, -2.0] }
        agents_per_cell = 4
        epochs = 2
        checkpoint_every = 1
        seed = 9
        ppo = { learning_rate = 0.0005 }
        eval = { robots = 2, seconds = 2.0 }
    "#;
    let r = SweepSpec::from_toml(text)
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    let cells = r.cells();
    assert_eq!(cells.len(), 12);
    assert_eq!(cells[3].w2, -6.0);
    assert_eq!(cells[3].w1, 4.0);
    assert_eq!(cells[6].terrain_index, 1);
    let seeds: std::collections::BTreeSet<u64> = cells.iter().map(|c| c.seed).collect();
    assert_eq!(seeds.len(), 12);
}

#[test]
fn a_score_covers_the_evaluation_levels_the_spec_resolves() {
    let base =
        "robot = \"anymal\"\nterrains = [\"flat\", \"rough\", \"stairs\"]\nagents_per_cell = 4\n\
                epochs = 10\nw1 = { values = [2.0] }\nw2 = { values = [-6.0] }\n";
    let r = SweepSpec::from_toml(base)
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(r.eval.levels, crate::defaults::EVAL_LEVELS);
    assert_eq!(r.eval_levels_for("flat"), [0]);
    assert_eq!(r.eval_levels_for("stairs"), [0, 3, 5, 7]);
    assert_eq!(r.eval.score, ScoreVariant::Eq4);
    let given = format!("{base}eval = {{ levels = [2, 6], score = \"bounded\" }}\n");
    let r = SweepSpec::from_toml(&given)
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(
        (r.eval_levels_for("rough"), r.eval.score),
        (vec![2, 6], ScoreVariant::Bounded)
    );
    let fixed = format!("difficulty = 4\n{base}");
    let r = SweepSpec::from_toml(&fixed)
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(r.eval_levels_for("rough"), [4]);
    // The task a worker gets carries the levels of its cell's terrain and the variant.
    let json = serde_json::to_value(&r).unwrap();
    let back: ResolvedSpec = serde_json::from_value(json.clone()).unwrap();
    assert_eq!(back, r);
    // A spec stored before per-level evaluation keeps its one level.
    let mut old = json;
    old.as_object_mut().unwrap().remove("eval_levels");
    old.as_object_mut().unwrap().remove("score");
    old["difficulty"] = serde_json::Value::Null;
    let old: ResolvedSpec = serde_json::from_value(old).unwrap();
    assert_eq!(old.eval_levels_for("rough"), [LEGACY_EVAL_LEVEL]);
    assert_eq!(old.eval.score, ScoreVariant::Eq4);
    let bad = format!("{base}eval = {{ levels = [3, 12, 3], score = \"fast\" }}\n");
    let Err(Error::InvalidSpec(p)) = SweepSpec::from_toml(&bad).unwrap().resolve_with(ok) else {
        panic!("accepted {bad}")
    };
    let all = p.join("\n");
    for needle in [
        "eval.levels has 12",
        "lists a level twice",
        "eval.score \"fast\"",
    ] {
        assert!(all.contains(needle), "{needle} not in {all}");
    }
}

#[test]
fn every_problem_is_listed() {
    let text = "robot = \"\"\nterrains = [\"lava\", \"flat\", \"flat\"]\ndifficulty = 12\nagents_per_cell = 0\nepochs = 0\nw1 = { values = [] }\n";
    let err = SweepSpec::from_toml(text)
        .unwrap()
        .resolve_with(ok)
        .unwrap_err();
    let Error::InvalidSpec(p) = err else {
        panic!("wrong error {err}")
    };
    let all = p.join("\n");
    for needle in [
        "robot is empty",
        "lava",
        "listed twice",
        "difficulty",
        "agents_per_cell is 0",
        "epochs is 0",
        "w1.values is empty",
        "w2 is missing",
    ] {
        assert!(all.contains(needle), "{needle} not in {all}");
    }
}

/// Fault-injection findings: a huge count ran the coordinator out of memory, and a
/// negative w1 or a descending range were accepted without comment.
#[test]
fn huge_counts_descending_ranges_and_negative_w1_are_refused() {
    let text = "robot = \"anymal\"\nterrains = [\"flat\"]\nagents_per_cell = 1\nepochs = 1\n\
                w1 = { min = -1.0, max = 2.0, count = 2 }\n\
                w2 = { min = -2.0, max = -6.0, count = 1000000000000 }\n";
    let err = SweepSpec::from_toml(text)
        .unwrap()
        .resolve_with(ok)
        .unwrap_err();
    let all = err.to_string();
    for needle in [
        "w2.count is 1000000000000",
        "w2 runs from min -2 down to max -6",
        "w1 -1 is negative",
    ] {
        assert!(all.contains(needle), "{needle} not in {all}");
    }
}

/// Every default is decided when the spec is resolved: nothing reaches a worker as 0.
#[test]
fn defaults_are_decided_at_resolution() {
    let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
    let r = SweepSpec::from_toml(base)
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(r.checkpoint_every, crate::defaults::CHECKPOINT_EVERY);
    assert_eq!(r.eval.robots, crate::defaults::EVAL_ROBOTS);
    assert_eq!(r.eval.seconds, crate::defaults::EVAL_SECONDS);
    let only_final = SweepSpec::from_toml(&format!("{base}checkpoint_every = 0\n"))
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(
        only_final.checkpoint_every, 3000,
        "only the final checkpoint"
    );
    let mut old = r.clone();
    (old.checkpoint_every, old.eval.robots, old.eval.seconds) = (0, 0, 0.0);
    let old = old.with_defaults();
    assert_eq!(
        (old.checkpoint_every, old.eval.robots, old.eval.seconds),
        (
            3000,
            crate::defaults::EVAL_ROBOTS,
            crate::defaults::EVAL_SECONDS
        )
    );
}

#[test]
fn unknown_keys_are_rejected() {
    assert!(matches!(
        SweepSpec::from_toml("robot = \"anymal\"\nbogus = 1\n"),
        Err(Error::SpecToml(_))
    ));
}

proptest::proptest! {
    #[test]
    fn grid_expansion_covers_every_pair(n1 in 1usize..6, n2 in 1usize..6, nt in 1usize..3) {
        let terrains = ["flat", "rough"][..nt].iter().map(|s| s.to_string()).collect();
        let spec = SweepSpec {
            robot: "anymal".into(), terrains,
            w1: Some(Axis::Range { min: 0.0, max: 1.0, count: n1 }),
            w2: Some(Axis::Range { min: -3.0, max: -1.0, count: n2 }),
            agents_per_cell: Some(1), epochs: Some(1), ..Default::default()
        };
        let r = spec.resolve_with(ok).unwrap();
        let cells = r.cells();
        proptest::prop_assert_eq!(cells.len(), n1 * n2 * nt);
        let pairs: std::collections::BTreeSet<(usize, crate::Place)> =
            cells.iter().map(|c| (c.terrain_index, c.place)).collect();
        proptest::prop_assert_eq!(pairs.len(), cells.len());
        proptest::prop_assert_eq!(cells[0].w1, 0.0);
        proptest::prop_assert_eq!(cells.last().unwrap().w2, if n2 == 1 { -3.0 } else { -1.0 });
    }
}

#[test]
fn successive_halving_leases_its_grid_in_a_seeded_random_order() {
    let text = "robot = \"anymal\"\nterrains = [\"flat\"]\nw1 = { min = 2.0, max = 12.0, count = 4 }\nw2 = { min = -10.0, max = -2.0, count = 4 }\nagents_per_cell = 2\nepochs = 90\nseed = 1\n";
    let resolve = |t: &str| {
        SweepSpec::from_toml(t)
            .unwrap()
            .resolve_with(|_| Ok((grid(), None)))
            .unwrap()
    };
    let plain = resolve(text);
    assert_eq!(plain.cells_in_lease_order(), plain.cells());
    let asha = resolve(&format!(
        "{text}[search]\nmethod = \"asha\"\nmin_epochs = 10\n"
    ));
    let (grid_order, lease) = (asha.cells(), asha.cells_in_lease_order());
    assert_ne!(lease, grid_order, "a 4 x 4 grid is not leased row by row");
    // The same cells with the same seeds, only in another order, and the same order on
    // every call.
    let mut sorted = lease.clone();
    sorted.sort_by_key(|c| c.place);
    assert_eq!(sorted, grid_order);
    assert_eq!(asha.cells_in_lease_order(), lease);
    // The first four leased are not all of one row.
    let rows: std::collections::BTreeSet<u32> =
        lease[..4].iter().map(|c| c.place.pair().0).collect();
    assert!(rows.len() > 1, "{rows:?}");
}

#[test]
fn replicates_multiply_the_cells_and_keep_replicate_zero_seeds() {
    let text = "robot = \"anymal\"\nterrains = [\"flat\"]\nw1 = { values = [2.0, 8.0] }\nw2 = { values = [-6.0] }\nagents_per_cell = 2\nepochs = 3\nseed = 5\n";
    let one = SweepSpec::from_toml(text)
        .unwrap()
        .resolve_with(|_| Ok((grid(), None)))
        .unwrap();
    let three = SweepSpec::from_toml(&format!("{text}seeds = 3\n"))
        .unwrap()
        .resolve_with(|_| Ok((grid(), None)))
        .unwrap();
    assert_eq!((one.replicates, three.replicates), (1, 3));
    let (a, b) = (one.cells(), three.cells());
    assert_eq!(
        (a.len(), b.len(), three.cell_count(), three.point_count()),
        (2, 6, 6, 2)
    );
    for p in &a {
        let r0 = b
            .iter()
            .find(|c| c.place == p.place && c.replicate == 0)
            .unwrap();
        assert_eq!(
            r0.seed, p.seed,
            "replicate 0 trains as the cell did without replicates"
        );
    }
    let seeds: std::collections::BTreeSet<u64> = b.iter().map(|c| c.seed).collect();
    assert_eq!(seeds.len(), 6);
    for bad in ["seeds = 0", "seeds = 33"] {
        let e = SweepSpec::from_toml(&format!("{text}{bad}\n"))
            .unwrap()
            .resolve_with(|_| Ok((grid(), None)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("replicates per grid point"), "{e}");
    }
    // A spec stored before replicates existed reads as one replicate.
    let mut json = serde_json::to_value(&one).unwrap();
    json.as_object_mut().unwrap().remove("replicates");
    let old: ResolvedSpec = serde_json::from_value(json).unwrap();
    assert_eq!(old.replicates, 1);
}

#[test]
fn random_search_draws_a_budgets_worth_of_grid_points() {
    // The preset's Table-1 grid: 4 x 7 points x 3000 epochs.
    let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
    let parse = |extra: &str| {
        SweepSpec::from_toml(&format!("{base}{extra}"))
            .unwrap()
            .resolve_with(ok)
    };
    // Default budget: a third of the grid's epochs, 9 of its 28 points.
    let d = parse("[search]\nmethod = \"random\"\n").unwrap();
    assert_eq!(d.search, Search::Random { points: 9 });
    assert_eq!(d.budget_epochs(), Some(9 * 3000));
    let r = parse("[search]\nmethod = \"random\"\nbudget_epochs = 14999\n").unwrap();
    assert_eq!(r.search, Search::Random { points: 4 });
    // The wire form round-trips, and resolves to itself without the robot's preset.
    let wire = crate::pb::SweepSpec::from(&r);
    assert!(matches!(
        wire.search.as_ref().and_then(|s| s.method.as_ref()),
        Some(crate::pb::search::Method::Random(crate::pb::RandomSearch {
            budget_epochs: 12000
        }))
    ));
    assert_eq!(crate::convert::search_method(&wire), "random");
    let back = crate::convert::resolved_from_wire(wire).unwrap();
    assert_eq!(back.search, r.search);
    assert_eq!(back, r);
    // A budget outside 1 to 28 points, and settings of other methods, are named.
    let err = |extra: &str| parse(extra).unwrap_err().to_string();
    assert!(err("[search]\nmethod = \"random\"\nbudget_epochs = 2999\n")
        .contains("use 3000 to 84000 for 1 to 28 points"));
    assert!(
        err("[search]\nmethod = \"random\"\nbudget_epochs = 90000\n")
            .contains("search.budget_epochs is 90000")
    );
    assert!(err("[search]\nmethod = \"random\"\npopulation = 4\n")
        .contains("search.population belongs to method"));
    assert!(err("[search]\nmethod = \"random\"\nreduction = 3\n").contains("belong to method"));
    assert!(err("[search]\nmethod = \"grid\"\nbudget_epochs = 3000\n")
        .contains("search.budget_epochs belongs to method"));
}

#[test]
fn every_search_method_crosses_the_wire_as_its_own_variant_and_comes_back() {
    let base = "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\n";
    for (search, method) in [
        ("", "grid"),
        ("[search]\nmethod = \"asha\"\nmin_epochs = 100\nreduction = 4\n", "asha"),
        ("[search]\nmethod = \"cmaes\"\npopulation = 4\nsigma = 0.2\nbudget_epochs = 24000\n", "cmaes"),
        ("[search]\nmethod = \"cmaes\"\nbudget_epochs = 36000\nmin_epochs = 300\nreduction = 3\n", "cmaes"),
        ("[search]\nmethod = \"genetic\"\npopulation = 4\nbudget_epochs = 24000\n", "genetic"),
        ("[search]\nmethod = \"random\"\nbudget_epochs = 9000\n", "random"),
    ] {
        let r = SweepSpec::from_toml(&format!("{base}{search}"))
            .unwrap()
            .resolve_with(ok)
            .unwrap();
        assert_eq!(r.search.method(), method);
        let wire = crate::pb::SweepSpec::from(&r);
        assert_eq!(crate::convert::search_method(&wire), method, "{search}");
        // The structured form a gRPC client sends resolves like the TOML it came from.
        let back = crate::convert::resolved_from_wire(wire).unwrap();
        assert_eq!(back.search, r.search, "{search}");
    }
    // A structured spec without a search is a grid.
    let mut wire = crate::pb::SweepSpec::from(
        &SweepSpec::from_toml(base)
            .unwrap()
            .resolve_with(ok)
            .unwrap(),
    );
    wire.search = None;
    assert_eq!(
        crate::convert::resolved_from_wire(wire).unwrap().search,
        Search::Grid
    );
}

#[test]
fn stop_unrewarded_resolves_to_an_epoch_crosses_the_wire_and_refuses_nonsense() {
    let base = "robot = \"anymal\"\nterrains = [\"rough\"]\npreset_grid = true\nepochs = 1200\n";
    let r = SweepSpec::from_toml(&format!("{base}stop_unrewarded = 0.1\n"))
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(r.stop_unrewarded, Some(0.1));
    assert_eq!(r.stop_unrewarded_after(), 120);
    let back = crate::convert::resolved_from_wire(crate::pb::SweepSpec::from(&r)).unwrap();
    assert_eq!(back.stop_unrewarded_after(), 120);
    // Rounded up, and never 0 (which would mean "off").
    let tiny = SweepSpec::from_toml(
        "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\nepochs = 7\nstop_unrewarded = 0.01\n",
    )
    .unwrap()
    .resolve_with(ok)
    .unwrap();
    assert_eq!(tiny.stop_unrewarded_after(), 1);
    // Rounded up from the exact fraction, not from the float product's last bit.
    let r7 = ResolvedSpec {
        epochs: 100,
        stop_unrewarded: Some(0.07),
        ..tiny.clone()
    };
    assert_eq!(r7.stop_unrewarded_after(), 7);

    // Off by default, and a spec stored without it reads (and is stored) as before.
    let off = SweepSpec::from_toml(base)
        .unwrap()
        .resolve_with(ok)
        .unwrap();
    assert_eq!(off.stop_unrewarded_after(), 0);
    let json = serde_json::to_string(&off).unwrap();
    assert!(!json.contains("stop_unrewarded"), "{json}");
    assert_eq!(crate::pb::SweepSpec::from(&off).stop_unrewarded, 0.0);

    let err = |extra: &str| {
        SweepSpec::from_toml(&format!("{base}{extra}"))
            .unwrap()
            .resolve_with(ok)
            .unwrap_err()
            .to_string()
    };
    for bad in ["0.0", "1.0", "-0.5", "nan"] {
        assert!(
            err(&format!("stop_unrewarded = {bad}\n")).contains("between 0 and 1"),
            "{bad}"
        );
    }
    assert!(err(
        "stop_unrewarded = 0.1\n[search]\nmethod = \"asha\"\nmin_epochs = 100\nreduction = 3\n"
    )
    .contains("successive halving"));
}
