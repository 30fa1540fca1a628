//! The references the standalone instrument takes off its channels, learnt from its own
//! first rows by `lssi identify`'s rule (host-tools' `identify::Reference` and
//! `system::references`): a channel far from zero (raw ADC counts, a sensor biased at
//! mid-rail, a displacement 10⁴ amplitudes from zero) leaves the f32 identifier only a few
//! bits of the motion; less its reference it keeps all 24.
//!
//! Streaming, with no buffer of rows: per channel the count, the f64 sum, the least and
//! largest of its first [`REFERENCE_ROWS`] finite values. Rows are pushed as they come
//! until every channel has its [`REFERENCE_ROWS`] finite values; then, if a channel lies far
//! from zero, the identifier is restarted and every row from that one on is pushed less
//! the references (`(reading as f64 − reference) as f32`). Channels about zero never
//! restart anything: their model is, bit for bit, the one without this module.

use super::Reading;
use lssi_proto::WireReference;

/// Finite values of a channel whose mean is its reference (host: `REFERENCE_ROWS`).
pub const REFERENCE_ROWS: u16 = 1024;

/// How many ranges of its first rows away from 0 their mean must lie to be a reference
/// (host: `REFERENCE_RANGES`).
pub const REFERENCE_RANGES: f64 = 3.0;

/// Which channels get a reference: those `lssi identify` gives one for the kind of
/// identifier, each by one equation's rule (`identify::Reference::channel`: the mean of its
/// first [`REFERENCE_ROWS`] finite values when it lies more than [`REFERENCE_RANGES`] times
/// their range from 0).
///
/// The host's `system::references` also gives one to an electrical channel, or to raw counts,
/// off centre by 5 % of its range, and takes the whole record's mean: a rule for the whole
/// record, which a device that learns from its first rows cannot follow (over the first
/// 1,024 rows a harvester's voltage about zero lies off centre by more than that: the start's
/// transient), and one about a constant term's collinearity, not about f32's bits (counts a
/// few ranges from zero lose none). The device takes the rule that keeps the bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// One equation (`identify::Reference`): x and v; the excitation u never.
    Equation,
    /// A system (`system::references`): x, v and the electrical channel; u never.
    System,
}

/// One channel's first rows: count, sum, least and largest value.
#[derive(Clone, Copy, Debug, Default)]
struct Head {
    n: u16,
    sum: f64,
    lo: f32,
    hi: f32,
}

impl Head {
    const fn new() -> Self {
        Self {
            n: 0,
            sum: 0.0,
            lo: 0.0,
            hi: 0.0,
        }
    }

    fn add(&mut self, q: f32) {
        if self.n >= REFERENCE_ROWS || !q.is_finite() {
            return;
        }
        if self.n == 0 {
            self.lo = q;
            self.hi = q;
        } else {
            self.lo = self.lo.min(q);
            self.hi = self.hi.max(q);
        }
        self.sum += f64::from(q);
        self.n += 1;
    }

    fn full(&self) -> bool {
        self.n >= REFERENCE_ROWS
    }

    fn mean(&self) -> f64 {
        self.sum / f64::from(self.n.max(1))
    }

    fn range(&self) -> f64 {
        f64::from(self.hi) - f64::from(self.lo)
    }

    /// The rule (`Reference::channel`): the mean when it lies more than [`REFERENCE_RANGES`]
    /// ranges from 0. A channel that does not vary keeps its values (the host gives none to
    /// a constant x; `system::references` none to any channel).
    fn far(&self) -> f64 {
        let (mean, range) = (self.mean(), self.range());
        if range > 0.0 && libm::fabs(mean) > REFERENCE_RANGES * range {
            mean
        } else {
            0.0
        }
    }
}

/// The references of the standalone instrument's channels, learnt from its first rows (see
/// the module's docs). All zero bytes when new (it lives in the engine's `static`, `.bss`).
#[derive(Clone, Copy, Debug, Default)]
pub struct References {
    x: Head,
    v: Head,
    e: Head,
    /// Every channel has its first rows: the references are settled.
    decided: bool,
    /// A reference is not zero: every row is pushed less them.
    active: bool,
    value: WireReference,
}

