//! A sample's way in: the checks that reject it (counted, never a panic), the gaps that
//! restart the window, and the schedule of rows and screenings.

use crate::config::Config;
use crate::real::Real;

/// One measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample<T> {
    /// Time, seconds (f64: a device runs for days).
    pub t: f64,
    /// Displacement.
    pub x: T,
    /// Measured velocity, when the configuration says there is one.
    pub v: Option<T>,
    /// Measured excitation, when the configuration says there is one.
    pub u: Option<T>,
}

/// Why a sample was not fed in. Each is counted in [`Counters`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Rejection {
    /// A value (or the time) is NaN or infinite.
    NonFinite,
    /// A value's magnitude exceeds `max_abs`.
    OutOfRange,
    /// The time is not later than the previous sample's (by at least half a period).
    OutOfOrder,
    /// A channel the configuration declares is missing (or one it does not declare is present).
    Channels,
}

impl core::fmt::Display for Rejection {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Rejection::NonFinite => "the sample has a NaN or infinite value",
            Rejection::OutOfRange => "the sample's magnitude exceeds max_abs",
            Rejection::OutOfOrder => "the sample's time is not after the previous sample's",
            Rejection::Channels => "the sample's channels differ from the configured ones",
        })
    }
}

impl core::error::Error for Rejection {}

/// What happened to the samples so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Samples fed in.
    pub accepted: u64,
    /// Rejected: non-finite.
    pub non_finite: u64,
    /// Rejected: beyond `max_abs`.
    pub out_of_range: u64,
    /// Rejected: time not increasing.
    pub out_of_order: u64,
    /// Rejected: wrong channels.
    pub channels: u64,
    /// Gaps in time (more than 1.5 periods) after which the window restarted.
    pub gaps: u64,
    /// Regression rows folded into the factors.
    pub rows: u64,
    /// Rows held back by the excitation gate.
    pub gated: u64,
    /// Screenings run.
    pub screenings: u64,
}

impl Counters {
    /// All rejected samples.
    pub fn rejected(&self) -> u64 {
        self.non_finite + self.out_of_range + self.out_of_order + self.channels
    }

    /// Counts a rejected sample.
    pub(super) fn reject(&mut self, r: Rejection) {
        match r {
            Rejection::NonFinite => self.non_finite += 1,
            Rejection::OutOfRange => self.out_of_range += 1,
            Rejection::OutOfOrder => self.out_of_order += 1,
            Rejection::Channels => self.channels += 1,
        }
    }
}

/// The checks a sample passes before it is fed in, and the time of the last one.
///
/// ```text
/// let since = intake.check(&sample, &config)?;
/// if intake.accept(sample.t, since) { /* a gap: restart the window */ }
/// ```
#[derive(Clone, Copy, Debug)]
pub(super) struct Intake<T> {
    /// Magnitudes below this are within `max_abs` for sure (compared in T, not f64).
    max_abs_sure: T,
    /// 0.5 and 1.5 sample periods: a sample closer than `too_early` to the previous one is
    /// out of order, one later than `gap_after` starts after a gap (precomputed: f64
    /// arithmetic is in software on the M4F).
    too_early: f64,
    gap_after: f64,
    last_t: Option<f64>,
}

impl<T: Real> Intake<T> {
    /// Storage, not usable checks (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            max_abs_sure: T::ZERO,
            too_early: 0.0,
            gap_after: 0.0,
            last_t: None,
        }
    }

    /// The checks of `config`, before any sample.
    pub(super) fn new(config: &Config) -> Self {
        Self {
            max_abs_sure: T::from_f64(config.max_abs * (1.0 - 1e-6)),
            too_early: 0.5 * config.sample_period,
            gap_after: 1.5 * config.sample_period,
            last_t: None,
        }
    }

    /// Why `s` cannot be fed in, if it cannot; otherwise the time since the last sample (for
    /// [`Intake::accept`]: one soft-f64 subtraction a sample instead of two).
    pub(super) fn check(&self, s: &Sample<T>, config: &Config) -> Result<Option<f64>, Rejection> {
        let channels = config.channels;
        if s.v.is_some() != channels.velocity || s.u.is_some() != channels.input {
            return Err(Rejection::Channels);
        }
        let values = [Some(s.x), s.v, s.u];
        if !s.t.is_finite() || values.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Rejection::NonFinite);
        }
        let limit = config.max_abs;
        // Compared in T first (soft f64 is dear on the M4F); only a value within 10⁻⁶ of the
        // limit is compared exactly.
        let sure = self.max_abs_sure;
        if values
            .iter()
            .flatten()
            .any(|v| !(v.abs() < sure) && beyond(*v, limit))
        {
            return Err(Rejection::OutOfRange);
        }
        let since = self.last_t.map(|last| s.t - last);
        if since.is_some_and(|d| below(d, self.too_early)) {
            return Err(Rejection::OutOfOrder);
        }
        Ok(since)
    }

    /// Takes the time of a checked sample and the time since the last one (what
    /// [`Intake::check`] returned); returns whether it comes after a gap.
    #[inline]
    pub(super) fn accept(&mut self, t: f64, since: Option<f64>) -> bool {
        let gap = since.is_some_and(|d| below(self.gap_after, d));
        self.last_t = Some(t);
        gap
    }
}

