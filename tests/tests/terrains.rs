//! A sweep over two terrains on real processes (issue 39): cells off flat ground are scored
//! at every evaluation level, each level's score is stored, and when the sweep ends the grid
//! point best across the terrains is promoted (`promotions.terrain = '*'`) by the rule of
//! `coordinator/src/across.rs`, shown by `coordinator show`, the report and the live page
//! (its JSON and the page rendered in headless Chromium).

mod common;

use common::*;
use gaitsweep_coordinator::across::{self, ScoredCell};
use gaitsweep_core::pb;
use std::time::Duration;

const SWEEP_TIMEOUT: Duration = Duration::from_secs(600);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_two_terrain_sweep_scores_every_level_and_promotes_the_point_best_across_terrains() {
    let browser = chromium_or_panic();
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(tmp.path(), "127.0.0.1:0", &["--http", "127.0.0.1:0"]).await;
    let mut c = coord.sweeps().await;
    // Forward commands in [0, 1] m/s (bench/learning-proof): a robot standing still earns
    // enough tracking credit for its score to be positive before it learned anything, and
    // the rule ranks points by their share of each terrain's best positive mean.
    let spec = "name = \"two-terrains\"\nrobot = \"bench/learning-proof\"\nterrains = [\"flat\", \"rough\"]\n\
                w1 = { values = [2.0, 12.0] }\nw2 = { values = [-6.0, -3.0] }\n\
                agents_per_cell = 4\nepochs = 2\ncheckpoint_every = 1\nseed = 5\n\
                eval = { robots = 4, seconds = 2.0, levels = [0, 5], score = \"bounded\" }\n";
    let sweep = create(&mut c, spec.to_string()).await;
    assert_eq!(sweep.cells_total, 8);
    let w = start_worker(tmp.path(), &coord.url(), "a");
    let done = wait_done(&coord, sweep.sweep_id, SWEEP_TIMEOUT, &[&coord.proc, &w]).await;
    assert_eq!(
        (done.state, done.cells_done),
        (pb::SweepState::Done as i32, 8),
        "{}",
        tail(&w.log_text(), 30)
    );

    let db = coord.db().await;
    // Flat cells at one level, rough cells at the spec's two; the score is their mean.
    let levels: Vec<(String, i64)> = sqlx::query_as(
        "SELECT c.terrain, COUNT(*) FROM level_scores l JOIN cells c ON c.id = l.cell_id \
         JOIN scores s ON s.cell_id = l.cell_id AND s.epochs = l.epoch GROUP BY c.terrain ORDER BY c.terrain",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(levels, vec![("flat".into(), 4), ("rough".into(), 8)]);
    let means: Vec<(i64, f64, f64, f64, f64)> = sqlx::query_as(
        "SELECT s.cell_id, s.score, AVG(l.score), s.progress_bounded, s.overspeed FROM scores s \
         JOIN level_scores l ON l.cell_id = s.cell_id AND l.epoch = s.epochs \
         JOIN cells c ON c.id = s.cell_id WHERE c.terrain = 'rough' GROUP BY s.cell_id, s.score, \
         s.progress_bounded, s.overspeed",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    assert_eq!(means.len(), 4);
    for (cell, score, mean, bounded, overspeed) in &means {
        assert!(
            (score - mean).abs() < 1e-9,
            "cell {cell}: score {score}, mean of levels {mean}"
        );
        assert!(bounded.is_finite() && *overspeed >= 0.0);
    }

    // The promotion across terrains is the rule applied to the stored scores.
    let scored: Vec<(i64, i64, i64, i64, f64)> = sqlx::query_as(
        "SELECT c.id, c.terrain_index, c.w1_index, c.w2_index, s.score FROM cells c \
         JOIN scores s ON s.cell_id = c.id ORDER BY c.id",
    )
    .fetch_all(&db)
    .await
    .unwrap();
    let cells: Vec<ScoredCell> = scored
        .iter()
        .map(|&(id, terrain, i, j, score)| ScoredCell {
            cell: gaitsweep_core::CellId(id),
            terrain: terrain as usize,
            place: gaitsweep_core::Place::point(i as u32, j as u32),
            score,
        })
        .collect();
    let want = across::best_across(&cells, 2).unwrap_or_else(|| {
        panic!("an untrained policy standing for 2 s under commands of 0-1 m/s scores above 0 on both terrains: {scored:?}")
    });
    let row: (i64, f64, Option<f64>) = sqlx::query_as(
        "SELECT cell_id, score, ci95 FROM promotions WHERE sweep_id = $1 AND terrain = '*'",
    )
    .bind(sweep.sweep_id)
    .fetch_one(&db)
    .await
    .unwrap();
    assert_eq!(
        (row.0, row.2),
        (want.cell.0, Some(0.0)),
        "one seed: no interval"
    );
    assert!((row.1 - want.value).abs() < 1e-12 && want.value > 0.0 && want.value <= 1.0);

    let out = std::process::Command::new(bin("coordinator"))
        .args([
            "show",
            "--connect",
            &coord.url(),
            &sweep.sweep_id.to_string(),
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "show failed: {text}");
    let w1 = [2.0, 12.0][want.w1_index as usize];
    assert!(
        text.contains("across terrains (max over grid points")
            && text.contains(&format!("w1 {w1:.3}")),
        "{text}"
    );
    assert!(
        text.contains("by level (score / fall rate): level 0"),
        "{text}"
    );

    // The live page: the same point across terrains, and every level of each cell.
    let http = std::fs::read_to_string(coord.data.join("http.addr")).unwrap();
    let (status, body) = http_get(&http, &format!("/api/sweeps/{}", sweep.sweep_id), None);
    assert!(status.contains("200"), "{status}");
    let live: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let across_json = &live["across"];
    assert_eq!(across_json["w1"].as_f64(), Some(w1), "{across_json}");
    assert_eq!(
        across_json["w2"].as_f64(),
        Some([-6.0, -3.0][want.w2_index as usize]),
        "{across_json}"
    );
    assert!((across_json["value"].as_f64().unwrap() - want.value).abs() < 1e-12);
    let cells_json = live["cells"].as_array().unwrap();
    assert_eq!(cells_json.len(), 8);
    for c in cells_json {
        let levels: Vec<i64> = c["levels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l["level"].as_i64().unwrap())
            .collect();
        let want_levels = if c["terrain_index"] == 1 {
            vec![0, 5]
        } else {
            vec![0]
        };
        assert_eq!(levels, want_levels, "{c}");
    }
    let dom = browse(&browser, &format!("http://{http}/"), &["--dump-dom"]);
    assert!(
        dom.contains("data-loaded=\"1\""),
        "page did not load: {dom}"
    );
    let across_p = dom
        .split("id=\"across\">")
        .nth(1)
        .and_then(|rest| rest.split("</p>").next())
        .unwrap_or_else(|| panic!("no weights for every terrain on the page: {dom}"));
    let w2_value = [-6.0, -3.0][want.w2_index as usize];
    assert!(
        across_p.starts_with("Weights for every terrain")
            && across_p.contains(&format!("<b>w1 {w1:.2}, w2 {w2_value:.2}</b>")),
        "{across_p}"
    );
    assert!(
        dom.contains("id=\"celllevels\""),
        "no per-level scores on the page: {dom}"
    );

    let report = tmp.path().join("report");
    let out = std::process::Command::new(bin("coordinator"))
        .args(["report", "--data-dir"])
        .arg(tmp.path().join("data"))
        .arg("--out")
        .arg(&report)
        .arg("--no-gif")
        .arg(sweep.sweep_id.to_string())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(
        html.contains("Weights for every terrain"),
        "report has no across-terrains line"
    );
    assert!(html.contains("L5 "), "report has no per-level scores");
    assert!(
        html.contains("Points not told apart from the best on every terrain"),
        "report has no near-best line across terrains"
    );
    assert!(html.contains("rough at levels 0, 5") && html.contains("progress term: bounded"));
    // findings.md holds the same sweep against the paper, one column per terrain, and its
    // weights for every terrain are the promoted point.
    let md = std::fs::read_to_string(report.join("findings.md")).unwrap();
    assert!(
        md.contains("| | the paper (Kim et al. 2024) | flat | rough |"),
        "{md}"
    );
    let w2 = [-6, -3][want.w2_index as usize];
    assert!(
        md.contains(&format!(
            "- the weights for every terrain (max over grid points of the min over terrains of (point mean / that terrain's best point mean)): ({w1}, {w2}), "
        )),
        "{md}"
    );
}
