//! The report's pictures, drawn with plotters into PNG (bitmap backend) and SVG. Text is
//! set in an embedded DejaVu Sans subset (assets/), so nothing depends on system fonts.

use super::{slug, ReportCell, ReportData};
use anyhow::Context;
use plotters::coord::ranged1d::SegmentValue;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// DejaVu Sans (Latin-1 and a few symbols), see assets/FONT-LICENSE.txt.
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans-subset.ttf");
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
) -> anyhow::Result<DrawingArea<DB, Shift>>
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

/// A picture that can be drawn on any backend.
trait Figure {
    fn size(&self) -> (u32, u32);
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static;
}

/// Writes `out/stem.png` and `out/stem.svg`.
fn save<F: Figure>(fig: &F, out: &Path, stem: &str) -> anyhow::Result<Vec<PathBuf>> {
    register_fonts();
    let png = out.join(format!("{stem}.png"));
    let svg = out.join(format!("{stem}.svg"));
    {
        let root = BitMapBackend::new(&png, fig.size()).into_drawing_area();
        fig.draw(&root)
            .with_context(|| format!("draw {}", png.display()))?;
        root.present()
            .with_context(|| format!("write {}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, fig.size()).into_drawing_area();
        fig.draw(&root)
            .with_context(|| format!("draw {}", svg.display()))?;
        root.present()
            .with_context(|| format!("write {}", svg.display()))?;
    }
    Ok(vec![png, svg])
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

/// Which cell a heatmap marks as best.
#[derive(Clone, Copy, PartialEq)]
enum Better {
    Higher,
    Lower,
    None,
}

/// A heatmap over the (w1, w2) grid with its colour bar.
struct Heatmap<'a> {
    title: String,
    subtitle: String,
    bar_label: String,
    w1: &'a [f64],
    w2: &'a [f64],
    /// `[w1_index][w2_index]`
    values: Vec<Vec<Option<f64>>>,
    /// Text for cells without a value (their state).
    notes: Vec<Vec<String>>,
    better: Better,
    /// Cells outlined in white (the overlap).
    marks: Vec<(usize, usize)>,
    integer: bool,
}

impl Heatmap<'_> {
    fn best(&self) -> Option<(usize, usize, f64)> {
        let mut best: Option<(usize, usize, f64)> = None;
        for (i, row) in self.values.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let Some(v) = v.filter(|v| v.is_finite()) else {
                    continue;
                };
                let better = match (self.better, best) {
                    (Better::None, _) => false,
                    (_, None) => true,
                    (Better::Higher, Some(b)) => v > b.2,
                    (Better::Lower, Some(b)) => v < b.2,
                };
                if better {
                    best = Some((i, j, v));
                }
            }
        }
        best
    }

    fn fmt(&self, v: f64) -> String {
        if self.integer {
            format!("{}", v.round() as i64)
        } else {
            fmt_value(v)
        }
    }
}

