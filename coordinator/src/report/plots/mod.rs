//! The report's pictures, drawn with plotters into PNG (bitmap backend) and SVG. Text is
//! set in an embedded DejaVu Sans subset (assets/), so nothing depends on system fonts.

use super::{slug, ReportCell, ReportData};
use crate::shape::GridValues;
use crate::{Error, Result};
use plotters::coord::ranged1d::SegmentValue;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// DejaVu Sans (Latin-1 and a few symbols), see assets/FONT-LICENSE.txt.
static FONT: &[u8] = include_bytes!("../../../assets/DejaVuSans-subset.ttf");
const SANS: &str = "sans-serif";

/// Registers the embedded font under every family name plotters asks for.
pub fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for family in ["sans-serif", "serif", "monospace"] {
            for style in [FontStyle::Normal, FontStyle::Bold] {
                if plotters::style::register_font(family, style, FONT).is_err() {
                    tracing::error!(
                        "embedded font does not load: report pictures will have no text"
                    );
                }
            }
        }
    });
}

/// Viridis-like colour of `t` in [0, 1] (dark purple to yellow).
pub fn colormap(t: f64) -> RGBColor {
    const STOPS: [(f64, [f64; 3]); 7] = [
        (0.0, [68.0, 1.0, 84.0]),
        (0.166, [68.0, 57.0, 131.0]),
        (0.333, [49.0, 104.0, 142.0]),
        (0.5, [33.0, 145.0, 140.0]),
        (0.666, [53.0, 183.0, 121.0]),
        (0.833, [144.0, 215.0, 67.0]),
        (1.0, [253.0, 231.0, 37.0]),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let k = STOPS
        .iter()
        .position(|s| s.0 >= t)
        .unwrap_or(STOPS.len() - 1)
        .max(1);
    let (a, b) = (STOPS[k - 1], STOPS[k]);
    let f = ((t - a.0) / (b.0 - a.0)).clamp(0.0, 1.0);
    let c = |i: usize| (a.1[i] + (b.1[i] - a.1[i]) * f).round() as u8;
    RGBColor(c(0), c(1), c(2))
}

/// The largest font size up to `max` at which `text` fits `width` pixels (less a margin)
/// of `area`, measured with the font itself.
fn fit<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, text: &str, width: u32, max: f64) -> f64 {
    let room = width.saturating_sub(40).max(100);
    let mut size = max;
    while size > 10.0 {
        match area.estimate_text_size(text, &TextStyle::from((SANS, size).into_font())) {
            Ok((w, _)) if w > room => size -= 1.0,
            _ => break,
        }
    }
    size
}

/// Draws a figure's title and subtitle (each shrunk to fit `width`) in a 78-pixel band at
/// the top of `root` and returns the area below it.
fn draw_header<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    subtitle: &str,
    width: u32,
) -> FigResult<DrawingArea<DB, Shift>>
where
    DB::ErrorType: 'static,
{
    let (head, body) = root.split_vertically(78);
    for (text, y, size, color) in [
        (title, 12, 26.0, BLACK),
        (subtitle, 46, 17.0, RGBColor(80, 80, 80)),
    ] {
        head.draw(&Text::new(
            text.to_string(),
            (20, y),
            (SANS, fit(&head, text, width, size))
                .into_font()
                .color(&color),
        ))?;
    }
    Ok(body)
}

fn luminance(c: RGBColor) -> f64 {
    (0.299 * c.0 as f64 + 0.587 * c.1 as f64 + 0.114 * c.2 as f64) / 255.0
}

/// A plotting error as text: each backend has its own error type, and a figure is drawn
/// on two (PNG and SVG).
struct DrawError(String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for DrawError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        DrawError(e.to_string())
    }
}

impl std::fmt::Display for DrawError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

type FigResult<T> = std::result::Result<T, DrawError>;

/// A picture that can be drawn on any backend.
trait Figure {
    fn size(&self) -> (u32, u32);
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> FigResult<()>
    where
        DB::ErrorType: 'static;
}

/// Writes `out/stem.png` and `out/stem.svg`.
fn save<F: Figure>(fig: &F, out: &Path, stem: &str) -> Result<Vec<PathBuf>> {
    register_fonts();
    let png = out.join(format!("{stem}.png"));
    let svg = out.join(format!("{stem}.svg"));
    {
        let root = BitMapBackend::new(&png, fig.size()).into_drawing_area();
        fig.draw(&root)
            .map_err(plot(format!("draw {}", png.display())))?;
        root.present()
            .map_err(plot(format!("write {}", png.display())))?;
    }
    {
        let root = SVGBackend::new(&svg, fig.size()).into_drawing_area();
        fig.draw(&root)
            .map_err(plot(format!("draw {}", svg.display())))?;
        root.present()
            .map_err(plot(format!("write {}", svg.display())))?;
    }
    Ok(vec![png, svg])
}

/// Maps a plotting error (a figure's [`DrawError`] or a backend's own) to [`Error::Plot`]
/// with what was being done.
fn plot<E: std::fmt::Display>(what: String) -> impl FnOnce(E) -> Error {
    move |e| Error::Plot {
        what,
        message: e.to_string(),
    }
}

