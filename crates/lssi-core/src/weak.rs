//! Test-function rows: the weak form of the regression (`Config::test_rows`; chosen from the
//! data by `tuning::choose_test_rows`; measured in the README's accuracy section).
//!
//! The equation ŷ = θ(x̂, v̂, t)·ξ holds row by row, so it holds for any weighted sum of
//! rows. A sum weighted by a smooth bump φ over `L` rows keeps the signal (φ passes the
//! harmonics of the motion) and cancels most of the derivative estimate's noise: the
//! target's noise is the raw noise through φ∗h₂, and φ∗h₂ ≈ φ'' is small when φ is smooth
//! and long, while h₂ alone (a short second-derivative filter) amplifies the noise by
//! ‖h₂‖. The library terms are still evaluated pointwise on estimates from a short window,
//! so the smoothing does not bend the nonlinear terms: a short derivative window (little
//! bias) and a long test function (little noise) instead of one window that must trade
//! one for the other. (Weak SINDy, Messenger & Bortz 2021, integrates by parts to the same
//! end; here the derivative filter stays, and the sum does the integration.)
//!
//! The rows must be taken at every sample. Summed at a stride s, the target's noise goes
//! through Σ_r φ_r·h₂[s·r − k], the sums of every s-th tap of h₂ weighted by φ, and those
//! polyphase sums of a derivative filter do not vanish: the noise came back in full
//! (zero-mean δ = 0.1, x only, seed 2, least squares on the true support: 0.45 % with every
//! row, 39 % with every fourth).
//!
//! φ(τ) = (1 − τ²)⁴ on τ ∈ (−1, 1), sampled at the row midpoints and normalised to sum 1.
//! Four sums overlap, started a quarter of `L` apart, so one completes every L/4 rows: each
//! row of the input is in four of them. Memory: four partial rows.

use crate::real::Real;

/// The bump φ(τ) = (1 − τ²)⁴ sampled at the midpoints of L rows and normalised to sum 1:
/// the weights of a test function (the single-equation sums here and the system's,
/// `identifier::system`).
#[derive(Clone, Copy)]
pub(crate) struct Bump<T> {
    /// 1/L: τ of row i is (2i + 1)/L − 1.
    step: T,
    /// 1/Σφ over the L midpoints.
    inverse_norm: T,
}

impl<T: Real> Bump<T> {
    /// Every field zero (no test function).
    pub(crate) const fn zeroed() -> Self {
        Self {
            step: T::ZERO,
            inverse_norm: T::ZERO,
        }
    }

    /// The bump over `width` rows (0: zeroed).
    pub(crate) fn new(width: u16) -> Self {
        if width == 0 {
            return Self::zeroed();
        }
        let l = f64::from(width);
        let mut sum = 0.0;
        for i in 0..u32::from(width) {
            let tau = (2.0 * f64::from(i) + 1.0) / l - 1.0;
            let b = 1.0 - tau * tau;
            sum += (b * b) * (b * b);
        }
        Self {
            step: T::from_f64(1.0 / l),
            inverse_norm: T::from_f64(1.0 / sum),
        }
    }

    /// φ at row `i`, over Σφ.
    #[inline(always)]
    pub(crate) fn weight(&self, i: u32) -> T {
        let tau = T::from_usize(2 * i as usize + 1) * self.step - T::ONE;
        let b = T::ONE - tau * tau;
        (b * b) * (b * b) * self.inverse_norm
    }
}

/// Overlapping test-function sums.
#[derive(Clone)]
pub(crate) struct TestRows<T, const P: usize> {
    /// Rows per test function, L (0: off).
    width: u32,
    /// L / 4: rows between two completed sums.
    quarter: u32,
    /// Rows taken since `configure`.
    phase: u32,
    /// The weights.
    bump: Bump<T>,
    /// The four partial sums of the columns and the target.
    columns: [[T; P]; 4],
    targets: [T; 4],
}

impl<T: Real, const P: usize> TestRows<T, P> {
    /// Off, every field zero (for a `.bss` identifier).
    pub const fn zeroed() -> Self {
        Self {
            width: 0,
            quarter: 0,
            phase: 0,
            bump: Bump::zeroed(),
            columns: [[T::ZERO; P]; 4],
            targets: [T::ZERO; 4],
        }
    }

    /// Sets the width L (a multiple of 4, or 0 for off) and clears the sums.
    #[cfg(test)]
    pub fn configure(&mut self, width: u16) {
        self.configure_with(width, None);
    }

    /// [`TestRows::configure`] with the bump of this width already designed (`Some`: from
    /// [`TestRows::bump_for`], the same bits as designing it again).
    pub(crate) fn configure_with(&mut self, width: u16, bump: Option<Bump<T>>) {
        self.width = u32::from(width);
        self.quarter = self.width / 4;
        if width > 0 {
            self.bump = bump.unwrap_or_else(|| Bump::new(width));
        }
        // Nothing summed yet. A gap in the data does not start the sums again: each is a
        // weighted sum of rows, which satisfies the equation whatever rows it holds.
        self.phase = 0;
        self.columns = [[T::ZERO; P]; 4];
        self.targets = [T::ZERO; 4];
    }

    /// φ at row `i` of a sum, over Σφ.
    #[inline(always)]
    fn weight(&self, i: u32) -> T {
        self.bump.weight(i)
    }

    /// The bump, when these sums have width `width` (> 0): configuring anew with the same
    /// width need not design it again (a loop over the L rows in f64, in software on the
    /// M4F: 1.5 M instructions at L ≈ 2,400, the most of configuring an identifier anew).
    pub(crate) fn bump_for(&self, width: u16) -> Option<Bump<T>> {
        (width > 0 && self.width == u32::from(width)).then_some(self.bump)
    }