impl Figure for Heatmap<'_> {
    fn size(&self) -> (u32, u32) {
        let w = (260 + 120 * self.w2.len() as u32).clamp(760, 1500);
        let h = (230 + 80 * self.w1.len() as u32).clamp(520, 1100);
        (w, h)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (w, _) = self.size();
        let body = draw_header(root, &self.title, &self.subtitle, self.size().0)?;
        let (main, bar) = body.split_horizontally(w - 150);
        let (nx, ny) = (self.w2.len() as i32, self.w1.len() as i32);
        let range = value_range(self.values.iter().flatten().flatten().copied());
        let (lo, hi) = range.unwrap_or((0.0, 1.0));
        let norm = |v: f64| (v - lo) / (hi - lo);

        let mut chart = ChartBuilder::on(&main)
            .margin_left(15)
            .margin_right(10)
            .margin_top(10)
            .margin_bottom(10)
            .x_label_area_size(65)
            .y_label_area_size(95)
            .build_cartesian_2d(
                (0..(nx - 1).max(0)).into_segmented(),
                (0..(ny - 1).max(0)).into_segmented(),
            )?;
        let (w1, w2) = (self.w1, self.w2);
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(nx.max(1) as usize)
            .y_labels(ny.max(1) as usize)
            .x_label_formatter(&|v| match v {
                SegmentValue::CenterOf(j) => {
                    w2.get(*j as usize).map(|x| fmt_w(*x)).unwrap_or_default()
                }
                _ => String::new(),
            })
            .y_label_formatter(&|v| match v {
                SegmentValue::CenterOf(i) => {
                    w1.get(*i as usize).map(|x| fmt_w(*x)).unwrap_or_default()
                }
                _ => String::new(),
            })
            .x_desc("log10 torque weight w2  (torque penalty = 10^w2)")
            .y_desc("w1 (tracking weight)")
            .label_style((SANS, 17))
            .axis_desc_style((SANS, 19))
            .draw()?;

        let (pw, ph) = chart.plotting_area().dim_in_pixel();
        let cell_w = pw as f64 / nx.max(1) as f64;
        let cell_h = ph as f64 / ny.max(1) as f64;
        let font = (cell_h * 0.24).min(cell_w * 0.16).clamp(11.0, 24.0);
        let best = self.best();
        let at = |j: usize, i: usize| {
            (
                SegmentValue::CenterOf(j as i32),
                SegmentValue::CenterOf(i as i32),
            )
        };
        // The far edge of the last segment is `Last` (exact coordinates past the range
        // would be extrapolated, and a one-value axis has no width to extrapolate from).
        let edge = |k: usize, n: i32| {
            if k as i32 >= n {
                SegmentValue::Last
            } else {
                SegmentValue::Exact(k as i32)
            }
        };
        let corners = |i: usize, j: usize| {
            [
                (edge(j, nx), edge(i, ny)),
                (edge(j + 1, nx), edge(i + 1, ny)),
            ]
        };
        for (i, row) in self.values.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let (fill, text) = match v.filter(|v| v.is_finite()) {
                    Some(v) => (colormap(norm(v)), self.fmt(v)),
                    None => (
                        RGBColor(225, 225, 225),
                        self.notes
                            .get(i)
                            .and_then(|r| r.get(j))
                            .cloned()
                            .filter(|s| !s.is_empty())
                            .unwrap_or_else(|| "-".into()),
                    ),
                };
                chart.draw_series(std::iter::once(Rectangle::new(
                    corners(i, j),
                    fill.filled(),
                )))?;
                chart.draw_series(std::iter::once(Rectangle::new(
                    corners(i, j),
                    ShapeStyle::from(&WHITE).stroke_width(1),
                )))?;
                let ink = if luminance(fill) < 0.5 { WHITE } else { BLACK };
                let style = TextStyle::from((SANS, font).into_font())
                    .color(&ink)
                    .pos(Pos::new(HPos::Center, VPos::Center));
                chart.draw_series(std::iter::once(Text::new(text, at(j, i), style)))?;
            }
        }
        for &(i, j) in &self.marks {
            let style = ShapeStyle::from(&RGBColor(220, 20, 60)).stroke_width(4);
            chart.draw_series(std::iter::once(Rectangle::new(corners(i, j), style)))?;
            let bg = self.values[i][j].map_or(RGBColor(225, 225, 225), |v| colormap(norm(v)));
            let small = TextStyle::from((SANS, (font * 0.7).max(10.0)).into_font())
                .color(if luminance(bg) < 0.5 { &WHITE } else { &BLACK })
                .pos(Pos::new(HPos::Center, VPos::Center));
            chart.draw_series(std::iter::once(
                EmptyElement::at(at(j, i))
                    + Text::new("all terrains", (0, (cell_h * 0.3) as i32), small),
            ))?;
        }
        if let Some((i, j, v)) = best {
            let red = RGBColor(220, 20, 60);
            chart.draw_series(std::iter::once(Rectangle::new(
                corners(i, j),
                ShapeStyle::from(&red).stroke_width(5),
            )))?;
            let fill = colormap(norm(v));
            let ink = if luminance(fill) < 0.5 { WHITE } else { BLACK };
            let label = match self.better {
                Better::Lower => "\u{2605} best (lowest)",
                _ => "\u{2605} best",
            };
            let small = TextStyle::from((SANS, (font * 0.75).max(11.0)).into_font())
                .color(&ink)
                .pos(Pos::new(HPos::Center, VPos::Center));
            chart.draw_series(std::iter::once(
                EmptyElement::at(at(j, i)) + Text::new(label, (0, -(cell_h * 0.28) as i32), small),
            ))?;
        }

        // Colour bar with its scale.
        let mut cb = ChartBuilder::on(&bar)
            .margin_top(20)
            .margin_bottom(85)
            .margin_left(10)
            .margin_right(5)
            .y_label_area_size(0)
            .right_y_label_area_size(95)
            .build_cartesian_2d(0.0..1.0f64, lo..hi)?;
        let integer = self.integer;
        cb.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_labels(if integer {
                ((hi - lo).round() as usize + 1).min(8)
            } else {
                7
            })
            .y_label_formatter(&|v| {
                if integer {
                    format!("{}", v.round() as i64)
                } else {
                    fmt_tick(*v, hi - lo)
                }
            })
            .y_desc(self.bar_label.clone())
            .label_style((SANS, 15))
            .axis_desc_style((SANS, 17))
            .draw()?;
        let n = 120;
        cb.draw_series((0..n).map(|k| {
            let (a, b) = (
                lo + (hi - lo) * k as f64 / n as f64,
                lo + (hi - lo) * (k + 1) as f64 / n as f64,
            );
            Rectangle::new(
                [(0.0, a), (1.0, b)],
                colormap((k as f64 + 0.5) / n as f64).filled(),
            )
        }))?;
        cb.draw_series(std::iter::once(Rectangle::new(
            [(0.0, lo), (1.0, hi)],
            ShapeStyle::from(&BLACK).stroke_width(1),
        )))?;
        if range.is_none() {
            main.draw(&Text::new(
                "no scored cells yet",
                (40, 40),
                (SANS, 22).into_font().color(&RED),
            ))?;
        }
        Ok(())
    }
}

