//! What `coordinator show` prints: the grid of a sweep with each point's mean, interval and
//! fall rate, the promoted cell with its per-level scores, the finalists and the point best
//! across terrains.

use gaitsweep_core::convert::place_of;
use gaitsweep_core::{pb, Place};

pub(crate) fn sweep_state(s: i32) -> &'static str {
    match pb::SweepState::try_from(s).unwrap_or_default() {
        pb::SweepState::Running => "running",
        pb::SweepState::Done => "done",
        pb::SweepState::Cancelled => "cancelled",
        pb::SweepState::Unspecified => "unknown",
    }
}

pub(crate) fn cell_state(s: i32) -> &'static str {
    match pb::CellState::try_from(s).unwrap_or_default() {
        pb::CellState::Queued => "queued",
        pb::CellState::Running => "running",
        pb::CellState::Done => "done",
        pb::CellState::Failed => "failed",
        pb::CellState::Cancelled => "cancelled",
        pb::CellState::Paused => "paused",
        pb::CellState::Stopped => "stopped",
        pb::CellState::Unspecified => "unknown",
    }
}

/// The replicates of one grid point summarised: the scores' mean with its 95% confidence
/// interval and the mean fall rate, over the replicates that have a score.
pub(crate) fn point_summary(cells: &[&pb::Cell]) -> Option<(gaitsweep_core::stats::Summary, f64)> {
    let scored: Vec<pb::GaitScore> = cells.iter().filter_map(|c| c.score.clone()).collect();
    let scores: Vec<f64> = scored.iter().map(|x| x.score).collect();
    let stats = gaitsweep_core::stats::Summary::of(&scores)?;
    let fall = scored.iter().map(|x| x.fall_rate).sum::<f64>() / scored.len() as f64;
    Some((stats, fall))
}

