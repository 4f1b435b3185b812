//! What the searches store: replicates, finalists, successive halving, the evolutionary
//! searches.

use super::*;

pub(super) async fn replicates_promote_a_point_by_their_mean_once_all_are_done() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 1, vec![TerrainKind::Flat]);
    s.replicates = 2;
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    assert_eq!(sweep.cells_total, 4);
    let cells = store.cells(sweep.id).await.unwrap();
    let seeds: std::collections::BTreeSet<u64> = cells.iter().map(|c| c.seed).collect();
    assert_eq!(seeds.len(), 4, "every replicate has its own seed");
    // Point w1 = 0: 0.9 and 0.1 (mean 0.5); point w1 = 1: 0.6 and 0.6 (mean 0.6).
    let value = |w1: u32, r: u32| [[0.9, 0.1], [0.6, 0.6]][w1 as usize][r as usize];
    let mut reported = [0; 2];
    while let Some(g) = store.lease_next(&w, 0, 1).await.unwrap() {
        let c = g.cell.clone();
        let out = store
            .report_result(
                g.lease,
                &score(value(c.place.pair().0, c.replicate)),
                3,
                None,
                3,
            )
            .await
            .unwrap();
        reported[c.place.pair().0 as usize] += 1;
        if reported[c.place.pair().0 as usize] < 2 {
            assert!(
                out.promotions.is_empty(),
                "promoted before its other replicate reported"
            );
        } else if reported.iter().sum::<i32>() == 2 {
            assert!(
                !out.promotions.is_empty(),
                "the first complete point is promoted"
            );
        }
        for p in &out.promotions {
            assert_eq!(p.cell.place.pair().0, c.place.pair().0);
            // Point 0's best is its 0.9; point 1's replicates tie and the lower id wins.
            assert_eq!(
                p.cell.replicate, 0,
                "the point's best replicate stands for it"
            );
        }
    }
    let best = store.promoted(sweep.id, None).await.unwrap();
    assert_eq!(
        best.cell.place.pair().0,
        1,
        "mean 0.6 beats mean 0.5 despite the single 0.9"
    );
    assert_eq!(best.cell.replicate, 0, "ties go to the lower id");
    let rec = store.sweep(sweep.id).await.unwrap();
    assert_eq!(rec.best_cell, Some(best.cell.id));
}

pub(super) async fn finalists_get_more_seeds_and_the_best_mean_is_promoted() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 2, vec![TerrainKind::Flat]);
    s.finalists = Some(gaitsweep_core::finalists::Finalists { top: 2, seeds: 3 });
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    assert_eq!(sweep.cells_total, 4, "the first pass is one seed per point");
    // First pass: (0,0) 0.9 and (0,1) 0.8 are the finalists; their further seeds score
    // 0.3, 0.3 (mean 0.5) and 0.7, 0.6 (mean 0.7).
    let value = |c: &CellRecord| match (c.place.pair().0, c.place.pair().1, c.replicate) {
        (0, 0, 0) => 0.9,
        (0, 0, _) => 0.3,
        (0, 1, 0) => 0.8,
        (0, 1, 1) => 0.7,
        (0, 1, _) => 0.6,
        (1, 0, _) => 0.1,
        _ => 0.2,
    };
    for _ in 0..4 {
        let g = store.lease_next(&w, 0, 1).await.unwrap().unwrap();
        let out = store
            .report_result(g.lease, &score(value(&g.cell)), 3, None, 1)
            .await
            .unwrap();
        assert!(out.finished.is_none(), "the finalists are still to train");
    }
    let cells = store.cells(sweep.id).await.unwrap();
    assert_eq!(cells.len(), 8);
    let mut replicated = s.clone();
    replicated.finalists = None;
    replicated.replicates = 3;
    let twins = replicated.cells();
    for c in cells.iter().filter(|c| c.replicate > 0) {
        assert_eq!(c.place.pair().0, 0, "only the top 2 points get more seeds");
        let twin = twins
            .iter()
            .find(|t| (t.place, t.replicate) == (c.place, c.replicate))
            .unwrap();
        assert_eq!(
            c.seed, twin.seed,
            "a finalist trains as a replicated grid would"
        );
    }
    let mut finished = None;
    while let Some(g) = store.lease_next(&w, 0, 2).await.unwrap() {
        let out = store
            .report_result(g.lease, &score(value(&g.cell)), 3, None, 2)
            .await
            .unwrap();
        assert!(
            out.promotions.is_empty(),
            "finalists are promoted together at the end"
        );
        finished = finished.or(out.finished);
    }
    assert_eq!(finished.unwrap().state, SweepState::Done);
    let best = store.promoted(sweep.id, None).await.unwrap();
    assert_eq!(
        (
            best.cell.place.pair().0,
            best.cell.place.pair().1,
            best.cell.replicate
        ),
        (0, 1, 0),
        "mean 0.7 beats the lucky single 0.9 (mean 0.5); its best seed stands for it"
    );
    let (mean, ci95): (f64, Option<f64>) = sqlx::query_as(
        "SELECT score, ci95 FROM promotions WHERE sweep_id = $1 AND terrain = '' ORDER BY id DESC LIMIT 1",
    )
    .bind(sweep.id.0)
    .fetch_one(store.reader())
    .await
    .unwrap();
    assert!((mean - 0.7).abs() < 1e-9);
    assert!(ci95.unwrap() > 0.0);
    let on_flat = store.promoted(sweep.id, Some("flat")).await.unwrap();
    assert_eq!(on_flat.cell.id, best.cell.id);
}

