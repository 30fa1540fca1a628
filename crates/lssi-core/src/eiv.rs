//! Errors in variables: the noise of x̂ and v̂ taken out of the normal equations.
//!
//! The regressors are estimates too. x̂, v̂ and the target ŷ are local-polynomial filters
//! h₀, h₁, h₂ (x only) of the same noisy samples, so each carries noise, and the noise of ŷ
//! is correlated with that of x̂ (h₀·h₂ ≠ 0; the odd h₁ against the even h₀, h₂ gives 0).
//! Least squares on noisy regressors is biased, and not by a little: with x only at
//! δ = 0.1 the x'' noise correlated with x̂ moved the linear coefficient by 40 % on eq. 17
//! (`cov(x̂, ŷ)/var(x)` amplified by the cubic), and v̂'s variance shrinks the damping.
//!
//! With white sample noise of variance σ² (from fourth differences), the row noise is
//! Gaussian (a sum of hundreds of samples) with the known covariances
//! `xx = σ²‖h₀‖²`, `vv = σ²‖h₁‖²`, `xy = σ²h₀·h₂`, `vy = σ²h₁·h₂` (x only; with a measured
//! v the channels' noises are independent and only xx, vv remain). The noisy moments are
//! then unbiased for the true ones after a Hermite transform, which for independent x̂ and
//! v̂ noise is a finite sum over lower moments that the factor already holds:
//!
//! - E[He_A(x̂) He_B(v̂)] = x^A v^B, with He_A(x̂) = Σ_j (−1)^j C(A,2j)(2j−1)!! xx^j x̂^(A−2j):
//!   the Gram entry of columns x^a v^b and x^c v^d (A = a + c, B = b + d) is corrected with
//!   the Gram entries of pairs whose monomials multiply to x^(A−2j) v^(B−2k);
//! - E[He_A(x̂) He_B(v̂) ŷ] = x^A v^B y + A·xy·x^(A−1)v^B + B·vy·x^A v^(B−1) (Stein's lemma and
//!   He' = A·He_(A−1)): the moment of column x^a v^b with the target is corrected with the
//!   lower columns' moments and the (corrected) Gram moments x^(A−1)v^B, x^A v^(B−1).
//!
//! The sin/cos columns and u are noise-free for this purpose (the phase is exact; u's own
//! noise is independent of x's). A moment the library cannot supply (no pair of its columns
//! multiplies to it) leaves its entry uncorrected.
//!
//! The corrected Gram G − Δ and moments g − d are turned back into a factor without squaring
//! the condition number in f32: with E = R⁻ᵀΔR⁻¹ (small, symmetric),
//! G − Δ = Rᵀ(I − E)R = (UR)ᵀ(UR) with U = chol(I − E) near the identity
//! ([`Factor::correct`]). A correction so large that I − E loses more than 99 % of a
//! direction (the noise would be most of that column) is not applied.

use crate::factor::Factor;
use crate::library::Term;
use crate::real::Real;

/// Noise covariances of one regression row's estimates, in the factor's scaled units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct RowNoise<T> {
    /// Variance of x̂'s noise.
    pub xx: T,
    /// Variance of v̂'s noise.
    pub vv: T,
    /// Covariance of x̂'s noise with the target's.
    pub xy: T,
    /// Covariance of v̂'s noise with the target's.
    pub vy: T,
}

impl<T: Real> RowNoise<T> {
    fn is_zero(&self) -> bool {
        self.xx == T::ZERO && self.vv == T::ZERO && self.xy == T::ZERO && self.vy == T::ZERO
    }
}

/// A column as (exogenous factor, power of x, power of v): the exogenous factor is 0 for
/// none, 2k for sin(kΩt), 2k + 1 for cos(kΩt), u16::MAX for the input u.
fn split(term: Term) -> (u16, u8, u8) {
    match term {
        Term::Constant => (0, 0, 0),
        Term::Monomial { px, pv } => (0, px, pv),
        Term::Sin(k) => (2 * u16::from(k), 0, 0),
        Term::Cos(k) => (2 * u16::from(k) + 1, 0, 0),
        Term::Input => (u16::MAX, 0, 0),
    }
}

/// The product of two exogenous factors as an unordered pair.
fn product(p: u16, q: u16) -> (u16, u16) {
    if p <= q { (p, q) } else { (q, p) }
}

/// The column with exogenous factor `e` and monomial x^a v^b.
fn column(terms: &[Term], e: u16, a: u8, b: u8) -> Option<usize> {
    terms.iter().position(|&t| split(t) == (e, a, b))
}

