//! Report tests: every picture is drawn from a synthetic sweep into a temp dir and checked
//! to be a whole PNG / SVG; a sweep written through the coordinator's own store is loaded
//! back and reported.

mod pictures;
mod spread;
mod stored;
mod study;

use super::*;
use crate::store::queries::AttemptCpu;
use crate::store::{SqlStore, Store, WorkerInfo, DB_FILE};
use gaitsweep_core::records::CheckpointRecord;
use gaitsweep_core::{ResolvedSpec, WorkerId};
use gaitsweep_model::GaitScore;
use gaitsweep_model::TerrainKind;
use std::collections::BTreeMap;
use std::path::Path;

fn score(v: f64) -> GaitScore {
    GaitScore {
        score: v,
        track: 0.5 + v / 4.0,
        effort: 0.2 - v / 10.0,
        tilt: 0.05,
        progress: v.max(0.0),
        fall_rate: 0.0,
        mean_vel_error: 0.3,
        mean_abs_torque: 5.0,
        cost_of_transport: 1.2,
        robots: 4,
        ..Default::default()
    }
}

/// A 3 x 4 grid on two terrains; one cell still running, one failed, one NaN score.
fn synthetic() -> ReportData {
    let w1 = vec![2.0, 7.0, 12.0];
    let w2 = vec![-10.0, -7.33, -4.67, -2.0];
    let terrains = vec!["flat".to_string(), "rough".to_string()];
    let mut cells = Vec::new();
    let mut id = 1;
    for (t, terrain) in terrains.iter().enumerate() {
        for (i, a) in w1.iter().enumerate() {
            for (j, b) in w2.iter().enumerate() {
                let v = 0.1 * i as f64 - 0.05 * (j as f64 - 1.5).powi(2) + 0.02 * t as f64;
                let (state, s) = match (t, i, j) {
                    (0, 0, 3) => ("running", None),
                    (1, 2, 0) => ("failed", None),
                    (1, 0, 0) => ("done", Some(score(f64::NAN))),
                    // The best row tracks its commands: it walks.
                    _ if i == 2 => (
                        "done",
                        Some(GaitScore {
                            mean_vel_error: 0.1,
                            mean_speed: 1.0,
                            ..score(v)
                        }),
                    ),
                    _ => ("done", Some(score(v))),
                };
                let curves = BTreeMap::from([
                    (
                        "mean_step_reward".to_string(),
                        (1..=20).map(|e| (e, v + 0.01 * e as f64)).collect(),
                    ),
                    (
                        "mean_return".to_string(),
                        (1..=20).map(|e| (e, 10.0 * v + 0.3 * e as f64)).collect(),
                    ),
                ]);
                cells.push(ReportCell {
                    id,
                    terrain_index: t,
                    terrain: terrain.clone(),
                    place: gaitsweep_core::Place::point(i as u32, j as u32),
                    replicate: 0,
                    w1: *a,
                    w2: *b,
                    state: state.into(),
                    attempts: 1,
                    epochs_done: 20,
                    last_error: (state == "failed").then(|| "worker <gone>".to_string()),
                    score: s,
                    checkpoint: Some(format!("checkpoints/{id}.safetensors")),
                    curves,
                    rung: None,
                    // every fifth cell moved from one machine to another halfway
                    trained_on: machines::cpu_spans(
                        &[
                            AttemptCpu {
                                cpu: "amd".into(),
                                resumed_from: 0,
                            },
                            AttemptCpu {
                                cpu: if id % 5 == 0 { "intel" } else { "amd" }.into(),
                                resumed_from: 10,
                            },
                        ],
                        20,
                    ),
                });
                id += 1;
            }
        }
    }
    ReportData {
        sweep_id: 7,
        name: "synthetic".into(),
        robot: "anymal".into(),
        state: "running".into(),
        difficulty: Some(3),
        terrains,
        w1_values: w1,
        w2_values: w2,
        cells,
        promotions: vec![],
        evolution: None,
        search: "grid".into(),
        search_title: "grid search".into(),
        budget: "64 robots per cell".into(),
        finalists: false,
    }
}

/// Checks a PNG's signature, its IHDR size and that it ends with IEND.
fn assert_png(path: &Path, min_w: u32, min_h: u32) {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
    assert_eq!(
        &b[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} is not a PNG",
        path.display()
    );
    assert_eq!(&b[12..16], b"IHDR");
    let w = u32::from_be_bytes(b[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(b[20..24].try_into().unwrap());
    assert!(w >= min_w && h >= min_h, "{}: {w}x{h}", path.display());
    assert_eq!(
        &b[b.len() - 8..b.len() - 4],
        b"IEND",
        "{} is truncated",
        path.display()
    );
    assert!(
        b.len() > 5000,
        "{} is suspiciously small ({} bytes)",
        path.display(),
        b.len()
    );
}

fn assert_svg(path: &Path, must_contain: &[&str]) {
    let s =
        std::fs::read_to_string(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
    assert!(
        s.starts_with("<svg") && s.trim_end().ends_with("</svg>"),
        "{} is not a whole SVG",
        path.display()
    );
    for m in must_contain {
        assert!(s.contains(m), "{} lacks {m:?}", path.display());
    }
}

fn spec() -> ResolvedSpec {
    ResolvedSpec {
        name: "store".into(),
        robot: "anymal".into(),
        terrains: vec![TerrainKind::Flat, TerrainKind::Stairs],
        difficulty: Some(2),
        w1_values: vec![2.0, 12.0],
        w2_values: vec![-6.0, -4.0, -2.0],
        agents_per_cell: 2,
        epochs: 3,
        checkpoint_every: 1,
        seed: 1,
        replicates: 1,
        ppo_overrides: Default::default(),
        eval: gaitsweep_model::EvalSettings {
            robots: 0,
            seconds: 0.0,
            levels: vec![],
            score: Default::default(),
            every: 0,
        },
        search: Default::default(),
        finalists: None,
        stop_unrewarded: None,
    }
}
