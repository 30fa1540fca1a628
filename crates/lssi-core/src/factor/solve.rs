//! Least squares on a subset of the columns: triangularise the kept columns, back-substitute.

use super::*;

impl<T: Real, const P: usize> Factor<T, P> {
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
pub(super) fn triangularise<T: Real, const P: usize>(
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