/// A point never rewarded (its reward clipped to 0 at every epoch) is no finalist, however
/// its untrained policy scores: the finalists' seeds go to the best rewarded points.
pub(super) async fn a_point_never_rewarded_is_no_finalist() {
    let (_d, store, w) = setup().await;
    let mut s = spec(3, 1, vec![TerrainKind::Flat]);
    s.finalists = Some(gaitsweep_core::finalists::Finalists { top: 1, seeds: 2 });
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    // w1 index 0: never rewarded, 0.9; 1: rewarded, 0.5; 2: rewarded, 0.4.
    while let Some(g) = store.lease_next(&w, 0, 1).await.unwrap() {
        let i = g.cell.place.pair().0;
        let reward = if i == 0 { 0.0 } else { 0.2 };
        let epochs: Vec<(u32, BTreeMap<String, f64>)> = (1..=3)
            .map(|e| (e, [("mean_step_reward".to_string(), reward)].into()))
            .collect();
        store.record_progress(g.lease, &epochs).await.unwrap();
        let value = [0.9, 0.5, 0.4][i as usize];
        store
            .report_result(g.lease, &score(value), 3, None, 1)
            .await
            .unwrap();
    }
    let seeds: Vec<u32> = store
        .cells(sweep.id)
        .await
        .unwrap()
        .iter()
        .filter(|c| c.replicate > 0)
        .map(|c| c.place.pair().0)
        .collect();
    assert_eq!(seeds, vec![1], "the finalist is the best rewarded point");
    let best = store.promoted(sweep.id, None).await.unwrap();
    assert_eq!(best.cell.place.pair().0, 1, "and it is promoted");
}

