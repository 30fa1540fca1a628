//! The normal equations of multiple shooting, kept in their block structure: the shared
//! parameters (the coefficients, and Ω for the standard errors) meet every sample, each
//! segment's initial state only its own. The states are eliminated segment by segment (a
//! Schur complement), so a solve costs a q × q factorisation and a 2 × 2 inverse per
//! segment instead of a dense (q + 2·segments)² one: a record cut into a thousand short
//! windows (a fast or chaotic signal) costs what ten long ones do.

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};

/// JᵀJ and Jᵀr of a multiple-shooting problem, by blocks.
pub(crate) struct BlockNormal {
    /// Shared × shared.
    a: DMatrix<f64>,
    /// Shared × each segment's state (q × 2, column-major: the x₀ column, then v₀).
    b: Vec<DMatrix<f64>>,
    /// Each segment's state × state.
    d: Vec<Matrix2<f64>>,
    /// Jᵀr of the shared parameters.
    gs: DVector<f64>,
    /// Jᵀr of each segment's state.
    gd: Vec<Vector2<f64>>,
}

/// A solve's step: the shared parameters', then each segment's (x₀, v₀).
pub(crate) type Step = (DVector<f64>, Vec<Vector2<f64>>);

impl BlockNormal {
    /// Accumulates JᵀJ and Jᵀr from the Jacobian's columns (`shared`, then the two state
    /// columns, each segment's state column nonzero on its own samples only) and the
    /// residuals.
    pub(crate) fn assemble(
        shared: &[&[f64]],
        state: [&[f64]; 2],
        residual: impl Fn(usize) -> f64,
        segs: &[(usize, usize)],
    ) -> Self {
        let q = shared.len();
        let mut a = DMatrix::zeros(q, q);
        let mut gs = DVector::zeros(q);
        let mut b = Vec::with_capacity(segs.len());
        let mut d = Vec::with_capacity(segs.len());
        let mut gd = Vec::with_capacity(segs.len());
        let mut row = vec![0.0; q];
        for &(start, end) in segs {
            let mut bs = DMatrix::zeros(q, 2);
            let mut ds = Matrix2::zeros();
            let mut gds = Vector2::zeros();
            for i in start..end {
                let r = residual(i);
                for (slot, column) in row.iter_mut().zip(shared) {
                    *slot = column[i];
                }
                let sx = [state[0][i], state[1][i]];
                for q1 in 0..q {
                    let j1 = row[q1];
                    if j1 == 0.0 {
                        continue;
                    }
                    gs[q1] += j1 * r;
                    for q2 in q1..q {
                        a[(q1, q2)] += j1 * row[q2];
                    }
                    bs[(q1, 0)] += j1 * sx[0];
                    bs[(q1, 1)] += j1 * sx[1];
                }
                for s1 in 0..2 {
                    gds[s1] += sx[s1] * r;
                    for s2 in 0..2 {
                        ds[(s1, s2)] += sx[s1] * sx[s2];
                    }
                }
            }
            b.push(bs);
            d.push(ds);
            gd.push(gds);
        }
        for q1 in 0..q {
            for q2 in 0..q1 {
                a[(q1, q2)] = a[(q2, q1)];
            }
        }
        Self { a, b, d, gs, gd }
    }

    /// The step of (JᵀJ + λ·diag(JᵀJ)) δ = −Jᵀr; `None` when it is not positive definite.
    pub(crate) fn solve(&self, lambda: f64) -> Option<Step> {
        let q = self.a.nrows();
        let damp = |x: f64| x + lambda * x.max(1e-300);
        let mut schur = self.a.clone();
        for j in 0..q {
            schur[(j, j)] = damp(self.a[(j, j)]);
        }
        let mut rhs = -&self.gs;
        let mut inverses = Vec::with_capacity(self.d.len());
        for ((bs, ds), gds) in self.b.iter().zip(&self.d).zip(&self.gd) {
            let mut dd = *ds;
            dd[(0, 0)] = damp(ds[(0, 0)]);
            dd[(1, 1)] = damp(ds[(1, 1)]);
            let inv = dd.cholesky()?.inverse();
            if q > 0 {
                let bd = bs * inv; // q × 2
                schur -= &bd * bs.transpose();
                rhs += &bd * gds;
            }
            inverses.push(inv);
        }
        let shared = if q > 0 {
            schur.cholesky()?.solve(&rhs)
        } else {
            DVector::zeros(0)
        };
        let states = self
            .b
            .iter()
            .zip(&self.gd)
            .zip(&inverses)
            .map(|((bs, gds), inv)| {
                let coupled = if q > 0 {
                    bs.transpose() * &shared
                } else {
                    DVector::zeros(2)
                };
                inv * (-gds - Vector2::new(coupled[0], coupled[1]))
            })
            .collect();
        Some((shared, states))
    }

