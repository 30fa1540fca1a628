//! Screening figure: the terms the identifier screened and the model it kept.

use super::*;

struct ScreeningFigure<'a> {
    report: &'a Report,
    units: &'a Units,
}

impl Figure for ScreeningFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1500, 1050)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let report = self.report;
        let n = report.solutions.len();
        let selected = report.selected;
        let root = root.titled(
            "Screening of the solutions (MES): held-out mean error of each sparse solution",
            font(CAPTION),
        )?;
        let (top, bottom) = root.split_vertically(560);
        let errors: Vec<f64> = report.solutions.iter().map(|s| s.mean_error).collect();
        let positive = errors
            .iter()
            .copied()
            .filter(|e| *e > 0.0 && e.is_finite())
            .fold(f64::INFINITY, f64::min);
        let floor = if positive.is_finite() {
            positive
        } else {
            1e-12
        };
        let top_value = errors
            .iter()
            .copied()
            .filter(|e| e.is_finite())
            .fold(floor, f64::max);
        let x_range = 0.5..(n as f64 + 0.5);
        let mut chart = ChartBuilder::on(&top)
            .margin(15)
            .margin_right(40)
            .x_label_area_size(55)
            .y_label_area_size(120)
            .build_cartesian_2d(x_range.clone(), (floor / 1.6..top_value * 1.6).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("solution Sᵢ (threshold rises →, fewer terms)")
            .y_desc(self.units.error())
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_labels(n.min(20))
            .x_label_formatter(&|v| format!("S{}", v.round() as i64))
            .y_label_formatter(&|v| tick(*v))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        let points: Vec<(f64, f64)> = errors
            .iter()
            .enumerate()
            .map(|(i, e)| ((i + 1) as f64, e.max(floor)))
            .collect();
        chart
            .draw_series(LineSeries::new(points.clone(), ACCENT.stroke_width(2)))?
            .label("mean error of x″ on held-out rows")
            .legend(line_legend(ACCENT, 3));
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 6, ACCENT.filled())))?;
        if let Some(p) = points.get(selected) {
            let terms = report.solutions[selected].terms.len();
            chart
                .draw_series(std::iter::once(Circle::new(
                    *p,
                    13,
                    SELECTED.stroke_width(4),
                )))?
                .label(format!(
                    "selected: S{} ({terms} terms, error {})",
                    selected + 1,
                    tick(p.1)
                ))
                .legend(|(x, y)| Circle::new((x + 14, y), 9, SELECTED.stroke_width(3)));
        }
        legend(&mut chart, SeriesLabelPosition::UpperLeft)?;

        let max_terms = report
            .solutions
            .iter()
            .map(|s| s.terms.len())
            .max()
            .unwrap_or(1);
        let caption = report.solutions.get(selected).map_or(String::new(), |s| {
            format!("selected S{}: x″ = f({})", selected + 1, s.terms.join(", "))
        });
        let mut chart = ChartBuilder::on(&bottom)
            .caption(caption, font(DESC).color(&SELECTED))
            .margin(15)
            .margin_right(40)
            .x_label_area_size(55)
            .y_label_area_size(120)
            .build_cartesian_2d(x_range, 0.0..(max_terms as f64 + 1.0))?;
        chart
            .configure_mesh()
            .x_desc("solution Sᵢ")
            .y_desc("active terms")
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_labels(n.min(20))
            .x_label_formatter(&|v| format!("S{}", v.round() as i64))
            .y_label_formatter(&|v| format!("{}", v.round() as i64))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        chart.draw_series(report.solutions.iter().enumerate().map(|(i, s)| {
            let x = (i + 1) as f64;
            let color = if i == selected { SELECTED } else { ACCENT };
            Rectangle::new(
                [(x - 0.35, 0.0), (x + 0.35, s.terms.len() as f64)],
                color.mix(0.8).filled(),
            )
        }))?;
        Ok(())
    }
}

/// The screening curve.
pub(in crate::plot) fn screening(
    base: &Path,
    report: &Report,
    units: &Units,
) -> Result<Written, PlotError> {
    if report.solutions.is_empty() {
        return Err(PlotError::Skipped("the sweep has no solutions.".into()));
    }
    write(base, "screening", &ScreeningFigure { report, units })
}

// ---------------------------------------------------------------------------------------
// ε(K) per channel (Fig. 4).
