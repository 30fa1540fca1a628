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

    /// Replaces the normal equations RᵀR ξ = Rᵀz by (RᵀR − Δ) ξ = Rᵀz − d, keeping the
    /// target's energy ‖z‖² + ρ²: the errors-in-variables correction (see `eiv`). `delta`
    /// (symmetric, n × n) is overwritten. Returns false, changing nothing, when R is
    /// singular or the correction would take more than 99 % of a direction's energy
    /// (I − R⁻ᵀΔR⁻¹ not safely positive definite).
    ///
    /// Without forming RᵀR (whose condition is squared): E = R⁻ᵀΔR⁻¹ by two triangular
    /// solves, U = chol(I − E), then R ← UR and z ← U⁻ᵀ(z − R⁻ᵀd).
    pub fn correct(&mut self, delta: &mut [[T; P]; P], d: &[T; P]) -> bool {
        let n = self.n;
        if (0..n).any(|i| self.r[i][i] == T::ZERO) {
            return false;
        }
        let r = &self.r;
        // X = R⁻ᵀΔ, column by column (forward substitution with Rᵀ), in place.
        for c in 0..n {
            for i in 0..n {
                let mut s = delta[i][c];
                for k in 0..i {
                    s -= r[k][i] * delta[k][c];
                }
                delta[i][c] = s / r[i][i];
            }
        }
        // E = X R⁻¹, row by row (eᵢ R = xᵢ), in place.
        for row in delta.iter_mut().take(n) {
            for j in 0..n {
                let mut s = row[j];
                for k in 0..j {
                    s -= row[k] * r[k][j];
                }
                row[j] = s / r[j][j];
            }
        }
        // I − E (symmetrised) and its Cholesky factor U in the upper triangle.
        let half = T::from_f64(0.5);
        for i in 0..n {
            for j in i..n {
                let e = half * (delta[i][j] + delta[j][i]);
                delta[i][j] = if i == j { T::ONE - e } else { -e };
            }
        }
        let floor = T::from_f64(0.01);
        for i in 0..n {
            let mut s = delta[i][i];
            for k in 0..i {
                s -= delta[k][i] * delta[k][i];
            }
            if !(s > floor) {
                return false;
            }
            let u = s.sqrt();
            delta[i][i] = u;
            for j in i + 1..n {
                let mut t = delta[i][j];
                for k in 0..i {
                    t -= delta[k][i] * delta[k][j];
                }
                delta[i][j] = t / u;
            }
        }
        // z' = z − R⁻ᵀd, then z_c = U⁻ᵀz'.
        let mut w = [T::ZERO; P];
        for i in 0..n {
            let mut s = d[i];
            for k in 0..i {
                s -= r[k][i] * w[k];
            }
            w[i] = s / r[i][i];
        }
        let mut zc = [T::ZERO; P];
        for i in 0..n {
            let mut s = self.z[i] - w[i];
            for k in 0..i {
                s -= delta[k][i] * zc[k];
            }
            zc[i] = s / delta[i][i];
        }
        if zc[..n].iter().any(|v| !v.is_finite()) {
            return false;
        }
        // R ← UR, top down: row i needs rows i.. of the old R only.
        let mut row = [T::ZERO; P];
        for i in 0..n {
            for (j, out) in row.iter_mut().enumerate().take(n).skip(i) {
                let mut s = T::ZERO;
                for k in i..=j {
                    s += delta[i][k] * self.r[k][j];
                }
                *out = s;
            }
            self.r[i][i..n].copy_from_slice(&row[i..n]);
        }
        // The target's energy ‖z‖² + ρ² stays: ρ² takes what z gave up (without cancellation).
        let mut change = T::ZERO;
        for i in 0..n {
            change += (self.z[i] - zc[i]) * (self.z[i] + zc[i]);
        }
        self.rho2 = (self.rho2 + change).max(T::ZERO);
        self.z[..n].copy_from_slice(&zc[..n]);
        true
    }

    /// Least-squares coefficients on the columns in `support` (bit j = column j); the others
    /// are set to zero. A column that is numerically dependent on the earlier kept ones is
    /// dropped from the support (its coefficient is zero). Returns the support actually used.
    pub fn solve(&self, support: u32, out: &mut [T]) -> u32 {
        let mut work = [[T::ZERO; P]; P];
        self.solve_in(support, out, &mut work)
    }

    /// [`Factor::solve`] with the caller's P×P scratch matrix (its contents on entry do not
    /// matter): the screening, which solves thousands of times, lends it one, so that its
    /// deepest frame does not hold another kilobyte (P = 16, f32).
    pub fn solve_in(&self, support: u32, out: &mut [T], work: &mut [[T; P]; P]) -> u32 {
        let n = self.n.min(out.len());
        for o in out.iter_mut() {
            *o = T::ZERO;
        }
        let mut columns = [0usize; P];
        let mut m = 0;
        for j in 0..n {
            if support & (1 << j) != 0 {
                columns[m] = j;
                m += 1;
            }
        }
        if m == 0 {
            return 0;
        }
        // Work matrix: the kept columns of R (n × m, staircase) and z. Only its n × m block
        // is written and read.
        let a = work;
        for i in 0..n {
            for (p, &j) in columns[..m].iter().enumerate() {
                a[i][p] = if j >= i { self.r[i][j] } else { T::ZERO };
            }
        }
        let mut z = self.z;
        // Each kept column j has nonzeros in rows 0..=j only (the rotations keep it so, and
        // skip the zeros below).
        triangularise(a, &mut z, n, m);
        // Back substitution, dropping columns whose pivot is negligible against their norm.
        let mut used = support;
        let tolerance = T::EPSILON * T::from_f64(64.0);
        let mut solution = [T::ZERO; P];
        for p in (0..m).rev() {
            let mut norm = T::ZERO;
            for i in 0..=p {
                norm += a[i][p] * a[i][p];
            }
            let pivot = a[p][p];
            if pivot.abs() <= tolerance * norm.sqrt() || norm == T::ZERO {
                used &= !(1 << columns[p]);
                continue;
            }
            let mut s = z[p];
            for q in p + 1..m {
                s -= a[p][q] * solution[q];
            }
            solution[p] = s / pivot;
        }
        for p in 0..m {
            out[columns[p]] = solution[p];
        }
        used
    }
}

