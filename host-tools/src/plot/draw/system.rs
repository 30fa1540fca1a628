//! A harvester's figures (issue 26): the predicted mean power against the load and against
//! the forcing frequency (`--load-ohms`), and the measured voltage against the identified
//! system's free run from the excitation alone.

use super::*;
use crate::system::power::Harvester;

/// Mean power against the load resistance (log–log), the recorded load and the optimum.
struct PowerLoad<'a> {
    h: &'a Harvester,
}

impl Figure for PowerLoad<'_> {
    fn size(&self) -> (u32, u32) {
        (1400, 900)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let h = self.h;
        let points: Vec<(f64, f64)> = h
            .load_sweep
            .iter()
            .filter_map(|p| p.power_w.map(|w| (p.at, w)))
            .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.1.is_finite())
            .collect();
        if h.load_sweep.is_empty()
            && h.transducer == crate::system::power::Transducer::Electromagnetic
            && h.coil_ohms.is_none()
        {
            return Err(PlotError::Skipped(
                "the power against the load of a coil needs its resistance (--coil-ohms R_c)."
                    .into(),
            ));
        }
        if points.len() < 2 {
            return Err(PlotError::Skipped(
                "the load sweep has fewer than two finite powers.".into(),
            ));
        }
        let measured = (h.power_measured_w > 0.0 && h.power_measured_w.is_finite())
            .then_some((h.load_ohms, h.power_measured_w));
        let ys = points
            .iter()
            .map(|p| p.1)
            .chain(measured.map(|m| m.1))
            .chain(h.optimal_power_w);
        let (ylo, yhi) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), y| (a.min(y), b.max(y)));
        let (ylo, yhi) = (ylo / 1.5, yhi * 1.5);
        let xlo = points.first().map_or(1.0, |p| p.0) / 1.2;
        let xhi = points.last().map_or(10.0, |p| p.0) * 1.2;
        let title = match (h.optimal_load_ohms, h.optimal_power_w) {
            (Some(r), Some(p)) => format!(
                "predicted mean power {} against the load: optimum {} W at {} Ω",
                h.power_formula(),
                coefficient(p),
                coefficient(r)
            ),
            _ => format!(
                "predicted mean power {} against the load",
                h.power_formula()
            ),
        };
        let root = root.titled(&title, font(CAPTION))?;
        let mut chart = ChartBuilder::on(&root)
            .margin(20)
            .margin_right(40)
            .x_label_area_size(70)
            .y_label_area_size(130)
            .build_cartesian_2d((xlo..xhi).log_scale(), (ylo..yhi).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("load resistance R [Ω]")
            .y_desc("mean power [W]")
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        chart
            .draw_series(LineSeries::new(points.clone(), MODEL.stroke_width(3)))?
            .label(match h.transducer {
                crate::system::power::Transducer::Piezoelectric => {
                    "predicted (the identified system's free run, λ(R) = 1/(R C_p))"
                }
                crate::system::power::Transducer::Electromagnetic => {
                    "predicted (the identified system's free run, λ(R) = (R_c + R)/L)"
                }
            })
            .legend(line_legend(MODEL, 3));
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 5, MODEL.filled())))?;
        if let Some(m) = measured {
            chart
                .draw_series(std::iter::once(Cross::new(
                    m,
                    12,
                    RECORDING.stroke_width(4),
                )))?
                .label(format!(
                    "measured at the recorded load {} Ω: {} W",
                    coefficient(m.0),
                    coefficient(m.1)
                ))
                .legend(|(x, y)| Cross::new((x + 14, y), 8, RECORDING.stroke_width(3)));
        }
        if let (Some(r), Some(p)) = (h.optimal_load_ohms, h.optimal_power_w) {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(r, ylo), (r, yhi)],
                    10,
                    6,
                    GOOD.stroke_width(2),
                ))?
                .label(format!("optimal load {} Ω", coefficient(r)))
                .legend(line_legend(GOOD, 2));
            chart.draw_series(std::iter::once(Circle::new(
                (r, p),
                10,
                GOOD.stroke_width(3),
            )))?;
        }
        legend(&mut chart, SeriesLabelPosition::LowerMiddle)?;
        Ok(())
    }
}

/// Mean power against the forcing frequency at the recorded load.
struct PowerFrequency<'a> {
    h: &'a Harvester,
    /// The recording's forcing frequency, rad/s (Ω).
    omega: f64,
}