/// How both study specs run: a grid over two terrains with a finalist stage. Each terrain's
/// finalists are its own top points; then the point best across the terrains gets the
/// further seeds on the terrain where it was no finalist; when the sweep ends the
/// finalists are promoted per terrain and overall, and the point best across the terrains
/// (`'*'`) is ranked by the means over every seed, the finalists' further seeds included,
/// with its interval.
pub(super) async fn finalists_on_two_terrains_feed_the_promotion_across_them() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 2, vec![TerrainKind::Flat, TerrainKind::Rough]);
    s.finalists = Some(gaitsweep_core::finalists::Finalists { top: 2, seeds: 3 });
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    assert_eq!(
        sweep.cells_total, 8,
        "the first pass is one seed per point and terrain"
    );
    // Flat: (0,0) 0.9 then 0.3, 0.3 (mean 0.5); (0,1) 0.8 then 0.7, 0.6 (mean 0.7).
    // Rough: (1,0) 0.6 x 3 (mean 0.6); (0,0) 0.5 then 0.2, 0.2 (mean 0.3); (0,1) 0.4, then
    // as the point best across terrains 0.5 and 0.3 (mean 0.4).
    let value = |c: &CellRecord| {
        let (i, j) = c.place.pair();
        match (c.terrain_index, i, j, c.replicate) {
            (0, 0, 0, 0) => 0.9,
            (0, 0, 0, _) => 0.3,
            (0, 0, 1, 0) => 0.8,
            (0, 0, 1, 1) => 0.7,
            (0, 0, 1, _) => 0.6,
            (0, 1, 0, _) => 0.1,
            (0, 1, 1, _) => 0.2,
            (1, 0, 0, 0) => 0.5,
            (1, 0, 0, _) => 0.2,
            (1, 0, 1, 0) => 0.4,
            (1, 0, 1, 1) => 0.5,
            (1, 0, 1, _) => 0.3,
            (1, 1, 0, _) => 0.6,
            _ => 0.1,
        }
    };
    let mut finished = None;
    // (cells so far, the live page's forecast of the confirmation's cells) before each score.
    let mut forecasts = Vec::new();
    while let Some(g) = store.lease_next(&w, 0, 1).await.unwrap() {
        forecasts.push((
            store.cells(sweep.id).await.unwrap().len(),
            crate::store::confirmation_to_come(store.reader(), sweep.id, &s)
                .await
                .unwrap(),
        ));
        let out = store
            .report_result(g.lease, &score(value(&g.cell)), 3, None, 1)
            .await
            .unwrap();
        finished = finished.or(out.finished);
    }
    assert_eq!(finished.unwrap().state, SweepState::Done);
    assert!(
        forecasts.iter().all(|&(n, f)| n != 8 || f == 0),
        "the first pass forecasts no confirmation: {forecasts:?}"
    );
    assert!(
        forecasts.contains(&(16, 2)),
        "once (0,0)'s rough seeds fall, (0,1) is the pick and 2 rough seeds are forecast: {forecasts:?}"
    );
    assert!(
        forecasts.iter().all(|&(n, f)| n != 18 || f == 0),
        "queued: the forecast is spent: {forecasts:?}"
    );
    let cells = store.cells(sweep.id).await.unwrap();
    let mut further: Vec<(u32, u32, u32)> = cells
        .iter()
        .filter(|c| c.replicate > 0)
        .map(|c| (c.terrain_index, c.place.pair().0, c.place.pair().1))
        .collect();
    further.sort();
    further.dedup();
    assert_eq!(
        further,
        vec![(0, 0, 0), (0, 0, 1), (1, 0, 0), (1, 0, 1), (1, 1, 0)],
        "each terrain's own top 2 points get more seeds, and the point best across both, (0,1), on rough too"
    );
    assert_eq!(cells.len(), 18);
    let promoted = |terrain: &'static str| {
        let (store, cells) = (&store, &cells);
        async move {
            let (cell, score): (i64, f64) = sqlx::query_as(
                "SELECT cell_id, score FROM promotions WHERE sweep_id = $1 AND terrain = $2 ORDER BY id DESC LIMIT 1",
            )
            .bind(sweep.id.0)
            .bind(terrain)
            .fetch_one(store.reader())
            .await
            .unwrap();
            let c = cells.iter().find(|c| c.id.0 == cell).unwrap().clone();
            (c.terrain_index, c.place.pair(), score)
        }
    };
    let (t, p, mean) = promoted("flat").await;
    assert_eq!((t, p), (0, (0, 1)), "flat's best mean, not its lucky 0.9");
    assert!((mean - 0.7).abs() < 1e-9);
    let (t, p, mean) = promoted("rough").await;
    assert_eq!((t, p), (1, (1, 0)));
    assert!((mean - 0.6).abs() < 1e-9);
    let (_, p, _) = promoted("").await;
    assert_eq!(p, (0, 1), "the highest finalist mean over both terrains");
    // Over point means with every seed: (0,1) is flat's best and 0.4 / 0.6 of rough's, the
    // highest minimum; over first seeds only, (0,0) would be (min(0.9/0.9, 0.5/0.6) = 0.83).
    let (t, p, value) = promoted("*").await;
    assert_eq!(p, (0, 1), "the rule over the finalists' means");
    assert_eq!(t, 1, "the row names its cell on the weakest terrain");
    assert!((value - 0.4 / 0.6).abs() < 1e-9, "{value}");
    let ci95: Option<f64> = sqlx::query_scalar(
        "SELECT ci95 FROM promotions WHERE sweep_id = $1 AND terrain = '*' ORDER BY id DESC LIMIT 1",
    )
    .bind(sweep.id.0)
    .fetch_one(store.reader())
    .await
    .unwrap();
    assert!(
        ci95.unwrap() > 0.0,
        "3 seeds on its weakest terrain give the rule's value an interval"
    );
}

