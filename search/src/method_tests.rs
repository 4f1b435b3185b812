use super::*;
use gaitsweep_core::spec::PresetGrid;
use gaitsweep_core::Axis;
use gaitsweep_core::SweepSpec;

/// The paper's ANYmal rectangle at 4 x `w2` points, 8 robots x 90 epochs.
fn grid(w2: usize) -> PresetGrid {
    PresetGrid {
        w1: Axis::Range {
            min: 2.0,
            max: 12.0,
            count: 4,
        },
        w2: Axis::Range {
            min: -10.0,
            max: -2.0,
            count: w2,
        },
        agents_per_cell: 8,
        epochs: 90,
    }
}

fn spec(extra: &str) -> ResolvedSpec {
    SweepSpec::from_toml(&format!(
        "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\nseed = 7\n{extra}"
    ))
    .unwrap()
    .resolve_with(|_| Ok((grid(4), None)))
    .unwrap()
}

fn view(
    id: i64,
    place: gaitsweep_core::Place,
    state: CellState,
    score: Option<f64>,
    rungs: &[(u32, f64)],
) -> CellView {
    CellView {
        id: CellId(id),
        place,
        state,
        score,
        rungs: rungs.iter().copied().collect(),
    }
}

#[test]
fn a_grid_starts_whole_and_never_acts() {
    let s = spec("");
    let m = method_for(&s);
    assert_eq!(m.name(), "grid");
    assert_eq!(m.initial_cells(&s).unwrap().len(), 16);
    assert!(!m.reacts());
}

#[test]
fn halving_decides_the_paused_cells_at_a_full_rung() {
    let s = spec("[search]\nmethod = \"asha\"\nmin_epochs = 10\nreduction = 3\n");
    let m = method_for(&s);
    assert_eq!((m.name(), m.initial_cells(&s).unwrap().len()), ("asha", 16));
    // Three cells paused at rung 0 (10 epochs): the best of three goes on, as asha::decide
    // says; the others wait until the rung's quota is known.
    let cells: Vec<CellView> = (0..3)
        .map(|i| {
            view(
                i + 1,
                gaitsweep_core::Place::point(0, i as u32),
                CellState::Paused,
                None,
                &[(10, 0.1 * i as f64)],
            )
        })
        .collect();
    let actions = m.react(&s, &cells).unwrap();
    let decided: Vec<(i64, bool)> = actions
        .iter()
        .map(|a| match a {
            Action::Rung(d) => (d.cell.0, d.continued),
            other => panic!("{other:?}"),
        })
        .collect();
    assert!(decided.contains(&(3, true)), "{decided:?}");
    assert!(!decided.iter().any(|(c, go)| *go && *c != 3), "{decided:?}");
}

