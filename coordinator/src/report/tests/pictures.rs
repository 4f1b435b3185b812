//! Every picture is a whole PNG / SVG, for a full grid, an empty sweep, one cell, replicates,
//! an evolutionary search and a stopped cell.

use super::*;

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
        // Flat: the w1 = 12 row (4 cells) walks, 11 scored; rough: 3 of that row (one
        // failed), 10 scored (one NaN).
        "Cells that walk: <b>4</b> of 11 scored",
        "Cells that walk: <b>3</b> of 10 scored",
        // Flat: the score climbs with w1 to the last row, its peak at w2 -7.33 (a tie with
        // -4.67, which does not count as rising); w1 7 stands (mean speed 0), w1 2 has an
        // unscored point, w1 12 walks.
        "the best point is w1 12, w2 -7.33 (mean 0.188), on the grid's edge; the score rises towards it on <b>12 of 15</b> steps",
        // Every step between neighbours is 0.1, of the range 0.3; of ties the first in grid
        // order is named.
        "the largest step between neighbouring points rewarded, from (2, -10) to (7, -10), is 0.33 of the range of their means",
        "(mean speed &lt; 0.2 m/s; points never rewarded left out): 7.</p>",
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
