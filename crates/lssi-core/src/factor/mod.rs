//! Recursive least squares in square-root information form (docs/design.md, "RLS").
//!
//! The weighted least-squares problem min Σ λ^age (y − θᵀξ)² is kept as an upper-triangular
//! factor R, a vector z and the residual energy ρ², with RᵀR = Σ λ^age θθᵀ and Rᵀz = Σ λ^age θy.
//! A new row is folded in by Givens rotations (paper eq. 14 solved incrementally); nothing is
//! ever inverted or subtracted, so the factor stays positive definite in f32 where the
//! covariance form diverges. From (R, z, ρ²) the exact least-squares solution on any subset of
//! columns, and the exact residual energy of any coefficient vector, are cheap.

use crate::real::Real;

/// A square-root information accumulator over `n ≤ P` columns.
#[derive(Clone, Debug)]
pub struct Factor<T, const P: usize> {
    n: usize,
    r: [[T; P]; P],
    z: [T; P],
    rho2: T,
    weight: T,
}

/// A Givens rotation that maps (a, b) to (r, 0): c = a/r, s = b/r, plus δ = 1 − c computed
/// without cancellation.
///
/// When a large accumulated entry absorbs a small new row, c is 1 − O(1/n): in f32, c itself
/// is quantised to a few ulps of 1 and the factor drifts (3 % after 10⁶ rows in a test). The
/// update is therefore written as r' = r + (s·a − δ·r), whose increment is computed to full
/// relative precision; only the final addition rounds, and without bias.
#[derive(Clone, Copy)]
struct Rotation<T> {
    c: T,
    s: T,
    delta: T,
    r: T,
}

#[inline]
fn givens<T: Real>(a: T, b: T) -> Rotation<T> {
    if b == T::ZERO {
        return Rotation {
            c: T::ONE,
            s: T::ZERO,
            delta: T::ZERO,
            r: a,
        };
    }
    let (aa, ab) = (a.abs(), b.abs());
    // Scale by the larger magnitude so the squares neither overflow nor underflow in f32.
    let big = aa.max(ab);
    let (sa, sb) = (a / big, b / big);
    let hyp = big * (sa * sa + sb * sb).sqrt();
    if a > T::ZERO {
        // r − a = b²/(r + a): the diagonal grows by an increment computed to full precision.
        let grow = b / (hyp + a) * b;
        let r = a + grow;
        let delta = grow / r;
        Rotation {
            c: a / r,
            s: b / r,
            delta,
            r,
        }
    } else {
        let c = a / hyp;
        Rotation {
            c,
            s: b / hyp,
            delta: T::ONE - c,
            r: hyp,
        }
    }
}

impl<T: Real> Rotation<T> {
    /// Rotates (p, q) — p on the accumulating row, q on the incoming one.
    #[inline]
    fn apply(&self, p: T, q: T) -> (T, T) {
        (p + (self.s * q - self.delta * p), self.c * q - self.s * p)
    }
}

impl<T: Real, const P: usize> Factor<T, P> {
    /// An empty factor over `n` columns (`n` is clamped to `P`).
    pub const fn new(n: usize) -> Self {
        Self {
            n: if n < P { n } else { P },
            r: [[T::ZERO; P]; P],
            z: [T::ZERO; P],
            rho2: T::ZERO,
            weight: T::ZERO,
        }
    }