pub(super) async fn successive_halving_continues_the_top_third_and_stops_the_rest() {
    let (_d, store, w) = setup().await;
    let mut s = spec(6, 1, vec![TerrainKind::Flat]);
    s.epochs = 9;
    s.search = gaitsweep_core::Search::Asha {
        min_epochs: 1,
        reduction: 3,
    };
    assert_eq!(s.rungs(), vec![1, 3, 9]);
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    // Rung 0 (epoch 1): six cells arrive with these scores, in cell order.
    let rung0 = [0.1, 0.6, 0.3, 0.9, 0.2, 0.5];
    let mut grants = Vec::new();
    while let Some(g) = store.lease_next(&w, 0, 5).await.unwrap() {
        grants.push(g);
    }
    assert_eq!(grants.len(), 6);
    let mut decided = Vec::new();
    for (i, (sc, g)) in rung0.iter().zip(&grants).enumerate() {
        let out = report_at_target(&store, g, *sc, 10 + i as i64).await;
        assert_eq!(
            g.cell.target_epochs, 1,
            "every cell trains to the first rung"
        );
        assert!(out.promotions.is_empty(), "a rung result promotes nothing");
        decided.extend(out.decisions.iter().map(|d| (d.cell.id, d.continued)));
        // A retried report of the same rung changes nothing.
        let dup = store
            .report_result(g.lease, &score(*sc), 1, None, 99)
            .await
            .unwrap();
        assert!(dup.duplicate && dup.decisions.is_empty());
    }
    // ASHA continues a cell as soon as it is in the top floor(n/3): the second leased
    // (0.6) at n = 3; at n = 6 the top two are 0.9 and 0.6; the rung is then closed and the
    // rest stop. (A halving sweep's cells are leased in a seeded random order of the grid,
    // by id: `id(i)` is the i-th leased.)
    let id = |i: usize| grants[i].cell.id;
    assert!(grants.windows(2).all(|g| g[0].cell.id < g[1].cell.id));
    let cont: Vec<CellId> = decided.iter().filter(|d| d.1).map(|d| d.0).collect();
    assert_eq!(cont, vec![id(1), id(3)]);
    let stopped = decided.iter().filter(|d| !d.1).count();
    assert_eq!(stopped, 4);
    let cells = store.cells(sweep.id).await.unwrap();
    let state = |i: usize| cells.iter().find(|c| c.id == id(i)).unwrap().state;
    assert_eq!(
        (0..6).map(state).collect::<Vec<_>>(),
        [
            CellState::Stopped,
            CellState::Queued,
            CellState::Stopped,
            CellState::Queued,
            CellState::Stopped,
            CellState::Stopped
        ]
    );
    // Continued cells resume from their rung checkpoint towards rung 1 (epoch 3); at rung 1
    // two cells, floor(2/3) = 0, the closed rung still continues its best to the end.
    let (g, out) = train_to_target(&store, &w, 0.4, 20).await.unwrap();
    assert_eq!(
        (g.cell.target_epochs, g.resume.as_ref().map(|r| r.epoch)),
        (3, Some(1))
    );
    assert!(out.decisions.is_empty(), "rung 1 is still open");
    let (_, out) = train_to_target(&store, &w, 0.8, 21).await.unwrap();
    let d: Vec<(CellId, bool)> = out
        .decisions
        .iter()
        .map(|d| (d.cell.id, d.continued))
        .collect();
    assert_eq!(d.len(), 2);
    assert!(
        d.contains(&(id(3), true)) && d.contains(&(id(1), false)),
        "{d:?}"
    );
    // The last cell trains to the full budget, is scored and promoted; the sweep ends.
    let (g, out) = train_to_target(&store, &w, 0.7, 22).await.unwrap();
    assert_eq!(g.cell.id, id(3));
    assert_eq!(g.cell.target_epochs, 9);
    assert_eq!(out.cell.state, CellState::Done);
    assert_eq!(out.promotions[0].cell.id, id(3));
    let done = out.finished.expect("sweep finished");
    assert_eq!(
        (done.cells_done, done.cells_stopped, done.cells_paused),
        (1, 5, 0)
    );
    assert!(store.lease_next(&w, 0, 30).await.unwrap().is_none());

    // SQL: one rung row per (cell, rung) reached, one decision per (cell, rung).
    let db = store.writer();
    let evals: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM evaluations WHERE kind = 'rung'")
        .fetch_one(db)
        .await
        .unwrap();
    let decisions: Vec<(i64, i64, String)> =
        sqlx::query_as("SELECT cell_id, rung, decision FROM rung_decisions ORDER BY rung, cell_id")
            .fetch_all(db)
            .await
            .unwrap();
    assert_eq!(evals, 8);
    assert_eq!(decisions.len(), 8);
    assert_eq!(
        decisions.iter().filter(|d| d.2 == "continue").count(),
        3,
        "two past rung 0, one past rung 1"
    );
}

