//! The live page in a real browser: a coordinator with a token and `--http`, a real worker
//! finishing a tiny sweep, headless Chromium (Debian's `chromium`, installed by
//! scripts/test.sh when missing) rendering the page until a finished cell's score is in
//! the DOM and a learning curve has points; a screenshot is saved. Without the token the
//! page is refused.

mod common;

use common::*;
use std::io::{Read, Write};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

const TOKEN: &str = "live-s3cret";

fn status_of(addr: &str, path: &str) -> String {
    http_get(addr, path, None).0
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_live_page_shows_a_finished_sweep_and_refuses_a_missing_token() {
    let browser = chromium_or_panic();
    let _g = heavy().await;
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(
        tmp.path(),
        "127.0.0.1:0",
        &["--http", "127.0.0.1:0", "--token", TOKEN],
    )
    .await;
    let http = wait_for("the page's address file", Duration::from_secs(30), || {
        let f = coord.data.join("http.addr");
        async move { std::fs::read_to_string(f).ok().filter(|s| !s.is_empty()) }
    })
    .await;

    // Without the token: refused, every route.
    assert!(
        status_of(&http, "/").contains("401"),
        "{}",
        status_of(&http, "/")
    );
    assert!(status_of(&http, "/api/sweeps").contains("401"));
    let login = browse(&browser, &format!("http://{http}/"), &["--dump-dom"]);
    assert!(login.contains("needs its access token"), "{login}");
    assert!(!login.contains(TOKEN));

    // The event stream the page listens to: opened before the sweep, read after it.
    let mut events = std::net::TcpStream::connect(&http).unwrap();
    write!(
        events,
        "GET /api/events HTTP/1.1\r\nHost: {http}\r\nAuthorization: Bearer {TOKEN}\r\n\r\n"
    )
    .unwrap();

    let spec = tmp.path().join("spec.toml");
    std::fs::write(&spec, tiny_spec(&[2.0, 8.0], &[-6.0], 3)).unwrap();
    let created = Command::new(bin("coordinator"))
        .args(["create", "--connect", &coord.url(), "--token", TOKEN])
        .arg(&spec)
        .output()
        .unwrap();
    assert!(created.status.success(), "{created:?}");
    let work = tmp.path().join("work-a");
    let args: Vec<String> = [
        "--connect",
        &coord.url(),
        "--token",
        TOKEN,
        "--slots",
        "1",
        "--threads",
        "1",
        "--work-dir",
        &work.display().to_string(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let w = Proc::spawn("worker", &args, tmp.path().join("worker-a.log"));
    let db = coord.db().await;
    let score: f64 = wait_for("the sweep to finish", Duration::from_secs(600), || {
        let db = db.clone();
        async move {
            let state: String = sqlx::query_scalar("SELECT state FROM sweeps")
                .fetch_one(&db)
                .await
                .ok()?;
            if state != "done" {
                return None;
            }
            sqlx::query_scalar(
                "SELECT s.score FROM promotions p JOIN scores s ON s.cell_id = p.cell_id \
                 WHERE p.terrain = '' ORDER BY p.id DESC LIMIT 1",
            )
            .fetch_one(&db)
            .await
            .ok()
        }
    })
    .await;
    drop(w);
    events
        .set_read_timeout(Some(Duration::from_secs(2)))
        .unwrap();
    let mut streamed = Vec::new();
    let mut buf = [0u8; 65536];
    while let Ok(n) = events.read(&mut buf) {
        if n == 0 {
            break;
        }
        streamed.extend_from_slice(&buf[..n]);
    }
    let streamed = String::from_utf8_lossy(&streamed);
    assert!(streamed.contains("text/event-stream"), "{streamed}");
    for kind in [
        "\"kind\":\"cell\"",
        "\"kind\":\"progress\"",
        "\"kind\":\"promotion\"",
        "\"kind\":\"finished\"",
    ] {
        assert!(
            streamed.contains(kind),
            "no {kind} event pushed: {streamed}"
        );
    }

    // With the token: the promoted cell's score in the grid and in the cell panel, its
    // learning curves drawn.
    let url = format!("http://{http}/?token={TOKEN}");
    let dom = browse(&browser, &url, &["--dump-dom"]);
    let shown = format!("{score:.4}");
    assert!(
        dom.contains("data-loaded=\"1\""),
        "page did not load: {dom}"
    );
    assert!(
        dom.contains(&format!("id=\"cellscore\">{shown}<")),
        "promoted score {shown} not in the page: {dom}"
    );
    let points: Vec<usize> = dom
        .match_indices("data-points=\"")
        .filter_map(|(i, m)| {
            let rest = &dom[i + m.len()..];
            rest[..rest.find('"')?].parse().ok()
        })
        .collect();
    assert!(
        points.iter().any(|&n| n >= 3),
        "no learning curve with points: {points:?}"
    );
    assert!(dom.contains("e2e"), "sweep name missing");
    assert!(!dom.contains(TOKEN), "the token leaked into the page");

    // The promoted gait and the score surface, drawn as `coordinator report` draws them.
    assert!(
        dom.contains("report/gait.gif?"),
        "no gait animation on the page"
    );
    let (status, gif) = http_get(&http, "/api/sweeps/1/report/gait.gif", Some(TOKEN));
    assert!(status.contains("200"), "{status}");
    assert!(gif.starts_with(b"GIF8"), "not a GIF");
    let (status, svg) = http_get(&http, "/api/sweeps/1/report/surface_flat.svg", Some(TOKEN));
    assert!(
        status.contains("200") && String::from_utf8_lossy(&svg).contains("<svg"),
        "{status}"
    );
    assert!(http_get(
        &http,
        "/api/sweeps/1/report/..%2Fgaitsweep.sqlite",
        Some(TOKEN)
    )
    .0
    .contains("400"));
    // The JSON the page reads is typed: a value of the wrong type is an error, not a null.
    let (status, workers) = http_get(&http, "/api/workers", Some(TOKEN));
    let workers: serde_json::Value = serde_json::from_slice(&workers).unwrap();
    assert!(status.contains("200"), "{status}");
    let worker = &workers["workers"][0];
    assert!(worker["cores"].as_i64().unwrap() >= 1, "{workers}");
    assert_eq!(worker["slots"].as_i64(), Some(1), "{workers}");
    // The worker told its CPU model (which CPU trained a cell decides its gait).
    assert!(!worker["cpu"].as_str().unwrap().is_empty(), "{workers}");
    let (_, cell) = http_get(&http, "/api/cells/1", Some(TOKEN));
    let cell: serde_json::Value = serde_json::from_slice(&cell).unwrap();
    let attempt = &cell["attempts"][0];
    assert!(
        attempt["worker"].is_string()
            && attempt["cpu"].is_string()
            && attempt["started_unix_ms"].is_i64(),
        "{cell}"
    );

    let shot = tmp.path().join("live.png");
    browse(
        &browser,
        &url,
        &[&format!("--screenshot={}", shot.display())],
    );
    let png = std::fs::read(&shot).expect("screenshot written");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    if let Ok(dir) = std::env::var("GAITSWEEP_SCREENSHOT_DIR") {
        std::fs::copy(&shot, Path::new(&dir).join("live.png")).unwrap();
    }
    assert!(
        !coord.proc.log_text().contains(TOKEN),
        "the token was logged"
    );
}
