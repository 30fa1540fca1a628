//! Model figure: the recording against the model's free run from the first sample and identify's short-horizon prediction.

use super::*;

struct ModelFigure<'a> {
    t: &'a [f64],
    x: &'a [f64],
    sim: Vec<f64>,
    /// The upper panel's span and caption (the whole record, or its start when the record
    /// holds too many periods to see).
    overview: ((f64, f64), &'static str),
    zoom: (f64, f64),
    title: String,
    /// identify's short-horizon figure, in the upper panel's caption.
    prediction: Option<String>,
    units: &'a Units,
}

impl Figure for ModelFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1500, 1050)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(&self.title, font(CAPTION))?;
        let (top, bottom) = root.split_vertically(480);
        let panels = [
            (&top, self.overview.0, self.overview.1),
            (&bottom, self.zoom, "close-up: the end of the free run"),
        ];
        for (area, (t0, t1), label) in panels {
            let inside = |t: f64| t >= t0 && t <= t1;
            let (ts, xs, ss): (Vec<f64>, Vec<f64>, Vec<f64>) = {
                let mut a = (Vec::new(), Vec::new(), Vec::new());
                for ((t, x), s) in self.t.iter().zip(self.x).zip(&self.sim) {
                    if inside(*t) {
                        a.0.push(*t);
                        a.1.push(*x);
                        a.2.push(*s);
                    }
                }
                a
            };
            let (lo, hi) = padded(xs.iter().chain(ss.iter()).copied());
            // Head room for the legend.
            let hi = hi + 0.3 * (hi - lo);
            let caption = match (&self.prediction, t0 == self.overview.0.0) {
                (Some(p), true) => format!("{label}; {p}"),
                _ => label.to_owned(),
            };
            let mut chart = ChartBuilder::on(area)
                .caption(caption, font(DESC))
                .margin(15)
                .margin_right(40)
                .x_label_area_size(60)
                .y_label_area_size(110)
                .build_cartesian_2d(t0..t1, lo..hi)?;
            chart
                .configure_mesh()
                .x_desc("time t [s]")
                .y_desc(self.units.x())
                .label_style(font(LABEL))
                .axis_desc_style(font(DESC))
                .x_label_formatter(&ticker(t0, t1))
                .y_label_formatter(&ticker(lo, hi))
                .light_line_style(BLACK.mix(0.06))
                .draw()?;
            if label == "whole record" && self.zoom.0 > t0 {
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(self.zoom.0, lo), (self.zoom.1, hi)],
                    ACCENT.mix(0.12).filled(),
                )))?;
            }
            chart
                .draw_series(LineSeries::new(
                    envelope(&ts, &xs, BUCKETS),
                    RECORDING.mix(0.45).stroke_width(6),
                ))?
                .label("recording")
                .legend(line_legend(RECORDING, 6));
            chart
                .draw_series(LineSeries::new(
                    envelope(&ts, &ss, BUCKETS),
                    MODEL.stroke_width(2),
                ))?
                .label("identified model, free run")
                .legend(line_legend(MODEL, 3));
            legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        }
        Ok(())
    }
}

/// The recording against its model's free simulation from the first sample with a velocity.
pub(in crate::plot) fn model(
    base: &Path,
    recording: &Recording,
    velocity: &[Option<f64>],
    report: &Report,
    prediction: Option<&str>,
    units: &Units,
) -> Result<Written, PlotError> {
    let start = (0..recording.len())
        .find(|&i| {
            recording.x[i].is_finite() && recording.t[i].is_finite() && velocity[i].is_some()
        })
        .ok_or_else(|| PlotError::Skipped("no sample has both x and a velocity.".into()))?;
    let t = &recording.t[start..];
    let x = &recording.x[start..];
    if t.len() < 2 {
        return Err(PlotError::Skipped("too few samples to simulate.".into()));
    }
    let v0 = velocity[start].unwrap_or(0.0);
    let model = SimModel::from_report(report);
    let u = recording.u.as_ref().map(|u| &u[start..]);
    let run = simulate(&model, t, u, (x[0], v0), 2);
    let score = match (run.diverged_at, nrmse(&run.x, x)) {
        (Some(i), _) => format!("the simulation diverged at t = {} s", tick(t[i])),
        (None, Some(e)) => format!("NRMSE {:.1} %", 100.0 * e),
        (None, None) => "NRMSE not defined".into(),
    };
    let span = t[t.len() - 1] - t[0];
    // Close-up: four periods of the excitation (or of the linear resonance), at the end.
    let forced = model
        .terms
        .iter()
        .any(|(term, c)| matches!(term, Term::Sin(_) | Term::Cos(_)) && *c != 0.0);
    // The strongest sin/cos term sets the period of the forced response.
    let strongest = model
        .terms
        .iter()
        .filter_map(|(term, c)| match term {
            Term::Sin(k) | Term::Cos(k) if *c != 0.0 => Some((*k, c.abs())),
            _ => None,
        })
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let period = if let (true, Some((k, _))) = (forced && report.omega > 0.0, strongest) {
        Some(2.0 * std::f64::consts::PI / (f64::from(k) * report.omega))
    } else {
        report
            .resonance_hz
            .or(report.well_resonance_hz)
            .map(|f| 1.0 / f)
    };
    let width = period.map_or(0.1 * span, |p| 3.0 * p).min(span);
    let end = t[t.len() - 1];
    let overview = match period {
        Some(p) if span > 30.0 * p => ((t[0], t[0] + 10.0 * p), "start of the free run"),
        _ => ((t[0], end), "whole record"),
    };
    let figure = ModelFigure {
        t,
        x,
        sim: run.x,
        overview,
        zoom: (end - width, end),
        title: format!(
            "Recording vs. the model, free run from the first sample: {score}{}",
            units.note()
        ),
        prediction: prediction.map(str::to_owned),
        units,
    };
    write(base, "model", &figure)
}

// ---------------------------------------------------------------------------------------
// Mean error of every solution (Figs. 6 and 12).