pub(super) async fn a_cell_failing_for_good_closes_the_rung_it_never_reached() {
    let (_d, store, w) = setup().await;
    let mut s = spec(2, 1, vec![TerrainKind::Flat]);
    s.epochs = 4;
    s.search = gaitsweep_core::Search::Asha {
        min_epochs: 2,
        reduction: 3,
    };
    store.create_sweep(&s, 0).await.unwrap();
    let (_, out) = train_to_target(&store, &w, 0.5, 1).await.unwrap();
    assert_eq!(out.cell.state, CellState::Paused);
    assert!(
        out.decisions.is_empty(),
        "the other cell may still reach the rung"
    );
    let g = store.lease_next(&w, 0, 2).await.unwrap().unwrap();
    let end = store
        .end_attempt(g.lease, AttemptEnd::Failed, "nan", 1, 3)
        .await
        .unwrap();
    assert_eq!(end.cell.state, CellState::Failed);
    assert_eq!(end.decisions.len(), 1);
    assert!(end.decisions[0].continued, "the rung's only cell goes on");
    let g = store.lease_next(&w, 0, 4).await.unwrap().unwrap();
    assert_eq!(g.cell.target_epochs, 4);
}

pub(super) async fn the_evolutionary_search_queues_a_generation_when_the_last_one_ends() {
    let (_d, store, w) = setup().await;
    let mut s = spec(3, 3, vec![TerrainKind::Flat]);
    s.replicates = 2;
    s.search = gaitsweep_core::Search::Cmaes {
        population: 3,
        sigma: 0.3,
        generations: 2,
        min_epochs: 0,
        reduction: 0,
    };
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    let gen0 = store.cells(sweep.id).await.unwrap();
    assert_eq!(gen0.len(), 6, "3 candidates x 2 replicates");
    for c in &gen0 {
        assert_eq!((c.place.generation().unwrap().0, c.target_epochs), (0, 3));
        assert!(
            (0.0..=2.0).contains(&c.w1) && (-2.0..=0.0).contains(&c.w2),
            "{c:?}"
        );
    }
    // A candidate's replicates share its (w1, w2), and their seeds differ.
    assert_eq!((gen0[0].w1, gen0[0].w2), (gen0[1].w1, gen0[1].w2));
    assert_ne!(gen0[0].seed, gen0[1].seed);

    // Generation 0: score = w1 (the best candidate has the largest w1); one cell fails
    // for good, and its candidate still has its other replicate's score.
    let mut now = 1;
    for n in 0..6 {
        let g = store.lease_next(&w, 0, now).await.unwrap().unwrap();
        assert_eq!(g.cell.place.generation().unwrap().0, 0);
        now += 1;
        if n == 1 {
            let end = store
                .end_attempt(g.lease, AttemptEnd::Failed, "nan", 1, now)
                .await
                .unwrap();
            assert_eq!(end.cell.state, CellState::Failed);
            continue;
        }
        let out = report_at_target(&store, &g, g.cell.w1, now).await;
        assert!(out.finished.is_none(), "one more generation to go");
        let queued = store.cells(sweep.id).await.unwrap().len();
        assert_eq!(
            queued,
            if n < 5 { 6 } else { 12 },
            "generation 1 waits for all of 0"
        );
    }
    let cells = store.cells(sweep.id).await.unwrap();
    let gen1: Vec<_> = cells
        .iter()
        .filter(|c| c.place.generation().unwrap().0 == 1)
        .collect();
    assert_eq!(gen1.len(), 6);
    assert!(gen1.iter().all(|c| c.state == CellState::Queued));

    // Generation 1 ends the budget: the sweep finishes, the best candidate mean promoted.
    let mut finished = None;
    while let Some(g) = store.lease_next(&w, 0, now).await.unwrap() {
        now += 1;
        let out = report_at_target(&store, &g, g.cell.w1, now).await;
        finished = finished.or(out.finished);
    }
    let done = finished.expect("the budget's two generations end the sweep");
    assert_eq!(done.state, SweepState::Done);
    assert_eq!(store.cells(sweep.id).await.unwrap().len(), 12);
    let best = store.promoted(sweep.id, None).await.unwrap();
    let max_w1 = store
        .cells(sweep.id)
        .await
        .unwrap()
        .iter()
        .filter(|c| c.state == CellState::Done)
        .map(|c| c.w1)
        .fold(f64::MIN, f64::max);
    assert_eq!(best.cell.w1, max_w1);
}

