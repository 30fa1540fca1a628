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
            let g = givens(self.r[i][i], a[i]);
            self.r[i][i] = g.r;
            let (ri, ai) = (&mut self.r[i][i + 1..n], &mut a[i + 1..n]);
            for (rij, aj) in ri.iter_mut().zip(ai.iter_mut()) {
                (*rij, *aj) = g.apply(*rij, *aj);
            }
            (self.z[i], b) = g.apply(self.z[i], b);
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

    /// Empties the factor (same columns).
    pub fn clear(&mut self) {
        *self = Self::new(self.n);
    }

    /// Folds in everything another factor over the same columns holds (no forgetting).
    pub fn merge(&mut self, other: &Self) {
        let n = self.n.min(other.n);
        let weight = self.weight + other.weight;
        for i in 0..n {
            let z = other.z[i];
            self.update(&other.r[i][..n], z, T::ONE);
        }
        // The rotations added the disagreement between the two fits to ρ²; the other's own
        // residual energy comes on top. `update` counted R's rows as data rows: fix the weight.
        self.rho2 += other.rho2;
        self.weight = weight;
    }

    /// Multiplies column j by `factors[j]` (a change of the column's units) and z by
    /// `target_factor`.
    pub fn scale(&mut self, factors: &[T], target_factor: T) {
        let n = self.n.min(factors.len());
        for i in 0..n {
            for j in i..n {
                self.r[i][j] *= factors[j];
            }
            self.z[i] *= target_factor;
        }
        self.rho2 *= target_factor * target_factor;
    }

    /// Replaces the columns Θ by Θ·B and re-triangularises: R ← qr(R·B).
    ///
    /// In place: row i of R·B needs only row i of R (upper triangular), so each row is
    /// computed into one row of scratch and written back; no P×P temporary is needed (the
    /// screening calls this in its deepest frames, where the stack peaks).
    pub fn transform(&mut self, b: &[[T; P]; P]) {
        let n = self.n;
        let mut row = [T::ZERO; P];
        for i in 0..n {
            for j in 0..n {
                let mut s = T::ZERO;
                for k in i..n {
                    s += self.r[i][k] * b[k][j];
                }
                row[j] = s;
            }
            self.r[i][..n].copy_from_slice(&row[..n]);
        }
        triangularise(&mut self.r, &mut self.z, n, n);
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

    /// Residual energy Σ λ^age (y − θᵀξ)² of a coefficient vector: ‖Rξ − z‖² + ρ².
    pub fn error(&self, coefficients: &[T]) -> T {
        let n = self.n.min(coefficients.len());
        let mut e = self.rho2;
        for i in 0..n {
            let mut s = -self.z[i];
            for j in i..n {
                s += self.r[i][j] * coefficients[j];
            }
            e += s * s;
        }
        e
    }

    /// Column norms ‖θ_j‖ (weighted), from R.
    pub fn column_norms(&self, out: &mut [T]) {
        let n = self.n.min(out.len());
        for (j, o) in out.iter_mut().enumerate().take(n) {
            let mut s = T::ZERO;
            for i in 0..=j {
                s += self.r[i][j] * self.r[i][j];
            }
            *o = s.sqrt();
        }
    }

    /// The target's norm ‖y‖ (weighted): √(‖z‖² + ρ²).
    pub fn target_norm(&self) -> T {
        let mut s = self.rho2;
        for v in &self.z[..self.n] {
            s += *v * *v;
        }
        s.sqrt()
    }

    /// Entry (i, j) of the Gram matrix RᵀR = Σ λ^age θθᵀ (0 outside the columns).
    pub fn gram(&self, i: usize, j: usize) -> T {
        if i >= self.n || j >= self.n {
            return T::ZERO;
        }
        let mut s = T::ZERO;
        for row in &self.r[..=i.min(j)] {
            s += row[i] * row[j];
        }
        s
    }

    /// Entry i of Rᵀz = Σ λ^age θ y (0 outside the columns).
    pub fn moment(&self, i: usize) -> T {
        if i >= self.n {
            return T::ZERO;
        }
        let mut s = T::ZERO;
        for (row, z) in self.r[..=i].iter().zip(self.z.iter()) {
            s += row[i] * *z;
        }
        s
    }
}

mod correct;
mod solve;

use solve::triangularise;
#[cfg(test)]
mod tests;
