use super::*;
use gaitsweep_core::spec::PresetGrid;
use gaitsweep_core::Axis;
use gaitsweep_core::SweepSpec;

fn spec(extra: &str) -> ResolvedSpec {
    let grid = PresetGrid {
        w1: Axis::Range {
            min: 2.0,
            max: 12.0,
            count: 4,
        },
        w2: Axis::Range {
            min: -10.0,
            max: -2.0,
            count: 4,
        },
        agents_per_cell: 8,
        epochs: 90,
    };
    SweepSpec::from_toml(&format!(
        "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\nseed = 7\n{extra}"
    ))
    .unwrap()
    .resolve_with(|_| Ok((grid, None)))
    .unwrap()
}

fn view(
    id: i64,
    g: u32,
    k: u32,
    state: CellState,
    score: Option<f64>,
    rungs: &[(u32, f64)],
) -> CellView {
    CellView {
        id: CellId(id),
        w1_index: g,
        w2_index: k,
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
                0,
                i as u32,
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
                view(k as i64 + 1, 0, k as u32, state, score, &[])
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
            assert!(cells.iter().all(|c| c.w1_index == 1));
        }
        other => panic!("{other:?}"),
    }
}