/// Formats a grid value for an axis (w1, w2).
pub fn fmt_w(v: f64) -> String {
    if (v - v.round()).abs() < 1e-9 {
        format!("{}", v.round() as i64)
    } else {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn fmt_value(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e4).contains(&a) {
        format!("{v:.2e}")
    } else if a >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

/// A tick label: values within a millionth of the axis span of zero are zero.
fn fmt_tick(v: f64, span: f64) -> String {
    let v = if v.abs() < span.abs() * 1e-6 { 0.0 } else { v };
    if !(span.is_finite() && span > 0.0) || v.abs() >= 1e5 || (v != 0.0 && v.abs() < 1e-4) {
        return fmt_value(v);
    }
    let decimals = (-(span / 10.0).log10()).ceil().clamp(0.0, 6.0) as usize;
    format!("{v:.decimals$}")
}

fn value_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    if hi - lo < 1e-12 {
        let pad = (lo.abs() * 0.05).max(1e-3);
        return Some((lo - pad, hi + pad));
    }
    Some((lo, hi))
}

mod candidates;
mod curves;
mod heatmap;
mod surface;

use candidates::{Candidate, Candidates};
use curves::Curves;
use heatmap::{Better, Heatmap};
use surface::Surface;

/// The component heatmaps: name, column label, which direction is better.
pub const COMPONENTS: [(&str, &str, bool); 4] = [
    ("track", "velocity tracking (higher is better)", true),
    (
        "effort",
        "normalised torque effort (lower is better)",
        false,
    ),
    ("tilt", "base tilt (lower is better)", false),
    (
        "progress",
        "ground covered, m\u{b2} per step sum (higher is better)",
        true,
    ),
];

fn component(c: &ReportCell, name: &str) -> Option<f64> {
    let s = c.score.as_ref()?;
    Some(match name {
        "track" => s.track,
        "effort" => s.effort,
        "tilt" => s.tilt,
        "progress" => s.progress,
        _ => s.score,
    })
}

fn notes(d: &ReportData, t: usize) -> Vec<Vec<String>> {
    d.grid(t, String::new(), |c| {
        match (&c.score, c.state.as_str(), c.rung) {
            (Some(_), _, _) => "NaN".into(),
            // A cell successive halving stopped: where, and its gait score there (named, as the
            // same note stands on the fall-rate and component maps).
            (None, "stopped", Some((epoch, score))) => {
                format!("stopped at {epoch}\nscore {score:.3}")
            }
            _ => c.state.clone(),
        }
    })
}

/// Draws every picture; returns the files written.
pub fn draw_all(d: &ReportData, out: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let who = format!(
        "sweep {} \u{201c}{}\u{201d}, robot {}",
        d.sweep_id, d.name, d.robot
    );
    if let Some(bounds) = d.evolution {
        return draw_evolution(d, out, &who, bounds);
    }
    for (t, terrain) in d.terrains.iter().enumerate() {
        let s = slug(terrain);
        let scored = d.cells_of(t).filter(|c| c.value().is_some()).count();
        let total = d.cells_of(t).count();
        let near = d.near_best(t).map(|n| n.near).unwrap_or_default();
        let heat = Heatmap {
            title: format!("Gait score on {terrain}: {who}"),
            subtitle: format!(
                "{scored} of {total} cells scored; higher is better; \u{2605} marks the best cell{}{}",
                if d.terrains.len() > 1 { " on this terrain" } else { "" },
                if near.is_empty() { "" } else { "; near best: not told apart from it at 95%" }
            ),
            bar_label: "gait score".into(),
            w1: &d.w1_values,
            w2: &d.w2_values,
            values: d.grid_mean(t, |c| c.value()),
            notes: notes(d, t),
            better: Better::Higher,
            marks: vec![],
            unrewarded: d.unrewarded_points(t),
            near,
            integer: false,
            log10: false,
        };
        files.extend(save(&heat, out, &format!("score_{s}"))?);
        let falls = Heatmap {
            title: format!("Fall rate on {terrain}: {who}"),
            subtitle:
                "fraction of the evaluation robots that fell; lower is better; a score is only \
                       comparable between cells that walk"
                    .into(),
            bar_label: "fall rate".into(),
            w1: &d.w1_values,
            w2: &d.w2_values,
            values: d.grid_mean(t, |c| {
                c.score
                    .as_ref()
                    .map(|s| s.fall_rate)
                    .filter(|v| v.is_finite())
            }),
            notes: notes(d, t),
            better: Better::Lower,
            marks: vec![],
            unrewarded: vec![],
            near: vec![],
            integer: false,
            log10: false,
        };
        files.extend(save(&falls, out, &format!("fall_rate_{s}"))?);
        let surf = Surface {
            title: format!("Gait score surface on {terrain}: {who}"),
            subtitle: "x: log10 torque weight w2, depth: w1 (tracking weight), height: gait score"
                .into(),
            w1: &d.w1_values,
            w2: &d.w2_values,
            values: d.grid_mean(t, |c| c.value()),
        };
        files.extend(save(&surf, out, &format!("surface_{s}"))?);
        let share = d.grid_mean(t, |c| c.torque_share().filter(|v| *v > 0.0).map(f64::log10));
        if share.iter().flatten().any(Option::is_some) {
            let heat = Heatmap {
                title: format!("Torque penalty against tracking reward on {terrain}: {who}"),
                subtitle: format!(
                    "mean over training of |torque penalty| / tracking reward per step; under {:.0}%, w2 hardly shapes the reward",
                    100.0 * super::NEGLIGIBLE_TORQUE_SHARE
                ),
                bar_label: "log10 of torque penalty / tracking reward".into(),
                w1: &d.w1_values,
                w2: &d.w2_values,
                values: share,
                notes: notes(d, t),
                better: Better::None,
                marks: vec![],
                unrewarded: d.unrewarded_points(t),
                near: vec![],
                integer: false,
                log10: true,
            };
            files.extend(save(&heat, out, &format!("torque_share_{s}"))?);
        }
        for (name, label, higher) in COMPONENTS {
            let heat = Heatmap {
                title: format!("Score component \u{201c}{name}\u{201d} on {terrain}: {who}"),
                subtitle: format!("{label}; \u{2605} marks the best cell by this component"),
                bar_label: name.into(),
                w1: &d.w1_values,
                w2: &d.w2_values,
                values: d.grid_mean(t, |c| component(c, name).filter(|v| v.is_finite())),
                notes: notes(d, t),
                better: if higher {
                    Better::Higher
                } else {
                    Better::Lower
                },
                marks: vec![],
                unrewarded: vec![],
                near: vec![],
                integer: false,
                log10: false,
            };
            files.extend(save(&heat, out, &format!("{name}_{s}"))?);
        }
        let curves = Curves {
            title: format!("Learning curves on {terrain}: {who}"),
            cells: d.cells_of(t).collect(),
            promoted: d.promoted().map(|c| c.id),
        };
        files.extend(save(&curves, out, &format!("curves_{s}"))?);
    }
    if d.terrains.len() > 1 {
        let (cells, count) = d.overlap();
        let heat = Heatmap {
            title: format!("Overlap across terrains: {who}"),
            subtitle: format!(
                "colour: on how many terrains ({}) a point's mean score is in the top quartile; boxed: on all ({} points)",
                d.terrains.join(", "),
                cells.len()
            ),
            bar_label: "terrains in the top quartile".into(),
            w1: &d.w1_values,
            w2: &d.w2_values,
            notes: count
                .iter()
                .map(|row| {
                    row.iter()
                        .map(|n| match n {
                            Some(_) => String::new(),
                            None => "not scored on\nevery terrain".into(),
                        })
                        .collect()
                })
                .collect(),
            values: count,
            better: Better::None,
            marks: cells,
            unrewarded: vec![],
            near: vec![],
            integer: true,
            log10: false,
        };
        files.extend(save(&heat, out, "overlap")?);
    }
    Ok(files)
}

/// An evolutionary search's pictures: its candidates in the (w2, w1) plane and the
/// learning curves, per terrain (a search has one).
fn draw_evolution(
    d: &ReportData,
    out: &Path,
    who: &str,
    bounds: ([f64; 2], [f64; 2]),
) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let promoted = d.promoted().map(|c| c.place);
    for (t, terrain) in d.terrains.iter().enumerate() {
        let s = slug(terrain);
        let mut points: Vec<(u32, u32)> =
            d.cells_of(t).filter_map(|c| c.place.generation()).collect();
        points.sort_unstable();
        points.dedup();
        let candidates: Vec<Candidate> = points
            .iter()
            .filter_map(|&(g, k)| {
                let reps: Vec<&ReportCell> = d
                    .cells_of(t)
                    .filter(|c| c.place.generation() == Some((g, k)))
                    .collect();
                let scores: Vec<f64> = reps.iter().filter_map(|c| c.value()).collect();
                let first = reps.first()?;
                Some(Candidate {
                    w1: first.w1,
                    w2: first.w2,
                    generation: g as usize,
                    score: (!scores.is_empty())
                        .then(|| scores.iter().sum::<f64>() / scores.len() as f64),
                    promoted: promoted == Some(gaitsweep_core::Place::candidate(g, k)),
                })
            })
            .collect();
        let generations = points.last().map_or(0, |p| p.0 + 1);
        let fig = Candidates {
            title: format!("Evolutionary search ({}) on {terrain}: {who}", d.search_title),
            subtitle: format!(
                "{} candidates in {generations} generations, labelled by generation; colour: gait score (mean over replicates); \u{2605} promoted; rings: not scored",
                candidates.len()
            ),
            bounds,
            candidates,
        };
        files.extend(save(&fig, out, &format!("candidates_{s}"))?);
        let curves = Curves {
            title: format!("Learning curves on {terrain}: {who}"),
            cells: d.cells_of(t).collect(),
            promoted: d.promoted().map(|c| c.id),
        };
        files.extend(save(&curves, out, &format!("curves_{s}"))?);
    }
    Ok(files)
}
