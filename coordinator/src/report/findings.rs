//! `findings.md`: the paper's findings (Kim et al. 2024, Figs. 7-10) beside a grid sweep's,
//! one column per terrain, in Markdown for BENCHMARKS.md and README (issue 39 item 5). Every
//! figure is computed from the [`ReportData`] the rest of the report draws, so the write-up
//! cites a command, not numbers copied by hand.

use super::plots::fmt_w;
use super::text::{dof_text, point_names};
use super::ReportData;
use crate::near_best::{NearBest, SpreadSource};
use gaitsweep_model::{WalkCount, WALK_MAX_FALL_RATE, WALK_MAX_VEL_ERROR};
use std::fmt::Write;

/// What the paper says of each finding, quoted from its results (Section 5) and figure
/// captions, or what it leaves out.
mod paper {
    pub const BEST: &str = "the red cell of Figs. 7-10";
    pub const INTERIOR: &str = "ANYmal: \"located in the center of the grid\"";
    pub const RISING: &str =
        "ANYmal: \"the gait score tends to gradually increase towards this red area\"";
    pub const CLIFF: &str = "heavy robot: \"the form of a cliff rather than a raised peak\"";
    pub const STANDING: &str =
        "heavy robot: \"when w1 = 2, the robot learned to stop in place in all cases\"";
    pub const NEAR: &str = "not given (one run per cell, no spread)";
    pub const WALKS: &str = "not measured";
    pub const UNREWARDED: &str = "not reported";
    pub const GAIT: &str = "not reported (Eq. 4's score only)";
    pub const OVERLAP: &str = "ANYmal: \"there is an overlapping area in the two terrains\" \
        (Fig. 8); heavy robot: \"there are overlapping points in the peak values\" (Fig. 10); \
        ANYmal (Section 5): \"we can refer to the two gait score tables to select appropriate reward \
        weight values\"";
}

/// The findings of a grid sweep as Markdown; `None` for an evolutionary search, whose
/// candidates are not a grid.
pub fn markdown(d: &ReportData) -> Option<String> {
    if d.evolution.is_some() {
        return None;
    }
    let mut o = String::new();
    let _ = writeln!(
        o,
        "# The paper's findings beside sweep {} \"{}\" ({})\n",
        d.sweep_id,
        one_line(&d.name),
        d.robot
    );
    let _ = writeln!(
        o,
        "Written by `coordinator report` from the sweep's database (state: {}). Budget: {}.\n",
        d.state, d.budget
    );
    // The same seed trains differently on two CPU models: a figure names its machines.
    if let Some(m) = super::machines::summary(&d.cells, false) {
        let _ = writeln!(o, "{m}\n");
    }
    let near = near_of(d);
    let columns: Vec<(String, Column)> = d
        .terrains
        .iter()
        .cloned()
        .zip(columns_of(d, &near))
        .collect();
    table(&mut o, &columns);
    if d.terrains.len() > 1 {
        let _ = writeln!(o, "\nAcross terrains (the paper: {}):\n", paper::OVERLAP);
        for item in across_terrains(d, &near) {
            let _ = writeln!(o, "- {item}");
        }
    }
    Some(o)
}

