//! Several right-hand sides over one square-root factor: the regression of a system of
//! equations whose targets (x'', V', …) share one library row θ.
//!
//! Every equation of a system is regressed on the same row θ(states, t, u); only its target
//! differs. The Givens rotations that fold a row into R depend on θ alone, so one R serves
//! every equation and each target only needs its own z and ρ²: RᵀR = Σ λ^age θθᵀ and
//! Rᵀz_k = Σ λ^age θ y_k. A row costs the rotations of R once (n(n − 1)/2 rotation
//! applications of 7 flops, n Givens of about 10 flops and a square root) plus 7 flops per
//! column and target for the z's, where one factor per equation would rotate R once per
//! equation: with n = 16 columns and two equations 1 224 flops a row instead of 2 224, and
//! P² + E·P + E + 1 numbers of memory instead of E·(P² + P + 2) (1 184 bytes instead of
//! 2 208 with f32, P = 16, E = 2, on the host). Each equation's factor is then exactly the
//! factor a single-target regression of its rows would have built, to rounding: the
//! rotations are the same ones and every z_k sees them in the same order
//! ([`MultiFactor::equation`]).

use super::*;

/// A square-root information accumulator over `n ≤ P` columns with `E` targets sharing R.
#[derive(Debug)]
pub struct MultiFactor<T, const P: usize, const E: usize> {
    n: usize,
    /// Targets in use (≤ E).
    targets: usize,
    r: [[T; P]; P],
    z: [[T; P]; E],
    rho2: [T; E],
    weight: T,
}

impl<T: Copy, const P: usize, const E: usize> Clone for MultiFactor<T, P, E> {
    fn clone(&self) -> Self {
        Self {
            n: self.n,
            targets: self.targets,
            r: self.r,
            z: self.z,
            rho2: self.rho2,
            weight: self.weight,
        }
    }

    /// In place, field by field: the derived one builds the copy on the stack first (1.2 KB
    /// with f32 and P = 16, on a device's interrupt stack when a snapshot is taken).
    fn clone_from(&mut self, source: &Self) {
        self.n = source.n;
        self.targets = source.targets;
        self.r.copy_from_slice(&source.r);
        self.z.copy_from_slice(&source.z);
        self.rho2 = source.rho2;
        self.weight = source.weight;
    }
}

impl<T: Real, const P: usize, const E: usize> MultiFactor<T, P, E> {
    /// An empty factor over `n` columns and `targets` right-hand sides (clamped to `P` and
    /// `E`).
    pub const fn new(n: usize, targets: usize) -> Self {
        Self {
            n: if n < P { n } else { P },
            targets: if targets < E { targets } else { E },
            r: [[T::ZERO; P]; P],
            z: [[T::ZERO; P]; E],
            rho2: [T::ZERO; E],
            weight: T::ZERO,
        }
    }

    /// Number of columns.
    pub fn columns(&self) -> usize {
        self.n
    }

    /// Number of right-hand sides in use.
    pub fn targets(&self) -> usize {
        self.targets
    }

    /// Σ λ^age: the effective number of rows.
    pub fn weight(&self) -> T {
        self.weight
    }

    /// Empty again, over `n` columns and `targets` right-hand sides (clamped to `P` and `E`):
    /// [`MultiFactor::new`] in place.
    pub fn reshape(&mut self, n: usize, targets: usize) {
        self.n = n.min(P);
        self.targets = targets.min(E);
        self.clear();
    }

