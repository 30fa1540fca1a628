//! Coefficients figure: the coefficients' history over the recording.

use super::*;

struct CoefficientsFigure<'a> {
    history: &'a History,
    /// (name, index in the history's library, final value from the report).
    terms: Vec<(String, usize, f64)>,
    rows: usize,
    columns: usize,
}

impl Figure for CoefficientsFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1600, 90 + 330 * self.rows as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(
            "Coefficients identified from the record up to time t (dashed: the whole record)",
            font(CAPTION),
        )?;
        let areas = root.split_evenly((self.rows, self.columns));
        let points = &self.history.points;
        let (_, t1) = padded(points.iter().map(|p| p.0));
        let t0 = 0.0;
        for (area, (name, j, last)) in areas.iter().zip(&self.terms) {
            let series: Vec<(f64, f64)> = points
                .iter()
                .filter_map(|(t, c)| c.get(*j).map(|c| (*t, *c)))
                .collect();
            // The range covers the later half of the run and ±2 % of the final value;
            // early excursions beyond it are drawn at the edge (hollow markers).
            let later = series.len() / 2;
            let (lo, hi) = padded(
                series[later..]
                    .iter()
                    .map(|p| p.1)
                    .chain([last * 0.98, last * 1.02]),
            );
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!("{name}   (whole record: {})", coefficient(*last)),
                    font(DESC),
                )
                .margin(12)
                .margin_right(30)
                .x_label_area_size(50)
                .y_label_area_size(110)
                .build_cartesian_2d(t0..t1, lo..hi)?;
            chart
                .configure_mesh()
                .x_desc("time t [s]")
                .label_style(font(LABEL))
                .axis_desc_style(font(LABEL))
                .x_label_formatter(&ticker(t0, t1))
                .y_label_formatter(&ticker(lo, hi))
                .y_labels(5)
                .light_line_style(BLACK.mix(0.06))
                .draw()?;
            chart.draw_series(DashedLineSeries::new(
                vec![(t0, *last), (t1, *last)],
                10,
                6,
                MODEL.stroke_width(2),
            ))?;
            let clipped: Vec<(f64, f64)> =
                series.iter().map(|(t, c)| (*t, c.clamp(lo, hi))).collect();
            chart.draw_series(LineSeries::new(clipped.clone(), ACCENT.stroke_width(2)))?;
            chart.draw_series(series.iter().zip(&clipped).map(|(raw, p)| {
                let style = if raw.1 == p.1 {
                    ACCENT.filled()
                } else {
                    ACCENT.stroke_width(2)
                };
                Circle::new(*p, 5, style)
            }))?;
        }
        Ok(())
    }
}

/// The selected terms' coefficients as the record grows.
pub(in crate::plot) fn coefficients(
    base: &Path,
    history: &History,
    report: &Report,
) -> Result<Written, PlotError> {
    if history.points.is_empty() {
        return Err(PlotError::Skipped(
            "no prefix of the record gave a model.".into(),
        ));
    }
    let terms: Vec<(String, usize, f64)> = report
        .terms
        .iter()
        .filter_map(|t| {
            history
                .names
                .iter()
                .position(|n| *n == t.term)
                .map(|j| (t.term.clone(), j, t.coef))
        })
        .collect();
    if terms.is_empty() {
        return Err(PlotError::Skipped(
            "the selected model has no terms.".into(),
        ));
    }
    let columns = if terms.len() > 3 { 2 } else { 1 };
    let rows = terms.len().div_ceil(columns);
    let figure = CoefficientsFigure {
        history,
        terms,
        rows,
        columns,
    };
    write(base, "coefficients", &figure)
}

// ---------------------------------------------------------------------------------------
// Phase portrait with the equilibria (wells) of the unforced model.
