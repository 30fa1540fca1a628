//! The excitation gate: a row passes while the recent RMS velocity is at least [`GATE`] of
//! the long-run RMS velocity; otherwise the factors neither learn nor forget (they cannot
//! wind up while the harvester is at rest).

use crate::real::Real;

/// The gate closes when the recent RMS velocity falls below this fraction of the long-run
/// RMS velocity.
pub(super) const GATE: f64 = 0.01;

/// The two running averages of v² the gate compares.
///
/// ```text
/// let mut gate = Gate::new(16, 1.0);
/// if gate.admit(row.v) { /* fold the row */ }
/// ```
#[derive(Clone, Copy, Debug)]
pub(super) struct Gate<T> {
    /// Recent mean of v², an exponential average of weight `short_alpha` a row.
    short_v2: T,
    /// Long-run mean of v² over the rows that passed, forgetting by `row_lambda`.
    long_v2: T,
    long_weight: T,
    short_alpha: T,
    /// λ of one row (the long average forgets by it).
    row_lambda: T,
    /// Rows the long average needs before it gates.
    warm_rows: T,
}

impl<T: Real> Gate<T> {
    /// Storage, not a usable gate (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            short_v2: T::ZERO,
            long_v2: T::ZERO,
            long_weight: T::ZERO,
            short_alpha: T::ZERO,
            row_lambda: T::ZERO,
            warm_rows: T::ZERO,
        }
    }

    /// A gate whose short average spans `blocks` rows and whose long one forgets by
    /// `sqrt_lambda_row`² a row.
    pub(super) fn new(blocks: u64, sqrt_lambda_row: f64) -> Self {
        let sqrt_lambda_one = T::from_f64(sqrt_lambda_row);
        Self {
            short_v2: T::ZERO,
            long_v2: T::ZERO,
            long_weight: T::ZERO,
            short_alpha: T::ONE / T::from_usize(blocks as usize),
            row_lambda: sqrt_lambda_one * sqrt_lambda_one,
            warm_rows: T::from_usize(blocks as usize),
        }
    }

    /// Takes a row's velocity; returns whether the row passes (and then counts it in the
    /// long-run average).
    #[inline]
    pub(super) fn admit(&mut self, v: T) -> bool {
        let v2 = v * v;
        self.short_v2 += self.short_alpha * (v2 - self.short_v2);
        let warm = self.long_weight > self.warm_rows;
        if warm && self.short_v2 < T::from_f64(GATE * GATE) * self.long_v2 {
            return false;
        }
        self.long_weight = self.row_lambda * self.long_weight + T::ONE;
        self.long_v2 += (v2 - self.long_v2) / self.long_weight;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_while_warming_up_then_closes_at_rest() {
        let mut gate = Gate::<f64>::new(16, 1.0);
        // Moving: every row passes.
        for i in 0..200 {
            assert!(gate.admit(if i % 2 == 0 { 1.0 } else { -1.0 }));
        }
        // At rest: the short average decays below 1 % of the long one and the gate closes.
        let closed = (0..200).position(|_| !gate.admit(0.0));
        assert!(closed.is_some_and(|n| n > 10), "{closed:?}");
        // It reopens once the motion is back.
        let reopened = (0..200).position(|_| gate.admit(1.0));
        assert!(reopened.is_some(), "{reopened:?}");
    }

    #[test]
    fn never_gates_before_warm_rows() {
        let mut gate = Gate::<f32>::new(64, 1.0);
        assert!(gate.admit(1.0));
        // After one row the long average is not warm: a still row passes.
        for _ in 0..32 {
            assert!(gate.admit(0.0));
        }
    }
}
