//! The 3D score surface over (w1, w2) (the paper's Fig. 3).

use super::*;
/// The gait score as a 3D surface over (w2, w1).
pub(super) struct Surface<'a> {
    pub(super) title: String,
    pub(super) subtitle: String,
    pub(super) w1: &'a [f64],
    pub(super) w2: &'a [f64],
    pub(super) values: GridValues,
}

impl Figure for Surface<'_> {
    fn size(&self) -> (u32, u32) {
        (1000, 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> FigResult<()>
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