/// The sweep header and one score table per terrain: rows w1, columns w2 (log10 torque
/// weight), each score with the fall rate of its evaluation beside it; `*` marks the best
/// point over all terrains, `+` the best on that terrain, `!` a point never rewarded. With replicates (`seeds = k`) a
/// point shows the mean of its replicates' scores ± the 95% confidence interval and the
/// mean fall rate.
pub(crate) fn render_show(s: &pb::Sweep, cells: &[pb::Cell]) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let spec = s.spec.clone().unwrap_or_default();
    // With finalists, the top points show the mean of their seeds like a replicated grid.
    let replicates = spec.seeds.max(spec.finalists_seeds).max(1);
    let _ = writeln!(
        o,
        "sweep {} {:?}: robot {}, {} | {} cells: {} done, {} running, {} queued, {} failed",
        s.sweep_id,
        spec.name,
        spec.robot,
        sweep_state(s.state),
        s.cells_total,
        s.cells_done,
        s.cells_running,
        s.cells_queued,
        s.cells_failed
    );
    if spec.finalists_seeds > 1 {
        let _ = writeln!(
            o,
            "finalists: the top {} points of each terrain by their first seed get {} seeds (mean score ± 95% confidence interval / mean fall rate; `n=1`: one seed scored, no interval yet); the promoted point is the finalist with the best mean",
            spec.finalists_top, spec.finalists_seeds
        );
    } else if replicates > 1 {
        let _ = writeln!(
            o,
            "{replicates} replicates (seeds) per grid point: mean score ± 95% confidence interval / mean fall rate (`n=1`: one seed scored, no interval yet); points rank by the mean"
        );
    }
    let width = if replicates > 1 { 22 } else { 16 };
    let best_point = cells
        .iter()
        .find(|c| c.cell_id == s.best_cell_id)
        .map(|b| (b.terrain_index, place_of(b)));
    // The search lays the sweep out and names itself; a spec this client cannot resolve
    // (a newer coordinator's) is shown as a grid under its method's name.
    let search = gaitsweep_core::convert::resolved_from_wire(spec.clone())
        .map(|r| gaitsweep_search::describe(&r));
    let title = search.as_ref().map_or_else(
        |_| gaitsweep_core::convert::search_method(&spec),
        |d| d.title.to_string(),
    );
    let evolutionary = search
        .as_ref()
        .is_ok_and(|d| d.layout == gaitsweep_search::Layout::Candidates);
    if evolutionary {
        render_candidates(&mut o, &title, cells, replicates, best_point);
    }
    for (ti, terrain) in spec.terrains.iter().enumerate().filter(|_| !evolutionary) {
        // Each grid point's cells on this terrain, gathered once: every pass below reads them.
        let mut grid: Vec<Vec<Vec<&pb::Cell>>> =
            vec![vec![Vec::new(); s.w2_values.len()]; s.w1_values.len()];
        for c in cells.iter().filter(|c| c.terrain_index as usize == ti) {
            if let Some(here) = grid
                .get_mut(c.w1_index as usize)
                .and_then(|row| row.get_mut(c.w2_index as usize))
            {
                here.push(c);
            }
        }
        let point = |i: usize, j: usize| -> &[&pb::Cell] { &grid[i][j] };
        let mut best_here: Option<((usize, usize), f64)> = None;
        // Once finalists exist, a terrain's best is among them, as its promotion is.
        let finalists_here = spec.finalists_seeds > 1
            && (0..s.w1_values.len())
                .any(|i| (0..s.w2_values.len()).any(|j| point(i, j).len() > 1));
        for i in 0..s.w1_values.len() {
            for j in 0..s.w2_values.len() {
                if finalists_here && point(i, j).len() < 2 {
                    continue;
                }
                if let Some((st, _)) = point_summary(point(i, j)) {
                    if best_here.is_none_or(|b| st.mean > b.1) {
                        best_here = Some(((i, j), st.mean));
                    }
                }
            }
        }
        let _ = writeln!(
            o,
            "\nterrain {terrain}: gait score / fall rate of its evaluation (rows w1, columns w2 = log10 torque weight)"
        );
        let scores: Vec<gaitsweep_model::GaitScore> = cells
            .iter()
            .filter(|c| c.terrain_index as usize == ti)
            .filter_map(|c| c.score.as_ref().map(Into::into))
            .collect();
        let walking = gaitsweep_model::WalkCount::of(&scores);
        if walking.scored > 0 {
            let _ = writeln!(
                o,
                "cells that walk (falls <= {:.0}%, |v_cmd - v| <= {} m/s, mean over levels): {} of {} scored; at every level: {}",
                100.0 * gaitsweep_model::WALK_MAX_FALL_RATE,
                gaitsweep_model::WALK_MAX_VEL_ERROR,
                walking.walks,
                walking.scored,
                walking.at_every_level
            );
        }
        let never: Vec<Vec<bool>> = grid
            .iter()
            .map(|row| {
                row.iter()
                    .map(|here| {
                        here.iter().any(|c| c.score.is_some())
                            && here
                                .iter()
                                .filter(|c| c.score.is_some())
                                .all(|c| c.never_rewarded)
                    })
                    .collect()
            })
            .collect();
        // A grid with a never-rewarded point gives every point a second mark column, so
        // that `*!` does not push its score one character out of line with the others.
        let unrewarded = never.iter().flatten().any(|&n| n);
        let _ = write!(o, "{:>10}", "w1 \\ w2");
        for w2 in &s.w2_values {
            let _ = write!(o, " {:>width$.3}", w2);
        }
        o.push('\n');
        for (i, w1) in s.w1_values.iter().enumerate() {
            let mut row = format!("{:>10.3}", w1);
            for (j, &never_here) in never[i].iter().enumerate() {
                let here = point(i, j);
                let mark = if best_point == Some((ti as u32, Place::point(i as u32, j as u32))) {
                    "*"
                } else if best_here.is_some_and(|b| b.0 == (i, j)) {
                    "+"
                } else {
                    " "
                };
                // Beside the best marks, not instead: a best point never rewarded says most.
                let mark = match (unrewarded, never_here) {
                    (false, _) => mark.to_string(),
                    (true, true) => format!("{mark}!"),
                    (true, false) => format!("{mark} "),
                };
                let text = point_text(here, replicates, &mark);
                let _ = write!(row, " {:>width$}", text);
            }
            // The mark columns of the last point would leave blanks at the line's end.
            o.push_str(row.trim_end());
            o.push('\n');
        }
        if unrewarded {
            let _ = writeln!(
                o,
                "! never rewarded: mean reward per step 0 at every epoch (every step's reward clipped to 0), so the score says nothing of the weights"
            );
        }
    }
    if !evolutionary && spec.terrains.len() > 1 {
        let _ = writeln!(o, "{}", across_line(&spec, s, cells));
    }
    if s.best_cell_id != 0 {
        if let Some(b) = cells.iter().find(|c| c.cell_id == s.best_cell_id) {
            let here: Vec<&pb::Cell> = cells
                .iter()
                .filter(|c| (c.terrain_index, place_of(c)) == (b.terrain_index, place_of(b)))
                .collect();
            // A point with one scored seed has no interval: it is shown as a single run.
            let several = point_summary(&here).filter(|(st, _)| replicates > 1 && st.n > 1);
            if let Some((st, fall)) = several {
                let _ = writeln!(
                    o,
                    "\nbest (*): w1 {:.3}, w2 {:.3} on {}: mean score {:.4} ± {:.4} (95% CI, sd {:.4}, {} replicates), mean fall rate {:.1}%; its model: replicate {} (cell {}, seed {})",
                    b.w1, b.w2, b.terrain, st.mean, st.ci95, st.sd, st.n, 100.0 * fall, b.replicate, b.cell_id, b.seed
                );
                return o;
            }
            let _ = writeln!(
                o,
                "\nbest (*): cell {} on {}, w1 {:.3}, w2 {:.3}, score {:.4}, fall rate {:.1}%, |v_cmd - v| {:.3} m/s",
                b.cell_id,
                b.terrain,
                b.w1,
                b.w2,
                b.score.as_ref().map_or(f64::NAN, |x| x.score),
                b.score.as_ref().map_or(f64::NAN, |x| 100.0 * x.fall_rate),
                b.score.as_ref().map_or(f64::NAN, |x| x.mean_vel_error)
            );
            if let Some(sc) = &b.score {
                let _ = writeln!(o, "{}", levels_line(sc));
            }
        }
    }
    o
}