/// The paper's findings beside several grid sweeps' in one table, one column per robot and
/// terrain: the write-up of a study recorded as one sweep per robot. Each sweep comes with
/// where it was read from, named in the text. Evolutionary searches are left to the caller
/// to refuse (their candidates are not a grid).
pub fn study_markdown(sweeps: &[(String, ReportData)]) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "# The paper's study: its findings beside the recordings\n\n\
         Written by `coordinator findings` from {} sweep{}, one column per robot and terrain:\n",
        sweeps.len(),
        if sweeps.len() == 1 { "" } else { "s" }
    );
    for (source, d) in sweeps {
        let _ = write!(
            o,
            "- {}: sweep {} \"{}\" read from {source} (state: {}). Budget: {}.",
            d.robot,
            d.sweep_id,
            one_line(&d.name),
            d.state,
            d.budget
        );
        if let Some(m) = super::machines::summary(&d.cells, false) {
            let _ = write!(o, " {m}");
        }
        o.push('\n');
    }
    o.push('\n');
    let near: Vec<Vec<Option<NearBest>>> = sweeps.iter().map(|(_, d)| near_of(d)).collect();
    let columns: Vec<(String, Column)> = sweeps
        .iter()
        .zip(&near)
        .flat_map(|((_, d), n)| {
            d.terrains
                .iter()
                .map(|t| format!("{} {t}", d.robot))
                .zip(columns_of(d, n))
        })
        .collect();
    table(&mut o, &columns);
    let several: Vec<_> = sweeps
        .iter()
        .zip(&near)
        .filter(|((_, d), _)| d.terrains.len() > 1)
        .collect();
    if !several.is_empty() {
        let _ = writeln!(o, "\nAcross terrains (the paper: {}):\n", paper::OVERLAP);
        for ((_, d), n) in several {
            let _ = writeln!(o, "- {}:", d.robot);
            for item in across_terrains(d, n) {
                let _ = writeln!(o, "  - {item}");
            }
        }
    }
    o
}

/// Each terrain's points near the best, read once for its column and for the overlap.
fn near_of(d: &ReportData) -> Vec<Option<NearBest>> {
    (0..d.terrains.len()).map(|t| d.near_best(t)).collect()
}

/// One [`Column`] a terrain, in the sweep's terrain order.
fn columns_of(d: &ReportData, near: &[Option<NearBest>]) -> Vec<Column> {
    near.iter()
        .enumerate()
        .map(|(t, n)| column(d, t, n.as_ref()))
        .collect()
}

/// The table of findings: the paper's column, then one a `(heading, column)`.
fn table(o: &mut String, columns: &[(String, Column)]) {
    let mut header = "| | the paper (Kim et al. 2024) |".to_string();
    let mut rule = "|---|---|".to_string();
    for (heading, _) in columns {
        let _ = write!(header, " {} |", cell_text(heading));
        rule.push_str("---|");
    }
    let _ = writeln!(o, "{header}\n{rule}");
    let standing = format!(
        "rows of w1 standing still at every w2 (mean speed < {} m/s; points never rewarded left out)",
        crate::shape::STANDING_SPEED
    );
    let walks = format!(
        "cells that walk (falls <= {:.0}%, |v_cmd - v| <= {} m/s, mean over the levels)",
        100.0 * WALK_MAX_FALL_RATE,
        WALK_MAX_VEL_ERROR
    );
    let rows: [(&str, &str, Field); 10] = [
        ("cells scored", "every cell, one run each", |c| &c.scored),
        ("best point (w1, w2): mean score", paper::BEST, |c| &c.best),
        (
            "the best point's gait: does Eq. 4's top point fall or overspeed?",
            paper::GAIT,
            |c| &c.best_gait,
        ),
        ("where the best point lies", paper::INTERIOR, |c| &c.place),
        (
            "steps between neighbouring points where the score rises towards the best",
            paper::RISING,
            |c| &c.rising,
        ),
        (
            "largest step between neighbouring points rewarded, as a share of the range of their means",
            paper::CLIFF,
            |c| &c.largest_step,
        ),
        (&standing, paper::STANDING, |c| &c.standing),
        (
            "points not told apart from the best at 95%",
            paper::NEAR,
            |c| &c.near,
        ),
        (&walks, paper::WALKS, |c| &c.walks),
        (
            "points never rewarded (mean reward per step 0 at every epoch)",
            paper::UNREWARDED,
            |c| &c.unrewarded,
        ),
    ];
    for (label, said, value) in rows {
        let _ = write!(o, "| {} | {} |", cell_text(label), cell_text(said));
        for (_, c) in columns {
            let _ = write!(o, " {} |", cell_text(value(c)));
        }
        o.push('\n');
    }
}