/// Σ e·x̂^a·v̂^b as it stands in the factor (a Gram entry), for an exogenous pair `e`.
fn noisy<T: Real, const P: usize>(
    f: &Factor<T, P>,
    terms: &[Term],
    e: (u16, u16),
    a: u8,
    b: u8,
) -> Option<T> {
    for (k, &term) in terms.iter().enumerate() {
        let (ek, ak, bk) = split(term);
        if ak > a || bk > b {
            continue;
        }
        // What the other column's exogenous factor must be.
        let other = if ek == 0 {
            if e.0 != 0 {
                continue;
            }
            e.1
        } else if e.0 == ek {
            e.1
        } else if e.1 == ek {
            e.0
        } else {
            continue;
        };
        if let Some(l) = column(terms, other, a - ak, b - bk) {
            return Some(f.gram(k, l));
        }
    }
    None
}

/// C(n, 2j)·(2j − 1)!!: the coefficient of s^j·z^(n−2j) in E[(z + e)^n], e ~ N(0, s).
fn hermite(n: u8, j: u8) -> f64 {
    let (n, j) = (u32::from(n), u32::from(j));
    let mut c = 1.0f64;
    // C(n, 2j) (2j−1)!! = n! / ((n − 2j)! · 2^j · j!)
    for i in 0..2 * j {
        c *= f64::from(n - i);
    }
    for i in 1..=j {
        c /= 2.0 * f64::from(i);
    }
    c
}

/// s^j in T.
fn power<T: Real>(s: T, j: u8) -> T {
    let mut p = T::ONE;
    for _ in 0..j {
        p *= s;
    }
    p
}

/// N − M for the moment e·x^a·v^b: what the noise adds to the noisy moment N, from the
/// Hermite transform over its lower moments. `None` if one of them is not in the factor.
fn gram_bias<T: Real, const P: usize>(
    f: &Factor<T, P>,
    terms: &[Term],
    noise: &RowNoise<T>,
    e: (u16, u16),
    a: u8,
    b: u8,
) -> Option<T> {
    let mut bias = T::ZERO;
    for j in 0..=a / 2 {
        if j > 0 && noise.xx == T::ZERO {
            break;
        }
        for k in 0..=b / 2 {
            if (j, k) == (0, 0) {
                continue;
            }
            if k > 0 && noise.vv == T::ZERO {
                break;
            }
            let c = T::from_f64(hermite(a, j) * hermite(b, k))
                * power(noise.xx, j)
                * power(noise.vv, k);
            let sign = if (j + k) % 2 == 1 { T::ONE } else { -T::ONE };
            bias += sign * c * noisy(f, terms, e, a - 2 * j, b - 2 * k)?;
        }
    }
    Some(bias)
}

/// Corrects factor `f` (columns `terms`, in scaled units) for the row noise. `scratch` is
/// overwritten. Returns whether the correction was applied.
pub(crate) fn correct<T: Real, const P: usize>(
    f: &mut Factor<T, P>,
    terms: &[Term],
    noise: &RowNoise<T>,
    scratch: &mut [[T; P]; P],
) -> bool {
    let n = f.columns().min(terms.len());
    if noise.is_zero() || n == 0 || f.weight() <= T::ZERO {
        return false;
    }
    let mut d = [T::ZERO; P];
    for i in 0..n {
        let (ei, ai, bi) = split(terms[i]);
        for j in i..n {
            let (ej, aj, bj) = split(terms[j]);
            let bias = gram_bias(f, terms, noise, product(ei, ej), ai + aj, bi + bj);
            let bias = bias.unwrap_or(T::ZERO);
            scratch[i][j] = bias;
            scratch[j][i] = bias;
        }
        d[i] = target_bias(f, terms, noise, i).unwrap_or(T::ZERO);
    }
    f.correct(scratch, &d)
}

