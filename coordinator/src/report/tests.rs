//! Report tests: every picture is drawn from a synthetic sweep into a temp dir and checked
//! to be a whole PNG / SVG; a sweep written through the coordinator's own store is loaded
//! back and reported.

use super::*;
use crate::store::queries::AttemptCpu;
use crate::store::{SqlStore, Store, WorkerInfo, DB_FILE};
use gaitsweep_core::records::CheckpointRecord;
use gaitsweep_core::{ResolvedSpec, WorkerId};
use gaitsweep_model::TerrainKind;

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

#[test]
fn best_and_overlap_follow_the_scores() {
    let d = synthetic();
    let best = d.best_cell(None).unwrap();
    assert_eq!(
        (best.terrain_index, best.grid().unwrap().0),
        (1, 2),
        "the highest score is on rough, w1 = 12"
    );
    assert_eq!(
        d.promoted().unwrap().id,
        best.id,
        "without promotions the best cell is promoted"
    );
    let (cells, count) = d.overlap();
    assert!(!cells.is_empty());
    for &(i, j) in &cells {
        assert_eq!(count[i][j], Some(2.0));
        for t in 0..2 {
            let c = d.cells_of(t).find(|c| c.grid() == Some((i, j))).unwrap();
            assert!(
                c.value().is_some(),
                "overlap cells are scored on every terrain"
            );
        }
    }
    // the cell failed on rough is never in the overlap, and a point not scored on every
    // terrain has no count (not 0: nothing was compared there)
    assert!(!cells.contains(&(2, 0)));
    assert_eq!(count[2][0], None);
    assert_eq!(count[0][3], None, "still running on flat");
    assert!(count[1][1].is_some());
    let dir = tempfile::tempdir().unwrap();
    write_report(&d, dir.path(), &GifStatus::NotMade("--no-gif".into())).unwrap();
    assert_svg(&dir.path().join("overlap.svg"), &["not scored on"]);
}

#[test]
fn points_never_rewarded_are_named_and_marked() {
    let mut d = synthetic();
    let zeros = |c: &mut ReportCell, last: f64| {
        let mut curve: Vec<(u32, f64)> = (1..=20).map(|e| (e, 0.0)).collect();
        curve[19].1 = last;
        c.curves.insert("mean_step_reward".into(), curve);
    };
    for c in &mut d.cells {
        match (c.terrain_index, c.grid()) {
            // Rough (w1 7, w2 -2): 0 at every epoch. Flat (w1 2, w2 -2): the same, but it
            // is still running and may yet be rewarded.
            (1, Some((1, 3))) | (0, Some((0, 3))) => zeros(c, 0.0),
            // Rough (w1 12, w2 -2): rewarded once, at its last epoch.
            (1, Some((2, 3))) => zeros(c, 1e-6),
            _ => {}
        }
    }
    assert_eq!(d.unrewarded_points(1), vec![(1, 3)]);
    assert!(d.unrewarded_points(0).is_empty());
    let unrewarded: Vec<i64> = d
        .cells
        .iter()
        .filter(|c| c.never_rewarded())
        .map(|c| c.id)
        .collect();
    assert_eq!(unrewarded.len(), 1);

    let dir = tempfile::tempdir().unwrap();
    let gif = GifStatus::NotMade("--no-gif".into());
    write_report(&d, dir.path(), &gif).unwrap();
    assert_svg(&dir.path().join("score_rough.svg"), &["no reward"]);
    let flat = std::fs::read_to_string(dir.path().join("score_flat.svg")).unwrap();
    assert!(!flat.contains("no reward"), "flat has no such point");
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    assert_eq!(
        html.matches("Points never rewarded").count(),
        1,
        "rough only"
    );
    assert!(html.contains("Points never rewarded: <b>1</b> (w1, w2) = (7, -2)."));
    // A spec that stops such cells says where, in the report's budget line.
    let mut spec = spec();
    assert!(!budget_text(&spec).contains("never rewarded"));
    spec.epochs = 1200;
    spec.stop_unrewarded = Some(0.1);
    assert!(budget_text(&spec).contains(
        "up to 1200 PPO epochs per cell (every cell trains all its epochs; except a cell whose mean reward was 0 at every epoch, stopped and scored at epoch 120 by stop_unrewarded = 0.1), 1 seed"
    ), "{}", budget_text(&spec));
    assert_eq!(
        html.matches("never rewarded: mean reward per step 0 at every epoch")
            .count(),
        1,
        "one row of the cell table says so"
    );
}

