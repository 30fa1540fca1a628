//! Test-function rows for a system: the single-equation weak form (`crate::weak`, the same
//! bump φ(τ) = (1 − τ²)⁴, four sums a quarter apart) with one weighted target per
//! equation. Kept apart from `crate::weak` so that path stays as it is; the arithmetic of
//! the columns' sums is the same.

use crate::real::Real;
use crate::weak::Bump;

/// Overlapping test-function sums of a row's columns and its `E` targets.
#[derive(Clone, Copy)]
pub(super) struct SystemTestRows<T, const P: usize, const E: usize> {
    /// Rows per test function, L (0: off).
    width: u32,
    /// L / 4.
    quarter: u32,
    /// Rows taken so far (kept below 4L + 3L/4).
    phase: u32,
    /// The weights.
    bump: Bump<T>,
    columns: [[T; P]; 4],
    targets: [[T; E]; 4],
}

impl<T: Real, const P: usize, const E: usize> SystemTestRows<T, P, E> {
    /// Off, every field zero.
    pub(super) const fn zeroed() -> Self {
        Self {
            width: 0,
            quarter: 0,
            phase: 0,
            bump: Bump::zeroed(),
            columns: [[T::ZERO; P]; 4],
            targets: [[T::ZERO; E]; 4],
        }
    }

    /// Sums of width `width` (a multiple of 4, at least 8; 0: off), empty.
    #[cfg(test)]
    pub(super) fn new(width: u16) -> Self {
        Self::new_with(width, None)
    }

    /// [`SystemTestRows::new`] with the bump of this width already designed (`Some`: from
    /// [`SystemTestRows::bump_for`], the same bits as designing it again).
    pub(super) fn new_with(width: u16, bump: Option<Bump<T>>) -> Self {
        Self {
            width: u32::from(width),
            quarter: u32::from(width) / 4,
            phase: 0,
            bump: bump.unwrap_or_else(|| Bump::new(width)),
            columns: [[T::ZERO; P]; 4],
            targets: [[T::ZERO; E]; 4],
        }
    }

    /// The bump, when these sums have width `width` (> 0): configuring anew with the same
    /// width need not design it again (see `crate::weak::TestRows::bump_for`).
    pub(super) fn bump_for(&self, width: u16) -> Option<Bump<T>> {
        (width > 0 && self.width == u32::from(width)).then_some(self.bump)
    }

    /// Whether the sums are on.
    pub(super) fn on(&self) -> bool {
        self.width > 0
    }

    /// φ at row `i` of a sum, over Σφ.
    #[inline(always)]
    fn weight(&self, i: u32) -> T {
        self.bump.weight(i)
    }

    /// Adds a row (first `n` columns, the targets `y`) to the sums it falls in; a sum that
    /// completes with it goes to `emit` and starts again.
    pub(super) fn push(
        &mut self,
        theta: &[T; P],
        y: &[T; E],
        n: usize,
        mut emit: impl FnMut(&[T; P], &[T; E]),
    ) {
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
            for (s, t) in self.targets[j].iter_mut().zip(y) {
                *s += w * *t;
            }
            if i + 1 == self.width {
                emit(&self.columns[j], &self.targets[j]);
                self.columns[j] = [T::ZERO; P];
                self.targets[j] = [T::ZERO; E];
            }
        }
        self.phase += 1;
        if self.phase >= 4 * self.width + 3 * self.quarter {
            self.phase -= 4 * self.width;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::weak::TestRows;

    /// The columns' sums and the first target's are the single-equation sums, bit for bit;
    /// the second target's are the sums of its own values.
    #[test]
    fn sums_are_the_single_equation_ones() {
        let mut one: TestRows<f64, 4> = TestRows::zeroed();
        one.configure(16);
        let mut two: SystemTestRows<f64, 4, 2> = SystemTestRows::new(16);
        let (mut a, mut b) = (std::vec::Vec::new(), std::vec::Vec::new());
        for r in 0..200 {
            let t = f64::from(r) * 0.1;
            let theta = [1.0, t.sin(), t.cos(), 0.0];
            one.push(&theta, 3.0 * t.sin(), 3, |c, y| a.push((*c, y)));
            two.push(&theta, &[3.0 * t.sin(), 1.0], 3, |c, y| b.push((*c, *y)));
        }
        assert_eq!(a.len(), b.len());
        assert!(a.len() > 40);
        for ((ca, ya), (cb, yb)) in a.iter().zip(&b) {
            assert_eq!(ca, cb);
            assert_eq!(*ya, yb[0]);
            assert!((yb[1] - 1.0).abs() < 1e-12);
        }
    }
}
