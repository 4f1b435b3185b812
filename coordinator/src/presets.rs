//! The coordinator's view of the robot presets on disk: a sweep spec is validated against
//! the preset it names (the robot exists; PPO overrides name real hyper-parameters and fit
//! every terrain's cells, as `CellSettings::resolve` will decide them on the worker) and
//! takes the preset's Table-1 grid for what it leaves unset. Only the preset file is read
//! (`gaitsweep_model`); the URDF is the workers' business.

use gaitsweep_core::spec::PresetGrid;
use gaitsweep_core::{Axis, ResolvedSpec, SweepSpec};
use gaitsweep_model::preset::{AxisSpec, PresetFile};
use gaitsweep_model::{CellSettings, TerrainKind};

fn axis(a: &AxisSpec) -> Axis {
    Axis::Range {
        min: a.min,
        max: a.max,
        count: a.count,
    }
}

/// Validates `spec` against the presets on disk (`robots/` or `GAITSWEEP_ROBOTS`) and fills
/// in every default. Reads files: call it off the async runtime.
pub fn resolve(spec: &SweepSpec) -> gaitsweep_core::Result<ResolvedSpec> {
    spec.resolve_with(|robot| {
        let preset = PresetFile::load(robot).map_err(|e| e.to_string())?;
        let g = &preset.grid;
        // Overrides are checked against what each terrain's cells will really train with
        // (terrain tables, then overrides, then the schedule over the cell's budget).
        let budget = spec.epochs.unwrap_or(g.epochs);
        let override_problem = spec
            .terrains
            .iter()
            .filter_map(|t| t.parse::<TerrainKind>().ok())
            .find_map(|t| {
                CellSettings::resolve(preset.settings(), t, &spec.ppo, budget)
                    .err()
                    .map(|e| format!("on {t}: {e}"))
            });
        let grid = PresetGrid {
            w1: axis(&g.w1),
            w2: axis(&g.w2),
            agents_per_cell: g.agents_per_cell,
            epochs: g.epochs,
        };
        Ok((grid, override_problem))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_presets_resolve_and_unknown_ones_are_named() {
        let spec = SweepSpec::from_toml(
            "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\nppo = { learning_rate = 3e-4 }\n",
        )
        .unwrap();
        let r = resolve(&spec).unwrap();
        assert_eq!(r.cell_count(), 28, "Table 1: 4 x 7");
        let bad = SweepSpec::from_toml(
            "robot = \"nosuch\"\nterrains = [\"flat\"]\npreset_grid = true\nppo = { bogus = 1.0 }\n",
        )
        .unwrap();
        let e = resolve(&bad).unwrap_err().to_string();
        assert!(e.contains("known robots: anymal, heavy"), "{e}");
        let bad_ppo = SweepSpec::from_toml(
            "robot = \"anymal\"\nterrains = [\"flat\"]\npreset_grid = true\nppo = { bogus = 1.0 }\n",
        )
        .unwrap();
        assert!(resolve(&bad_ppo).unwrap_err().to_string().contains("bogus"));
        // The preset anneals by fractions of the budget: a schedule in epochs on top of it
        // would fail on every worker, so the sweep is refused when it is created.
        let clash = SweepSpec::from_toml(
            "robot = \"anymal\"\nterrains = [\"rough\"]\npreset_grid = true\nppo = { noise_decay_start = 300 }\n",
        )
        .unwrap();
        let e = resolve(&clash).unwrap_err().to_string();
        assert!(
            e.contains("on rough") && e.contains("both in epochs"),
            "{e}"
        );
    }

    #[test]
    fn the_study_specs_are_table_1s_grids_on_rough_and_stairs() {
        // The ANYmal recording predates stop_unrewarded; the heavy one stops its cells at
        // w2 = -2 (never rewarded) at a tenth of 1,200 epochs.
        for (robot, w2, cells, stop_after) in [("anymal", -10.0, 56, 0), ("heavy", -20.0, 32, 120)]
        {
            let path = format!("{}/../studies/{robot}.toml", env!("CARGO_MANIFEST_DIR"));
            let spec = SweepSpec::from_toml(&std::fs::read_to_string(&path).unwrap()).unwrap();
            let r = resolve(&spec).unwrap();
            assert_eq!(r.robot, robot);
            assert_eq!(
                r.cell_count(),
                cells,
                "{path}: Table 1's grid on two terrains"
            );
            assert_eq!((r.w1_values[0], r.w1_values[3]), (2.0, 12.0));
            assert_eq!((r.w2_values[0], *r.w2_values.last().unwrap()), (w2, -2.0));
            assert_eq!(r.eval.robots, 256, "issue 39: 256-robot evaluations");
            for terrain in ["rough", "stairs"] {
                assert_eq!(r.eval_levels_for(terrain), vec![0, 3, 5, 7], "{path}");
            }
            // A spec cannot set commands: the preset's are Table 1's on every terrain.
            let preset = PresetFile::load(robot).unwrap();
            assert_eq!(
                preset.commands.forward_speed,
                [0.0, 2.0],
                "Table 1: 0-2 m/s"
            );
            let [lo, hi] = preset.commands.heading;
            assert!(
                (lo + std::f32::consts::PI).abs() < 1e-4
                    && (hi - std::f32::consts::PI).abs() < 1e-4,
                "Table 1: headings in ±pi, got {lo}..{hi}"
            );
            assert_eq!(
                r.finalists,
                Some(gaitsweep_core::finalists::Finalists { top: 4, seeds: 3 })
            );
            assert_eq!(r.stop_unrewarded_after(), stop_after, "{path}");
        }
    }

    #[test]
    fn the_demo_spec_resolves_from_any_directory() {
        // The test runs in coordinator/: the spec's robot path is found in the source tree.
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/demo-sweep.toml");
        let spec = SweepSpec::from_toml(&std::fs::read_to_string(path).unwrap()).unwrap();
        let r = resolve(&spec).unwrap();
        assert_eq!(r.robot, "bench/learning-proof");
        assert_eq!(r.cell_count(), 4);
        assert_eq!(r.rungs(), vec![50, 200]);
        assert_eq!(r.ppo_overrides["final_noise_std"], 0.05);
    }
}