/// The gait score as a 3D surface over (w2, w1).
struct Surface<'a> {
    title: String,
    subtitle: String,
    w1: &'a [f64],
    w2: &'a [f64],
    values: Vec<Vec<Option<f64>>>,
}

impl Figure for Surface<'_> {
    fn size(&self) -> (u32, u32) {
        (1000, 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let body = draw_header(root, &self.title, &self.subtitle, self.size().0)?;
        let span = |v: &[f64]| {
            let (lo, hi) = value_range(v.iter().copied()).unwrap_or((0.0, 1.0));
            let pad = (hi - lo).max(1.0) * 0.04;
            (lo - pad, hi + pad)
        };
        let (x0, x1) = span(self.w2);
        let (z0, z1) = span(self.w1);
        let Some((lo, hi)) = value_range(self.values.iter().flatten().flatten().copied()) else {
            body.draw(&Text::new(
                "no scored cells yet",
                (40, 40),
                (SANS, 22).into_font().color(&RED),
            ))?;
            return Ok(());
        };
        let pad = (hi - lo) * 0.08;
        let (y0, y1) = (lo - pad, hi + pad);
        let norm = |v: f64| (v - lo) / (hi - lo);
        let (main, legend) = body.split_vertically(610);
        let mut chart =
            ChartBuilder::on(&main)
                .margin(25)
                .build_cartesian_3d(x0..x1, y0..y1, z0..z1)?;
        chart.with_projection(|mut p| {
            p.yaw = 0.65;
            p.pitch = 0.35;
            p.scale = 0.78;
            p.into_matrix()
        });
        chart
            .configure_axes()
            .light_grid_style(BLACK.mix(0.08))
            .max_light_lines(3)
            .label_style((SANS, 14))
            .x_formatter(&|v| fmt_w(*v))
            .z_formatter(&|v| fmt_w(*v))
            .y_formatter(&|v| fmt_tick(*v, y1 - y0))
            .draw()?;
        // Quads between neighbouring scored cells, far ones (low w1 and w2 index) first.
        let mut quads = Vec::new();
        for i in 0..self.w1.len().saturating_sub(1) {
            for j in 0..self.w2.len().saturating_sub(1) {
                let pts = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)];
                let vals: Vec<f64> = pts
                    .iter()
                    .filter_map(|&(a, b)| self.values[a][b])
                    .filter(|v| v.is_finite())
                    .collect();
                if vals.len() == 4 {
                    let poly: Vec<(f64, f64, f64)> = pts
                        .iter()
                        .zip(&vals)
                        .map(|(&(a, b), v)| (self.w2[b], *v, self.w1[a]))
                        .collect();
                    quads.push((i + j, poly, vals.iter().sum::<f64>() / 4.0));
                }
            }
        }
        quads.sort_by_key(|q| q.0);
        for (_, poly, mean) in quads {
            chart.draw_series(std::iter::once(Polygon::new(
                poly.clone(),
                colormap(norm(mean)).mix(0.9).filled(),
            )))?;
            let mut outline = poly;
            outline.push(outline[0]);
            chart.draw_series(std::iter::once(PathElement::new(outline, BLACK.mix(0.5))))?;
        }
        // Every cell as a dot on a stem from the floor, the best one marked.
        let mut best: Option<(usize, usize, f64)> = None;
        for (i, row) in self.values.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let Some(v) = v.filter(|v| v.is_finite()) else {
                    continue;
                };
                if best.is_none_or(|b| v > b.2) {
                    best = Some((i, j, v));
                }
                let (x, z) = (self.w2[j], self.w1[i]);
                chart.draw_series(std::iter::once(PathElement::new(
                    vec![(x, y0, z), (x, v, z)],
                    BLACK.mix(0.35),
                )))?;
                chart.draw_series(std::iter::once(Circle::new(
                    (x, v, z),
                    4,
                    colormap(norm(v)).filled().stroke_width(1),
                )))?;
            }
        }
        if let Some((i, j, v)) = best {
            let red = RGBColor(220, 20, 60);
            let p = (self.w2[j], v, self.w1[i]);
            chart.draw_series(std::iter::once(Circle::new(
                p,
                9,
                ShapeStyle::from(&red).stroke_width(3),
            )))?;
            chart.draw_series(std::iter::once(
                EmptyElement::at(p)
                    + Text::new(
                        format!(
                            "\u{2605} best {} (w1 {}, w2 {})",
                            fmt_value(v),
                            fmt_w(self.w1[i]),
                            fmt_w(self.w2[j])
                        ),
                        (12, -26),
                        (SANS, 17).into_font().color(&red),
                    ),
            ))?;
        }
        let axis = (SANS, 17).into_font().color(&RGBColor(30, 30, 140));
        let centred = axis.clone().pos(Pos::new(HPos::Center, VPos::Top));
        chart.draw_series(std::iter::once(Text::new(
            "log10 torque weight w2 \u{2192}",
            ((x0 + x1) / 2.0, y0, z1 + (z1 - z0) * 0.3),
            centred,
        )))?;
        chart.draw_series(std::iter::once(Text::new(
            "w1 (tracking weight) \u{2192}",
            (x1 + (x1 - x0) * 0.12, y0, (z0 + z1) / 2.0),
            axis.clone(),
        )))?;
        chart.draw_series(std::iter::once(Text::new(
            "gait score \u{2191}",
            (x0, y1, z1),
            axis,
        )))?;
        legend.draw(&Text::new(
            "height and colour: gait score (higher is better); each dot is one trained cell",
            (30, 8),
            (SANS, 16).into_font().color(&RGBColor(60, 60, 60)),
        ))?;
        let n = 200;
        for k in 0..n {
            let x = 30 + k * 3;
            legend.draw(&Rectangle::new(
                [(x, 36), (x + 3, 54)],
                colormap(k as f64 / (n - 1) as f64).filled(),
            ))?;
        }
        let lab = (SANS, 15).into_font().color(&BLACK);
        legend.draw(&Text::new(fmt_value(lo), (30, 58), lab.clone()))?;
        legend.draw(&Text::new(fmt_value(hi), (30 + 3 * n - 50, 58), lab))?;
        Ok(())
    }
}

