//! The factor's algorithms, once, on views of wherever its rows are kept.
//!
//! Row i of an upper-triangular factor is its diagonal entry and the n − 1 − i entries right
//! of it. A [`Factor`] keeps them in place, R[i][i..n]. A [`FactorPair`] keeps two factors
//! in the memory of about one: the first in place, the second's diagonal in an array of its
//! own and the entries right of it at the start of row P − 1 − i, in the part of the matrix
//! the first leaves free (row P − 1 − i of the first starts at column P − 1 − i, and the
//! second's row i needs columns 0..n − 1 − i). Every operation reads and writes the same
//! numbers in the same order whichever way the rows are kept, so the results are the same
//! bits.

use super::*;

/// Where the rows of a factor written through a [`FactorMut`] are kept.
pub(super) enum Layout<'a, T, const P: usize> {
    /// In place, and the whole matrix is the factor's (a [`Factor`]: the entries left of the
    /// diagonal are its own, zero).
    Whole,
    /// In place, but the entries left of the diagonal hold another factor's rows (the first
    /// of a [`FactorPair`]).
    Upper,
    /// The diagonal in the array given, the rest flipped (the second of a [`FactorPair`]).
    Flipped(&'a mut [T; P]),
}

/// Read access to a square-root factor: (R, z, ρ², weight) wherever R's rows are kept.
#[derive(Clone, Copy)]
pub struct FactorRef<'a, T, const P: usize> {
    pub(super) n: usize,
    pub(super) r: &'a [[T; P]; P],
    /// The diagonal, when the rows are kept flipped.
    pub(super) flipped: Option<&'a [T; P]>,
    pub(super) z: &'a [T; P],
    pub(super) rho2: T,
    pub(super) weight: T,
}

/// Write access to a square-root factor (see [`FactorRef`]).
pub struct FactorMut<'a, T, const P: usize> {
    pub(super) n: usize,
    pub(super) r: &'a mut [[T; P]; P],
    pub(super) layout: Layout<'a, T, P>,
    pub(super) z: &'a mut [T; P],
    pub(super) rho2: &'a mut T,
    pub(super) weight: &'a mut T,
}

impl<'a, T: Real, const P: usize> FactorRef<'a, T, P> {
    /// Row `i`: its diagonal entry and the entries right of it (columns i + 1..n).
    #[inline(always)]
    fn row(&self, i: usize) -> (T, &'a [T]) {
        match self.flipped {
            None => (self.r[i][i], &self.r[i][i + 1..self.n]),
            Some(d) => (d[i], &self.r[P - 1 - i][..self.n - 1 - i]),
        }
    }

    /// Entry (i, j), j ≥ i.
    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> T {
        match self.flipped {
            None => self.r[i][j],
            Some(d) if j == i => d[i],
            Some(_) => self.r[P - 1 - i][j - i - 1],
        }
    }

    /// Σ λ^age: the effective number of rows.
    pub fn weight(&self) -> T {
        self.weight
    }