    /// Empties the factor (same columns and targets).
    pub fn clear(&mut self) {
        for row in self.r.iter_mut() {
            row.fill(T::ZERO);
        }
        for z in self.z.iter_mut() {
            z.fill(T::ZERO);
        }
        self.rho2 = [T::ZERO; E];
        self.weight = T::ZERO;
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
            for z in self.z[..self.targets].iter_mut() {
                z[i] *= sqrt_lambda;
            }
        }
        let lambda = sqrt_lambda * sqrt_lambda;
        for r in self.rho2[..self.targets].iter_mut() {
            *r *= lambda;
        }
        self.weight *= lambda;
    }

    /// Forgets by `sqrt_lambda` and folds in one row θ (`row`, first `n` entries) with the
    /// targets `y` (first `targets` entries).
    pub fn update(&mut self, row: &[T], y: &[T], sqrt_lambda: T) {
        self.forget(sqrt_lambda);
        let n = self.n.min(row.len());
        let mut a = [T::ZERO; P];
        a[..n].copy_from_slice(&row[..n]);
        let mut b = [T::ZERO; E];
        let k = self.targets.min(y.len());
        b[..k].copy_from_slice(&y[..k]);
        self.fold(&mut a, &mut b, n);
        for (r, b) in self.rho2[..self.targets].iter_mut().zip(b) {
            *r += b * b;
        }
        self.weight += T::ONE;
    }

    /// Rotates row `a` (targets `b`) into R and the z's; leaves the targets' remainders in
    /// `b`. The same rotations as [`Factor::update`], applied to each target in turn.
    #[inline]
    fn fold(&mut self, a: &mut [T; P], b: &mut [T; E], n: usize) {
        let targets = self.targets;
        for i in 0..n {
            if a[i] == T::ZERO {
                continue;
            }
            let g = givens(self.r[i][i], a[i]);
            self.r[i][i] = g.r;
            for (rij, aj) in self.r[i][i + 1..n].iter_mut().zip(a[i + 1..n].iter_mut()) {
                (*rij, *aj) = g.apply(*rij, *aj);
            }
            for (z, bk) in self.z[..targets].iter_mut().zip(b.iter_mut()) {
                (z[i], *bk) = g.apply(z[i], *bk);
            }
        }
    }

    /// Folds in everything another factor over the same columns and targets holds (no
    /// forgetting).
    pub fn merge(&mut self, other: &Self) {
        let n = self.n.min(other.n);
        for i in 0..n {
            let mut row = [T::ZERO; P];
            row[i..n].copy_from_slice(&other.r[i][i..n]);
            let mut b = [T::ZERO; E];
            for (bk, z) in b.iter_mut().zip(other.z.iter()).take(self.targets) {
                *bk = z[i];
            }
            self.fold(&mut row, &mut b, n);
            for (r, b) in self.rho2[..self.targets].iter_mut().zip(b) {
                *r += b * b;
            }
        }
        for (r, o) in self.rho2[..self.targets].iter_mut().zip(other.rho2) {
            *r += o;
        }
        self.weight += other.weight;
    }

    /// Writes equation `k`'s single-target factor (R, z_k, ρ²_k, weight) into `out`, which
    /// takes this factor's columns. Nothing is written for a target out of range.
    pub fn equation(&self, k: usize, out: &mut Factor<T, P>) {
        if k >= self.targets {
            return;
        }
        out.n = self.n;
        out.r = self.r;
        out.z = self.z[k];
        out.rho2 = self.rho2[k];
        out.weight = self.weight;
    }

    /// Equation `k`'s single-target factor (R, z_k, ρ²_k, weight), to read where it is (as
    /// every single-target factor is read: solved, merged, copied into a [`FactorPair`]);
    /// `None` for a target out of range.
    pub fn equation_view(&self, k: usize) -> Option<FactorRef<'_, T, P>> {
        (k < self.targets).then(|| FactorRef {
            n: self.n,
            r: &self.r,
            flipped: None,
            z: &self.z[k],
            rho2: self.rho2[k],
            weight: self.weight,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(i: usize) -> ([f64; 5], [f64; 2]) {
        let t = i as f64 * 0.13;
        let (x, v, e) = (t.sin(), (0.7 * t).cos(), (1.3 * t).sin() * 0.5);
        (
            [1.0, x, v, e, x * e],
            [-2.0 * x + 0.3 * e + 0.01 * (i % 5) as f64, -e - 0.4 * v],
        )
    }

    /// Each equation's factor is the one its own regression builds: the same solution, to
    /// rounding, whether rows go in one by one, merged in blocks or with forgetting.
    #[test]
    fn each_equation_is_its_own_regression() {
        for sqrt_lambda in [1.0, 0.999] {
            let mut multi = MultiFactor::<f64, 8, 2>::new(5, 2);
            let mut block = MultiFactor::<f64, 8, 2>::new(5, 2);
            let mut single = [Factor::<f64, 8>::new(5), Factor::<f64, 8>::new(5)];
            for i in 0..300 {
                let (theta, y) = row(i);
                block.update(&theta, &y, sqrt_lambda);
                if i % 16 == 15 {
                    multi.forget(if sqrt_lambda == 1.0 {
                        1.0
                    } else {
                        0.999f64.powi(16)
                    });
                    multi.merge(&block);
                    block.clear();
                }
                for (k, f) in single.iter_mut().enumerate() {
                    f.update(&theta, y[k], sqrt_lambda);
                }
            }
            multi.forget(if sqrt_lambda == 1.0 {
                1.0
            } else {
                0.999f64.powi(300 % 16)
            });
            multi.merge(&block);
            let mut f = Factor::<f64, 8>::new(0);
            for k in 0..2 {
                multi.equation(k, &mut f);
                let (mut p, mut q) = ([0.0; 8], [0.0; 8]);
                f.solve(0b11111, &mut p);
                single[k].solve(0b11111, &mut q);
                for (p, q) in p.iter().zip(q) {
                    assert!((p - q).abs() < 1e-9, "{k}: {p} {q}");
                }
                // Relative to the target's energy (the second equation's residual is rounding).
                let diff = (f.residual_energy() - single[k].residual_energy()).abs();
                assert!(diff < 1e-9 * single[k].target_norm().powi(2), "{k}: {diff}");
                assert!((f.weight() - single[k].weight()).abs() < 1e-9);
            }
            // The second equation holds exactly: its sparse solution is the truth.
            multi.equation(1, &mut f);
            let mut xi = [0.0; 8];
            f.solve(0b01100, &mut xi);
            assert!(
                (xi[2] + 0.4).abs() < 1e-9 && (xi[3] + 1.0).abs() < 1e-9,
                "{xi:?}"
            );
        }
    }

    /// A target-free factor (targets 0) still builds R; out-of-range equations write nothing.
    #[test]
    fn out_of_range_targets_are_ignored() {
        let mut multi = MultiFactor::<f32, 4, 2>::new(3, 1);
        multi.update(&[1.0, 2.0, 3.0], &[1.0, 5.0], 1.0);
        assert_eq!(multi.targets(), 1);
        let mut f = Factor::<f32, 4>::new(2);
        multi.equation(1, &mut f);
        assert_eq!(f.columns(), 2);
        assert_eq!(f.weight(), 0.0);
        multi.equation(0, &mut f);
        assert_eq!((f.columns(), f.weight()), (3, 1.0));
    }
}