/// Learning curves of every cell of one terrain: one line per cell, two panels.
struct Curves<'a> {
    title: String,
    cells: Vec<&'a ReportCell>,
    promoted: Option<i64>,
}

fn line_color(k: usize, n: usize) -> RGBColor {
    // Evenly spread hues, alternating lightness so that neighbours differ.
    let h = (k as f64 / n.max(1) as f64) * 0.85;
    let l = if k % 2 == 0 { 0.42 } else { 0.58 };
    let c = HSLColor(h, 0.75, l).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

impl Figure for Curves<'_> {
    fn size(&self) -> (u32, u32) {
        let h = (260 + 22 * self.cells.len() as u32).max(820);
        (1250, h.min(2000))
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (w, _) = self.size();
        let (head, body) = root.split_vertically(60);
        head.draw(&Text::new(
            self.title.clone(),
            (20, 14),
            (SANS, 26).into_font().color(&BLACK),
        ))?;
        let (plots, legend) = body.split_horizontally(w - 300);
        let panels = [
            ("mean_step_reward", "mean reward per step"),
            ("mean_return", "mean episode return"),
        ];
        let areas = plots.split_evenly((panels.len(), 1));
        let n = self.cells.len();
        for ((metric, label), area) in panels.iter().zip(&areas) {
            let series: Vec<(usize, &Vec<(u32, f64)>)> = self
                .cells
                .iter()
                .enumerate()
                .filter_map(|(k, c)| c.curves.get(*metric).map(|s| (k, s)))
                .collect();
            let max_epoch = series
                .iter()
                .flat_map(|(_, s)| s.iter().map(|p| p.0))
                .max()
                .unwrap_or(1)
                .max(1);
            let min_epoch = series
                .iter()
                .flat_map(|(_, s)| s.iter().map(|p| p.0))
                .min()
                .unwrap_or(0)
                .min(max_epoch);
            let Some((lo, hi)) =
                value_range(series.iter().flat_map(|(_, s)| s.iter().map(|p| p.1)))
            else {
                area.draw(&Text::new(
                    format!("no {metric} metrics yet"),
                    (60, 60),
                    (SANS, 20).into_font().color(&RED),
                ))?;
                continue;
            };
            let pad = (hi - lo) * 0.05;
            let mut chart = ChartBuilder::on(area)
                .margin(12)
                .x_label_area_size(50)
                .y_label_area_size(90)
                .build_cartesian_2d(
                    (min_epoch as f64 - 0.2).max(0.0)..max_epoch as f64 + 0.2,
                    (lo - pad)..(hi + pad),
                )?;
            chart
                .configure_mesh()
                .light_line_style(BLACK.mix(0.05))
                .x_desc("epoch")
                .y_desc(*label)
                .x_labels(((max_epoch - min_epoch) as usize + 1).clamp(2, 10))
                .x_label_formatter(&|v| {
                    if (v - v.round()).abs() < 1e-6 {
                        format!("{}", v.round() as i64)
                    } else {
                        String::new()
                    }
                })
                .y_label_formatter(&|v| fmt_tick(*v, hi - lo))
                .label_style((SANS, 15))
                .axis_desc_style((SANS, 18))
                .draw()?;
            for (k, s) in series {
                let bold = Some(self.cells[k].id) == self.promoted;
                let color = line_color(k, n);
                let style = ShapeStyle::from(&color).stroke_width(if bold { 4 } else { 2 });
                let pts: Vec<(f64, f64)> = s.iter().map(|&(e, v)| (e as f64, v)).collect();
                if pts.len() == 1 {
                    chart.draw_series(std::iter::once(Circle::new(pts[0], 4, color.filled())))?;
                } else {
                    chart.draw_series(LineSeries::new(pts, style))?;
                }
            }
        }
        // Legend: one entry per cell.
        legend.draw(&Text::new(
            "cells (w1, w2)",
            (10, 10),
            (SANS, 17).into_font().color(&BLACK),
        ))?;
        let step = (((legend.dim_in_pixel().1 as usize).saturating_sub(50)) / n.max(1))
            .clamp(12, 24) as i32;
        let font = (step as f64 * 0.75).clamp(10.0, 15.0);
        for (k, c) in self.cells.iter().enumerate() {
            let y = 42 + k as i32 * step;
            let color = line_color(k, n);
            let bold = Some(c.id) == self.promoted;
            legend.draw(&PathElement::new(
                vec![(10, y + step / 3), (40, y + step / 3)],
                ShapeStyle::from(&color).stroke_width(if bold { 4 } else { 2 }),
            ))?;
            let mut text = format!("w1 {}, w2 {}", fmt_w(c.w1), fmt_w(c.w2));
            if let Some(v) = c.value() {
                text.push_str(&format!("  ({})", fmt_value(v)));
            }
            if bold {
                text.push_str(" \u{2605}");
            }
            legend.draw(&Text::new(
                text,
                (46, y),
                (SANS, font).into_font().color(&BLACK),
            ))?;
        }
        Ok(())
    }
}

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
        if c.score.is_some() {
            "NaN".into()
        } else {
            c.state.clone()
        }
    })
}