    /// Rows between two completed sums.
    pub fn quarter(&self) -> u32 {
        self.quarter
    }

    /// Whether the next [`TestRows::push`] completes a sum. Sum k (started k·L/4 rows in)
    /// completes when its row (phase − k·L/4) mod L is its last, L − 1; the four are a
    /// quarter apart, so this is when phase + 1 is a multiple of L/4, from L on.
    #[inline]
    pub fn completes_next(&self) -> bool {
        let next = self.phase + 1;
        self.quarter > 0 && next.is_multiple_of(self.quarter) && next >= self.width
    }

    /// Adds a row's weighted target `wy` to sum `j`, at its row `i`; hands the sum to `emit`
    /// and starts it again when that row is its last.
    #[inline(always)]
    fn add_target(&mut self, j: usize, i: u32, wy: T, emit: &mut impl FnMut(&[T; P], T)) {
        self.targets[j] += wy;
        if i + 1 == self.width {
            emit(&self.columns[j], self.targets[j]);
            self.columns[j] = [T::ZERO; P];
            self.targets[j] = T::ZERO;
        }
    }

    /// Adds a row (its first `n` columns and its target) to the sums it falls in; a sum
    /// that completes with it is handed to `emit` and started again.
    pub fn push(&mut self, theta: &[T; P], y: T, n: usize, mut emit: impl FnMut(&[T; P], T)) {
        // Once all four sums run (after the first 3L/4 rows), the four column updates go in
        // one pass over the row: each θ_c loaded once for four sums. Every sum gets the same
        // products in the same order as one at a time, so the sums are the same bit for bit.
        if self.phase >= 3 * self.quarter {
            let mut positions = [0u32; 4];
            let mut weights = [T::ZERO; 4];
            for k in 0..4u32 {
                let i = (self.phase - k * self.quarter) % self.width;
                positions[k as usize] = i;
                weights[k as usize] = self.weight(i);
            }
            let [w0, w1, w2, w3] = weights;
            let [c0, c1, c2, c3] = &mut self.columns;
            let rows = c0[..n]
                .iter_mut()
                .zip(&mut c1[..n])
                .zip(&mut c2[..n])
                .zip(&mut c3[..n]);
            for ((((s0, s1), s2), s3), t) in rows.zip(&theta[..n]) {
                let t = *t;
                *s0 += w0 * t;
                *s1 += w1 * t;
                *s2 += w2 * t;
                *s3 += w3 * t;
            }
            for (j, (i, w)) in positions.into_iter().zip(weights).enumerate() {
                self.add_target(j, i, w * y, &mut emit);
            }
        } else {
            for k in 0..4u32 {
                let start = k * self.quarter;
                if self.phase < start {
                    continue;
                }
                let j = k as usize;
                let i = (self.phase - start) % self.width;
                let w = self.weight(i);
                for (s, t) in self.columns[j][..n].iter_mut().zip(theta[..n].iter()) {
                    *s += w * *t;
                }
                self.add_target(j, i, w * y, &mut emit);
            }
        }
        self.phase = self.phase.wrapping_add(1);
        // Keep the phase bounded without moving any sum's position (a multiple of L).
        if self.phase >= 4 * self.width + 3 * self.quarter {
            self.phase -= 4 * self.width;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each completed sum is the φ-weighted mean of the L rows it covers: a constant row
    /// comes out unchanged, one sum every L/4 rows once the first is complete.
    #[test]
    fn sums_are_weighted_means_one_every_quarter() {
        let mut t: TestRows<f64, 4> = TestRows::zeroed();
        t.configure(16);
        let mut out = std::vec::Vec::new();
        for r in 0..100 {
            t.push(&[1.0, 2.0, 0.0, 0.0], 3.0, 2, |c, y| {
                out.push((r, c[0], c[1], y))
            });
        }
        let rows: std::vec::Vec<_> = out.iter().map(|o| o.0).collect();
        assert_eq!(rows[..4], [15, 19, 23, 27]);
        assert!(rows.windows(2).all(|w| w[1] - w[0] == 4));
        for (_, a, b, y) in out {
            assert!((a - 1.0).abs() < 1e-12 && (b - 2.0).abs() < 1e-12 && (y - 3.0).abs() < 1e-12);
        }
    }

    /// `completes_next` says beforehand exactly which pushes complete a sum, across the
    /// phase's wrap, for widths 4 to 64.
    #[test]
    fn completes_next_foretells_every_completion() {
        for width in (4..=64).step_by(4) {
            let mut t: TestRows<f64, 2> = TestRows::zeroed();
            t.configure(width);
            for r in 0..20 * u32::from(width) {
                let foretold = t.completes_next();
                let mut completed = false;
                t.push(&[1.0, 2.0], 3.0, 2, |_, _| completed = true);
                assert_eq!(foretold, completed, "width {width}, row {r}");
            }
        }
        let off: TestRows<f64, 2> = TestRows::zeroed();
        assert!(!off.completes_next());
    }

    /// A linear ramp's weighted mean is its value at the window's centre (φ is symmetric),
    /// and configuring anew drops what was summed before.
    #[test]
    fn symmetric_weights_and_reconfigure() {
        let mut t: TestRows<f64, 2> = TestRows::zeroed();
        t.configure(8);
        let mut out = std::vec::Vec::new();
        for r in 0..5 {
            t.push(&[1e6, 0.0], 0.0, 1, |_, _| {
                panic!("emitted before configuring anew {r}")
            });
        }
        t.configure(8);
        for r in 0..8 {
            t.push(&[r as f64, 0.0], 0.0, 1, |c, _| out.push(c[0]));
        }
        assert_eq!(out.len(), 1);
        assert!((out[0] - 3.5).abs() < 1e-12, "{}", out[0]);
    }
}