/// Tracking reward per step given to every cell by [`with_torque_shares`].
const TRACK: f64 = 0.05;

/// `d` with 20 epochs of torque and tracking terms per cell whose
/// |torque penalty| / tracking is 10^(w2 + 3): 1e-7 at w2 = -10, 10 at -2.
fn with_torque_shares(mut d: ReportData) -> ReportData {
    for c in &mut d.cells {
        let torque = -TRACK * 10f64.powf(c.w2 + 3.0);
        c.curves.insert(
            "reward/torques".into(),
            (1..=20).map(|e| (e, torque)).collect(),
        );
        c.curves.insert(
            "reward/tracking_lin_vel".into(),
            (1..=20).map(|e| (e, TRACK)).collect(),
        );
    }
    d
}

/// Index in `d.cells` of terrain `t`'s cell at grid point `p`.
fn cell_at(d: &ReportData, t: usize, p: (usize, usize)) -> usize {
    d.cells
        .iter()
        .position(|c| c.terrain_index == t && c.grid() == Some(p))
        .unwrap()
}

#[test]
fn the_torque_share_says_where_w2_shapes_the_reward() {
    let track = TRACK;
    // |torque penalty| / tracking = 10^(w2 + 3): 1e-7 at w2 = -10, 10 at -2.
    let mut d = with_torque_shares(synthetic());
    let k = cell_at(&d, 0, (1, 3));
    assert!((d.cells[k].torque_share().unwrap() - 10.0).abs() < 1e-9);
    // Flat: w2 -10 (1e-7) and -7.33 (5e-5) are under 1%, -4.67 (0.02) is not.
    assert_eq!(d.negligible_torque_columns(0), vec![0, 1]);
    // Rough: one cell of column -7.33 whose penalty weighs half the tracking.
    let k = cell_at(&d, 1, (2, 1));
    d.cells[k]
        .curves
        .insert("reward/torques".into(), vec![(1, -track), (2, 0.0)]);
    assert_eq!(d.negligible_torque_columns(1), vec![0]);
    // No tracking reward: no share.
    let k = cell_at(&d, 1, (0, 2));
    d.cells[k]
        .curves
        .insert("reward/tracking_lin_vel".into(), vec![(1, 0.0)]);
    assert_eq!(d.cells[k].torque_share(), None);

    let dir = tempfile::tempdir().unwrap();
    let gif = GifStatus::NotMade("--no-gif".into());
    let files = write_report(&d, dir.path(), &gif).unwrap().files;
    for t in ["flat", "rough"] {
        let png = dir.path().join(format!("torque_share_{t}.png"));
        assert!(files.contains(&png));
        assert_png(&png, 700, 500);
    }
    assert_svg(
        &dir.path().join("torque_share_flat.svg"),
        &[
            "log10 of torque penalty / tracking reward",
            "1e-7",
            "5e-5",
            "10",
        ],
    );
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    assert!(html.contains("torque_share_rough.png"));
    assert!(html.contains("tracking reward (mean over training, every cell): w2 = -10, -7.33. "));
    assert!(html.contains("tracking reward (mean over training, every cell): w2 = -10. "));
}

