//! Triangularisation by Givens rotations: of the kept columns in a solve (see
//! `FactorRef::solve_in`), and of R·B in a transform.

use super::*;

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