    /// Residual energy Σ λ^age (y − θᵀξ)² of a coefficient vector: ‖Rξ − z‖² + ρ².
    pub fn error(&self, coefficients: &[T]) -> T {
        let n = self.n.min(coefficients.len());
        let mut e = self.rho2;
        for i in 0..n {
            let (d, tail) = self.row(i);
            let mut s = -self.z[i];
            s += d * coefficients[i];
            for (r, c) in tail[..n - 1 - i].iter().zip(&coefficients[i + 1..n]) {
                s += *r * *c;
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
                let v = self.at(i, j);
                s += v * v;
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
        for k in 0..=i.min(j) {
            s += self.at(k, i) * self.at(k, j);
        }
        s
    }

    /// Entry i of Rᵀz = Σ λ^age θ y (0 outside the columns).
    pub fn moment(&self, i: usize) -> T {
        if i >= self.n {
            return T::ZERO;
        }
        let mut s = T::ZERO;
        for k in 0..=i {
            s += self.at(k, i) * self.z[k];
        }
        s
    }

    /// Least squares on the columns in `support` with the caller's P×P scratch matrix (its
    /// contents on entry do not matter): see [`Factor::solve`]. The screening, which solves
    /// thousands of times, lends it one, so that its deepest frame does not hold another
    /// kilobyte (P = 16, f32).
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
        for (i, out) in a.iter_mut().enumerate().take(n) {
            let (d, tail) = self.row(i);
            for (p, &j) in columns[..m].iter().enumerate() {
                out[p] = if j > i {
                    tail[j - i - 1]
                } else if j == i {
                    d
                } else {
                    T::ZERO
                };
            }
        }
        let mut z = *self.z;
        // Each kept column j has nonzeros in rows 0..=j only (the rotations keep it so, and
        // skip the zeros below).
        triangularise(a, &mut z, n, m);
        // Back substitution, dropping columns whose pivot is negligible against their norm.
        let mut used = support;
        let tolerance = T::EPSILON * T::from_f64(64.0);
        let mut solution = [T::ZERO; P];
        for p in (0..m).rev() {
            let mut norm = T::ZERO;
            for row in a.iter().take(p + 1) {
                norm += row[p] * row[p];
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

/// One Givens rotation of a factor's row (`d`, `tail`; z entry `zi`) against the incoming
/// row `a` (from the same column on) and target `b`; returns the new target.
#[inline(always)]
pub(super) fn rotate_in<T: Real>(d: &mut T, tail: &mut [T], a: &mut [T], zi: &mut T, b: T) -> T {
    let g = givens(*d, a[0]);
    *d = g.r;
    for (rij, aj) in tail.iter_mut().zip(a[1..].iter_mut()) {
        (*rij, *aj) = g.apply(*rij, *aj);
    }
    let (z, b) = g.apply(*zi, b);
    *zi = z;
    b
}

impl<T: Real, const P: usize> FactorMut<'_, T, P> {
    /// Read access to the same factor.
    #[inline]
    pub fn view(&self) -> FactorRef<'_, T, P> {
        FactorRef {
            n: self.n,
            r: self.r,
            flipped: match &self.layout {
                Layout::Flipped(d) => Some(&**d),
                _ => None,
            },
            z: self.z,
            rho2: *self.rho2,
            weight: *self.weight,
        }
    }

    /// Row `i`, writable: its diagonal entry and the entries right of it.
    #[inline(always)]
    fn row_mut(&mut self, i: usize) -> (&mut T, &mut [T]) {
        let n = self.n;
        match &mut self.layout {
            Layout::Flipped(d) => (&mut d[i], &mut self.r[P - 1 - i][..n - 1 - i]),
            _ => {
                let (d, tail) = self.r[i][i..n].split_at_mut(1);
                (&mut d[0], tail)
            }
        }
    }

    /// Forgets by `sqrt_lambda` (√λ) and folds in one row θ with target y.
    pub fn update(&mut self, row: &[T], y: T, sqrt_lambda: T) {
        let n = self.n.min(row.len());
        self.forget(sqrt_lambda);
        let mut a = [T::ZERO; P];
        a[..n].copy_from_slice(&row[..n]);
        let b = self.fold(0, n, n, &mut a, y);
        self.close_update(b);
    }

    /// [`FactorMut::update`] in two parts: this one forgets and rotates the row `a` (target
    /// `b`) into the first `split` rows of the factor, leaving in `a` and the returned target
    /// what [`FactorMut::finish_update`] folds in later. The two parts do the same arithmetic
    /// in the same order as `update`, so the factor comes out the same, bit for bit; in
    /// between, the factor must not be read or changed otherwise.
    pub fn begin_update(&mut self, a: &mut [T; P], b: T, split: usize, sqrt_lambda: T) -> T {
        self.forget(sqrt_lambda);
        let n = self.n;
        self.fold(0, split.min(n), n, a, b)
    }

    /// The rest of an update that [`FactorMut::begin_update`] began at `split`.
    pub fn finish_update(&mut self, a: &mut [T; P], b: T, split: usize) {
        let n = self.n;
        let b = self.fold(split.min(n), n, n, a, b);
        self.close_update(b);
    }

    /// Ends a row's update: its residual `b` goes to ρ², its weight to the factor's.
    #[inline]
    fn close_update(&mut self, b: T) {
        *self.rho2 += b * b;
        *self.weight += T::ONE;
    }

    /// Rotates the row `a` (target `b`) over the first `n` columns into the factor's rows
    /// `start..end`; the row's entries left of `start` are zero, those from `end` on are what is left to fold in
    /// (the factor's rows from `end` on are untouched). Returns the target's remainder.
    /// The loop is written once for rows in place and once for flipped ones (the per-row
    /// layout test cost 8 % of an update).
    #[inline(never)]
    fn fold(&mut self, start: usize, end: usize, n: usize, a: &mut [T; P], mut b: T) -> T {
        let z = &mut *self.z;
        match &mut self.layout {
            Layout::Flipped(diag) => {
                for i in start..end {
                    if a[i] == T::ZERO {
                        continue;
                    }
                    let tail = &mut self.r[P - 1 - i][..n - 1 - i];
                    b = rotate_in(&mut diag[i], tail, &mut a[i..n], &mut z[i], b);
                }
            }
            _ => {
                for i in start..end {
                    if a[i] == T::ZERO {
                        continue;
                    }
                    let (d, tail) = self.r[i][i..n].split_at_mut(1);
                    b = rotate_in(&mut d[0], tail, &mut a[i..n], &mut z[i], b);
                }
            }
        }
        b
    }

    /// Ages everything by `sqrt_lambda` (√λ per row, raised to the rows elapsed).
    pub fn forget(&mut self, sqrt_lambda: T) {
        if sqrt_lambda == T::ONE {
            return;
        }
        for i in 0..self.n {
            let (d, tail) = self.row_mut(i);
            *d *= sqrt_lambda;
            for v in tail {
                *v *= sqrt_lambda;
            }
            self.z[i] *= sqrt_lambda;
        }
        let lambda = sqrt_lambda * sqrt_lambda;
        *self.rho2 *= lambda;
        *self.weight *= lambda;
    }

    /// Folds in everything another factor over the same columns holds (no forgetting).
    pub fn merge(&mut self, other: FactorRef<'_, T, P>) {
        let n = self.n.min(other.n);
        for i in 0..n {
            // Row i of the other's R (zero left of the diagonal: the rotations start at i).
            let mut row = [T::ZERO; P];
            let (d, tail) = other.row(i);
            row[i] = d;
            for (r, t) in row[i + 1..n].iter_mut().zip(tail) {
                *r = *t;
            }
            let b = self.fold(i, n, n, &mut row, other.z[i]);
            *self.rho2 += b * b;
        }
        // The rotations added the disagreement between the two fits to ρ²; the other's own
        // residual energy comes on top.
        *self.rho2 += other.rho2;
        *self.weight += other.weight;
    }

    /// Multiplies column j by `factors[j]` (a change of the column's units) and z by
    /// `target_factor`.
    pub fn scale(&mut self, factors: &[T], target_factor: T) {
        let n = self.n.min(factors.len());
        for i in 0..n {
            let (d, tail) = self.row_mut(i);
            *d *= factors[i];
            for (v, f) in tail[..n - 1 - i].iter_mut().zip(&factors[i + 1..n]) {
                *v *= *f;
            }
            self.z[i] *= target_factor;
        }
        *self.rho2 *= target_factor * target_factor;
    }

    /// Makes this factor (same columns) a copy of the one `other` reads.
    pub fn copy_from(&mut self, other: FactorRef<'_, T, P>) {
        let n = self.n.min(other.n);
        for i in 0..n {
            let (d, tail) = other.row(i);
            let (sd, st) = self.row_mut(i);
            *sd = d;
            for (s, t) in st.iter_mut().zip(tail) {
                *s = *t;
            }
            self.z[i] = other.z[i];
        }
        *self.rho2 = other.rho2;
        *self.weight = other.weight;
    }

    /// Replaces the columns Θ by Θ·B, for an upper-triangular B: R ← R·B, which is upper
    /// triangular too, so that nothing is left to rotate. The identifier's maps are: a shift
    /// of an origin maps a monomial onto ones of lower degree, which come first. Panics if B
    /// has a nonzero entry below its diagonal.
    ///
    /// In place: row i of R·B needs only row i of R, so each row is computed into one row of
    /// scratch and written back; no P×P temporary is needed (the screening calls this in its
    /// deepest frames, where the stack peaks).
    pub fn transform(&mut self, b: &[[T; P]; P]) {
        let n = self.n;
        assert!(
            (1..n).all(|k| b[k][..k].iter().all(|v| *v == T::ZERO)),
            "a factor is transformed by upper-triangular maps only"
        );
        let mut row = [T::ZERO; P];
        for i in 0..n {
            let (d, tail) = self.row_mut(i);
            for (j, out) in row.iter_mut().enumerate().take(n).skip(i) {
                let mut s = T::ZERO;
                s += *d * b[i][j];
                for (k, r) in tail.iter().enumerate() {
                    s += *r * b[i + 1 + k][j];
                }
                *out = s;
            }
            *d = row[i];
            for (t, r) in tail.iter_mut().zip(&row[i + 1..n]) {
                *t = *r;
            }
        }
    }
}