#[test]
fn runs_of_nearly_the_same_reward_give_the_spread_of_one_run() {
    let track = TRACK;
    // |torque penalty| / tracking = 10^(w2 + 3): under 1% at w2 = -10 and -7.33 only.
    let mut d = with_torque_shares(synthetic());
    // Flat, every row: 0.1 i - 0.1125 at w2 = -10 and 0.1 i - 0.0125 at -7.33.
    let rows = d.same_reward_rows(0);
    assert_eq!(
        rows.iter().map(|r| r.w1_index).collect::<Vec<_>>(),
        vec![0, 1, 2]
    );
    let sd = 0.1 / 2f64.sqrt();
    for r in &rows {
        assert_eq!(r.runs.iter().map(|x| x.0).collect::<Vec<_>>(), vec![0, 1]);
        assert!((r.mean - (0.1 * r.w1_index as f64 - 0.0625)).abs() < 1e-9);
        assert!((r.sd - sd).abs() < 1e-9, "{r:?}");
    }
    let (pooled, dof) = SameRewardRow::pooled(&rows).unwrap();
    assert!((pooled - sd).abs() < 1e-9);
    assert_eq!(dof, 3, "three rows of two runs");
    // Rough: row 0's -10 has no finite score and row 2's -10 failed, so one run each is
    // left: only row 1 has a spread.
    let rows = d.same_reward_rows(1);
    assert_eq!(rows.iter().map(|r| r.w1_index).collect::<Vec<_>>(), vec![1]);

    // A replicate is not a first-seed run; a cell whose penalty weighs is not the same
    // reward; a third run joins its row, and the pooled SD weighs rows by their runs.
    let k = cell_at(&d, 0, (0, 0));
    d.cells[k].replicate = 1;
    let k = cell_at(&d, 0, (1, 1));
    d.cells[k]
        .curves
        .insert("reward/torques".into(), vec![(1, -track)]);
    let k = cell_at(&d, 0, (2, 2));
    d.cells[k]
        .curves
        .insert("reward/torques".into(), vec![(1, 0.0)]);
    d.cells[k].score = Some(score(0.0875 + 0.3));
    let rows = d.same_reward_rows(0);
    assert_eq!(rows.len(), 1);
    let r = &rows[0];
    assert_eq!(r.w1_index, 2);
    let v = [0.0875, 0.1875, 0.3875];
    assert_eq!(
        r.runs.iter().map(|x| x.0).collect::<Vec<_>>(),
        vec![0, 1, 2]
    );
    for (run, want) in r.runs.iter().zip(v) {
        assert!((run.1 - want).abs() < 1e-9);
    }
    let mean = v.iter().sum::<f64>() / 3.0;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 2.0;
    assert!((r.sd - var.sqrt()).abs() < 1e-9);
    let two = [
        r.clone(),
        SameRewardRow {
            w1_index: 0,
            runs: vec![(0, 0.0), (1, 1.0)],
            mean: 0.5,
            sd: 0.5f64.sqrt(),
        },
    ];
    let pooled = ((2.0 * var + 0.5) / 3.0).sqrt();
    let (sd, dof) = SameRewardRow::pooled(&two).unwrap();
    assert!((sd - pooled).abs() < 1e-9);
    assert_eq!(dof, 3);
    assert_eq!(SameRewardRow::pooled(&[]), None);

    let dir = tempfile::tempdir().unwrap();
    let gif = GifStatus::NotMade("--no-gif".into());
    write_report(&d, dir.path(), &gif).unwrap();
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    assert!(
        html.contains(&format!(
            "Pooled SD <b>{:.3}</b> (2 degrees of freedom): two single runs are told apart at 95% only when their \
             scores differ by more than {:.3} (t &middot; &radic;2 &middot; SD, t = 4.303)",
            var.sqrt(),
            4.303 * 2f64.sqrt() * var.sqrt()
        )),
        "flat's one row"
    );
    let scores: Vec<String> = r.runs.iter().map(|x| format!("{:.3}", x.1)).collect();
    assert!(html.contains(&format!(
        "<li>w1 = 12: {} (w2 = -10, -7.33, -4.67), mean {mean:.3}, SD <b>{:.3}</b></li>",
        scores.join(" / "),
        var.sqrt()
    )));
    assert_eq!(
        html.matches("Runs of nearly the same reward").count(),
        2,
        "flat and rough"
    );
}

