//! Synthetic recordings with a known equation, for testing and benchmarking the identifier:
//! [`paper`] is the paper's eq. (17), [`eveh`] its harvester, eq. (19), and [`harvester`] the
//! piezoelectric and electromagnetic harvesters with their electrical equation, [`twodof`] a
//! two-degree-of-freedom piezoelectric harvester (two displacements).
//!
//! Each generator is a pure function from options to [`Generated`] (no file I/O), so a benchmark
//! can generate in memory and the `lssi gen` command only writes what it gets ([`files`]). The trajectories
//! come from [`ode`] (fixed-step RK4), the noise from [`noise`] (eq. 16), and the answer key
//! is a [`Truth`] ([`truth`]), which `lssi bench` and `lssi identify --track` read back.
//!
//! ```
//! use lssi_host::synth::paper::{PaperOptions, generate_paper};
//!
//! let options = PaperOptions { t_end: 1.0, dt: 0.01, ..PaperOptions::default() };
//! options.validate().unwrap();
//! let generated = generate_paper(&options);
//! assert_eq!(generated.t.len(), 101);
//! assert_eq!(generated.truth.coefficient("x^3"), Some(-4.0));
//! ```

pub mod eveh;
pub mod files;
pub mod harvester;
pub mod noise;
pub mod ode;
pub mod paper;
pub mod truth;
pub mod twodof;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::recording::{ColumnNames, Recording};
use crate::synth::truth::Truth;

/// The most samples a generator produces; past this a CSV runs to gigabytes.
pub const MAX_SAMPLES: usize = 10_000_000;

/// Which channels a generated recording contains besides t.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Observe {
    /// Displacement only: the identifier must estimate the velocity.
    X,
    /// Displacement and velocity.
    Xv,
}

/// A generated recording: the noisy observed channels, the clean trajectory, and the truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Generated {
    /// Sample times t₀ = 0, Δt, 2Δt, … in seconds.
    pub t: Vec<f64>,
    /// Observed (noisy) displacement.
    pub x: Vec<f64>,
    /// Observed (noisy) velocity, when velocity is observed.
    pub v: Option<Vec<f64>>,
    /// Noise-free displacement at each sample time.
    pub clean_x: Vec<f64>,
    /// Noise-free velocity at each sample time.
    pub clean_v: Vec<f64>,
    /// The equation and noise behind the data.
    pub truth: Truth,
}

impl Generated {
    /// The CSV header and columns of the observed data: `t,x` or `t,x,v`.
    pub fn csv_columns(&self) -> (Vec<&'static str>, Vec<&[f64]>) {
        let mut header = vec!["t", "x"];
        let mut columns = vec![self.t.as_slice(), self.x.as_slice()];
        if let Some(v) = &self.v {
            header.push("v");
            columns.push(v.as_slice());
        }
        (header, columns)
    }

    /// The first sample time at which the clean trajectory is not finite, if any: the
    /// simulation diverged there and the data after it are meaningless.
    pub fn diverged_at(&self) -> Option<f64> {
        self.t
            .iter()
            .zip(self.clean_x.iter().zip(&self.clean_v))
            .find(|(_, (x, v))| !(x.is_finite() && v.is_finite()))
            .map(|(t, _)| *t)
    }

    /// The observed data as a [`Recording`], as if written to `path` and read back.
    pub fn to_recording(&self, path: impl Into<PathBuf>) -> Recording {
        Recording {
            path: path.into(),
            t: self.t.clone(),
            x: self.x.clone(),
            v: self.v.clone(),
            u: None,
            columns: ColumnNames {
                v: self.v.as_ref().map(|_| "v".to_owned()),
                u: None,
                ..ColumnNames::default()
            },
        }
    }
}

/// A generator option that cannot be used; names the field at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field} = {value} cannot be used: it must be {requirement}.")]
pub struct OptionError {
    /// The option's field name, e.g. `dt`.
    pub field: &'static str,
    /// The value given.
    pub value: f64,
    /// What the value must be, as the end of a sentence: "positive and finite".
    pub requirement: &'static str,
}

