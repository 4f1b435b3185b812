//! The page's paragraphs on one terrain's grid, and on the grid across terrains: its shape,
//! the points never rewarded, where w2 shapes the reward, one run's spread and the points
//! near the best.

use super::plots::fmt_w;
use super::text::{dof_text, point_names};
use super::ReportData;
use crate::near_best::SpreadSource;
use std::fmt::Write;

/// The grid's shape on terrain `t` ([`crate::shape`]), what the paper's findings are
/// read from: where the peak is, whether the score rises towards it, which w1 rows stand.
pub(super) fn shape_paragraph(o: &mut String, d: &ReportData, t: usize) {
    let Some(s) = d.shape(t) else {
        return;
    };
    let standing: Vec<String> = s
        .standing_rows
        .iter()
        .map(|&i| fmt_w(d.w1_values[i]))
        .collect();
    let _ = writeln!(
        o,
        "<p>Shape of the grid: the best point is w1 {}, w2 {} (mean {:.3}), {}; the score rises towards it on <b>{} of {}</b> steps between neighbouring points; the largest step between neighbouring points rewarded{}; rows of w1 standing still at every w2 (mean speed &lt; {} m/s; points never rewarded left out): {}.</p>",
        fmt_w(d.w1_values[s.peak.0]),
        fmt_w(d.w2_values[s.peak.1]),
        s.peak_mean,
        if s.interior { "inside the grid" } else { "on the grid's edge" },
        s.rising,
        s.steps,
        s.largest_step.as_ref().map_or_else(
            || ": none".to_string(),
            |l| format!(
                ", from {} to {}, is {:.2} of the range of their means \
                 (most of it: a cliff; a raised peak climbs in several steps)",
                point_names(d, &[l.points[0]]),
                point_names(d, &[l.points[1]]),
                l.share,
            )
        ),
        crate::shape::STANDING_SPEED,
        if standing.is_empty() { "none".to_string() } else { standing.join(", ") },
    );
}

/// The grid points of terrain `t` whose cells were never rewarded
/// ([`ReportCell::never_rewarded`](super::ReportCell::never_rewarded)): their score is not
/// a measure of what their weights teach.
pub(super) fn unrewarded_paragraph(o: &mut String, d: &ReportData, t: usize) {
    let points = d.unrewarded_points(t);
    if points.is_empty() {
        return;
    }
    let _ = writeln!(
        o,
        "<p>Points never rewarded: <b>{}</b> (w1, w2) = {}. Their mean reward per step was 0 at every epoch: \
         every step's reward was clipped to 0 (only_positive_rewards) because the penalties, the torque's above all, \
         outweighed the positive terms, so PPO had no reward to learn from. Their scores are those of policies that \
         their weights taught nothing, marked &ldquo;no reward&rdquo; in the heatmap.</p>",
        points.len(),
        point_names(d, &points),
    );
}

/// Where on terrain `t` the torque weight shapes the reward
/// ([`ReportData::negligible_torque_columns`]).
pub(super) fn torque_share_paragraph(o: &mut String, d: &ReportData, t: usize) {
    let cols = d.negligible_torque_columns(t);
    if cols.is_empty() {
        return;
    }
    let names: Vec<String> = cols.iter().map(|&j| fmt_w(d.w2_values[j])).collect();
    let _ = writeln!(
        o,
        "<p>Torque penalty under {:.0}% of the tracking reward (mean over training, every scored cell): w2 = {}. \
         There the weights give nearly the same reward whatever w2, so cells of one row differ by their runs' spread \
         more than by w2.</p>",
        100.0 * super::NEGLIGIBLE_TORQUE_SHARE,
        names.join(", "),
    );
}