/// Draws every picture; returns the files written.
pub fn draw_all(d: &ReportData, out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let who = format!(
        "sweep {} \u{201c}{}\u{201d}, robot {}",
        d.sweep_id, d.name, d.robot
    );
    for (t, terrain) in d.terrains.iter().enumerate() {
        let s = slug(terrain);
        let scored = d.cells_of(t).filter(|c| c.value().is_some()).count();
        let total = d.cells_of(t).count();
        let heat = Heatmap {
            title: format!("Gait score on {terrain}: {who}"),
            subtitle: format!(
                "{scored} of {total} cells scored; higher is better; \u{2605} marks the best cell{}",
                if d.terrains.len() > 1 { " on this terrain" } else { "" }
            ),
            bar_label: "gait score".into(),
            w1: &d.w1_values,
            w2: &d.w2_values,
            values: d.grid(t, None, |c| c.value()),
            notes: notes(d, t),
            better: Better::Higher,
            marks: vec![],
            integer: false,
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
            values: d.grid(t, None, |c| {
                c.score
                    .as_ref()
                    .map(|s| s.fall_rate)
                    .filter(|v| v.is_finite())
            }),
            notes: notes(d, t),
            better: Better::Lower,
            marks: vec![],
            integer: false,
        };
        files.extend(save(&falls, out, &format!("fall_rate_{s}"))?);
        let surf = Surface {
            title: format!("Gait score surface on {terrain}: {who}"),
            subtitle: "x: log10 torque weight w2, depth: w1 (tracking weight), height: gait score"
                .into(),
            w1: &d.w1_values,
            w2: &d.w2_values,
            values: d.grid(t, None, |c| c.value()),
        };
        files.extend(save(&surf, out, &format!("surface_{s}"))?);
        for (name, label, higher) in COMPONENTS {
            let heat = Heatmap {
                title: format!("Score component \u{201c}{name}\u{201d} on {terrain}: {who}"),
                subtitle: format!("{label}; \u{2605} marks the best cell by this component"),
                bar_label: name.into(),
                w1: &d.w1_values,
                w2: &d.w2_values,
                values: d.grid(t, None, |c| component(c, name).filter(|v| v.is_finite())),
                notes: notes(d, t),
                better: if higher {
                    Better::Higher
                } else {
                    Better::Lower
                },
                marks: vec![],
                integer: false,
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
                "colour: on how many terrains ({}) a cell's score is in the top quartile; boxed: on all ({} cells)",
                d.terrains.join(", "),
                cells.len()
            ),
            bar_label: "terrains in the top quartile".into(),
            w1: &d.w1_values,
            w2: &d.w2_values,
            values: count,
            notes: vec![],
            better: Better::None,
            marks: cells,
            integer: true,
        };
        files.extend(save(&heat, out, "overlap")?);
    }
    Ok(files)
}