#[test]
fn points_near_the_best_are_read_with_the_spread_of_one_run() {
    // Without torque terms there is no run of nearly the same reward, and no replicate.
    let d = synthetic();
    assert_eq!(d.near_best(0), None);
    // The page, and whether flat's score heatmap labels a cell "near best".
    let html = |d: &ReportData| {
        let dir = tempfile::tempdir().unwrap();
        write_report(d, dir.path(), &GifStatus::NotMade("--no-gif".into())).unwrap();
        let svg = std::fs::read_to_string(dir.path().join("score_flat.svg")).unwrap();
        let page = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
        (page, svg.matches("\nnear best\n").count())
    };
    let (page, labelled) = html(&d);
    assert!(page.contains("Points not told apart from the best on every terrain: not yet"));
    assert_eq!(labelled, 0);

    // Flat's same-reward rows give SD 0.1 / sqrt(2) over 3 degrees of freedom (t 3.182):
    // a single run is told apart only 0.318 below the best, so every scored point is near.
    let mut d = with_torque_shares(synthetic());
    let n = d.near_best(0).unwrap();
    assert_eq!(n.source, crate::near_best::SpreadSource::SameReward);
    assert_eq!((n.best, n.best_runs, n.dof, n.scored), ((2, 1), 1, 3, 11));
    assert!((n.sd - 0.1 / 2f64.sqrt()).abs() < 1e-9);
    assert_eq!(n.near.len(), 11);

    // Two more seeds of flat's (12, -7.33) and (1, -7.33), each 0.01 either side of the
    // first: one run's SD is now theirs, 0.01 over 4 degrees of freedom (t 2.776), and only
    // (12, -4.67), equal to the best's mean, stays within 0.032 of it.
    for (p, base) in [((2, 1), 0.1875), ((1, 1), 0.0875)] {
        let k = cell_at(&d, 0, p);
        for (r, delta) in [(1, -0.01), (2, 0.01)] {
            let mut c = d.cells[k].clone();
            c.id += 1000 * r;
            c.replicate = r as u32;
            c.score = Some(score(base + delta));
            d.cells.push(c);
        }
    }
    let n = d.near_best(0).unwrap();
    assert_eq!(n.source, crate::near_best::SpreadSource::Replicates);
    assert_eq!((n.best, n.best_runs, n.dof), ((2, 1), 3, 4));
    assert!((n.sd - 0.01).abs() < 1e-9 && (n.lsd(1) - 0.03205).abs() < 1e-4);
    assert_eq!(n.near, vec![(2, 1), (2, 2)]);
    // A finalist stage half trained: a queued seed of (7, -10) keeps the same-reward SD.
    let mut queued = d.cells[cell_at(&d, 0, (1, 0))].clone();
    (queued.id, queued.replicate, queued.state, queued.score) = (5000, 1, "queued".into(), None);
    d.cells.push(queued);
    assert_eq!(
        d.near_best(0).unwrap().source,
        crate::near_best::SpreadSource::SameReward
    );
    for ended in ["failed", "cancelled", "stopped"] {
        d.cells.last_mut().unwrap().state = ended.into();
        assert_eq!(d.near_best(0).unwrap(), n, "a {ended} seed has ended");
    }
    // After a finalist stage the first seeds, picked for scoring high, are left out of the
    // spread: 0.1775 / 0.1975 and 0.0775 / 0.0975 pool to SD 0.0141 over 2 degrees of freedom.
    let mut f = d.clone();
    f.finalists = true;
    let fin = f.near_best(0).unwrap();
    assert_eq!(
        (fin.dof, fin.best_runs),
        (2, 3),
        "the means keep every seed"
    );
    assert!((fin.sd - 0.0002f64.sqrt()).abs() < 1e-9, "{fin:?}");
    // Rough reads its own spread (row 1's two runs, t 12.7): all of its points are near.
    let rough = d.near_best(1).unwrap();
    assert_eq!(rough.near.len(), rough.scored);

    let (page, labelled) = html(&d);
    assert_eq!(labelled, 1, "(12, -4.67); the best keeps its own mark");
    assert!(
        page.contains("Points not told apart from the best at 95%: <b>2 of 11</b> scored, (12, -7.33), (12, -4.67). The best, (12, -7.33), has mean 0.188 over 3 runs; "),
        "{page}"
    );
    assert!(page.contains("one run's SD 0.010 (4 degrees of freedom) from the seeds of the points trained more than once"));
    assert!(page.contains(
        "on every terrain at once (95%, each terrain's spread of one run): <b>(12, -7.33), (12, -4.67)</b>"
    ));
}