pub(super) async fn cmaes_halves_inside_each_generation() {
    let (_d, store, w) = setup().await;
    let mut s = spec(3, 3, vec![TerrainKind::Flat]);
    s.epochs = 9;
    s.search = gaitsweep_core::Search::Cmaes {
        population: 3,
        sigma: 0.3,
        generations: 2,
        min_epochs: 1,
        reduction: 3,
    };
    assert_eq!(s.rungs(), vec![1, 3, 9]);
    let sweep = store.create_sweep(&s, 0).await.unwrap();
    let mut now = 1;
    // Generation 0 at rung 0: the best of three (score = w1) goes on, the others stop.
    let mut decided = Vec::new();
    for _ in 0..3 {
        let (g, out) = train_to_target(&store, &w, 0.0, now).await.unwrap();
        assert_eq!(
            (g.cell.place.generation().unwrap().0, g.cell.target_epochs),
            (0, 1)
        );
        decided.extend(out.decisions);
        now += 1;
    }
    assert_eq!(decided.len(), 3);
    assert_eq!(decided.iter().filter(|d| d.continued).count(), 1);
    // It trains on through rung 1 to the end; then generation 1 is queued at rung 0.
    let (g, out) = train_to_target(&store, &w, 0.5, now).await.unwrap();
    assert_eq!(g.cell.target_epochs, 3);
    assert_eq!(out.decisions.len(), 1, "alone at rung 1, it goes on");
    assert_eq!(
        store.cells(sweep.id).await.unwrap().len(),
        3,
        "generation 0 is still open"
    );
    let (g, out) = train_to_target(&store, &w, 0.7, now + 1).await.unwrap();
    assert_eq!((g.cell.target_epochs, out.cell.state), (9, CellState::Done));
    assert_eq!(out.promotions.len(), 2, "overall and on its terrain");
    let cells = store.cells(sweep.id).await.unwrap();
    assert_eq!(cells.len(), 6);
    assert!(cells[3..]
        .iter()
        .all(|c| c.place.generation().unwrap().0 == 1
            && c.state == CellState::Queued
            && c.target_epochs == 1));
    // Generation 1 repeats it; the budget's two generations end the sweep.
    let mut finished = None;
    while let Some((_, out)) = train_to_target(&store, &w, 0.1, now + 10).await {
        now += 1;
        finished = finished.or(out.finished);
    }
    let done = finished.expect("the sweep ends after generation 1");
    assert_eq!((done.cells_done, done.cells_stopped), (2, 4));
    let trained: i64 = sqlx::query_scalar("SELECT CAST(SUM(epochs_done) AS BIGINT) FROM cells")
        .fetch_one(store.writer())
        .await
        .unwrap();
    assert_eq!(
        trained,
        2 * (3 + 2 + 6),
        "each generation: 3x1 + 1x2 + 1x6 epochs"
    );
}
