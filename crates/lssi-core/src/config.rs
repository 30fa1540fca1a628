//! Tunables of the identifier, validated once when it is built (state lives apart, in
//! [`crate::Identifier`]).

use crate::library::{LibraryConfig, PolyFamily};
use core::fmt;

/// Which measured channels a sample carries besides t and x.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Channels {
    /// A measured velocity v = x' (used instead of differentiating x).
    pub velocity: bool,
    /// A measured excitation u.
    pub input: bool,
}

impl Channels {
    /// How many sample channels these are with x: the ring buffers an
    /// [`Identifier`](crate::Identifier) needs (1 to 3).
    pub const fn count(&self) -> usize {
        1 + self.velocity as usize + self.input as usize
    }
}

/// The identifier's configuration. `Config::default()` is the one default configuration
/// used for every benchmark row; only the sample period, Ω and the library differ between
/// recordings, and those describe the recording, not the method.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Nominal sample period, seconds.
    pub sample_period: f64,
    /// Samples in the local polynomial (derivative) window; the estimates lag by half of it.
    pub window: usize,
    /// Degree of the local polynomial.
    pub derivative_degree: u8,
    /// The candidate terms.
    pub library: LibraryConfig,
    /// Base angular frequency Ω of the sin/cos terms, rad/s (ignored without harmonics).
    pub omega: f64,
    /// Measured channels besides x.
    pub channels: Channels,
    /// Memory time constant of the forgetting, seconds (`None`: remember everything).
    pub memory: Option<f64>,
    /// Samples between two screenings (threshold sweep + MES).
    pub screening_period: u32,
    /// Points of the logarithmic threshold grid added to the data's own thresholds.
    pub thresholds: u8,
    /// k-neighbour smoothing of x and v (off only for the ablation).
    pub smoothing: bool,
    /// One regression row every `row_stride` samples (the rows of a smoothed signal a few
    /// samples apart carry the same information). With `test_rows`, 1: summed at a stride,
    /// the derivative filter's noise does not cancel (see `test_rows`).
    pub row_stride: u16,
    /// MES parsimony: the sparsest solution whose held-out mean error is within this
    /// fraction of the least one is chosen.
    pub parsimony: f64,
    /// Estimate and remove the sensor offsets of x and v (docs/design.md, "Sensor offsets").
    pub offsets: bool,
    /// A sample whose |x|, |v| or |u| exceeds this is absurd and rejected.
    pub max_abs: f64,
    /// Take the noise of x̂ and v̂ out of the normal equations before each sweep (errors in
    /// variables, the `eiv` module). Off by default: it removes the bias of the estimates
    /// on a given support, but the MES selection at high noise is not up to it (see the
    /// README's accuracy section). For rows as they are only (`test_rows` 0): its
    /// correction is derived from the moments of pointwise rows, which sums of rows do not
    /// have.
    pub noise_correction: bool,
    /// Test-function rows (the weak form): each row that goes into the regression is the
    /// average of `test_rows` consecutive rows weighted by the smooth bump (1 − τ²)⁴, four
    /// such averages overlapping (one completes every `test_rows / 4` rows). The equation
    /// holds row by row, so it holds for any weighted sum of rows; a smooth weight cancels
    /// most of the noise of the derivative estimates (Σφ·ĥ₂∗x = Σ(φ∗ĥ₂)·x ≈ Σφ''·x) while
    /// the library terms are still taken pointwise from a short window. 0: every row goes
    /// in as it is. A multiple of 4, at least 8.
    pub test_rows: u16,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            sample_period: 1e-3,
            window: 255,
            derivative_degree: 5,
            library: LibraryConfig::default(),
            omega: 1.0,
            channels: Channels::default(),
            memory: None,
            screening_period: 10_000,
            thresholds: 24,
            smoothing: true,
            row_stride: 4,
            parsimony: 0.05,
            offsets: true,
            max_abs: 1e9,
            noise_correction: false,
            test_rows: 0,
        }
    }
}