impl Figure for PowerFrequency<'_> {
    fn size(&self) -> (u32, u32) {
        (1400, 900)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let h = self.h;
        let hz = std::f64::consts::TAU;
        let points: Vec<(f64, f64)> = h
            .frequency_sweep
            .iter()
            .filter_map(|p| p.power_w.map(|w| (p.at / hz, w)))
            .filter(|p| p.1 > 0.0 && p.1.is_finite())
            .collect();
        if points.len() < 2 {
            return Err(PlotError::Skipped(
                "the frequency sweep has fewer than two finite powers.".into(),
            ));
        }
        let (ylo, yhi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
        let (ylo, yhi) = (ylo / 1.5, yhi * 1.5);
        let (xlo, xhi) = padded(points.iter().map(|p| p.0));
        let best = points
            .iter()
            .copied()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0.0, 0.0));
        let root = root.titled(
            &format!(
                "predicted mean power {} against the forcing frequency at R = {} Ω: most at {:.3} Hz",
                h.power_formula(),
                coefficient(h.load_ohms),
                best.0
            ),
            font(CAPTION),
        )?;
        let mut chart = ChartBuilder::on(&root)
            .margin(20)
            .margin_right(40)
            .x_label_area_size(70)
            .y_label_area_size(130)
            .build_cartesian_2d(xlo..xhi, (ylo..yhi).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("forcing frequency [Hz]")
            .y_desc("mean power [W]")
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_label_formatter(&ticker(xlo, xhi))
            .y_label_formatter(&|v| tick(*v))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        chart
            .draw_series(LineSeries::new(points.clone(), MODEL.stroke_width(3)))?
            .label("predicted (the identified system's free run, the forcing's amplitude kept)")
            .legend(line_legend(MODEL, 3));
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 5, MODEL.filled())))?;
        if self.omega > 0.0 {
            let f = self.omega / hz;
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(f, ylo), (f, yhi)],
                    10,
                    6,
                    RECORDING.stroke_width(2),
                ))?
                .label(format!("the recording's forcing, {f:.3} Hz"))
                .legend(line_legend(RECORDING, 2));
        }
        legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        Ok(())
    }
}

/// The measured electrical channel against the free run: the whole record and a close-up.
struct Voltage<'a> {
    t: &'a [f64],
    measured: &'a [f64],
    predicted: &'a [f64],
    symbol: &'a str,
    nrmse_percent: f64,
}

impl Voltage<'_> {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        title: &str,
        span: std::ops::Range<usize>,
    ) -> Result<(), PlotError> {
        let t = &self.t[span.clone()];
        let m = &self.measured[span.clone()];
        let p = &self.predicted[span];
        let (lo, hi) = padded(m.iter().chain(p.iter()).copied());
        let (t0, t1) = (t[0], t[t.len() - 1]);
        let mut chart = ChartBuilder::on(area)
            .caption(title, font(DESC))
            .margin(15)
            .margin_right(30)
            .x_label_area_size(60)
            .y_label_area_size(120)
            .build_cartesian_2d(t0..t1, lo..hi)?;
        let unit = if self.symbol == "V" { "V" } else { "A" };
        chart
            .configure_mesh()
            .x_desc("time t [s]")
            .y_desc(format!("{} [{unit}]", self.symbol))
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_label_formatter(&ticker(t0, t1))
            .y_label_formatter(&ticker(lo, hi))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        chart
            .draw_series(LineSeries::new(
                envelope(t, m, BUCKETS),
                RECORDING.stroke_width(2),
            ))?
            .label(format!("measured {}", self.symbol))
            .legend(line_legend(RECORDING, 2));
        let finite: Vec<(f64, f64)> = t
            .iter()
            .zip(p)
            .filter(|q| q.1.is_finite())
            .map(|(a, b)| (*a, *b))
            .collect();
        let (ft, fp): (Vec<f64>, Vec<f64>) = finite.into_iter().unzip();
        if !ft.is_empty() {
            chart
                .draw_series(LineSeries::new(
                    envelope(&ft, &fp, BUCKETS),
                    MODEL.stroke_width(2),
                ))?
                .label("predicted from the excitation alone (free run from the first row)")
                .legend(line_legend(MODEL, 2));
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    }
}

impl Figure for Voltage<'_> {
    fn size(&self) -> (u32, u32) {
        (1600, 1100)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let n = self.t.len();
        if n < 16 {
            return Err(PlotError::Skipped("fewer than 16 samples.".into()));
        }
        let root = root.titled(
            &format!(
                "measured {} against the identified system's prediction: NRMSE {}",
                self.symbol,
                if self.nrmse_percent.is_finite() {
                    format!("{:.2} % over the record", self.nrmse_percent)
                } else {
                    "— (the free run diverged)".to_owned()
                }
            ),
            font(CAPTION),
        )?;
        let (top, bottom) = root.split_vertically(550);
        self.panel(&top, "(a) the whole record", 0..n)?;
        // The close-up: the last few periods of the measured channel.
        let period = crate::identify::refine::mean_period_samples(self.measured).unwrap_or(64.0);
        let width = ((6.0 * period) as usize).clamp(16, n);
        self.panel(
            &bottom,
            "(b) close-up: the record's last six periods",
            n - width..n,
        )?;
        Ok(())
    }
}

/// `<base>-power-load` (with `--load-ohms`).
pub(in crate::plot) fn power_load(base: &Path, h: &Harvester) -> Result<Written, PlotError> {
    write(base, "power-load", &PowerLoad { h })
}

/// `<base>-power-frequency` (with `--load-ohms`).
pub(in crate::plot) fn power_frequency(
    base: &Path,
    h: &Harvester,
    omega: f64,
) -> Result<Written, PlotError> {
    write(base, "power-frequency", &PowerFrequency { h, omega })
}

/// `<base>-voltage` (or `-current`): the measured channel against the free run.
pub(in crate::plot) fn voltage(
    base: &Path,
    t: &[f64],
    measured: &[f64],
    predicted: &[f64],
    symbol: &str,
    nrmse_percent: f64,
) -> Result<Written, PlotError> {
    let name = if symbol == "V" { "voltage" } else { "current" };
    write(
        base,
        name,
        &Voltage {
            t,
            measured,
            predicted,
            symbol,
            nrmse_percent,
        },
    )
}