/// The bias of column `i`'s moment with the target: the lower columns' moments, and
/// Stein's terms; `None` when a column it needs is not in the library.
fn target_bias<T: Real, const P: usize>(
    f: &Factor<T, P>,
    terms: &[Term],
    noise: &RowNoise<T>,
    i: usize,
) -> Option<T> {
    let (ei, ai, bi) = split(terms[i]);
    let mut bias = T::ZERO;
    for j in 0..=ai / 2 {
        for k in 0..=bi / 2 {
            if (j, k) == (0, 0) {
                continue;
            }
            let c = T::from_f64(hermite(ai, j) * hermite(bi, k))
                * power(noise.xx, j)
                * power(noise.vv, k);
            if c == T::ZERO {
                continue;
            }
            let l = column(terms, ei, ai - 2 * j, bi - 2 * k)?;
            let sign = if (j + k) % 2 == 1 { T::ONE } else { -T::ONE };
            bias += sign * c * f.moment(l);
        }
    }
    let e = product(ei, 0);
    for (power_, cov, da, db) in [(ai, noise.xy, 1u8, 0u8), (bi, noise.vy, 0, 1)] {
        if power_ == 0 || cov == T::ZERO {
            continue;
        }
        let (a, b) = (ai - da, bi - db);
        // The true moment e·x^a·v^b: the noisy one less its bias.
        let (m, g) = noisy(f, terms, e, a, b).zip(gram_bias(f, terms, noise, e, a, b))?;
        bias += T::from_usize(usize::from(power_)) * cov * (m - g);
    }
    Some(bias)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::library::{Library, LibraryConfig};

    /// The equation the test's rows obey: y = −x + 0.5v − 2x³ − 0.8x²v + 3 cos t.
    fn expect(term: Term) -> f64 {
        match term {
            Term::Monomial { px: 1, pv: 0 } => -1.0,
            Term::Monomial { px: 0, pv: 1 } => 0.5,
            Term::Monomial { px: 3, pv: 0 } => -2.0,
            Term::Monomial { px: 2, pv: 1 } => -0.8,
            Term::Cos(1) => 3.0,
            _ => 0.0,
        }
    }

    /// A deterministic pseudo-random Gaussian stream (Box–Muller on an LCG).
    struct Gauss(u64);

    impl Gauss {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }

        fn next(&mut self) -> f64 {
            let (a, b) = (self.uniform(), self.uniform());
            libm::sqrt(-2.0 * libm::log(a)) * libm::cos(2.0 * core::f64::consts::PI * b)
        }
    }

    /// 200,000 rows of [`expect`]'s equation with row noise of covariances `noise` (e_x and
    /// e_y correlated, e_v independent), accumulated into a factor.
    fn noisy_rows(library: &Library<16>, noise: &RowNoise<f64>) -> Factor<f64, 16> {
        let n = library.terms().len();
        let mut factor: Factor<f64, 16> = Factor::new(n);
        let mut gauss = Gauss(0x2545_f491_4f6c_dd1d);
        let truth =
            |x: f64, v: f64, c: f64| -x + 0.5 * v - 2.0 * x * x * x - 0.8 * x * x * v + 3.0 * c;
        let mut row = [0.0f64; 16];
        for i in 0..200_000 {
            let t = i as f64 * 0.01;
            let (x, v) = (
                libm::sin(0.7 * t) + 0.3 * libm::cos(1.9 * t),
                libm::cos(1.1 * t),
            );
            let y = truth(x, v, libm::cos(t));
            let (g1, g2, g3) = (gauss.next(), gauss.next(), gauss.next());
            let ex = libm::sqrt(noise.xx) * g1;
            let ev = libm::sqrt(noise.vv) * g2;
            let ey = noise.xy / libm::sqrt(noise.xx) * g1 + 0.3 * g3;
            library.evaluate_sin_cos(x + ex, v + ev, libm::sin(t), libm::cos(t), 0.0, &mut row);
            factor.update(&row[..n], y + ey, 1.0);
        }
        factor
    }

    /// x uniform, v = x' of a sinusoid: a row noise added with known covariances; the
    /// corrected least squares recovers the noise-free coefficients, the plain one does not.
    #[test]
    fn corrected_factor_removes_the_noise_bias() {
        let library: Library<16> = Library::new(&LibraryConfig {
            harmonics: 1,
            ..LibraryConfig::default()
        })
        .unwrap();
        let terms = library.terms();
        let n = terms.len();
        let noise = RowNoise {
            xx: 0.02,
            vv: 0.05,
            xy: -0.01,
            vy: 0.0,
        };
        let noisy_f = noisy_rows(&library, &noise);
        let full = (1u32 << n) - 1;
        let mut plain = [0.0; 16];
        noisy_f.solve(full, &mut plain);
        let mut corrected_f = noisy_f.clone();
        let mut scratch = [[0.0; 16]; 16];
        assert!(correct(&mut corrected_f, terms, &noise, &mut scratch));
        let mut corrected = [0.0; 16];
        corrected_f.solve(full, &mut corrected);
        let worst = |c: &[f64; 16]| {
            terms
                .iter()
                .enumerate()
                .map(|(j, &t)| (c[j] - expect(t)).abs())
                .fold(0.0f64, f64::max)
        };
        assert!(
            worst(&plain) > 0.1,
            "the noise biases plain LS: {}",
            worst(&plain)
        );
        assert!(worst(&corrected) < 0.03, "corrected: {:?}", &corrected[..n]);
    }

    #[test]
    fn hermite_coefficients() {
        // E[(z+e)^4] = z^4 + 6 s z^2 + 3 s^2
        assert_eq!(hermite(4, 0), 1.0);
        assert_eq!(hermite(4, 1), 6.0);
        assert_eq!(hermite(4, 2), 3.0);
        // E[(z+e)^6] = z^6 + 15 s z^4 + 45 s^2 z^2 + 15 s^3
        assert_eq!(hermite(6, 1), 15.0);
        assert_eq!(hermite(6, 2), 45.0);
        assert_eq!(hermite(6, 3), 15.0);
    }
}