    /// The shared parameters' block of (JᵀJ)⁻¹ (their marginal covariance over σ²): the
    /// inverse of the Schur complement. `None` when JᵀJ is not positive definite.
    pub(crate) fn shared_inverse(&self) -> Option<DMatrix<f64>> {
        let mut schur = self.a.clone();
        for (bs, ds) in self.b.iter().zip(&self.d) {
            let inv = ds.cholesky()?.inverse();
            schur -= bs * inv * bs.transpose();
        }
        Some(schur.cholesky()?.inverse())
    }

    /// Parameters in all: shared and two a segment.
    pub(crate) fn parameters(&self) -> usize {
        self.a.nrows() + 2 * self.d.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The block solve equals a dense solve of the same normal equations.
    #[test]
    fn the_schur_solve_equals_the_dense_one() {
        let segs = [(0, 7), (7, 15), (15, 20)];
        let n = 20;
        let col = |f: &dyn Fn(usize) -> f64| (0..n).map(f).collect::<Vec<f64>>();
        let c0 = col(&|i| (i as f64 * 0.37).sin());
        let c1 = col(&|i| (i as f64 * 0.11).cos() + 0.2);
        let sx = col(&|i| 1.0 + 0.1 * (i % 7) as f64);
        let sv = col(&|i| (i as f64 * 0.9).sin() * 0.5 + 0.01 * i as f64);
        let r = |i: usize| (i as f64 * 1.3).cos() * 0.3;
        let normal = BlockNormal::assemble(&[&c0, &c1], [&sx, &sv], r, &segs);
        let lambda = 0.05;
        let (shared, states) = normal.solve(lambda).expect("solves");
        // Dense: parameters c0, c1, then (x0, v0) per segment.
        let p = 2 + 2 * segs.len();
        let mut jac = DMatrix::<f64>::zeros(n, p);
        for i in 0..n {
            jac[(i, 0)] = c0[i];
            jac[(i, 1)] = c1[i];
            let s = segs
                .iter()
                .position(|&(a, b)| (a..b).contains(&i))
                .expect("in a segment");
            jac[(i, 2 + 2 * s)] = sx[i];
            jac[(i, 3 + 2 * s)] = sv[i];
        }
        let res = DVector::from_iterator(n, (0..n).map(r));
        let jtj = jac.transpose() * &jac;
        let mut damped = jtj.clone();
        for j in 0..p {
            damped[(j, j)] += lambda * jtj[(j, j)];
        }
        let dense = damped
            .cholesky()
            .expect("dense")
            .solve(&(-(jac.transpose() * res)));
        assert!((shared[0] - dense[0]).abs() < 1e-9 && (shared[1] - dense[1]).abs() < 1e-9);
        for (s, st) in states.iter().enumerate() {
            assert!((st[0] - dense[2 + 2 * s]).abs() < 1e-9, "{st} vs {dense}");
            assert!((st[1] - dense[3 + 2 * s]).abs() < 1e-9);
        }
        let inv = normal.shared_inverse().expect("inverts");
        let dense_inv = jtj.cholesky().expect("dense").inverse();
        for a in 0..2 {
            for b in 0..2 {
                assert!(
                    (inv[(a, b)] - dense_inv[(a, b)]).abs()
                        < 1e-9 * dense_inv[(a, b)].abs().max(1.0)
                );
            }
        }
        assert_eq!(normal.parameters(), p);
    }
}
