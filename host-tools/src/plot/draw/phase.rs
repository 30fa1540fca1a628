//! Phase figure: the phase portrait of the recording and the model, with the equilibria.

use super::*;

struct PhaseFigure<'a> {
    points: Vec<(f64, f64)>,
    /// (x, stable) of each equilibrium in the recording's coordinates.
    equilibria: Vec<(f64, bool)>,
    v_origin: f64,
    title: String,
    units: &'a Units,
}

impl Figure for PhaseFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1300, 1050)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(&self.title, font(CAPTION))?;
        let (x0, x1) = padded(
            self.points
                .iter()
                .map(|p| p.0)
                .chain(self.equilibria.iter().map(|e| e.0)),
        );
        let (v0, v1) = padded(self.points.iter().map(|p| p.1).chain([self.v_origin]));
        let mut chart = ChartBuilder::on(&root)
            .margin(20)
            .margin_right(40)
            .x_label_area_size(65)
            .y_label_area_size(120)
            .build_cartesian_2d(x0..x1, v0..v1)?;
        chart
            .configure_mesh()
            .x_desc(self.units.x())
            .y_desc(self.units.v())
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_label_formatter(&ticker(x0, x1))
            .y_label_formatter(&ticker(v0, v1))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        chart
            .draw_series(LineSeries::new(
                self.points.clone(),
                ACCENT.mix(0.45).stroke_width(1),
            ))?
            .label("recording")
            .legend(line_legend(ACCENT, 3));
        let wells: Vec<(f64, f64)> = self
            .equilibria
            .iter()
            .filter(|e| e.1)
            .map(|e| (e.0, self.v_origin))
            .collect();
        let saddles: Vec<(f64, f64)> = self
            .equilibria
            .iter()
            .filter(|e| !e.1)
            .map(|e| (e.0, self.v_origin))
            .collect();
        let double = wells.len() > 1;
        if !wells.is_empty() {
            for w in wells.iter().filter(|_| double) {
                chart.draw_series(DashedLineSeries::new(
                    vec![(w.0, v0), (w.0, v1)],
                    10,
                    6,
                    GOOD.mix(0.8).stroke_width(2),
                ))?;
            }
            chart
                .draw_series(wells.iter().map(|p| Circle::new(*p, 12, GOOD.filled())))?
                .label(format!(
                    "{} at x = {}",
                    if double {
                        "wells (stable equilibria)"
                    } else {
                        "stable equilibrium"
                    },
                    wells
                        .iter()
                        .map(|w| tick(w.0))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
                .legend(|(x, y)| Circle::new((x + 14, y), 9, GOOD.filled()));
        }
        if !saddles.is_empty() {
            chart
                .draw_series(
                    saddles
                        .iter()
                        .map(|p| Cross::new(*p, 12, SELECTED.stroke_width(4))),
                )?
                .label(format!(
                    "saddle (unstable equilibrium) at x = {}",
                    saddles
                        .iter()
                        .map(|w| tick(w.0))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
                .legend(|(x, y)| Cross::new((x + 14, y), 9, SELECTED.stroke_width(3)));
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    }
}

/// Real roots of the model's unforced restoring force p(x) = Σ c₍ₐ,₀₎ (x − offset)ᵃ within
/// `[lo, hi]`, with whether each is stable (p′ < 0): [`RestoringForce::equilibria`].
fn equilibria(report: &Report, lo: f64, hi: f64) -> Vec<(f64, bool)> {
    let force = RestoringForce::from_terms(report.model.iter().copied(), report.offsets[0]);
    let mut out = Vec::new();
    force.equilibria(lo, hi, |e| out.push((e.x, e.stable)));
    out
}

/// The phase portrait.
pub(in crate::plot) fn phase(
    base: &Path,
    recording: &Recording,
    velocity: &[Option<f64>],
    report: &Report,
    units: &Units,
) -> Result<Written, PlotError> {
    let all: Vec<(f64, f64)> = recording
        .x
        .iter()
        .zip(velocity)
        .filter_map(|(x, v)| v.filter(|_| x.is_finite()).map(|v| (*x, v)))
        .collect();
    if all.len() < 2 {
        return Err(PlotError::Skipped(
            "no sample has both x and a velocity.".into(),
        ));
    }
    let step = all.len().div_ceil(40_000).max(1);
    let points: Vec<(f64, f64)> = all.iter().step_by(step).copied().collect();
    let (lo, hi) = padded(points.iter().map(|p| p.0));
    let equilibria = equilibria(report, lo, hi);
    let title = match (report.wells, report.well_resonance_hz) {
        (Some(w), Some(f)) => format!(
            "Phase portrait: double well, wells at x = {} ± {} (in-well resonance {} Hz)",
            tick(report.offsets[0]),
            tick(w),
            tick(f)
        ),
        _ => match report.resonance_hz {
            Some(f) => format!(
                "Phase portrait: single well, linear resonance {} Hz",
                tick(f)
            ),
            None => "Phase portrait".into(),
        },
    };
    let figure = PhaseFigure {
        points,
        equilibria,
        v_origin: report.offsets[1],
        title: format!("{title}{}", units.note()),
        units,
    };
    write(base, "phase", &figure)
}