/// Whether |v| exceeds `limit` in f64: out of line and cold, so that the conversion (soft
/// f64 on the M4F) is not hoisted above the cheap comparison in T that rules it out.
#[cold]
#[inline(never)]
fn beyond<T: Real>(v: T, limit: f64) -> bool {
    v.abs().to_f64() > limit
}

/// `a < b` for f64 values that are not NaN, by their bits: the same answer as the float
/// comparison (a soft-float call on the M4F), in integer instructions. Doubles of one sign
/// order as their bit patterns (negative ones reversed); the two zeros are equal.
#[inline]
pub(super) fn below(a: f64, b: f64) -> bool {
    debug_assert!(!a.is_nan() && !b.is_nan());
    let (ia, ib) = (a.to_bits(), b.to_bits());
    if (ia | ib) << 1 == 0 {
        return false;
    }
    match (ia >> 63 == 1, ib >> 63 == 1) {
        (false, false) => ia < ib,
        (true, false) => true,
        (false, true) => false,
        (true, true) => ia > ib,
    }
}

/// When rows and screenings are due.
#[derive(Clone, Copy, Debug)]
pub(super) struct Schedule {
    /// Samples since the last row (counted once the window is full).
    since_row: u16,
    /// Samples since the last scheduled screening.
    since_screen: u32,
    /// (window − 1)/2 sample periods: a row's time behind its newest sample (precomputed:
    /// f64 arithmetic is in software on the M4F, and this is per row).
    pub(super) row_lag: f64,
}

impl Schedule {
    /// Storage (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            since_row: 0,
            since_screen: 0,
            row_lag: 0.0,
        }
    }

    /// Nothing due yet.
    pub(super) fn new(config: &Config) -> Self {
        Self {
            row_lag: (config.window - 1) as f64 / 2.0 * config.sample_period,
            ..Self::zeroed()
        }
    }

    /// Counts a sample with a full window; returns whether a row is due (every `stride`).
    #[inline]
    pub(super) fn row_due(&mut self, stride: u16) -> bool {
        self.since_row += 1;
        if self.since_row >= stride {
            self.since_row = 0;
            return true;
        }
        false
    }

    /// Starts the rows anew (after a gap).
    pub(super) fn restart_rows(&mut self) {
        self.since_row = 0;
    }

    /// Counts a sample; returns whether a screening is due (every `period`).
    #[inline]
    pub(super) fn screening_due(&mut self, period: u32) -> bool {
        self.since_screen += 1;
        if self.since_screen >= period {
            self.since_screen = 0;
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f64, x: f32) -> Sample<f32> {
        Sample {
            t,
            x,
            v: None,
            u: None,
        }
    }

    #[test]
    fn checks_reject_and_name_the_reason() {
        let config = Config {
            sample_period: 0.01,
            max_abs: 2.0,
            ..Config::default()
        };
        let mut intake = Intake::<f32>::new(&config);
        assert_eq!(intake.check(&sample(0.0, 1.0), &config), Ok(None));
        assert!(!intake.accept(0.0, None));
        let bad = [
            (sample(0.01, f32::NAN), Rejection::NonFinite),
            (sample(f64::INFINITY, 0.0), Rejection::NonFinite),
            (sample(0.01, 2.5), Rejection::OutOfRange),
            (sample(0.004, 0.0), Rejection::OutOfOrder),
            (
                Sample {
                    v: Some(0.0),
                    ..sample(0.01, 0.0)
                },
                Rejection::Channels,
            ),
        ];
        let mut counters = Counters::default();
        for (s, why) in bad {
            assert_eq!(intake.check(&s, &config), Err(why), "{s:?}");
            counters.reject(why);
        }
        assert_eq!(counters.rejected(), 5);
        assert_eq!(counters.non_finite, 2);
        // Exactly at the limit is within it.
        assert_eq!(intake.check(&sample(0.01, 2.0), &config), Ok(Some(0.01)));
        // A late sample is a gap.
        assert!(!intake.accept(0.01, Some(0.01)));
        assert!(intake.accept(0.05, Some(0.05 - 0.01)));
        // The bit comparison answers as the float one.
        let pairs = [
            (0.5, 1.0),
            (1.0, 0.5),
            (-0.0, 0.5),
            (0.0, 0.5),
            (-3.0, 0.5),
            (0.5, 0.5),
            (0.5, -1.0),
            (1e-300, 1e-310),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-1.0, -2.0),
            (-2.0, -1.0),
            (f64::INFINITY, 1.0),
        ];
        for (a, b) in pairs {
            assert_eq!(below(a, b), a < b, "{a} {b}");
        }
    }

    #[test]
    fn rows_and_screenings_come_on_schedule() {
        let config = Config {
            window: 63,
            sample_period: 0.5,
            ..Config::default()
        };
        let mut s = Schedule::new(&config);
        assert_eq!(s.row_lag, 15.5);
        let rows: Vec<bool> = (0..8).map(|_| s.row_due(4)).collect();
        assert_eq!(rows, [false, false, false, true, false, false, false, true]);
        s.row_due(4);
        s.restart_rows();
        assert!(!s.row_due(4));
        let due = (1..=10).filter(|_| s.screening_due(5)).count();
        assert_eq!(due, 2);
    }
}