    /// Read access, as the screening's functions take every factor (see [`FactorRef`]).
    #[inline]
    pub fn view(&self) -> FactorRef<'_, T, P> {
        FactorRef {
            n: self.n,
            r: &self.r,
            flipped: None,
            z: &self.z,
            rho2: self.rho2,
            weight: self.weight,
        }
    }

    /// Write access (see [`FactorMut`]); the factor owns its whole matrix.
    #[inline]
    pub fn view_mut(&mut self) -> FactorMut<'_, T, P> {
        FactorMut {
            n: self.n,
            r: &mut self.r,
            layout: Layout::Whole,
            z: &mut self.z,
            rho2: &mut self.rho2,
            weight: &mut self.weight,
        }
    }

    /// Sets the number of columns of an empty factor (clamped to `P`).
    pub fn set_columns(&mut self, n: usize) {
        self.n = n.min(P);
    }

    /// Number of columns.
    pub fn columns(&self) -> usize {
        self.n
    }

    /// Σ λ^age: the effective number of rows.
    pub fn weight(&self) -> T {
        self.weight
    }

    /// The residual energy ρ² of the full least-squares fit.
    pub fn residual_energy(&self) -> T {
        self.rho2
    }

    /// Row `i` of R (entries left of the diagonal are zero).
    pub fn r_row(&self, i: usize) -> &[T] {
        match self.r.get(i) {
            Some(row) => &row[..self.n],
            None => &[],
        }
    }

    /// The vector z.
    pub fn z(&self) -> &[T] {
        &self.z[..self.n]
    }

    /// Forgets by `sqrt_lambda` (√λ) and folds in one row θ with target y.
    ///
    /// Written out for a whole factor (the view's `update` does the same in the same order):
    /// the block factor takes every row as it is, and the warm-up flush 64 at once, where
    /// the view's layout dispatch cost 2–12 % depending on the image.
    pub fn update(&mut self, row: &[T], y: T, sqrt_lambda: T) {
        let n = self.n.min(row.len());
        self.forget(sqrt_lambda);
        let mut a = [T::ZERO; P];
        a[..n].copy_from_slice(&row[..n]);
        let mut b = y;
        for i in 0..n {
            if a[i] == T::ZERO {
                continue;
            }
            let (d, tail) = self.r[i][i..n].split_at_mut(1);
            b = view::rotate_in(&mut d[0], tail, &mut a[i..n], &mut self.z[i], b);
        }
        self.rho2 += b * b;
        self.weight += T::ONE;
    }

    /// Ages everything by `sqrt_lambda` (√λ per row, raised to the rows elapsed).
    pub fn forget(&mut self, sqrt_lambda: T) {
        if sqrt_lambda == T::ONE {
            return;
        }
        for i in 0..self.n {
            for v in &mut self.r[i][i..self.n] {
                *v *= sqrt_lambda;
            }
            self.z[i] *= sqrt_lambda;
        }
        let lambda = sqrt_lambda * sqrt_lambda;
        self.rho2 *= lambda;
        self.weight *= lambda;
    }

    /// Empties the factor (same columns), in place (a new factor would be built on the stack
    /// first).
    pub fn clear(&mut self) {
        for row in self.r.iter_mut() {
            row.fill(T::ZERO);
        }
        self.z.fill(T::ZERO);
        self.rho2 = T::ZERO;
        self.weight = T::ZERO;
    }

    /// Folds in everything another factor over the same columns holds (no forgetting).
    pub fn merge(&mut self, other: &Self) {
        self.view_mut().merge(other.view());
    }

    /// Multiplies column j by `factors[j]` (a change of the column's units) and z by
    /// `target_factor`.
    pub fn scale(&mut self, factors: &[T], target_factor: T) {
        self.view_mut().scale(factors, target_factor);
    }

    /// Replaces the columns Θ by Θ·B for an upper-triangular B (see [`FactorMut::transform`]).
    pub fn transform(&mut self, b: &[[T; P]; P]) {
        self.view_mut().transform(b);
    }

    /// Makes this factor a copy of `other` without a temporary (same as `*self =
    /// other.clone()`, but the compiler need not build the copy on the stack first).
    pub fn copy_from(&mut self, other: &Self) {
        self.n = other.n;
        self.r = other.r;
        self.z = other.z;
        self.rho2 = other.rho2;
        self.weight = other.weight;
    }

    /// Makes this factor a copy of the one `other` reads (its columns too).
    pub fn copy_from_view(&mut self, other: FactorRef<'_, T, P>) {
        // A factor's entries left of the diagonal are zero (every operation leaves them so):
        // the rows from the diagonal on are the whole factor.
        self.n = other.n;
        self.view_mut().copy_from(other);
    }

    /// Residual energy Σ λ^age (y − θᵀξ)² of a coefficient vector: ‖Rξ − z‖² + ρ².
    pub fn error(&self, coefficients: &[T]) -> T {
        self.view().error(coefficients)
    }

    /// Column norms ‖θ_j‖ (weighted), from R.
    pub fn column_norms(&self, out: &mut [T]) {
        self.view().column_norms(out);
    }

    /// The target's norm ‖y‖ (weighted): √(‖z‖² + ρ²).
    pub fn target_norm(&self) -> T {
        self.view().target_norm()
    }

    /// Entry (i, j) of the Gram matrix RᵀR = Σ λ^age θθᵀ (0 outside the columns).
    pub fn gram(&self, i: usize, j: usize) -> T {
        self.view().gram(i, j)
    }

    /// Entry i of Rᵀz = Σ λ^age θ y (0 outside the columns).
    pub fn moment(&self, i: usize) -> T {
        self.view().moment(i)
    }

    /// Least-squares coefficients on the columns in `support` (bit j = column j); the others
    /// are set to zero. A column that is numerically dependent on the earlier kept ones is
    /// dropped from the support (its coefficient is zero). Returns the support actually used.
    pub fn solve(&self, support: u32, out: &mut [T]) -> u32 {
        let mut work = [[T::ZERO; P]; P];
        self.view().solve_in(support, out, &mut work)
    }

    /// [`Factor::solve`] with the caller's P×P scratch matrix (see [`FactorRef::solve_in`]).
    pub fn solve_in(&self, support: u32, out: &mut [T], work: &mut [[T; P]; P]) -> u32 {
        self.view().solve_in(support, out, work)
    }
}

mod correct;
mod multi;
mod pair;
mod solve;
mod view;

pub use multi::MultiFactor;
pub use pair::FactorPair;
use solve::triangularise;
use view::Layout;
pub use view::{FactorMut, FactorRef};
#[cfg(test)]
mod tests;
