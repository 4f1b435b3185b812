//! A sweep written through the coordinator's own store is loaded back and reported.

use super::*;

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

    // `coordinator findings`, the sweep named after a colon and by a recording's sweep.id.
    std::fs::write(
        dir.path().join(crate::report::study::SWEEP_ID_FILE),
        sweep.id.0.to_string(),
    )
    .unwrap();
    let md_file = dir.path().join("study/findings.md");
    let data_dir = dir.path().display().to_string();
    crate::report::study::run(crate::report::study::FindingsArgs {
        sweeps: vec![format!("{data_dir}:{}", sweep.id.0), data_dir.clone()],
        out: Some(md_file.clone()),
    })
    .await
    .unwrap();
    let md = std::fs::read_to_string(&md_file).unwrap();
    assert!(
        md.contains("| | the paper (Kim et al. 2024) | anymal flat | anymal stairs | anymal flat | anymal stairs |"),
        "{md}"
    );
    assert_eq!(
        md.matches(&format!("read from {data_dir} (state: running)"))
            .count(),
        2,
        "{md}"
    );
    let missing = crate::report::study::run(crate::report::study::FindingsArgs {
        sweeps: vec![format!("{data_dir}:999")],
        out: None,
    })
    .await
    .unwrap_err();
    assert!(
        matches!(missing, crate::Error::UnknownSweep(_)),
        "{missing}"
    );
}

impl ReportData {
    async fn load_missing_sweep_is_an_error(&self, db: &sqlx::AnyPool) -> bool {
        load(db, self.sweep_id + 1000).await.is_err()
    }
}
