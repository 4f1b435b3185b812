//! The (w1, w2) heatmap of one score component or the fall rate, with its colour bar.

use super::*;
/// Which cell a heatmap marks as best.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Better {
    Higher,
    Lower,
    None,
}

/// A heatmap over the (w1, w2) grid with its colour bar.
pub(super) struct Heatmap<'a> {
    pub(super) title: String,
    pub(super) subtitle: String,
    pub(super) bar_label: String,
    pub(super) w1: &'a [f64],
    pub(super) w2: &'a [f64],
    /// `[w1_index][w2_index]`
    pub(super) values: GridValues,
    /// Text for cells without a value (their state).
    pub(super) notes: Vec<Vec<String>>,
    pub(super) better: Better,
    /// Cells outlined in white (the overlap).
    pub(super) marks: Vec<(usize, usize)>,
    /// Cells labelled "no reward" under their value ([`crate::report::ReportCell::never_rewarded`]).
    pub(super) unrewarded: Vec<(usize, usize)>,
    /// Cells labelled "near best" under their value: not told apart from the best at 95%
    /// ([`crate::report::ReportData::near_best`]); the best itself keeps its own mark.
    pub(super) near: Vec<(usize, usize)>,
    pub(super) integer: bool,
    /// The values are log10 of a ratio: the colours follow the log, a cell's text is the
    /// ratio itself.
    pub(super) log10: bool,
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
        } else if self.log10 {
            fmt_ratio(10f64.powf(v))
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

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> FigResult<()>
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
                // A note may have two lines ("stopped at 400" over its rung score); a long
                // line gets a smaller font so that it stays inside its cell.
                let lines: Vec<&str> = text.lines().collect();
                let longest = lines.iter().map(|l| l.chars().count()).max().unwrap_or(1);
                let size = font.min(cell_w * 0.9 / (0.6 * longest as f64)).max(9.0);
                let style = TextStyle::from((SANS, size).into_font())
                    .color(&ink)
                    .pos(Pos::new(HPos::Center, VPos::Center));
                let n = lines.len();
                for (k, line) in lines.into_iter().enumerate() {
                    let dy = ((k as f64 - (n as f64 - 1.0) / 2.0) * size * 1.2) as i32;
                    chart.draw_series(std::iter::once(
                        EmptyElement::at(at(j, i))
                            + Text::new(line.to_string(), (0, dy), style.clone()),
                    ))?;
                }
            }
        }
        // A small label under a cell's value ("all terrains", "no reward", "near best"), inked against
        // the cell's colour.
        let mut label_under = |i: usize, j: usize, text: &str| {
            let bg = self.values[i][j].map_or(RGBColor(225, 225, 225), |v| colormap(norm(v)));
            let small = TextStyle::from((SANS, (font * 0.7).max(10.0)).into_font())
                .color(if luminance(bg) < 0.5 { &WHITE } else { &BLACK })
                .pos(Pos::new(HPos::Center, VPos::Center));
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at(at(j, i))
                        + Text::new(text.to_string(), (0, (cell_h * 0.3) as i32), small),
                ))
                .map(|_| ())
        };
        for &(i, j) in &self.unrewarded {
            label_under(i, j, "no reward")?;
        }
        for &(i, j) in &self.marks {
            label_under(i, j, "all terrains")?;
        }
        for &(i, j) in &self.near {
            // The best keeps its own mark, and one label fits under a value.
            if best.is_none_or(|b| (b.0, b.1) != (i, j))
                && !self.unrewarded.contains(&(i, j))
                && !self.marks.contains(&(i, j))
            {
                label_under(i, j, "near best")?;
            }
        }
        for &(i, j) in &self.marks {
            let style = ShapeStyle::from(&RGBColor(220, 20, 60)).stroke_width(4);
            chart.draw_series(std::iter::once(Rectangle::new(corners(i, j), style)))?;
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

        if range.is_none() {
            // No value yet, so no scale: the bar's place says so (each cell's note says why),
            // rather than a 0-1 scale or a label over the grid's axis.
            for (k, line) in ["no scored", "cells yet"].iter().enumerate() {
                bar.draw(&Text::new(
                    *line,
                    (12, 40 + 26 * k as i32),
                    (SANS, 20).into_font().color(&RED),
                ))?;
            }
            return Ok(());
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
            // plotters right-aligns right-axis labels to a width it estimates, which comes out
            // narrower than the rendered text for labels of 5 or more characters ("0.880"):
            // their first digit went under the bar. A leading space takes the difference.
            .y_label_formatter(&|v| {
                if integer {
                    format!(" {}", v.round() as i64)
                } else {
                    format!(" {}", fmt_tick(*v, hi - lo))
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
        Ok(())
    }
}

/// A ratio to two significant digits, in powers of ten when it is small or large.
fn fmt_ratio(x: f64) -> String {
    if x != 0.0 && !(0.01..1e4).contains(&x) {
        format!("{x:.0e}")
    } else if x >= 10.0 {
        format!("{x:.0}")
    } else if x >= 1.0 {
        format!("{x:.1}")
    } else {
        format!("{x:.2}")
    }
}
