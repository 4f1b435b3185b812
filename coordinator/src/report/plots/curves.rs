//! Learning curves of the sweep's cells.

use super::*;
/// Learning curves of every cell of one terrain: one line per cell, two panels.
pub(super) struct Curves<'a> {
    pub(super) title: String,
    pub(super) cells: Vec<&'a ReportCell>,
    pub(super) promoted: Option<i64>,
}

fn line_color(k: usize, n: usize) -> RGBColor {
    // Evenly spread hues, alternating lightness so that neighbours differ.
    let h = (k as f64 / n.max(1) as f64) * 0.85;
    let l = if k.is_multiple_of(2) { 0.42 } else { 0.58 };
    let c = HSLColor(h, 0.75, l).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

impl Figure for Curves<'_> {
    fn size(&self) -> (u32, u32) {
        let h = (260 + 22 * self.cells.len() as u32).max(820);
        (1250, h.min(2000))
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> FigResult<()>
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
