//! The row rate a device needs for a harvester: what `lssi identify` proposes from a model.
//!
//! A field device should not sample a 3–50 Hz harvester at 10 kHz: every row costs energy
//! (issue 27). The identifier holds its accuracy down to about 30 samples a period of the
//! fastest line that matters (docs/figures.md, "Low sample rates": the eveh harvester at
//! 1 % noise, x only, streaming median 0.7–1.2 % at 30–60 samples a forcing period, the
//! damping kept; at 24 the weak form is off and a monostable seed loses terms). The
//! proposal keeps a margin: [`SAMPLES_PER_PERIOD`] samples a period of the fastest of the
//! forcing's highest harmonic in the model, the linear resonance and the resonance in a
//! well, rounded up to 10 Hz.

use lssi_core::Term;

/// Samples a period of the fastest line the proposal asks for.
pub const SAMPLES_PER_PERIOD: f64 = 50.0;

/// A proposed row rate and the line that sets it.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceRate {
    /// Rows a second, Hz (a multiple of 10).
    pub hz: f64,
    /// The fastest line's frequency, Hz.
    pub line_hz: f64,
    /// Which line it is: "the forcing", "its k-th harmonic", "the linear resonance",
    /// "the resonance in a well".
    pub line: String,
}

/// The rate for a model with forcing Ω (rad/s), its terms, and its linear and in-well
/// resonances (Hz). `None` without any line to go by (no harmonic term and no resonance).
pub fn device_rate(
    omega: f64,
    terms: &[(Term, f64)],
    resonance_hz: Option<f64>,
    well_resonance_hz: Option<f64>,
) -> Option<DeviceRate> {
    let mut lines: Vec<(f64, String)> = Vec::new();
    let harmonic = terms
        .iter()
        .filter_map(|(t, c)| match t {
            Term::Sin(k) | Term::Cos(k) if *c != 0.0 => Some(*k),
            _ => None,
        })
        .max();
    if let Some(k) = harmonic
        && omega.is_finite()
        && omega > 0.0
    {
        let name = if k == 1 {
            "the forcing".to_string()
        } else {
            format!("the forcing's harmonic {k}Ω")
        };
        lines.push((f64::from(k) * omega / (2.0 * std::f64::consts::PI), name));
    }
    if let Some(f) = resonance_hz {
        lines.push((f, "the linear resonance".into()));
    }
    if let Some(f) = well_resonance_hz {
        lines.push((f, "the resonance in a well".into()));
    }
    let (line_hz, line) = lines
        .into_iter()
        .filter(|(f, _)| f.is_finite() && *f > 0.0)
        .max_by(|a, b| a.0.total_cmp(&b.0))?;
    let hz = (SAMPLES_PER_PERIOD * line_hz / 10.0).ceil() * 10.0;
    Some(DeviceRate { hz, line_hz, line })
}

impl super::Report {
    /// The row rate a device needs for the reported model ([`device_rate`]).
    pub fn device_rate(&self) -> Option<DeviceRate> {
        device_rate(
            self.omega,
            &self.model,
            self.resonance_hz,
            self.well_resonance_hz,
        )
    }
}

/// The report's sentence: "a device needs 200 Hz for this harvester (…)", with a note when
/// the recording was sampled below it.
pub fn sentence(rate: &DeviceRate, sample_period: f64) -> String {
    let mut s = format!(
        "a device needs {} Hz for this harvester ({} samples a period of {} at {:.4} Hz)",
        rate.hz, SAMPLES_PER_PERIOD, rate.line, rate.line_hz
    );
    let recorded = 1.0 / sample_period;
    if recorded.is_finite() && recorded < rate.hz {
        s.push_str(&format!(
            "; this recording has {:.1} samples a period of it",
            recorded / rate.line_hz
        ));
    }
    s
}

/// Samples a period of the fastest line under which the identifier's accuracy is not held
/// (docs/figures.md, "Low sample rates": from 30 samples a forcing period the eveh harvester
/// keeps every term; at 24 a monostable one loses its damping and cubic).
pub const FEWEST_SAMPLES_PER_PERIOD: f64 = 28.0;

/// A warning for a recording sampled too coarsely for its model's fastest line, or `None`.
pub fn coarse_warning(report: &super::Report) -> Option<String> {
    let rate = report.device_rate()?;
    let per_period = 1.0 / (report.sample_period * rate.line_hz);
    (per_period.is_finite() && per_period < FEWEST_SAMPLES_PER_PERIOD).then(|| {
        format!(
            "this recording has {per_period:.1} samples a period of {} ({:.4} Hz); the identifier holds its accuracy from about 30 (docs/figures.md, low sample rates): a damping or cubic term may be off or missing, sample at {} Hz or faster",
            rate.line, rate.line_hz, rate.hz
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fastest_line_sets_the_rate() {
        let terms = [
            (Term::Monomial { px: 1, pv: 0 }, -336.6),
            (Term::Cos(1), 0.98),
        ];
        // eveh: forcing 21.4 rad/s (3.406 Hz), resonance in a well 3.96 Hz: 198 -> 200 Hz.
        let r = device_rate(21.4, &terms, None, Some(3.96)).unwrap();
        assert_eq!(r.hz, 200.0);
        assert_eq!(r.line, "the resonance in a well");
        // A third harmonic in the model sets it.
        let terms3 = [(Term::Cos(1), 1.0), (Term::Sin(3), 0.1)];
        let r = device_rate(1.0, &terms3, Some(0.1), None).unwrap();
        assert!((r.line_hz - 3.0 / (2.0 * std::f64::consts::PI)).abs() < 1e-12);
        assert_eq!(r.hz, 30.0);
        // A harmonic with a zero coefficient is not in the model.
        let zero = [(Term::Cos(5), 0.0)];
        assert_eq!(device_rate(1.0, &zero, None, None), None);
        assert_eq!(device_rate(f64::NAN, &terms3, None, None), None);
    }

    #[test]
    fn the_sentence_says_when_the_recording_is_too_coarse() {
        let r = DeviceRate {
            hz: 200.0,
            line_hz: 3.96,
            line: "the resonance in a well".into(),
        };
        assert!(!sentence(&r, 1e-4).contains("this recording"));
        assert!(sentence(&r, 1.0 / 100.0).contains("25.3 samples a period"));
    }
}