#[test]
fn an_evolutionary_search_queues_the_next_generation_once_the_last_has_ended() {
    let s = spec("[search]\nmethod = \"genetic\"\npopulation = 4\nbudget_epochs = 1080\n");
    let m = method_for(&s);
    assert_eq!(m.name(), "genetic");
    let first = m.initial_cells(&s).unwrap();
    assert_eq!(first.len(), 4);
    let scored = |open: bool| -> Vec<CellView> {
        first
            .iter()
            .enumerate()
            .map(|(k, _)| {
                let (state, score) = if open && k == 3 {
                    (CellState::Running, None)
                } else {
                    (CellState::Done, Some(0.1 * k as f64))
                };
                view(
                    k as i64 + 1,
                    gaitsweep_core::Place::candidate(0, k as u32),
                    state,
                    score,
                    &[],
                )
            })
            .collect()
    };
    assert!(
        m.react(&s, &scored(true)).unwrap().is_empty(),
        "a generation still trains"
    );
    match &m.react(&s, &scored(false)).unwrap()[..] {
        [Action::Queue {
            generation: 1,
            cells,
            target: 90,
        }] => {
            assert_eq!(cells.len(), 4);
            assert!(cells.iter().all(|c| c.place.generation().unwrap().0 == 1));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn every_method_describes_its_layout_and_budget() {
    let cases = [
        ("", "grid", Layout::Grid, true),
        (
            "[search]\nmethod = \"asha\"\nmin_epochs = 10\nreduction = 3\n",
            "asha",
            Layout::Grid,
            false,
        ),
        (
            "[search]\nmethod = \"cmaes\"\npopulation = 4\n",
            "cmaes",
            Layout::Candidates,
            true,
        ),
        (
            "[search]\nmethod = \"genetic\"\npopulation = 4\n",
            "genetic",
            Layout::Candidates,
            true,
        ),
        (
            "[search]\nmethod = \"random\"\nbudget_epochs = 450\n",
            "random",
            Layout::Grid,
            true,
        ),
    ];
    for (extra, name, layout, known_total) in cases {
        let s = spec(extra);
        let d = describe(&s);
        assert_eq!(
            (d.name, d.layout, d.known_total),
            (name, layout, known_total),
            "{extra}"
        );
        assert_eq!(d.name, s.search.method());
        assert!(!d.title.is_empty() && !d.budget.is_empty());
    }
    assert_eq!(
        describe(&spec(
            "[search]\nmethod = \"random\"\nbudget_epochs = 450\n"
        ))
        .budget,
        "random search: 5 of the grid's 16 points drawn at random, each trained all its epochs"
    );
}

#[test]
fn random_search_trains_its_drawn_points_on_every_terrain_and_seed_and_never_acts() {
    let resolve = |seed: u64| {
        SweepSpec::from_toml(&format!(
            "robot = \"anymal\"\nterrains = [\"rough\", \"stairs\"]\npreset_grid = true\nseeds = 2\nseed = {seed}\n\
             [search]\nmethod = \"random\"\nbudget_epochs = 3600\n"
        ))
        .unwrap()
        .resolve_with(|_| Ok((grid(7), None)))
        .unwrap()
    };
    let s = resolve(7);
    // 3,600 epochs at 90 epochs x 2 seeds x 2 terrains per point: 10 of the 28 points.
    assert_eq!(s.search, gaitsweep_core::Search::Random { points: 10 });
    assert_eq!(s.budget_epochs(), Some(3600));
    let m = method_for(&s);
    assert_eq!(m.name(), "random");
    assert!(!m.reacts());
    let cells = m.initial_cells(&s).unwrap();
    assert_eq!(cells.len(), 10 * 2 * 2);
    let points: std::collections::BTreeSet<(u32, u32)> =
        cells.iter().map(|c| c.place.grid().unwrap()).collect();
    assert_eq!(points.len(), 10);
    for &(i, j) in &points {
        let of_point: Vec<_> = cells
            .iter()
            .filter(|c| c.place.grid() == Some((i, j)))
            .map(|c| (c.terrain_index, c.replicate))
            .collect();
        assert_eq!(of_point.len(), 4, "every terrain and seed of ({i}, {j})");
    }
    // The same seed draws the same points (a restarted coordinator, search-bench's
    // replay); another seed draws others.
    let again: Vec<_> = method_for(&resolve(7)).initial_cells(&resolve(7)).unwrap();
    assert_eq!(again, cells);
    let other = method_for(&resolve(8)).initial_cells(&resolve(8)).unwrap();
    assert_ne!(other, cells);
    assert_eq!(
        crate::random::random_points(4, 7, 10, 7)
            .into_iter()
            .map(|(i, j)| (i as u32, j as u32))
            .collect::<std::collections::BTreeSet<_>>(),
        points
    );
}

proptest::proptest! {
    #[test]
    fn random_points_are_distinct_grid_points_and_grow_by_prefix(
        w1 in 1usize..8, w2 in 1usize..8, seed in proptest::prelude::any::<u64>(),
    ) {
        let all = crate::random::random_points(w1, w2, w1 * w2, seed);
        let distinct: std::collections::BTreeSet<_> = all.iter().copied().collect();
        proptest::prop_assert_eq!(distinct.len(), w1 * w2);
        proptest::prop_assert!(all.iter().all(|&(i, j)| i < w1 && j < w2));
        for k in 0..=w1 * w2 {
            proptest::prop_assert_eq!(&crate::random::random_points(w1, w2, k, seed)[..], &all[..k]);
        }
    }
}
