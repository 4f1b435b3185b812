//! The spread of one run, the torque share, the points never rewarded and those near the
//! best, on synthetic sweeps.

use super::*;

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
    // A cell still training has no share yet, though its metrics give one.
    let k = cell_at(&d, 0, (1, 3));
    let scored = d.cells[k].score.take();
    assert_eq!(d.cells[k].torque_share(), None);
    d.cells[k].score = scored;

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
    assert!(
        html.contains("tracking reward (mean over training, every scored cell): w2 = -10, -7.33. ")
    );
    assert!(html.contains("tracking reward (mean over training, every scored cell): w2 = -10. "));
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
    assert!(page.contains("<a href=\"findings.md\">findings.md</a>"));

    // The same figures in findings.md, beside the paper's, one column per terrain.
    let dir = tempfile::tempdir().unwrap();
    write_report(&d, dir.path(), &GifStatus::NotMade("--no-gif".into())).unwrap();
    let md = std::fs::read_to_string(dir.path().join(FINDINGS_FILE)).unwrap();
    let row = |label: &str| {
        md.lines()
            .find(|l| l.starts_with(&format!("| {label}")))
            .unwrap_or_else(|| panic!("no row {label:?} in\n{md}"))
            .to_string()
    };
    // synthetic(): every fifth cell moved from an "amd" to an "intel" machine halfway.
    assert!(md.contains("Trained on amd: "), "{md}");
    assert!(md.contains("; intel: "), "{md}");
    assert!(
        md.contains("| | the paper (Kim et al. 2024) | flat | rough |\n|---|---|---|---|\n"),
        "{md}"
    );
    // Flat: 12 first seeds (one running), 4 more seeds, a stopped one; rough: one failed,
    // one NaN.
    assert!(
        row("cells scored").ends_with(
            "| 15 of 17 cells; 11 of 12 grid points | 10 of 12 cells; 10 of 12 grid points |"
        ),
        "{md}"
    );
    assert!(
        // t(0.975, 4 dof) 2.776 x 0.010 / sqrt 3 = 0.016.
        row("best point")
            .contains("| (12, -7.33): 0.188 \u{b1} 0.016 over 3 runs (nominal 95% for this point alone, one run's SD 0.010; the highest of 11 points' means reads high) |"),
        "{md}"
    );
    // Its first seed walks (|v_cmd - v| 0.1 at 1 m/s), the two more seeds 0.3 at rest.
    assert!(
        row("the best point's gait").contains("| not reported (Eq. 4's score only) | falls 0.0%, \\|v_cmd - v\\| 0.233 m/s, mean speed 0.333 m/s, overspeed 0.000 m/s (mean over 3 runs and the levels) |"),
        "{md}"
    );
    assert!(row("where the best").ends_with("| on the grid's edge | on the grid's edge |"));
    // A score stored before speeds were measured reads them as NaN: said, not printed.
    let mut old = d.clone();
    for c in old
        .cells
        .iter_mut()
        .filter(|c| c.terrain_index == 0 && c.grid() == Some((2, 1)))
    {
        c.score.as_mut().unwrap().mean_speed = f64::NAN;
    }
    let old_md = super::super::findings::markdown(&old).unwrap();
    assert!(
        old_md.contains("| falls 0.0%, \\|v_cmd - v\\| 0.233 m/s, mean speed not recorded, overspeed 0.000 m/s (mean over 3 runs"),
        "{old_md}"
    );
    // Flat's means: rows 0.1 apart, columns -0.1125 / -0.0125 / -0.0125 / -0.1125, (2, -2)
    // unscored. Along w1 all 7 steps rise; along w2 the 3 steps between the two equal
    // columns do not, the other 5 do. Every step is 0.1, of the range 0.1875 + 0.1125:
    // the largest named is the first of the ties in grid order (a later one must be larger).
    assert!(row("steps between").contains("| 12 of 15 (80%) |"), "{md}");
    assert!(
        row("largest step")
            .ends_with("| heavy robot: \"the form of a cliff rather than a raised peak\" | 0.33, (2, -10) to (7, -10) | 0.33, (2, -7.33) to (7, -7.33) |"),
        "{md}"
    );
    // Only the rows of w1 < 12 stand (mean speed 0); flat's w1 = 2 has a point unscored,
    // rough's a NaN score.
    assert!(
        row("rows of w1 standing").ends_with("| w1 = 7 | w1 = 7 |"),
        "{md}"
    );
    assert!(row("points not told apart").contains("| 2 of 11 scored points: (12, -7.33), (12, -4.67); one run's SD 0.010 (4 degrees of freedom, the seeds of the points trained more than once) |"), "{md}");
    // The w1 = 12 cells track their commands; the extra seeds were scored without it.
    assert!(
        row("cells that walk").contains("\\|v_cmd - v\\| <= 0.25 m/s"),
        "the bars are escaped"
    );
    assert!(
        row("cells that walk")
            .ends_with("| 4 of 15 (4 at every level) | 3 of 10 (3 at every level) |"),
        "{md}"
    );
    assert!(row("points never rewarded").ends_with("| none | none |"));
    assert!(md.contains("- points not told apart from the best on every terrain at once: (12, -7.33), (12, -4.67)\n"));
    // By point means: flat's top quartile (threshold 0.0875, the third of 11) is the w1 = 12
    // row and (7, -7.33), (7, -4.67); rough's (0.1075) the same but (12, -10), failed there.
    // Counted per cell, the three seeds of (12, -7.33) would have made it "in" 4 terrains.
    assert!(
        md.contains("- points in the top quartile of every terrain: (7, -7.33), (7, -4.67), (12, -7.33), (12, -4.67), (12, -2)\n"),
        "{md}"
    );
    assert!(md.contains(
        "- the weights for every terrain (max over grid points of the min over terrains"
    ));
    // An evolutionary search has no grid to hold against the paper.
    let mut e = d.clone();
    e.evolution = Some(([2.0, -10.0], [12.0, -2.0]));
    assert_eq!(super::super::findings::markdown(&e), None);
}