/// The grid point best across the sweep's terrains ([`gaitsweep_coordinator::across`]),
/// in one line.
pub(crate) fn across_line(spec: &pb::SweepSpec, s: &pb::Sweep, cells: &[pb::Cell]) -> String {
    use gaitsweep_coordinator::across;
    let scored: Vec<across::ScoredCell> = cells
        .iter()
        .filter_map(|c| {
            Some(across::ScoredCell {
                cell: gaitsweep_core::CellId(c.cell_id),
                terrain: c.terrain_index as usize,
                place: place_of(c),
                score: c.score.as_ref()?.score,
            })
        })
        .collect();
    match across::best_across(&scored, spec.terrains.len()) {
        Some(a) => {
            let rel: Vec<String> = spec
                .terrains
                .iter()
                .zip(&a.relative)
                .map(|(t, r)| format!("{t} {:.1}%", 100.0 * r))
                .collect();
            format!(
                "\nacross terrains ({}): w1 {:.3}, w2 {:.3}: {:.1}% {} of the best on its weakest terrain, {} ({}){}",
                across::RULE,
                s.w1_values.get(a.w1_index as usize).copied().unwrap_or(f64::NAN),
                s.w2_values.get(a.w2_index as usize).copied().unwrap_or(f64::NAN),
                100.0 * a.value,
                a.interval_text(),
                spec.terrains.get(a.weakest).map_or("?", String::as_str),
                rel.join(", "),
                if s.state == pb::SweepState::Done as i32 { "" } else { " (sweep still running)" }
            )
        }
        None => "\nacross terrains: no grid point is scored on every terrain yet (or a terrain's best score is not positive)".to_string(),
    }
}

/// A score's levels and overspeed in one line: `by level: 0 0.912/0% · 3 0.804/2%;
/// overspeed 0.031 m/s`.
pub(crate) fn levels_line(s: &pb::GaitScore) -> String {
    let by: Vec<String> = s
        .levels
        .iter()
        .filter_map(|l| {
            let x = l.score.as_ref()?;
            Some(format!(
                "level {} {:.4}/{:.0}%",
                l.level,
                x.score,
                100.0 * x.fall_rate
            ))
        })
        .collect();
    format!(
        "  by level (score / fall rate): {}; overspeed {:.3} m/s (mean speed above the command)",
        if by.is_empty() {
            "-".to_string()
        } else {
            by.join(" · ")
        },
        s.overspeed
    )
}