/// A configuration field that is out of range.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ConfigError {
    /// `sample_period` is not positive and finite.
    SamplePeriod(f64),
    /// `window` does not fit the capacity or the degree.
    Window {
        /// Requested.
        window: usize,
        /// Smallest allowed.
        min: usize,
        /// Largest allowed (the buffer capacity).
        max: usize,
    },
    /// `derivative_degree` is out of range.
    DerivativeDegree(u8),
    /// The library cannot be built.
    Library(crate::library::LibraryError),
    /// `omega` must be positive and finite when there are harmonics.
    Omega(f64),
    /// `memory` must be positive (seconds) when given.
    Memory(f64),
    /// `screening_period` is zero.
    ScreeningPeriod,
    /// `row_stride` is zero.
    RowStride,
    /// `parsimony` is negative or not finite.
    Parsimony(f64),
    /// `max_abs` is not positive.
    MaxAbs(f64),
    /// The library asks for the input u, but the channels have none.
    InputWithoutChannel,
    /// The channels (x, and v and u when measured) need more ring buffers than the
    /// identifier's capacity `C` holds.
    Channels {
        /// Channels the configuration has, x included.
        channels: usize,
        /// Ring buffers the identifier has (its `C`).
        capacity: usize,
    },
    /// `noise_correction` is on, but lssi-core was built without its `noise-correction`
    /// feature (the firmware leaves it out: 3.5 KB of flash).
    NoiseCorrectionUnavailable,
    /// `test_rows` is neither 0 nor a multiple of 4 of at least 8.
    TestRows(u16),
    /// `noise_correction` and `test_rows` are both on.
    NoiseCorrectionWithTestRows,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::SamplePeriod(v) => write!(f, "sample_period is {v}, but it must be a positive number of seconds"),
            ConfigError::Window { window, min, max } => {
                write!(f, "window is {window} samples, but it must be between {min} and {max}")
            }
            ConfigError::DerivativeDegree(d) => write!(f, "derivative_degree is {d}, but it must be between 2 and 8"),
            ConfigError::Library(e) => fmt::Display::fmt(e, f),
            ConfigError::Omega(v) => write!(f, "omega is {v}, but the sin/cos terms need a positive frequency in rad/s"),
            ConfigError::Memory(v) => write!(f, "memory is {v}, but it must be a positive time constant in seconds"),
            ConfigError::ScreeningPeriod => f.write_str("screening_period must be at least 1 sample"),
            ConfigError::RowStride => f.write_str("row_stride must be at least 1"),
            ConfigError::Parsimony(v) => write!(f, "parsimony is {v}, but it must be a fraction between 0 and 1"),
            ConfigError::MaxAbs(v) => write!(f, "max_abs is {v}, but it must be positive"),
            ConfigError::InputWithoutChannel => {
                f.write_str("library.input asks for the excitation u, but channels.input says the samples carry none")
            }
            ConfigError::Channels { channels, capacity } => write!(
                f,
                "the samples carry {channels} channels (x, and v and u when measured), but this identifier was built with ring buffers for {capacity}"
            ),
            ConfigError::TestRows(v) => write!(f, "test_rows is {v}, but it must be 0 (off) or a multiple of 4 of at least 8"),
            ConfigError::NoiseCorrectionWithTestRows => f.write_str(
                "noise_correction works on rows as they are, but test_rows asks for sums of rows; set test_rows to 0",
            ),
            ConfigError::NoiseCorrectionUnavailable => f.write_str(
                "noise_correction is on, but this build of lssi-core has no `noise-correction` feature",
            ),
        }
    }
}

impl core::error::Error for ConfigError {}

impl From<crate::library::LibraryError> for ConfigError {
    fn from(e: crate::library::LibraryError) -> Self {
        ConfigError::Library(e)
    }
}

impl Config {
    /// Every field zero (bits): storage for an identifier not yet configured.
    pub(crate) const fn zeroed() -> Self {
        Config {
            sample_period: 0.0,
            window: 0,
            derivative_degree: 0,
            library: LibraryConfig {
                poly_order: 0,
                family: PolyFamily::All,
                constant: false,
                harmonics: 0,
                input: false,
            },
            omega: 0.0,
            channels: Channels {
                velocity: false,
                input: false,
            },
            memory: None,
            screening_period: 0,
            thresholds: 0,
            smoothing: false,
            row_stride: 0,
            parsimony: 0.0,
            offsets: false,
            max_abs: 0.0,
            noise_correction: false,
            test_rows: 0,
        }
    }

