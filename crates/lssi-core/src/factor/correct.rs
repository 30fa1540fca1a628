//! The errors-in-variables correction of a factor (see `eiv`).

use super::*;

impl<T: Real, const P: usize> Factor<T, P> {
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
        if !whiten_cholesky(&self.r, delta, n) {
            return false;
        }
        let r = &self.r;
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
}

/// Overwrites `delta` (Δ, symmetric, n × n) with the Cholesky factor U (upper triangle) of
/// I − E, E = R⁻ᵀΔR⁻¹ by two triangular solves; false when I − E is not safely positive
/// definite (a pivot at or below 0.01).
#[inline(always)]
fn whiten_cholesky<T: Real, const P: usize>(
    r: &[[T; P]; P],
    delta: &mut [[T; P]; P],
    n: usize,
) -> bool {
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
    true
}