/// The spread of one run on terrain `t`, read from the rows' runs of nearly the same reward
/// ([`ReportData::same_reward_rows`]).
pub(super) fn same_reward_paragraph(o: &mut String, d: &ReportData, t: usize) {
    let rows = d.same_reward_rows(t);
    let Some((pooled, dof)) = super::SameRewardRow::pooled(&rows) else {
        return;
    };
    // Student's t over the pooled degrees of freedom, as for the points near the best.
    let t975 = gaitsweep_core::stats::t975(dof);
    let items: Vec<String> = rows
        .iter()
        .map(|r| {
            let scores: Vec<String> = r.runs.iter().map(|&(_, v)| format!("{v:.3}")).collect();
            let w2s: Vec<String> = r.runs.iter().map(|&(j, _)| fmt_w(d.w2_values[j])).collect();
            format!(
                "<li>w1 = {}: {} (w2 = {}), mean {:.3}, SD <b>{:.3}</b></li>",
                fmt_w(d.w1_values[r.w1_index]),
                scores.join(" / "),
                w2s.join(", "),
                r.mean,
                r.sd,
            )
        })
        .collect();
    let _ = writeln!(
        o,
        "<p>Runs of nearly the same reward (first seed, torque penalty under {:.0}% of the tracking reward): \
         within a row they differ by their seeds, not their weights, so their spread is that of a single run. \
         Pooled SD <b>{:.3}</b> ({}): two single runs are told apart at 95% only when their \
         scores differ by more than {:.3} (t &middot; &radic;2 &middot; SD, t = {:.3}).</p>\n<ul>{}</ul>",
        100.0 * super::NEGLIGIBLE_TORQUE_SHARE,
        pooled,
        dof_text(dof),
        t975 * std::f64::consts::SQRT_2 * pooled,
        t975,
        items.join(""),
    );
}

/// The points of terrain `t` that its runs cannot tell apart from the best
/// ([`ReportData::near_best`]): the grid's answer as a set, with the spread it rests on.
pub(super) fn near_best_paragraph(o: &mut String, d: &ReportData, t: usize) {
    let Some(n) = d.near_best(t) else {
        return;
    };
    let source = match n.source {
        SpreadSource::Replicates if d.finalists => {
            "the finalists' seeds drawn after the selection (the first was picked for scoring high)"
        }
        SpreadSource::Replicates => "the seeds of the points trained more than once",
        // Rows at the grid's edge can spread far more than those at its top (stairs in the
        // ANYmal study: SD 0.297 at w1 = 5.33, 0.034 at 8.67), so this SD may be wide there.
        SpreadSource::SameReward => {
            "the runs of nearly the same reward above, pooled over rows of every level of \
             score, so the set is generous where the top rows spread less; the seeds of \
             points trained more than once (the finalists) replace it once scored"
        }
    };
    let _ = writeln!(
        o,
        "<p>Points not told apart from the best at 95%: <b>{} of {}</b> scored, {}. The best, {}, has mean {:.3} over {} run{}; \
         a point is behind it only when its mean is lower by more than t &middot; SD &middot; &radic;(1/n<sub>best</sub> + 1/n) \
         ({:.3} for a single run), with one run's SD {:.3} ({}) from {}.</p>",
        n.near.len(),
        n.scored,
        point_names(d, &n.near),
        point_names(d, &[n.best]),
        n.best_mean,
        n.best_runs,
        if n.best_runs == 1 { "" } else { "s" },
        n.lsd(1),
        n.sd,
        dof_text(n.dof),
        source,
    );
}

/// The points near the best on every terrain at once: the paper's overlap of the terrains'
/// peaks, read with each terrain's spread of one run.
pub(super) fn near_best_everywhere_paragraph(o: &mut String, d: &ReportData) {
    let per_terrain: Option<Vec<_>> = (0..d.terrains.len()).map(|t| d.near_best(t)).collect();
    let Some(per_terrain) = per_terrain else {
        o.push_str("<p class=\"note\">Points not told apart from the best on every terrain: not yet (a terrain has no spread of one run to read it with).</p>\n");
        return;
    };
    let _ = writeln!(
        o,
        "<p>Points not told apart from the best on every terrain at once (95%, each terrain's spread of one run): <b>{}</b>.</p>",
        point_names(d, &crate::near_best::near_best_everywhere(&per_terrain)),
    );
}