/// One point's cell text: score (mean ± 95% CI with replicates) / fall rate and `mark`,
/// or the state of its first cell while none is scored (with blanks where `mark` would be,
/// so that states and scores stay in line).
pub(crate) fn point_text(here: &[&pb::Cell], replicates: u32, mark: &str) -> String {
    let blank = " ".repeat(mark.chars().count());
    match (point_summary(here), here.first()) {
        (Some((st, fall)), _) if replicates > 1 && st.n > 1 => {
            format!("{:.3}±{:.3}/{:>3.0}%{mark}", st.mean, st.ci95, 100.0 * fall)
        }
        // One seed scored of several: there is no interval yet, and `±0.000` would claim one.
        (Some((st, fall)), _) if replicates > 1 => {
            format!("{:.3} n=1/{:>3.0}%{mark}", st.mean, 100.0 * fall)
        }
        (Some((st, fall)), _) => format!("{:.4}/{:>3.0}%{mark}", st.mean, 100.0 * fall),
        (None, Some(c)) => match here.iter().find_map(|c| c.rung_score) {
            Some(r) if c.state == pb::CellState::Stopped as i32 => {
                format!("stopped@{}: {r:.3}{blank}", c.epochs_done)
            }
            // A long cell's epoch says how far it is (and a queued one resumes from there).
            _ if c.epochs_done > 0 && c.state != pb::CellState::Done as i32 => {
                format!("{}@{}{blank}", cell_state(c.state), c.epochs_done)
            }
            _ => format!("{}{blank}", cell_state(c.state)),
        },
        (None, None) => format!("-{blank}"),
    }
}