/// Checks that `value` is finite, naming `field` if not.
pub(crate) fn require_finite(field: &'static str, value: f64) -> Result<(), OptionError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(OptionError {
            field,
            value,
            requirement: "a finite number",
        })
    }
}

/// Checks that `value` is positive and finite, naming `field` if not.
pub(crate) fn require_positive(field: &'static str, value: f64) -> Result<(), OptionError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(OptionError {
            field,
            value,
            requirement: "positive and finite",
        })
    }
}

/// Checks a sampling grid: `dt` and `t_end` positive, `dt` ≤ `t_end`, and at most
/// [`MAX_SAMPLES`] samples.
pub(crate) fn validate_grid(dt: f64, t_end: f64) -> Result<(), OptionError> {
    require_positive("dt", dt)?;
    require_positive("t_end", t_end)?;
    if dt > t_end {
        return Err(OptionError {
            field: "dt",
            value: dt,
            requirement: "no longer than t_end",
        });
    }
    if sample_count(dt, t_end) > MAX_SAMPLES {
        return Err(OptionError {
            field: "dt",
            value: dt,
            requirement: "long enough that t_end/dt stays under 10 million samples",
        });
    }
    Ok(())
}

/// How many samples t = 0, Δt, …, t_end holds; 1 for a grid that makes no sense.
fn sample_count(dt: f64, t_end: f64) -> usize {
    // The small slack keeps t_end itself when t_end/dt is an integer up to round-off
    // (100 / 0.001 is 99999.99999999999 in floating point).
    let intervals = (t_end / dt * (1.0 + 1e-12)).floor();
    if intervals.is_finite() && intervals >= 0.0 {
        // Saturating conversion; anything past the cap is cut below.
        (intervals as usize).saturating_add(1)
    } else {
        1
    }
}

/// The sample times 0, Δt, 2Δt, …, up to and including `t_end` (within round-off).
///
/// When 1/Δt is a whole number of samples per second, tₖ = k / (1/Δt), which is the correctly
/// rounded decimal (0.003, not 0.0030000000000000001) and so prints as a person would write it;
/// otherwise tₖ = k Δt. Never more than [`MAX_SAMPLES`] times; a single t = 0 for a `dt` or
/// `t_end` that is not positive and finite.
pub fn sample_times(dt: f64, t_end: f64) -> Vec<f64> {
    if !(dt.is_finite() && dt > 0.0 && t_end.is_finite() && t_end >= 0.0) {
        return vec![0.0];
    }
    let count = sample_count(dt, t_end).min(MAX_SAMPLES);
    let rate = (1.0 / dt).round();
    let whole_rate = rate >= 1.0 && ((rate * dt) - 1.0).abs() < 1e-12;
    (0..count)
        .map(|k| {
            if whole_rate {
                k as f64 / rate
            } else {
                k as f64 * dt
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_times_include_the_end() {
        let t = sample_times(0.001, 100.0);
        assert_eq!(t.len(), 100_001);
        assert_eq!(t[3], 0.003);
        assert_eq!(t[100_000], 100.0);
        let t = sample_times(0.3, 1.0);
        assert_eq!(t, vec![0.0, 0.3, 0.6, 0.8999999999999999]);
    }

    #[test]
    fn nonsense_grids_give_one_sample() {
        assert_eq!(sample_times(0.0, 1.0), vec![0.0]);
        assert_eq!(sample_times(f64::NAN, 1.0), vec![0.0]);
        assert_eq!(sample_times(0.1, -1.0), vec![0.0]);
        assert_eq!(sample_times(1e-300, 1.0).len(), MAX_SAMPLES);
    }

    #[test]
    fn grid_errors_name_the_field() {
        assert_eq!(validate_grid(0.0, 1.0).map_err(|e| e.field), Err("dt"));
        assert_eq!(
            validate_grid(0.1, f64::INFINITY).map_err(|e| e.field),
            Err("t_end")
        );
        assert_eq!(validate_grid(2.0, 1.0).map_err(|e| e.field), Err("dt"));
        assert_eq!(validate_grid(1e-9, 100.0).map_err(|e| e.field), Err("dt"));
        assert_eq!(validate_grid(0.001, 100.0), Ok(()));
    }
}