/// A name on one line, with its double quotes made single (it is written in quotes).
fn one_line(s: &str) -> String {
    s.replace('"', "'").replace('\n', " ")
}

/// Reads one figure of a [`Column`].
type Field = fn(&Column) -> &str;

/// One terrain's figures, each as the text of its table cell.
struct Column {
    scored: String,
    best: String,
    best_gait: String,
    place: String,
    rising: String,
    largest_step: String,
    standing: String,
    near: String,
    walks: String,
    unrewarded: String,
}

fn column(d: &ReportData, t: usize, near: Option<&NearBest>) -> Column {
    let cells = d.cells_of(t).count();
    let scored: Vec<_> = d.cells_of(t).filter(|c| c.value().is_some()).collect();
    let points = d.w1_values.len() * d.w2_values.len();
    let scored_points = d
        .grid_mean(t, |c| c.value())
        .iter()
        .flatten()
        .flatten()
        .count();
    let shape = d.shape(t);
    let none = || "none scored".to_string();
    let runs_at = |p: (usize, usize)| scored.iter().filter(|c| c.grid() == Some(p)).count();
    let walking = WalkCount::of(d.cells_of(t).filter_map(|c| c.score.as_ref()));
    let best_point = near.map(|n| n.best).or(shape.as_ref().map(|s| s.peak));
    Column {
        best_gait: best_point.map_or_else(none, |p| gait_at(&scored, p)),
        scored: format!(
            "{} of {cells} cells; {scored_points} of {points} grid points",
            scored.len()
        ),
        best: match (near, &shape) {
            // The interval of the best point's mean with one run's SD, which pools more
            // degrees of freedom than the point's own few seeds; nominal, as for a point
            // named in advance: the highest of many means reads high.
            (Some(nb), _) => format!(
                "{}: {:.3} \u{b1} {:.3} over {} run{} (nominal 95% for this point alone, one run's SD {:.3}; \
                 the highest of {} points' means reads high)",
                point_names(d, &[nb.best]),
                nb.best_mean,
                gaitsweep_core::stats::t975(nb.dof) * nb.sd / (nb.best_runs.max(1) as f64).sqrt(),
                nb.best_runs,
                if nb.best_runs == 1 { "" } else { "s" },
                nb.sd,
                nb.scored,
            ),
            (None, Some(s)) => {
                let n = runs_at(s.peak);
                format!(
                    "{}: {:.3} over {n} run{} (no spread of one run measured yet)",
                    point_names(d, &[s.peak]),
                    s.peak_mean,
                    if n == 1 { "" } else { "s" }
                )
            }
            (None, None) => none(),
        },
        place: shape.as_ref().map_or_else(none, |s| {
            if s.interior {
                "inside the grid".into()
            } else {
                "on the grid's edge".into()
            }
        }),
        rising: shape.as_ref().map_or_else(none, |s| {
            if s.steps == 0 {
                "no neighbouring points scored".into()
            } else {
                format!(
                    "{} of {} ({:.0}%)",
                    s.rising,
                    s.steps,
                    100.0 * s.rising as f64 / s.steps as f64
                )
            }
        }),
        largest_step: shape
            .as_ref()
            .and_then(|s| s.largest_step.as_ref())
            .map_or_else(
                || "no step measured".into(),
                |l| {
                    format!(
                        "{:.2}, {} to {}",
                        l.share,
                        point_names(d, &[l.points[0]]),
                        point_names(d, &[l.points[1]])
                    )
                },
            ),
        standing: shape.as_ref().map_or_else(none, |s| {
            if s.standing_rows.is_empty() {
                "none".into()
            } else {
                let rows: Vec<String> = s
                    .standing_rows
                    .iter()
                    .map(|&i| format!("w1 = {}", fmt_w(d.w1_values[i])))
                    .collect();
                rows.join(", ")
            }
        }),
        near: near.map_or_else(
            || "not yet (no spread of one run measured)".into(),
            |n| {
                format!(
                    "{} of {} scored points: {}; one run's SD {:.3} ({}, {})",
                    n.near.len(),
                    n.scored,
                    point_names(d, &n.near),
                    n.sd,
                    dof_text(n.dof),
                    match n.source {
                        SpreadSource::Replicates if d.finalists => {
                            "the finalists' seeds drawn after the selection"
                        }
                        SpreadSource::Replicates =>
                            "the seeds of the points trained more than once",
                        SpreadSource::SameReward => "runs of nearly the same reward",
                    }
                )
            },
        ),
        walks: format!(
            "{} of {} ({} at every level)",
            walking.walks, walking.scored, walking.at_every_level
        ),
        unrewarded: point_names(d, &d.unrewarded_points(t)),
    }
}