/// An evolutionary search's candidates, generation by generation: (w1, w2), the score
/// (mean ± 95% CI over replicates) / fall rate or the state; `*` marks the promoted one.
pub(crate) fn render_candidates(
    o: &mut String,
    title: &str,
    cells: &[pb::Cell],
    replicates: u32,
    best: Option<(u32, Place)>,
) {
    use std::fmt::Write;
    let mut points: Vec<(u32, u32)> = cells
        .iter()
        .filter_map(|c| place_of(c).generation())
        .collect();
    points.sort_unstable();
    points.dedup();
    let _ = writeln!(
        o,
        "\nevolutionary search ({title}): {} candidates in {} generations; score{} / fall rate of its evaluation",
        points.len(),
        points.last().map_or(0, |p| p.0 + 1),
        if replicates > 1 { " (mean ± 95% CI)" } else { "" }
    );
    let _ = writeln!(
        o,
        "{:>10} {:>9} {:>9} {:>9} {:>22}",
        "generation", "candidate", "w1", "w2", "score / falls"
    );
    for (g, k) in points {
        let here: Vec<&pb::Cell> = cells
            .iter()
            .filter(|c| place_of(c).generation() == Some((g, k)))
            .collect();
        let mark = if best.is_some_and(|b| b.1 == Place::candidate(g, k)) {
            "*"
        } else {
            " "
        };
        let text = point_text(&here, replicates, mark);
        let (w1, w2) = here.first().map_or((f64::NAN, f64::NAN), |c| (c.w1, c.w2));
        let _ = writeln!(o, "{g:>10} {k:>9} {w1:>9.3} {w2:>9.3} {text:>22}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(id: i64, w1_index: u32, replicate: u32, score: f64) -> pb::Cell {
        pb::Cell {
            cell_id: id,
            terrain: "flat".into(),
            w1_index,
            w1: [2.0, 8.0][w1_index as usize],
            w2: -6.0,
            replicate,
            seed: 100 + id as u64,
            state: pb::CellState::Done as i32,
            score: Some(pb::GaitScore {
                score,
                fall_rate: 0.25,
                ..Default::default()
            }),
            ..Default::default()
        }
    }

    #[test]
    fn replicated_points_show_their_mean_and_interval() {
        let sweep = pb::Sweep {
            sweep_id: 1,
            spec: Some(pb::SweepSpec {
                terrains: vec!["flat".into()],
                seeds: 2,
                ..Default::default()
            }),
            w1_values: vec![2.0, 8.0],
            w2_values: vec![-6.0],
            best_cell_id: 3,
            ..Default::default()
        };
        let cells = [
            cell(1, 0, 0, 0.9),
            cell(2, 0, 1, 0.1),
            cell(3, 1, 0, 0.6),
            cell(4, 1, 1, 0.6),
        ];
        let text = render_show(&sweep, &cells);
        // Point w1 = 2: mean 0.5, sd 0.566, half-width 12.706 * 0.566 / sqrt(2) = 5.082.
        assert!(text.contains("0.500±5.082/ 25%\n"), "{text}");
        assert!(
            text.contains("cells that walk (falls <= 10%, |v_cmd - v| <= 0.25 m/s, mean over levels): 0 of 4 scored"),
            "{text}"
        );
        assert!(text.contains("0.600±0.000/ 25%*"), "{text}");
        assert!(
            text.contains("mean score 0.6000 ± 0.0000 (95% CI, sd 0.0000, 2 replicates)"),
            "{text}"
        );
    }

    #[test]
    fn a_point_never_rewarded_is_marked_and_explained() {
        let sweep = pb::Sweep {
            sweep_id: 1,
            spec: Some(pb::SweepSpec {
                terrains: vec!["flat".into()],
                seeds: 1,
                ..Default::default()
            }),
            w1_values: vec![2.0, 8.0],
            w2_values: vec![-6.0],
            best_cell_id: 2,
            ..Default::default()
        };
        let plain = [cell(1, 0, 0, 0.2), cell(2, 1, 0, 0.6)];
        let text = render_show(&sweep, &plain);
        assert!(!text.contains("never rewarded"), "{text}");
        let marked = [
            pb::Cell {
                never_rewarded: true,
                ..cell(1, 0, 0, 0.2)
            },
            cell(2, 1, 0, 0.6),
        ];
        let text = render_show(&sweep, &marked);
        assert!(text.contains("0.2000/ 25% !"), "{text}");
        assert!(text.contains("0.6000/ 25%*\n"), "{text}");
        // The best point never rewarded keeps both marks.
        let best = [
            cell(1, 0, 0, 0.2),
            pb::Cell {
                never_rewarded: true,
                ..cell(2, 1, 0, 0.6)
            },
        ];
        let text = render_show(&sweep, &best);
        assert!(text.contains("0.6000/ 25%*!"), "{text}");
        // Both marks take no more room than one: the scores stay in line.
        let column = |row: &str| {
            let line = text.lines().find(|l| l.starts_with(row)).unwrap();
            line.find('%').unwrap()
        };
        assert_eq!(column("     2.000"), column("     8.000"), "{text}");
        assert!(text.lines().all(|l| l == l.trim_end()), "{text}");
        assert!(
            text.contains("! never rewarded: mean reward per step 0 at every epoch"),
            "{text}"
        );
    }

    /// A one-seed grid over w1 2 and 8 (w2 -6) on flat ground whose best point gets
    /// `seeds` seeds; `best` is the promoted cell (0: none).
    fn finalist_sweep(seeds: u32, best: i64) -> pb::Sweep {
        pb::Sweep {
            sweep_id: 1,
            spec: Some(pb::SweepSpec {
                terrains: vec!["flat".into()],
                seeds: 1,
                finalists_top: 1,
                finalists_seeds: seeds,
                ..Default::default()
            }),
            w1_values: vec![2.0, 8.0],
            w2_values: vec![-6.0],
            best_cell_id: best,
            ..Default::default()
        }
    }

    #[test]
    fn finalists_are_marked_among_themselves() {
        // Point w1 = 2 had the best single run (0.9) but is no finalist here; point w1 = 8
        // is, with seeds 0.6 and 0.5: the terrain's best (+) is the finalist, not the 0.9.
        let sweep = finalist_sweep(2, 0);
        let cells = [cell(1, 0, 0, 0.9), cell(3, 1, 0, 0.6), cell(4, 1, 1, 0.5)];
        let text = render_show(&sweep, &cells);
        assert!(text.contains("finalists: the top 1 points"), "{text}");
        // One seed of the point w1 = 2 is scored: no interval is claimed.
        assert!(text.contains("0.900 n=1/ 25%\n"), "{text}");
        assert!(!text.contains("±0.000"), "{text}");
        assert!(text.contains("0.550±"), "{text}");
        assert!(text.contains("/ 25%+"), "{text}");
    }

    #[test]
    fn a_best_point_with_one_scored_seed_is_shown_as_a_single_run() {
        // The finalists' extra seeds are not scored yet: the best point has one run.
        let sweep = finalist_sweep(3, 1);
        let mut queued = cell(3, 0, 1, 0.0);
        queued.state = pb::CellState::Queued as i32;
        queued.score = None;
        let mut running = cell(4, 1, 1, 0.0);
        running.state = pb::CellState::Running as i32;
        running.score = None;
        running.epochs_done = 300;
        let cells = [
            cell(1, 0, 0, 0.9),
            cell(2, 1, 0, 0.4),
            queued,
            running.clone(),
        ];
        let text = render_show(&sweep, &cells);
        assert!(text.contains("0.900 n=1/ 25%*"), "{text}");
        // The point w1 = 8 shows its scored seed; a cell on its own shows its epoch.
        assert!(text.contains("0.400 n=1/ 25%"), "{text}");
        assert_eq!(point_text(&[&running], 3, " "), "running@300 ");
        assert!(
            text.contains(
                "best (*): cell 1 on flat, w1 2.000, w2 -6.000, score 0.9000, fall rate 25.0%"
            ),
            "{text}"
        );
        assert!(text.contains("by level"), "{text}");
        assert!(!text.contains("replicates), mean fall rate"), "{text}");
    }
}