#[test]
fn every_picture_is_a_whole_png_and_svg() {
    let d = synthetic();
    let dir = tempfile::tempdir().unwrap();
    let gif = GifStatus::NotMade("the worker binary was not found".into());
    let files = write_report(&d, dir.path(), &gif).unwrap().files;
    // GAITSWEEP_KEEP_REPORT=DIR keeps a copy to look at.
    if let Some(keep) = std::env::var_os("GAITSWEEP_KEEP_REPORT") {
        write_report(&d, Path::new(&keep), &gif).unwrap();
    }
    let mut stems = vec!["overlap".to_string()];
    for t in ["flat", "rough"] {
        for p in [
            "score", "surface", "track", "effort", "tilt", "progress", "curves",
        ] {
            stems.push(format!("{p}_{t}"));
        }
    }
    for s in &stems {
        let png = dir.path().join(format!("{s}.png"));
        assert!(files.contains(&png), "{s}.png listed");
        assert_png(&png, 700, 500);
        let svg = dir.path().join(format!("{s}.svg"));
        assert!(files.contains(&svg), "{s}.svg listed");
    }
    assert_svg(
        &dir.path().join("score_flat.svg"),
        &[
            "log10 torque weight w2",
            "w1 (tracking weight)",
            "gait score",
            "best",
        ],
    );
    assert_svg(&dir.path().join("effort_rough.svg"), &["best (lowest)"]);
    assert_svg(
        &dir.path().join("overlap.svg"),
        &["all terrains", "top quartile"],
    );
    assert_svg(
        &dir.path().join("curves_flat.svg"),
        &["epoch", "mean reward per step", "w1 12, w2 -2"],
    );
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    for needle in [
        "score_flat.png",
        "surface_rough.png",
        "overlap.png",
        "curves_rough.png",
        "the worker binary was not found",
        "worker &lt;gone&gt;",
        "class=\"best\"",
        // Flat: the w1 = 12 row (4 cells) walks, 11 scored; rough: 3 of that row (one failed).
        "Cells that walk: <b>4</b> of 11 scored",
        "Cells that walk: <b>3</b> of 11 scored",
        // Flat: the score climbs with w1 to the last row, its peak at w2 -7.33 (a tie with
        // -4.67, which does not count as rising); w1 7 stands (mean speed 0), w1 2 has an
        // unscored point, w1 12 walks.
        "the best point is w1 12, w2 -7.33 (mean 0.188), on the grid's edge; the score rises towards it on <b>12 of 15</b> steps",
        "(mean speed &lt; 0.2 m/s): 7.</p>",
    ] {
        assert!(
            html.contains(needle),
            "index.html lacks {needle:?}: {}",
            html.lines().filter(|l| l.contains("Shape of the grid")).collect::<Vec<_>>().join("\n")
        );
    }
    assert_eq!(
        html.matches("<tr").count(),
        d.cells.len() + 1,
        "one table row per cell"
    );
    let moved = d.cells.iter().filter(|c| c.id % 5 == 0).count();
    assert!(moved > 1);
    let said = format!(
        "Trained on amd: {} cells; intel: {moved} cells. {moved} cells trained on more than one CPU",
        d.cells.len()
    );
    assert!(html.contains(&said), "index.html lacks {said:?}");
    assert!(html.contains("<td>amd</td>"), "a cell on one CPU names it");
    assert!(
        html.contains("<td>amd 0\u{2013}10 \u{b7} intel 10\u{2013}20</td>"),
        "a cell that moved names each CPU's epochs"
    );
}

#[test]
fn pictures_render_text_with_the_embedded_font() {
    // Text must change many pixels: a PNG with text compresses far worse than a blank one,
    // which is what plotters draws when no font is available.
    use plotters::prelude::*;
    register_fonts();
    let dir = tempfile::tempdir().unwrap();
    let draw = |name: &str, text: &str| {
        let path = dir.path().join(name);
        let root = BitMapBackend::new(&path, (300, 60)).into_drawing_area();
        root.fill(&WHITE).unwrap();
        root.draw(&Text::new(
            text.to_string(),
            (5, 10),
            ("sans-serif", 30).into_font(),
        ))
        .unwrap();
        root.present().unwrap();
        drop(root);
        std::fs::metadata(&path).unwrap().len()
    };
    let blank = draw("blank.png", "");
    let text = draw("text.png", "w1 log10 \u{2605} 0.123");
    assert!(
        text > blank + 800,
        "text was drawn: {text} bytes vs {blank} blank"
    );
}