/// How the runs of grid point `p` among `scored` (cells with a finite score) walk: their
/// mean fall rate, velocity error, speed and overspeed (each already a mean over the levels).
fn gait_at(scored: &[&super::ReportCell], p: (usize, usize)) -> String {
    let runs: Vec<_> = scored
        .iter()
        .filter(|c| c.grid() == Some(p))
        .filter_map(|c| c.score.as_ref())
        .collect();
    if runs.is_empty() {
        return "none scored".into();
    }
    // Scores stored before a metric existed read it as NaN: "not recorded", not "NaN m/s".
    let mean =
        |f: fn(&gaitsweep_model::GaitScore) -> f64, unit: &str, scale: f64, digits: usize| {
            let v: Vec<f64> = runs
                .iter()
                .map(|s| f(s))
                .filter(|v| v.is_finite())
                .collect();
            if v.is_empty() {
                "not recorded".to_string()
            } else {
                format!(
                    "{:.digits$}{unit}",
                    scale * v.iter().sum::<f64>() / v.len() as f64
                )
            }
        };
    format!(
        "falls {}, |v_cmd - v| {}, mean speed {}, overspeed {} (mean over {} run{} and the levels)",
        mean(|s| s.fall_rate, "%", 100.0, 1),
        mean(|s| s.mean_vel_error, " m/s", 1.0, 3),
        mean(|s| s.mean_speed, " m/s", 1.0, 3),
        mean(|s| s.overspeed, " m/s", 1.0, 3),
        runs.len(),
        if runs.len() == 1 { "" } else { "s" },
    )
}

/// The paper's overlap of the terrains' peaks, read three ways: with each terrain's spread
/// of one run, by top quartile, and by the rule that picks the weights for every terrain;
/// one list item each.
fn across_terrains(d: &ReportData, near: &[Option<NearBest>]) -> [String; 3] {
    let per_terrain: Option<Vec<NearBest>> = near.iter().cloned().collect();
    let near = per_terrain.map_or_else(
        || "not yet (a terrain has no spread of one run)".into(),
        |p| point_names(d, &crate::near_best::near_best_everywhere(&p)),
    );
    let rule = d.across().map_or_else(
        || "not yet (no point scored on every terrain with a positive best score)".into(),
        |a| {
            format!(
                "{}, its weakest terrain ({}) at {:.1}% of that terrain's best mean {}",
                point_names(d, &[(a.w1_index as usize, a.w2_index as usize)]),
                d.terrains.get(a.weakest).map_or("?", String::as_str),
                100.0 * a.value,
                a.interval_text()
            )
        },
    );
    [
        format!("points not told apart from the best on every terrain at once: {near}"),
        format!(
            "points in the top quartile of every terrain: {}",
            point_names(d, &d.overlap().0)
        ),
        format!(
            "the weights for every terrain ({}): {rule}",
            crate::across::RULE
        ),
    ]
}

/// Text safe inside a Markdown table cell.
fn cell_text(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_cells_escape_their_bars() {
        assert_eq!(cell_text("|v| a\nb"), "\\|v\\| a b");
    }
}
