//! The candidates of an evolutionary search in the (w2, w1) plane: one disc per candidate,
//! coloured by its score (mean over replicates), labelled with its generation; the
//! promoted candidate is starred. Unscored candidates are grey rings.

use super::{colormap, draw_header, fmt_tick, luminance, value_range, FigResult, Figure, SANS};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// One candidate: (w1, w2), generation, score if any.
pub struct Candidate {
    /// Tracking weight.
    pub w1: f64,
    /// log10 torque weight.
    pub w2: f64,
    /// Generation it was proposed in.
    pub generation: usize,
    /// Mean score of its replicates.
    pub score: Option<f64>,
    /// Whether it is the promoted one.
    pub promoted: bool,
}

/// The figure.
pub struct Candidates {
    /// Title line.
    pub title: String,
    /// Subtitle line.
    pub subtitle: String,
    /// The (w1, w2) rectangle searched: `([w1_lo, w2_lo], [w1_hi, w2_hi])`.
    pub bounds: ([f64; 2], [f64; 2]),
    /// Every candidate.
    pub candidates: Vec<Candidate>,
}

impl Figure for Candidates {
    fn size(&self) -> (u32, u32) {
        (1000, 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> FigResult<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let body = draw_header(root, &self.title, &self.subtitle, self.size().0)?;
        let (plot, bar) = body.split_horizontally(860);
        let ([w1_lo, w2_lo], [w1_hi, w2_hi]) = self.bounds;
        let pad = |lo: f64, hi: f64| ((hi - lo).abs() * 0.05).max(1e-3);
        let (p1, p2) = (pad(w1_lo, w1_hi), pad(w2_lo, w2_hi));
        let mut chart = ChartBuilder::on(&plot)
            .margin(16)
            .x_label_area_size(55)
            .y_label_area_size(80)
            .build_cartesian_2d((w2_lo - p2)..(w2_hi + p2), (w1_lo - p1)..(w1_hi + p1))?;
        chart
            .configure_mesh()
            .light_line_style(BLACK.mix(0.05))
            .x_desc("w2 = log10 torque weight")
            .y_desc("w1 (velocity tracking weight)")
            .x_label_formatter(&|v| fmt_tick(*v, w2_hi - w2_lo))
            .y_label_formatter(&|v| fmt_tick(*v, w1_hi - w1_lo))
            .label_style((SANS, 15))
            .axis_desc_style((SANS, 18))
            .draw()?;
        chart.draw_series(std::iter::once(Rectangle::new(
            [(w2_lo, w1_lo), (w2_hi, w1_hi)],
            ShapeStyle::from(&BLACK.mix(0.4)).stroke_width(1),
        )))?;
        let range = value_range(self.candidates.iter().filter_map(|c| c.score));
        let t = |v: f64| range.map_or(0.5, |(lo, hi)| (v - lo) / (hi - lo));
        let centred = Pos::new(HPos::Center, VPos::Center);
        let red = RGBColor(200, 30, 30);
        for c in &self.candidates {
            let at = (c.w2, c.w1);
            let label = match c.score {
                Some(v) => {
                    let fill = colormap(t(v));
                    chart.draw_series(std::iter::once(Circle::new(
                        at,
                        10,
                        ShapeStyle::from(&fill).filled(),
                    )))?;
                    if luminance(fill) < 0.5 {
                        WHITE
                    } else {
                        BLACK
                    }
                }
                None => {
                    chart.draw_series(std::iter::once(Circle::new(
                        at,
                        10,
                        ShapeStyle::from(&RGBColor(150, 150, 150)).stroke_width(2),
                    )))?;
                    BLACK
                }
            };
            chart.draw_series(std::iter::once(Text::new(
                format!("{}", c.generation),
                at,
                (SANS, 13).into_font().color(&label).pos(centred),
            )))?;
            if c.promoted {
                chart.draw_series(std::iter::once(Circle::new(
                    at,
                    15,
                    ShapeStyle::from(&red).stroke_width(3),
                )))?;
                chart.draw_series(std::iter::once(
                    EmptyElement::at(at)
                        + Text::new(
                            "\u{2605}".to_string(),
                            (18, 0),
                            (SANS, 26)
                                .into_font()
                                .color(&red)
                                .pos(Pos::new(HPos::Left, VPos::Center)),
                        ),
                ))?;
            }
        }
        // Colour bar.
        if let Some((lo, hi)) = range {
            let (x0, y0, h) = (20, 30, 520);
            for k in 0..h {
                let f = 1.0 - k as f64 / h as f64;
                bar.draw(&Rectangle::new(
                    [(x0, y0 + k), (x0 + 24, y0 + k + 1)],
                    ShapeStyle::from(&colormap(f)).filled(),
                ))?;
            }
            for (f, v) in [(1.0, hi), (0.5, (lo + hi) / 2.0), (0.0, lo)] {
                let y = y0 + ((1.0 - f) * h as f64) as i32;
                bar.draw(&Text::new(
                    fmt_tick(v, hi - lo),
                    (x0 + 30, y - 7),
                    (SANS, 14).into_font(),
                ))?;
            }
            bar.draw(&Text::new(
                "gait score".to_string(),
                (x0, y0 + h + 16),
                (SANS, 15).into_font(),
            ))?;
        }
        Ok(())
    }
}