impl References {
    /// Nothing learnt yet.
    pub const fn new() -> Self {
        Self {
            x: Head::new(),
            v: Head::new(),
            e: Head::new(),
            decided: false,
            active: false,
            value: WireReference {
                x: 0.0,
                v: 0.0,
                e: 0.0,
            },
        }
    }

    /// The references subtracted from every row now (`None` while nothing is: still
    /// learning, or every channel about zero).
    pub fn subtracted(&self) -> Option<WireReference> {
        self.active.then_some(self.value)
    }

    /// Takes a row: learns from it while the first rows come, and from the row that settles
    /// the references on, takes them off it. Returns whether the identifier must restart
    /// before this row is pushed (a channel was found far from zero at this row). The hot
    /// path, once settled, is a branch and (only with a reference) a subtraction per
    /// channel.
    #[inline]
    pub fn take(&mut self, reading: &mut Reading, rule: Rule) -> bool {
        if self.active {
            self.shift(reading);
            false
        } else if self.decided {
            false
        } else {
            self.learn(reading, rule)
        }
    }

    fn shift(&self, reading: &mut Reading) {
        let r = &self.value;
        let less = |q: f32, r: f64| (f64::from(q) - r) as f32;
        if r.x != 0.0 {
            reading.x = less(reading.x, r.x);
        }
        if r.v != 0.0
            && let Some(v) = reading.v.as_mut()
        {
            *v = less(*v, r.v);
        }
        if r.e != 0.0
            && let Some(e) = reading.e.as_mut()
        {
            *e = less(*e, r.e);
        }
    }

    /// The first rows' part (cold: 1,024 rows of a recording). Not inlined.
    #[inline(never)]
    fn learn(&mut self, reading: &mut Reading, rule: Rule) -> bool {
        self.x.add(reading.x);
        if let Some(v) = reading.v {
            self.v.add(v);
        }
        let electrical = rule == Rule::System;
        if electrical && let Some(e) = reading.e {
            self.e.add(e);
        }
        // Settled once every channel the rows carry has its first rows.
        let settled = self.x.full()
            && (reading.v.is_none() || self.v.full())
            && (!electrical || reading.e.is_none() || self.e.full());
        if !settled {
            return false;
        }
        self.decided = true;
        // An x that does not vary over its first rows: none on x and v (the host's
        // `Reference::of` and `system::references` give none to a constant recording).
        let moves = self.x.range() > 0.0;
        self.value = WireReference {
            x: if moves { self.x.far() } else { 0.0 },
            v: if moves && reading.v.is_some() {
                self.v.far()
            } else {
                0.0
            },
            e: if electrical && reading.e.is_some() {
                self.e.far()
            } else {
                0.0
            },
        };
        self.active = self.value != WireReference::default();
        if self.active {
            self.shift(reading);
        }
        self.active
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn learn(rows: impl Iterator<Item = Reading>, rule: Rule) -> (References, Option<usize>) {
        let mut r = References::new();
        let mut restart = None;
        for (i, mut reading) in rows.enumerate() {
            if r.take(&mut reading, rule) {
                assert!(restart.is_none(), "one restart");
                restart = Some(i);
            }
        }
        (r, restart)
    }

    #[test]
    fn a_channel_far_from_zero_gets_its_first_rows_mean_and_restarts_at_its_1024th_row() {
        let x = |i: usize| 1.0e4 + libm::sin(i as f64 * 0.05) as f32;
        let (r, restart) = learn((0..3000).map(|i| Reading::x(x(i))), Rule::Equation);
        assert_eq!(restart, Some(1023));
        let mean = (0..1024).map(|i| f64::from(x(i))).sum::<f64>() / 1024.0;
        assert_eq!(r.subtracted().map(|r| r.x), Some(mean));
        // About zero: nothing.
        let (r, restart) = learn((0..3000).map(|i| Reading::x(x(i) - 1.0e4)), Rule::Equation);
        assert_eq!((r.subtracted(), restart), (None, None));
        // Constant: nothing.
        let (r, restart) = learn((0..3000).map(|_| Reading::x(5.0)), Rule::Equation);
        assert_eq!((r.subtracted(), restart), (None, None));
    }
}
