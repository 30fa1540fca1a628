//! Neighbours figure: the model beside its nearest competing models.

use super::*;

struct NeighboursFigure<'a> {
    neighbours: &'a Neighbours,
    used: (u8, u8),
    units: &'a Units,
}

impl NeighboursFigure<'_> {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        title: &str,
        unit: &str,
        r: &Reconstruction,
        used: u8,
    ) -> Result<(), PlotError> {
        let (lo, hi) = padded(r.rms.iter().map(|p| p.1));
        let k_lo = r.rms.first().map_or(2, |p| p.0) as f64 - 0.5;
        let k_hi = r.rms.last().map_or(8, |p| p.0) as f64 + 0.5;
        let mut chart = ChartBuilder::on(area)
            .caption(title, font(DESC))
            .margin(15)
            .margin_right(30)
            .x_label_area_size(60)
            .y_label_area_size(120)
            .build_cartesian_2d(k_lo..k_hi, lo..hi)?;
        chart
            .configure_mesh()
            .x_desc("neighbours K")
            .y_desc(format!("RMS reconstruction error [{unit}]"))
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_labels(r.rms.len())
            .x_label_formatter(&|v| format!("{}", v.round() as i64))
            .y_label_formatter(&ticker(lo, hi))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        let points: Vec<(f64, f64)> = r.rms.iter().map(|(k, e)| (*k as f64, *e)).collect();
        chart
            .draw_series(LineSeries::new(points.clone(), ACCENT.stroke_width(3)))?
            .label("ε(K), leave-one-out, whole record")
            .legend(line_legend(ACCENT, 3));
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 6, ACCENT.filled())))?;
        if used > 0 {
            let k = f64::from(used);
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(k, lo), (k, hi)],
                    10,
                    6,
                    SELECTED.stroke_width(2),
                ))?
                .label(format!("K used by lssi identify: {used}"))
                .legend(line_legend(SELECTED, 2));
        }
        if let Some(p) = points.iter().find(|p| p.0 as usize == r.chosen) {
            chart
                .draw_series(std::iter::once(Circle::new(*p, 11, GOOD.stroke_width(3))))?
                .label(format!("least ε(K) (within 1 %): K = {}", r.chosen))
                .legend(|(x, y)| Circle::new((x + 14, y), 8, GOOD.stroke_width(3)));
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    }
}

impl Figure for NeighboursFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1600, 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(
            &format!(
                "k-neighbour smoothing: reconstruction error ε(K) per channel{}",
                self.units.note()
            ),
            font(CAPTION),
        )?;
        let (left, right) = root.split_horizontally(800);
        let unit = self.units.x_unit();
        self.panel(
            &left,
            "(a) displacement x",
            &unit,
            &self.neighbours.x,
            self.used.0,
        )?;
        self.panel(
            &right,
            "(b) velocity v = x′",
            &format!("{unit}/s"),
            &self.neighbours.v,
            self.used.1,
        )?;
        Ok(())
    }
}

/// ε(K) of x and v.
pub(in crate::plot) fn neighbours(
    base: &Path,
    neighbours: &Neighbours,
    report: &Report,
    units: &Units,
) -> Result<Written, PlotError> {
    let figure = NeighboursFigure {
        neighbours,
        used: (report.k.x, report.k.v),
        units,
    };
    write(base, "k-neighbours", &figure)
}

// ---------------------------------------------------------------------------------------
// Coefficients after each screening.