/// Triangularises the first `n` columns of an `rows × n` matrix by Givens rotations, applying
/// them to `z` as well.
fn triangularise<T: Real, const P: usize>(
    c: &mut [[T; P]; P],
    z: &mut [T; P],
    rows: usize,
    n: usize,
) {
    for p in 0..n {
        for i in p + 1..rows {
            if c[i][p] == T::ZERO {
                continue;
            }
            let g = givens(c[p][p], c[i][p]);
            c[p][p] = g.r;
            c[i][p] = T::ZERO;
            for q in p + 1..n {
                (c[p][q], c[i][q]) = g.apply(c[p][q], c[i][q]);
            }
            (z[p], z[i]) = g.apply(z[p], z[i]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random sequence for tests (xorshift).
    fn noise(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    fn rows(count: usize) -> std::vec::Vec<([f64; 4], f64)> {
        let mut s = 7u64;
        (0..count)
            .map(|_| {
                let row = [1.0, noise(&mut s), noise(&mut s) * 3.0, noise(&mut s)];
                let y = 0.5 - 2.0 * row[1] + 0.25 * row[2] + 0.01 * noise(&mut s);
                (row, y)
            })
            .collect()
    }

    extern crate std;

    #[test]
    fn matches_batch_least_squares() {
        let data = rows(500);
        let mut f: Factor<f64, 4> = Factor::new(4);
        for (row, y) in &data {
            f.update(row, *y, 1.0);
        }
        let a = nalgebra::DMatrix::from_fn(data.len(), 4, |i, j| data[i].0[j]);
        let b = nalgebra::DVector::from_fn(data.len(), |i, _| data[i].1);
        let reference = a.clone().svd(true, true).solve(&b, 1e-14).unwrap();
        let mut xi = [0.0; 4];
        assert_eq!(f.solve(0b1111, &mut xi), 0b1111);
        for j in 0..4 {
            assert!(
                (xi[j] - reference[j]).abs() < 1e-10,
                "{j}: {} vs {}",
                xi[j],
                reference[j]
            );
        }
        let residual = (&a * &reference - &b).norm_squared();
        assert!((f.error(&xi) - residual).abs() < 1e-10 * residual.max(1.0));
        assert!((f.residual_energy() - residual).abs() < 1e-10);
        // A subset: columns 0, 1 and 3.
        let sub = a.select_columns(&[0, 1, 3]);
        let reference = sub.svd(true, true).solve(&b, 1e-14).unwrap();
        f.solve(0b1011, &mut xi);
        assert_eq!(xi[2], 0.0);
        for (p, j) in [0, 1, 3].into_iter().enumerate() {
            assert!((xi[j] - reference[p]).abs() < 1e-10);
        }
    }

    #[test]
    fn forgetting_weights_rows_geometrically() {
        let data = rows(200);
        let lambda: f64 = 0.98;
        let mut f: Factor<f64, 4> = Factor::new(4);
        for (row, y) in &data {
            f.update(row, *y, lambda.sqrt());
        }
        let n = data.len();
        let w = |i: usize| lambda.powi((n - 1 - i) as i32).sqrt();
        let a = nalgebra::DMatrix::from_fn(n, 4, |i, j| data[i].0[j] * w(i));
        let b = nalgebra::DVector::from_fn(n, |i, _| data[i].1 * w(i));
        let reference = a.svd(true, true).solve(&b, 1e-14).unwrap();
        let mut xi = [0.0; 4];
        f.solve(0b1111, &mut xi);
        for j in 0..4 {
            assert!((xi[j] - reference[j]).abs() < 1e-9);
        }
        let total: f64 = (0..n).map(|i| lambda.powi((n - 1 - i) as i32)).sum();
        assert!((f.weight() - total).abs() < 1e-9);
    }

    #[test]
    fn merge_equals_one_factor_over_all_rows() {
        let data = rows(300);
        let mut all: Factor<f64, 4> = Factor::new(4);
        let mut even: Factor<f64, 4> = Factor::new(4);
        let mut odd: Factor<f64, 4> = Factor::new(4);
        for (i, (row, y)) in data.iter().enumerate() {
            all.update(row, *y, 1.0);
            if i % 2 == 0 {
                even.update(row, *y, 1.0)
            } else {
                odd.update(row, *y, 1.0)
            }
        }
        even.merge(&odd);
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        all.solve(0b1111, &mut a);
        even.solve(0b1111, &mut b);
        for j in 0..4 {
            assert!((a[j] - b[j]).abs() < 1e-10);
        }
        assert!((all.residual_energy() - even.residual_energy()).abs() < 1e-9);
        assert_eq!(all.weight(), even.weight());
    }

    #[test]
    fn transform_is_a_change_of_basis() {
        let data = rows(200);
        let mut f: Factor<f64, 4> = Factor::new(4);
        for (row, y) in &data {
            f.update(row, *y, 1.0);
        }
        let mut xi = [0.0; 4];
        f.solve(0b1111, &mut xi);
        // New columns: c0, c1 + 2 c0, c2, c3 − c1.
        let mut b = [[0.0; 4]; 4];
        b[0][0] = 1.0;
        b[0][1] = 2.0;
        b[1][1] = 1.0;
        b[2][2] = 1.0;
        b[3][3] = 1.0;
        b[1][3] = -1.0;
        let e = f.residual_energy();
        f.transform(&b);
        let mut eta = [0.0; 4];
        f.solve(0b1111, &mut eta);
        // Θ ξ = Θ B η  ⇒  ξ = B η.
        for i in 0..4 {
            let mapped: f64 = (0..4).map(|j| b[i][j] * eta[j]).sum();
            assert!((mapped - xi[i]).abs() < 1e-10);
        }
        assert!((f.error(&eta) - e).abs() < 1e-9);
    }

    #[test]
    fn f32_stays_finite_and_close_over_a_million_rows() {
        let mut f: Factor<f32, 4> = Factor::new(4);
        let mut s = 3u64;
        let lambda = 0.9999f32;
        for _ in 0..1_000_000 {
            let row = [
                1.0f32,
                noise(&mut s) as f32,
                noise(&mut s) as f32 * 3.0,
                noise(&mut s) as f32,
            ];
            let y = 0.5 - 2.0 * row[1] + 0.25 * row[2] + 0.01 * noise(&mut s) as f32;
            f.update(&row, y, lambda.sqrt());
        }
        let mut xi = [0.0f32; 4];
        f.solve(0b1111, &mut xi);
        // The same rows in f64 are the reference: f32 rounding must stay far below the
        // statistical error (~1e-4 here).
        let mut g: Factor<f64, 4> = Factor::new(4);
        let mut s = 3u64;
        for _ in 0..1_000_000 {
            let row = [
                1.0f32,
                noise(&mut s) as f32,
                noise(&mut s) as f32 * 3.0,
                noise(&mut s) as f32,
            ];
            let y = 0.5 - 2.0 * row[1] + 0.25 * row[2] + 0.01 * noise(&mut s) as f32;
            g.update(&row.map(f64::from), f64::from(y), (lambda as f64).sqrt());
        }
        let mut reference = [0.0f64; 4];
        g.solve(0b1111, &mut reference);
        for j in 0..4 {
            assert!(
                (f64::from(xi[j]) - reference[j]).abs() < 2e-4,
                "{j}: {xi:?} vs {reference:?}"
            );
        }
    }
}
