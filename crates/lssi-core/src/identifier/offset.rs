//! The velocity offset: mean(v̂ − dx̂/dt) over the rows, when v is measured.
//!
//! The offset of a velocity sensor shows as mean(v) − mean(dx/dt). The sum of dx/dt over the
//! rows of a segment (between gaps) telescopes: by the midpoint rule,
//! h·Σ_{r=1..R} x'(t_r) = x̂(t_R + h/2) − x̂(t_1 − h/2) + O(h³x‴·R), and the half steps past
//! the ends are extrapolated by the end differences, so
//!   Σ dx/dt ≈ (x̂_R − x̂_1)/h + ½(x̂_2 − x̂_1)/h + ½(x̂_R − x̂_(R−1))/h.
//! That is the same estimate as a 255-tap derivative filter on every row (which it
//! replaced) to O(h²x'') per segment, from the x̂ the row computes anyway. Each row adds v̂
//! minus its backward difference (keeping the sum small), the second row also the start
//! correction; the end correction is `last`.

use crate::real::Real;

/// The running sum behind the velocity offset.
///
/// ```text
/// let mut offset = VelocityOffset::new(row_period);
/// offset.observe(x_hat, v_hat); // every row
/// offset.restart();             // at a gap
/// let dv = offset.value();      // at a screening
/// ```
#[derive(Clone, Copy, Debug)]
pub(super) struct VelocityOffset<T> {
    /// Σ(v̂ − dx̂/dt), dx̂/dt telescoped, but for the half difference `last` of the current
    /// segment's newest row.
    sum: T,
    weight: T,
    /// x̂ of the previous row of this segment (since the last gap) and the segment's rows.
    prev: T,
    rows: u32,
    /// (x̂ₙ − x̂ₙ₋₁)/h of the newest row of this segment: the end correction.
    last: T,
    /// 1/h, h the time between rows.
    inverse_row_period: T,
}

impl<T: Real> VelocityOffset<T> {
    /// Storage, not a usable sum (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            sum: T::ZERO,
            weight: T::ZERO,
            prev: T::ZERO,
            rows: 0,
            last: T::ZERO,
            inverse_row_period: T::ZERO,
        }
    }

    /// No rows yet; rows `row_period` seconds apart.
    pub(super) fn new(row_period: f64) -> Self {
        Self {
            inverse_row_period: T::from_f64(1.0 / row_period),
            ..Self::zeroed()
        }
    }

    /// Adds a row's x̂ and v̂.
    #[inline]
    pub(super) fn observe(&mut self, x_hat: T, v_hat: T) {
        let mut dv = v_hat;
        if self.rows > 0 {
            let d = (x_hat - self.prev) * self.inverse_row_period;
            dv -= d;
            if self.rows == 1 {
                dv -= T::from_f64(0.5) * d;
            }
            self.last = d;
        }
        self.prev = x_hat;
        self.rows = self.rows.saturating_add(1);
        self.sum += dv;
        self.weight += T::ONE;
    }

    /// Closes the segment (at a gap): its end correction becomes final.
    pub(super) fn restart(&mut self) {
        self.sum -= T::from_f64(0.5) * self.last;
        self.last = T::ZERO;
        self.rows = 0;
    }

    /// Whether any row was observed.
    pub(super) fn has_rows(&self) -> bool {
        self.weight > T::ZERO
    }

    /// The velocity offset mean(v̂ − dx/dt) over the rows so far.
    pub(super) fn value(&self) -> T {
        (self.sum - T::from_f64(0.5) * self.last) / self.weight
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// v = x' + offset exactly, sampled at h, in segments split by gaps.
    fn offset_of(segments: &[(u32, u32)], offset: f64) -> f64 {
        let h = 0.01;
        let mut o = VelocityOffset::<f64>::new(h);
        for seg in segments {
            for i in seg.0..seg.1 {
                let t = f64::from(i) * h;
                o.observe((2.0 * t).sin(), 2.0 * (2.0 * t).cos() + offset);
            }
            o.restart();
        }
        o.value()
    }

    #[test]
    fn recovers_a_constant_offset() {
        let dv = offset_of(&[(0, 2000)], 0.25);
        assert!((dv - 0.25).abs() < 1e-4, "{dv}");
    }

    #[test]
    fn gaps_do_not_bias_it() {
        let dv = offset_of(&[(0, 700), (900, 1500), (1600, 2400)], -0.1);
        assert!((dv + 0.1).abs() < 1e-4, "{dv}");
        assert!(!VelocityOffset::<f32>::new(0.01).has_rows());
    }
}
