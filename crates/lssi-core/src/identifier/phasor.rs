//! The excitation's phasor (sin Ωt, cos Ωt) at a row's time, turned by a fixed rotation from
//! one row to the next instead of computed anew.

use super::intake::below;
use crate::real::Real;

/// Rows the phasor is rotated across before it is recomputed from t.
///
/// Each rotation by the fixed (sin, cos) of Ω·(row period) rounds the phasor by about
/// 2 ulp in magnitude and angle, so after 64 rows its error is at most 64·2·2⁻²⁴ ≈ 8·10⁻⁶
/// in f32 (10⁻¹⁴ in f64), far below the sensor noise and the 1-ulp error of sinf itself;
/// the exact recomputation costs a sinf and a cosf (about 3 000 instructions on the M4F in
/// software f64 range reduction), 1/64 of what every row paid before.
pub(super) const PHASOR_RESYNC: u16 = 64;

/// Rotations a resync may wait on rows that are busy otherwise (a test-function sum's fold,
/// an evaluation of ε(K)): at most 72 rotations, 9·10⁻⁶ in f32.
pub(super) const PHASOR_SLACK: u16 = 8;

/// (sin Ωt, cos Ωt) of the last row, and the rotation of one row period.
///
/// ```text
/// let mut phasor = Phasor::new(omega, row_period);
/// phasor.turn_to(row.t, omega, false);
/// let (s, c) = phasor.sin_cos();
/// ```
#[derive(Clone, Copy, Debug)]
pub(super) struct Phasor<T> {
    /// sin and cos of Ω t at `t`, the time of the last folded row.
    value: (T, T),
    t: Option<f64>,
    /// Rotations since the phasor was last computed exactly.
    age: u16,
    /// sin and cos of Ω h: one row's rotation.
    rotation: (T, T),
    /// The interval that the time between two consecutive rows falls in (one row period,
    /// ± 10⁻⁶ of it): the phasor then turns by `rotation`.
    step: (f64, f64),
}

impl<T: Real> Phasor<T> {
    /// Storage, not a usable phasor (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            value: (T::ZERO, T::ZERO),
            t: None,
            age: 0,
            rotation: (T::ZERO, T::ZERO),
            step: (0.0, 0.0),
        }
    }

    /// (0, 1) until the first row, for rows `row_period` apart at angular frequency `omega`.
    pub(super) fn new(omega: f64, row_period: f64) -> Self {
        let step = omega * row_period;
        Self {
            value: (T::ZERO, T::ONE),
            t: None,
            age: 0,
            // Through T's own sin/cos: in f32, sinf and cosf are linked already, libm's f64
            // sin and cos would add 4 KB of flash (the rounding of the step to f32 turns
            // the phasor by 10⁻⁹ rad a row at most, re-synced every PHASOR_RESYNC rows).
            rotation: (T::from_f64(step).sin(), T::from_f64(step).cos()),
            step: (
                row_period - 1e-6 * row_period,
                row_period + 1e-6 * row_period,
            ),
        }
    }

    /// Moves the phasor to time `t`: by one rotation when `t` is one row period after the
    /// last row (to 10⁻⁶ of it); after a gap, a gated row, irregular time stamps or
    /// [`PHASOR_RESYNC`] rotations, computed from t. On a `busy` row the resync waits, for
    /// up to [`PHASOR_SLACK`] more rotations.
    #[inline]
    pub(super) fn turn_to(&mut self, t: f64, omega: f64, busy: bool) {
        let (lo, hi) = self.step;
        // lo ≤ d ≤ hi, compared by the bits (`below`: no soft-float compare calls).
        let consecutive = self.t.is_some_and(|t0| {
            let d = t - t0;
            !below(d, lo) && !below(hi, d)
        });
        let limit = if busy {
            PHASOR_RESYNC + PHASOR_SLACK
        } else {
            PHASOR_RESYNC
        };
        if consecutive && self.age < limit {
            let (s, c) = self.value;
            let (sr, cr) = self.rotation;
            self.value = (s * cr + c * sr, c * cr - s * sr);
            self.age += 1;
        } else {
            let p = omega * t;
            let tau = 2.0 * core::f64::consts::PI;
            let phase = T::from_f64(p - tau * libm::floor(p / tau));
            self.value = (phase.sin(), phase.cos());
            self.age = 0;
        }
        self.t = Some(t);
    }

    /// (sin Ωt, cos Ωt) at the last row's time.
    pub(super) fn sin_cos(&self) -> (T, T) {
        self.value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_tracks_the_exact_phasor() {
        let (omega, h) = (15.0, 0.004);
        let mut p = Phasor::<f32>::new(omega, h);
        assert_eq!(p.sin_cos(), (0.0, 1.0));
        for i in 0..1000u32 {
            let t = 3.0 + f64::from(i) * h;
            p.turn_to(t, omega, false);
            let (s, c) = p.sin_cos();
            let (se, ce) = ((omega * t).sin(), (omega * t).cos());
            assert!((f64::from(s) - se).abs() < 2e-5, "{i}: {s} {se}");
            assert!((f64::from(c) - ce).abs() < 2e-5, "{i}: {c} {ce}");
        }
    }

    #[test]
    fn a_gap_recomputes_it() {
        let (omega, h) = (2.0, 0.01);
        let mut p = Phasor::<f64>::new(omega, h);
        p.turn_to(1.0, omega, false);
        p.turn_to(1.0 + h, omega, false);
        assert_eq!(p.age, 1);
        p.turn_to(1.0 + 5.0 * h, omega, false);
        assert_eq!(p.age, 0);
        let (s, c) = p.sin_cos();
        assert!((s - (omega * (1.0 + 5.0 * h)).sin()).abs() < 1e-12);
        assert!((c - (omega * (1.0 + 5.0 * h)).cos()).abs() < 1e-12);
    }

    /// On busy rows the resync waits up to PHASOR_SLACK more rotations, no longer, and the
    /// phasor stays within the bound of its docs meanwhile.
    #[test]
    fn a_busy_row_delays_the_resync_a_little() {
        let (omega, h) = (15.0, 0.004);
        let mut p = Phasor::<f32>::new(omega, h);
        let mut longest = 0;
        for i in 0..1000u32 {
            let t = 3.0 + f64::from(i) * h;
            p.turn_to(t, omega, true);
            longest = longest.max(p.age);
            let (s, c) = p.sin_cos();
            assert!((f64::from(s) - (omega * t).sin()).abs() < 2e-5, "{i}");
            assert!((f64::from(c) - (omega * t).cos()).abs() < 2e-5, "{i}");
        }
        assert_eq!(longest, PHASOR_RESYNC + PHASOR_SLACK);
    }
}