#[test]
fn an_empty_sweep_still_gets_a_report() {
    let mut d = synthetic();
    for c in &mut d.cells {
        c.score = None;
        c.state = "queued".into();
        c.curves.clear();
    }
    let dir = tempfile::tempdir().unwrap();
    write_report(
        &d,
        dir.path(),
        &GifStatus::NotMade("no cell has a score yet".into()),
    )
    .unwrap();
    assert_png(&dir.path().join("score_flat.png"), 700, 500);
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    assert!(html.contains("nothing is promoted"));
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

#[tokio::test]
async fn a_sweep_stored_by_the_coordinator_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqlStore::open(&dir.path().join(DB_FILE)).await.unwrap();
    let w = WorkerId("w".into());
    let info = WorkerInfo {
        hostname: "h".into(),
        cores: 2,
        device: "cpu".into(),
        slots: 1,
        version: "t".into(),
        cpu: "test cpu".into(),
    };
    store.register_worker(&w, &info, 0).await.unwrap();
    let sweep = store.create_sweep(&spec(), 0).await.unwrap();
    let mut k = 0.0;
    // all cells but the last get a score, metrics and a checkpoint
    while let Some(g) = store.lease_next(&w, 0, 1).await.unwrap() {
        k += 1.0;
        if k > 11.0 {
            break;
        }
        let ck = CheckpointRecord {
            sha256: format!("{:064x}", g.lease.0),
            size: 10,
            epoch: 3,
        };
        let rel = format!("checkpoints/{}.safetensors", ck.sha256);
        store
            .record_checkpoint(g.lease, &ck, &rel, 2)
            .await
            .unwrap();
        let epochs: Vec<(u32, BTreeMap<String, f64>)> = (1..=3)
            .map(|e| {
                (
                    e,
                    BTreeMap::from([
                        ("mean_step_reward".to_string(), k * 0.01 + e as f64 * 0.1),
                        ("mean_return".to_string(), k + e as f64),
                        ("kl".to_string(), 0.01),
                    ]),
                )
            })
            .collect();
        store.record_progress(g.lease, &epochs).await.unwrap();
        store
            .report_result(g.lease, &score(k / 10.0), 3, Some(&ck.sha256), 3)
            .await
            .unwrap();
    }
    let db = crate::store::reader::open(dir.path(), None).await.unwrap();
    let d = load(&db, sweep.id.0).await.unwrap();
    assert_eq!(d.terrains, vec!["flat", "stairs"]);
    assert_eq!(d.w1_values, vec![2.0, 12.0]);
    assert_eq!(d.w2_values, vec![-6.0, -4.0, -2.0]);
    assert_eq!(d.difficulty, Some(2));
    assert_eq!(d.cells.len(), 12);
    assert_eq!(d.cells.iter().filter(|c| c.score.is_some()).count(), 11);
    let best = d.promoted().expect("a promoted cell");
    assert_eq!(
        best.value(),
        Some(1.1),
        "the stored promotion is the best score"
    );
    assert!(d
        .promotions
        .iter()
        .any(|p| p.terrain.is_empty() && p.cell_id == best.id));
    assert!(best
        .checkpoint
        .as_deref()
        .unwrap()
        .starts_with("checkpoints/"));
    let c = d.cells.iter().find(|c| c.score.is_some()).unwrap();
    assert_eq!(c.curves["mean_step_reward"].len(), 3);
    assert_eq!(
        c.trained_on,
        vec![machines::CpuSpan {
            cpu: "test cpu".into(),
            from: 0,
            to: 3
        }],
        "the CPU of the worker that trained it, from the attempts"
    );
    assert!(
        !c.curves.contains_key("kl"),
        "only curve metrics are loaded"
    );
    assert!(d.load_missing_sweep_is_an_error(&db).await);

    // the whole command, with no worker binary: the report says so instead of failing
    let out = dir.path().join("report");
    run(ReportArgs {
        sweep: sweep.id.0,
        data_dir: dir.path().to_path_buf(),
        database: None,
        out: out.clone(),
        worker: Some(dir.path().join("no-such-worker")),
        no_gif: false,
        gif_seconds: 1.0,
    })
    .await
    .unwrap();
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(html.contains("No gait GIF"), "{html}");
    assert!(
        html.contains(
            "Budget: 2 robots per cell, up to 3 PPO epochs per cell (every cell trains all its epochs), 1 seed per grid point"
        ),
        "the report states the sweep's budget: {html}"
    );
    assert_png(&out.join("score_stairs.png"), 700, 500);
    assert_png(&out.join("overlap.png"), 700, 500);
}