    /// Checks every field against the capacities `W` (window), `P` (terms) and `C` (channel
    /// ring buffers: x, and v and u when measured).
    pub fn validate<const W: usize, const P: usize, const C: usize>(
        &self,
    ) -> Result<(), ConfigError> {
        if self.noise_correction && !cfg!(feature = "noise-correction") {
            return Err(ConfigError::NoiseCorrectionUnavailable);
        }
        if !(self.sample_period.is_finite() && self.sample_period > 0.0) {
            return Err(ConfigError::SamplePeriod(self.sample_period));
        }
        if !(2..=crate::derivative::MAX_DEGREE as u8).contains(&self.derivative_degree) {
            return Err(ConfigError::DerivativeDegree(self.derivative_degree));
        }
        let min = usize::from(self.derivative_degree) + 3;
        if self.window < min || self.window > W {
            return Err(ConfigError::Window {
                window: self.window,
                min,
                max: W,
            });
        }
        crate::library::Library::<P>::new(&self.library)?;
        if self.library.harmonics > 0 && !(self.omega.is_finite() && self.omega > 0.0) {
            return Err(ConfigError::Omega(self.omega));
        }
        if let Some(m) = self.memory
            && !(m > 0.0)
        {
            return Err(ConfigError::Memory(m));
        }
        if self.screening_period == 0 {
            return Err(ConfigError::ScreeningPeriod);
        }
        if self.row_stride == 0 {
            return Err(ConfigError::RowStride);
        }
        if !(self.parsimony.is_finite() && (0.0..1.0).contains(&self.parsimony)) {
            return Err(ConfigError::Parsimony(self.parsimony));
        }
        if !(self.max_abs > 0.0) {
            return Err(ConfigError::MaxAbs(self.max_abs));
        }
        if self.test_rows != 0 && (self.test_rows < 8 || !self.test_rows.is_multiple_of(4)) {
            return Err(ConfigError::TestRows(self.test_rows));
        }
        if self.noise_correction && self.test_rows != 0 {
            return Err(ConfigError::NoiseCorrectionWithTestRows);
        }
        if self.library.input && !self.channels.input {
            return Err(ConfigError::InputWithoutChannel);
        }
        if self.channels.count() > C {
            return Err(ConfigError::Channels {
                channels: self.channels.count(),
                capacity: C,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The correction is refused by a build without it, with a sentence that says so, and
    /// accepted by one with it.
    #[test]
    fn noise_correction_needs_its_feature() {
        let config = Config {
            noise_correction: true,
            ..Config::default()
        };
        let result = config.validate::<256, 16, 3>();
        if cfg!(feature = "noise-correction") {
            assert_eq!(result, Ok(()));
        } else {
            assert_eq!(result, Err(ConfigError::NoiseCorrectionUnavailable));
            let text = std::format!("{}", ConfigError::NoiseCorrectionUnavailable);
            assert!(text.contains("noise-correction"), "{text}");
        }
    }

    /// Test-function rows: 0 or a multiple of 4 of at least 8, and not with the noise
    /// correction (which needs pointwise rows).
    #[test]
    fn test_rows_are_checked() {
        for ok in [0u16, 8, 12, 1048, 65532] {
            let config = Config {
                test_rows: ok,
                ..Config::default()
            };
            assert_eq!(config.validate::<256, 16, 3>(), Ok(()), "{ok}");
        }
        for bad in [1u16, 4, 6, 9, 1050, 65535] {
            let config = Config {
                test_rows: bad,
                ..Config::default()
            };
            assert_eq!(
                config.validate::<256, 16, 3>(),
                Err(ConfigError::TestRows(bad))
            );
        }
        let both = Config {
            test_rows: 64,
            noise_correction: true,
            ..Config::default()
        };
        let expected = if cfg!(feature = "noise-correction") {
            ConfigError::NoiseCorrectionWithTestRows
        } else {
            ConfigError::NoiseCorrectionUnavailable
        };
        assert_eq!(both.validate::<256, 16, 3>(), Err(expected));
        assert!(std::format!("{}", ConfigError::TestRows(6)).contains("test_rows is 6"));
    }
}
