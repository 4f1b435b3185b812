//! `index.html`: the report's pictures, the promoted cell, the gait GIF and the table of
//! cells, in one self-contained page (no scripts, no external files).

use super::paragraphs;
use super::plots::{fmt_w, COMPONENTS};
use super::text::point_names;
use super::{slug, GifStatus, ReportData};
use gaitsweep_model::{WalkCount, WALK_MAX_FALL_RATE, WALK_MAX_VEL_ERROR};
use std::fmt::Write;
use std::path::PathBuf;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn num(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.4}")
    } else {
        "NaN".into()
    }
}

/// The page.
pub fn index(d: &ReportData, files: &[PathBuf], gif: &GifStatus) -> String {
    let have = |name: &str| {
        files
            .iter()
            .any(|f| f.file_name().is_some_and(|n| n == name))
    };
    let fig = |o: &mut String, stem: &str, alt: &str, class: &str| {
        if have(&format!("{stem}.png")) {
            let _ = writeln!(
                o,
                "<figure class=\"{class}\"><a href=\"{stem}.svg\"><img src=\"{stem}.png\" alt=\"{alt}\"></a><figcaption>{alt} (<a href=\"{stem}.svg\">SVG</a>)</figcaption></figure>",
                alt = esc(alt)
            );
        }
    };
    let mut o = String::new();
    let title = format!(
        "gaitsweep report: sweep {} \u{201c}{}\u{201d}",
        d.sweep_id, d.name
    );
    let _ = write!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n<style>\n\
         body{{font-family:sans-serif;margin:2em;max-width:1500px;color:#222}}\n\
         img{{max-width:100%;border:1px solid #ddd}} figure{{display:inline-block;margin:0.5em;vertical-align:top;max-width:760px}}\n\
         figure.wide{{max-width:1250px}} table{{border-collapse:collapse;font-size:0.9em}}\n\
         td,th{{border:1px solid #ccc;padding:3px 8px;text-align:right}} th{{background:#f0f0f0}}\n\
         tr.best{{background:#ffe9a8;font-weight:bold}} .note{{color:#a33}} code{{background:#f4f4f4;padding:0 3px}}\n\
         </style></head><body>\n<h1>{}</h1>\n",
        esc(&title),
        esc(&title)
    );
    let terrains = d.terrains.join(", ");
    let scored = d.cells.iter().filter(|c| c.score.is_some()).count();
    let _ = write!(
        o,
        "<p>Robot <b>{}</b>, terrains <b>{}</b>{}, state <b>{}</b>: {} of {} cells scored. \
         Grid: w1 (velocity-tracking weight) = {}; w2 (log10 of the torque-penalty weight) = {}. \
         The gait score is J = mean(track \u{2212} effort \u{2212} tilt) + progress (higher is better), averaged over the evaluation's levels.</p>\n\
         <p>Budget: {}.</p>\n",
        esc(&d.robot),
        esc(&terrains),
        d.difficulty.map(|x| format!(" (difficulty {x})")).unwrap_or_default(),
        esc(&d.state),
        scored,
        d.cells.len(),
        d.w1_values.iter().map(|v| fmt_w(*v)).collect::<Vec<_>>().join(", "),
        d.w2_values.iter().map(|v| fmt_w(*v)).collect::<Vec<_>>().join(", "),
        esc(&d.budget),
    );
    if let Some(m) = super::machines::summary(&d.cells, true) {
        let _ = writeln!(
            o,
            "<p>{} The same seed trains differently on two CPU models, so a result names the CPUs it was trained on.</p>",
            esc(&m)
        );
    }

    if have(super::FINDINGS_FILE) {
        let _ = writeln!(
            o,
            "<p>The paper's findings beside this sweep's, one column per terrain, as a Markdown table: <a href=\"{0}\">{0}</a>.</p>",
            super::FINDINGS_FILE
        );
    }

    o.push_str("<h2>Promoted policy</h2>\n");
    let promoted = d.promoted();
    match promoted {
        Some(c) => {
            let s = c.score.clone().unwrap_or_default();
            let _ = writeln!(
                o,
                "<p>Cell <b>{}</b> on <b>{}</b>: w1 = <b>{}</b>, w2 = <b>{}</b> (torque weight 10^{}), gait score <b>{}</b> \
                 (track {}, effort {}, tilt {}, progress {}; fall rate {}, |v_cmd \u{2212} v| {} m/s). \
                 Download it with <code>coordinator fetch-best {}</code>.</p>",
                c.id,
                esc(&c.terrain),
                fmt_w(c.w1),
                fmt_w(c.w2),
                fmt_w(c.w2),
                num(s.score),
                num(s.track),
                num(s.effort),
                num(s.tilt),
                num(s.progress),
                num(s.fall_rate),
                num(s.mean_vel_error),
                d.sweep_id
            );
            if !s.levels.is_empty() {
                let by: Vec<String> = s
                    .levels
                    .iter()
                    .map(|l| {
                        format!(
                            "level {}: score {}, fall rate {}, |v_cmd \u{2212} v| {} m/s",
                            l.level,
                            num(l.score.score),
                            num(l.score.fall_rate),
                            num(l.score.mean_vel_error)
                        )
                    })
                    .collect();
                let _ = writeln!(
                    o,
                    "<p>By evaluation level: {}; overspeed {} m/s.</p>",
                    esc(&by.join("; ")),
                    num(s.overspeed)
                );
            }
            if d.terrains.len() > 1 {
                o.push_str("<p>Best per terrain: ");
                let per: Vec<String> = d
                    .terrains
                    .iter()
                    .enumerate()
                    .filter_map(|(t, name)| {
                        let p = d
                            .promotions
                            .iter()
                            .find(|p| &p.terrain == name)
                            .and_then(|p| d.cell(p.cell_id))
                            .or_else(|| d.best_cell(Some(t)))?;
                        Some(format!(
                            "{}: cell {} (w1 {}, w2 {}, score {})",
                            esc(name),
                            p.id,
                            fmt_w(p.w1),
                            fmt_w(p.w2),
                            num(p.value().unwrap_or(f64::NAN))
                        ))
                    })
                    .collect();
                o.push_str(&per.join("; "));
                o.push_str("</p>\n");
            }
        }
        None => o.push_str("<p class=\"note\">No cell has a score yet: nothing is promoted.</p>\n"),
    }
    match gif {
        GifStatus::Written(f) => {
            let _ = writeln!(
                o,
                "<figure><img src=\"{f}\" alt=\"gait of the promoted policy\"><figcaption>The promoted policy walking on its terrain \
                 (deterministic actions, one robot; body red, legs blue, feet black).</figcaption></figure>",
                f = esc(f)
            );
        }
        GifStatus::NotMade(why) => {
            let _ = writeln!(o, "<p class=\"note\">No gait GIF: {}</p>", esc(why));
        }
    }

    for terrain in &d.terrains {
        let s = slug(terrain);
        let _ = writeln!(o, "<h2>Terrain: {}</h2>", esc(terrain));
        if let Some(t) = d.terrains.iter().position(|x| x == terrain) {
            let walking = WalkCount::of(d.cells_of(t).filter_map(|c| c.score.as_ref()));
            if walking.scored > 0 {
                let _ = writeln!(
                    o,
                    "<p>Cells that walk: <b>{}</b> of {} scored (fall rate &le; {:.0}% and |v_cmd &minus; v| &le; {} m/s, \
                     mean over the evaluation levels); at every level: <b>{}</b>.</p>",
                    walking.walks,
                    walking.scored,
                    100.0 * WALK_MAX_FALL_RATE,
                    WALK_MAX_VEL_ERROR,
                    walking.at_every_level,
                );
            }
            if d.evolution.is_none() {
                paragraphs::shape_paragraph(&mut o, d, t);
                paragraphs::unrewarded_paragraph(&mut o, d, t);
                paragraphs::torque_share_paragraph(&mut o, d, t);
                paragraphs::same_reward_paragraph(&mut o, d, t);
                paragraphs::near_best_paragraph(&mut o, d, t);
            }
        }
        fig(
            &mut o,
            &format!("candidates_{s}"),
            &format!("the evolutionary search's candidates on {terrain}, by generation"),
            "",
        );
        fig(
            &mut o,
            &format!("score_{s}"),
            &format!("gait score over (w1, w2) on {terrain}"),
            "",
        );
        fig(
            &mut o,
            &format!("fall_rate_{s}"),
            &format!("fall rate of each cell's evaluation on {terrain} (lower is better)"),
            "",
        );
        fig(
            &mut o,
            &format!("surface_{s}"),
            &format!("gait score surface on {terrain}"),
            "",
        );
        fig(
            &mut o,
            &format!("torque_share_{s}"),
            &format!("torque penalty against tracking reward on {terrain}, the contrast w2 sets"),
            "",
        );
        o.push_str("<h3>Score components</h3>\n");
        for (name, label, _) in COMPONENTS {
            fig(
                &mut o,
                &format!("{name}_{s}"),
                &format!("{name} on {terrain}: {label}"),
                "",
            );
        }
        o.push_str("<h3>Learning curves</h3>\n");
        fig(
            &mut o,
            &format!("curves_{s}"),
            &format!("learning curves of every cell on {terrain} (promoted cell drawn thick)"),
            "wide",
        );
    }
    if d.terrains.len() > 1 {
        o.push_str("<h2>Overlap across terrains</h2>\n");
        match d.across() {
            Some(a) => {
                let rel: Vec<String> = d
                    .terrains
                    .iter()
                    .zip(&a.relative)
                    .map(|(t, r)| format!("{t} {:.1}%", 100.0 * r))
                    .collect();
                let _ = writeln!(
                    o,
                    "<p>Weights for every terrain ({}): <b>w1 {}, w2 {}</b>, {:.1}% {} of the best point on its weakest terrain, {} ({}).</p>",
                    esc(crate::across::RULE),
                    fmt_w(d.w1_values[a.w1_index as usize]),
                    fmt_w(d.w2_values[a.w2_index as usize]),
                    100.0 * a.value,
                    a.interval_text(),
                    esc(&d.terrains[a.weakest]),
                    esc(&rel.join(", "))
                );
            }
            None => o.push_str("<p class=\"note\">No grid point is scored on every terrain with a positive best score yet: no weights for every terrain.</p>\n"),
        }
        if d.evolution.is_none() {
            paragraphs::near_best_everywhere_paragraph(&mut o, d);
        }
        let (cells, _) = d.overlap();
        let _ = writeln!(
            o,
            "<p>Grid points (w1, w2) whose mean score is in the top quartile of their terrain's points on every terrain at once: {}.</p>",
            point_names(d, &cells)
        );
        fig(
            &mut o,
            "overlap",
            "grid points in the top quartile on every terrain (boxed)",
            "",
        );
    }

    o.push_str("<h2>Cells</h2>\n<table>\n<tr><th>cell</th><th>terrain</th><th>w1</th><th>w2</th><th>replicate</th><th>state</th><th>epochs</th><th>attempts</th>\
                <th>score</th><th>track</th><th>effort</th><th>tilt</th><th>progress</th><th>bounded progress</th><th>fall rate</th><th>|v_cmd \u{2212} v|</th>\
                <th>overspeed (m/s)</th><th>mean |\u{3c4}|</th><th>cost of transport</th><th>by level: score / falls</th><th>trained on (CPU, epochs)</th><th>error</th></tr>\n");
    let best_id = promoted.map(|c| c.id);
    for c in &d.cells {
        let class = if Some(c.id) == best_id {
            " class=\"best\""
        } else {
            ""
        };
        let _ = write!(
            o,
            "<tr{class}><td>{}{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
            c.id,
            if Some(c.id) == best_id { " \u{2605}" } else { "" },
            esc(&c.terrain),
            fmt_w(c.w1),
            fmt_w(c.w2),
            c.replicate,
            esc(&c.state),
            c.epochs_done,
            c.attempts
        );
        match &c.score {
            Some(s) => {
                for v in [
                    s.score,
                    s.track,
                    s.effort,
                    s.tilt,
                    s.progress,
                    s.progress_bounded,
                    s.fall_rate,
                    s.mean_vel_error,
                    s.overspeed,
                    s.mean_abs_torque,
                    s.cost_of_transport,
                ] {
                    let _ = write!(o, "<td>{}</td>", num(v));
                }
                let levels: Vec<String> = s
                    .levels
                    .iter()
                    .map(|l| {
                        format!(
                            "L{} {} / {:.0}%",
                            l.level,
                            num(l.score.score),
                            100.0 * l.score.fall_rate
                        )
                    })
                    .collect();
                let _ = write!(o, "<td>{}</td>", esc(&levels.join(" \u{b7} ")));
            }
            None => o.push_str(&"<td></td>".repeat(12)),
        }
        let _ = write!(
            o,
            "<td>{}</td>",
            esc(&super::machines::spans_text(&c.trained_on))
        );
        let note = [
            c.never_rewarded().then_some(NEVER_REWARDED),
            c.last_error.as_deref(),
        ];
        let note: Vec<&str> = note.into_iter().flatten().collect();
        let _ = writeln!(o, "<td>{}</td></tr>", esc(&note.join("; ")));
    }
    o.push_str("</table>\n<p>Every value comes from the coordinator's database (tables cells, scores, level_scores, epoch_metrics, promotions, attempts and workers). \
                Overspeed is the mean of max(0, |v| \u{2212} |v_cmd|): how much faster than commanded the robots ran, which Eq. 4's progress term pays for.</p>\n</body></html>\n");
    o
}

/// What the cell table says of a cell that was never rewarded.
const NEVER_REWARDED: &str = "never rewarded: mean reward per step 0 at every epoch";