impl ReportData {
    async fn load_missing_sweep_is_an_error(&self, db: &sqlx::AnyPool) -> bool {
        load(db, self.sweep_id + 1000).await.is_err()
    }
}

#[test]
fn a_one_cell_grid_is_drawn() {
    let mut d = synthetic();
    d.terrains.truncate(1);
    d.w1_values.truncate(1);
    d.w2_values.truncate(1);
    d.cells
        .retain(|c| c.terrain_index == 0 && c.grid() == Some((0, 0)));
    let dir = tempfile::tempdir().unwrap();
    write_report(&d, dir.path(), &GifStatus::NotMade("x".into())).unwrap();
    for s in ["score_flat", "surface_flat", "curves_flat", "tilt_flat"] {
        assert_png(&dir.path().join(format!("{s}.png")), 500, 400);
    }
    assert!(
        !dir.path().join("overlap.png").exists(),
        "no overlap with one terrain"
    );
}

#[test]
fn replicated_points_are_drawn_as_their_mean() {
    let mut d = synthetic();
    // A second replicate of every cell, scoring 0.2 less.
    let extra: Vec<ReportCell> = d
        .cells
        .iter()
        .map(|c| {
            let mut r = c.clone();
            r.id += 1000;
            r.replicate = 1;
            if let Some(s) = r.score.as_mut() {
                s.score -= 0.2;
            }
            r
        })
        .collect();
    let single = d.grid_mean(0, |c| c.value());
    d.cells.extend(extra);
    let mean = d.grid_mean(0, |c| c.value());
    for (r1, r2) in single.iter().zip(&mean) {
        for (a, b) in r1.iter().zip(r2) {
            match (a, b) {
                (Some(a), Some(b)) => assert!((a - 0.1 - b).abs() < 1e-12, "{a} {b}"),
                (None, None) => {}
                _ => panic!("a point gained or lost its value: {a:?} {b:?}"),
            }
        }
    }
}

#[test]
fn an_evolutionary_search_is_drawn_as_its_candidates() {
    // Three generations of four candidates, the synthetic grid's cells made an
    // evolutionary search's candidates on one terrain.
    let mut d = synthetic();
    d.terrains.truncate(1);
    d.cells.retain(|c| c.terrain_index == 0);
    for (n, c) in d.cells.iter_mut().enumerate() {
        let (i, j) = c.place.pair();
        c.place = gaitsweep_core::Place::candidate(i, j);
        c.w1 = 2.0 + (n as f64 * 0.77) % 10.0;
        c.w2 = -10.0 + (n as f64 * 1.31) % 8.0;
    }
    d.evolution = Some(([2.0, -10.0], [12.0, -2.0]));
    d.search = "cmaes".into();
    d.search_title = "CMA-ES".into();
    let dir = tempfile::tempdir().unwrap();
    let files = write_report(&d, dir.path(), &GifStatus::NotMade("x".into()))
        .unwrap()
        .files;
    if let Some(keep) = std::env::var_os("GAITSWEEP_KEEP_REPORT") {
        write_report(&d, Path::new(&keep), &GifStatus::NotMade("x".into())).unwrap();
    }
    let png = dir.path().join("candidates_flat.png");
    assert!(files.contains(&png));
    assert_png(&png, 900, 700);
    assert_svg(
        &dir.path().join("candidates_flat.svg"),
        &[
            "CMA-ES",
            "12 candidates in 3 generations",
            "log10 torque weight",
            "gait score",
        ],
    );
    assert!(
        !dir.path().join("score_flat.png").exists(),
        "no grid heatmap for candidates off the grid"
    );
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    assert!(html.contains("candidates_flat.png") && html.contains("curves_flat.png"));
}

#[test]
fn a_stopped_cell_shows_its_rung_and_its_score_there() {
    let mut d = synthetic();
    let c = d
        .cells
        .iter_mut()
        .find(|c| c.terrain_index == 0 && c.score.as_ref().is_some_and(|s| s.score.is_finite()))
        .unwrap();
    c.score = None;
    c.state = "stopped".into();
    c.rung = Some((400, 0.8654));
    let dir = tempfile::tempdir().unwrap();
    write_report(&d, dir.path(), &GifStatus::NotMade("x".into())).unwrap();
    assert_svg(
        &dir.path().join("score_flat.svg"),
        &["stopped at 400", "0.865"],
    );
}
