//! The restoring force of an identified model: its x-only terms as a polynomial, with what a
//! harvester's designer reads from it (equilibria and wells, the potential, the resonances).
//!
//! ```
//! use lssi_core::{RestoringForce, Term};
//! // x'' = 100x − 10⁶x³ + …: a double well at ±1 cm, about a sensor zero 2 mm off.
//! let force = RestoringForce::from_terms(
//!     [(Term::Monomial { px: 1, pv: 0 }, 100.0), (Term::Monomial { px: 3, pv: 0 }, -1e6),
//!      (Term::Monomial { px: 1, pv: 1 }, -0.5)], // not x-only: left out
//!     0.002,
//! );
//! assert_eq!(force.wells(), Some(0.01));
//! let mut wells = Vec::new();
//! force.equilibria(-0.05, 0.05, |e| wells.push(e));
//! assert_eq!(wells.len(), 3);
//! assert!(wells[1].x == 0.002 && !wells[1].stable); // the saddle, at the offset
//! assert!((wells[2].x - 0.012).abs() < 1e-12 && wells[2].stable);
//! assert!(force.potential(0.012) < force.potential(0.002));
//! ```

use crate::library::{MAX_POLY_ORDER, Term};
use crate::model::Model;
use crate::real::Real;

/// Coefficients the polynomial holds: x⁰ to x⁹ (at least the library's highest order).
const COEFFICIENTS: usize = if MAX_POLY_ORDER as usize + 1 > 10 {
    MAX_POLY_ORDER as usize + 1
} else {
    10
};

/// Grid steps on which [`RestoringForce::equilibria`] brackets the roots.
pub const EQUILIBRIUM_GRID: usize = 2000;

/// p(x) = Σₐ cₐ (x − offset)ᵃ: the part of x'' = f(x, x', t) that depends on x alone (the
/// unforced force at rest, per unit mass), about the sensor's offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestoringForce {
    /// cₐ, the coefficient of (x − offset)ᵃ.
    coefficients: [f64; COEFFICIENTS],
    /// The x origin of the model (its sensor offset).
    offset: f64,
}

/// A root of the restoring force.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equilibrium {
    /// Where, in the recording's x.
    pub x: f64,
    /// Whether it is stable (p′ < 0 there: a well's bottom rather than a saddle).
    pub stable: bool,
}

impl RestoringForce {
    /// The x-only terms (the constant and x^a) of `terms`, about `offset`; the others are
    /// left out.
    pub fn from_terms(terms: impl IntoIterator<Item = (Term, f64)>, offset: f64) -> Self {
        let mut coefficients = [0.0; COEFFICIENTS];
        for (term, c) in terms {
            match term {
                Term::Constant => coefficients[0] = c,
                Term::Monomial { px, pv: 0 } if usize::from(px) < COEFFICIENTS => {
                    coefficients[usize::from(px)] = c
                }
                _ => {}
            }
        }
        Self {
            coefficients,
            offset,
        }
    }

    /// A model's restoring force, about its x offset.
    pub fn from_model<T: Real, const P: usize>(model: &Model<T, P>) -> Self {
        Self::from_terms(
            model
                .terms
                .iter()
                .zip(model.coefficients.iter())
                .map(|(&t, c)| (t, c.to_f64())),
            model.offset_x.to_f64(),
        )
    }

    /// cₐ, the coefficient of (x − offset)ᵃ (0 beyond the polynomial).
    pub fn coefficient(&self, a: usize) -> f64 {
        self.coefficients.get(a).copied().unwrap_or(0.0)
    }

    /// The x origin the polynomial is about.
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// Whether any x^a (a ≥ 1) term is there.
    pub fn is_constant(&self) -> bool {
        self.coefficients[1..].iter().all(|c| *c == 0.0)
    }

    /// p(x − offset), by Horner's rule in the model's coordinate `s = x − offset`.
    fn p(&self, s: f64) -> f64 {
        self.coefficients
            .iter()
            .rev()
            .fold(0.0, |acc, &c| acc * s + c)
    }

    /// p′ at `s = x − offset`.
    fn dp(&self, s: f64) -> f64 {
        self.coefficients
            .iter()
            .enumerate()
            .skip(1)
            .rev()
            .fold(0.0, |acc, (a, &c)| acc * s + a as f64 * c)
    }

    /// The force at `x` (the recording's coordinate).
    pub fn force(&self, x: f64) -> f64 {
        self.p(x - self.offset)
    }

    /// dp/dx at `x`: negative at a stable equilibrium.
    pub fn slope(&self, x: f64) -> f64 {
        self.dp(x - self.offset)
    }

    /// The potential U(x) = −∫ p, zero at the offset: wells are its minima.
    pub fn potential(&self, x: f64) -> f64 {
        let s = x - self.offset;
        let integral = self
            .coefficients
            .iter()
            .enumerate()
            .rev()
            .fold(0.0, |acc, (a, &c)| acc * s + c / (a + 1) as f64);
        -integral * s
    }

    /// Linear resonance f = √(−c₁)/2π in Hz, where c₁ < 0 (a single well).
    pub fn resonance_hz(&self) -> Option<f64> {
        let k1 = self.coefficients[1];
        (k1 < 0.0).then(|| libm::sqrt(-k1) / (2.0 * core::f64::consts::PI))
    }

    /// For a double well (c₁ > 0, c₃ < 0): the well positions ±√(−c₁/c₃), in the model's
    /// coordinates (about the offset).
    pub fn wells(&self) -> Option<f64> {
        let (k1, k3) = (self.coefficients[1], self.coefficients[3]);
        (k1 > 0.0 && k3 < 0.0).then(|| libm::sqrt(-k1 / k3))
    }

    /// For a double well: the small-oscillation frequency inside a well, √(2c₁)/2π in Hz.
    pub fn well_resonance_hz(&self) -> Option<f64> {
        self.wells()
            .map(|_| libm::sqrt(2.0 * self.coefficients[1]) / (2.0 * core::f64::consts::PI))
    }

    /// The real roots of p in `[lo, hi]` (the recording's x), left to right, each with its
    /// stability: bracketed on a grid of [`EQUILIBRIUM_GRID`] steps and bisected; a root
    /// within 10⁻⁹ of the range of the offset is the offset. None for a constant force.
    pub fn equilibria(&self, lo: f64, hi: f64, mut each: impl FnMut(Equilibrium)) {
        if self.is_constant() {
            return;
        }
        let (lo, hi) = (lo - self.offset, hi - self.offset);
        bracket_roots(
            |s| self.p(s),
            lo,
            hi,
            EQUILIBRIUM_GRID,
            |root| {
                let root = if libm::fabs(root) < 1e-9 * (hi - lo) {
                    0.0
                } else {
                    root
                };
                each(Equilibrium {
                    x: root + self.offset,
                    stable: self.dp(root) < 0.0,
                });
            },
        );
    }
}

/// The roots of `p` in `[lo, hi]`, left to right: each sign change (or zero) between the
/// points of a grid of `steps` steps, bisected 80 times. The one root finder of the crate
/// (the origin search's equilibria and [`RestoringForce::equilibria`]).
pub(crate) fn bracket_roots(
    p: impl Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    steps: usize,
    mut found: impl FnMut(f64),
) {
    let mut x0 = lo;
    let mut p0 = p(x0);
    for i in 1..=steps {
        let x1 = lo + (hi - lo) * i as f64 / steps as f64;
        let p1 = p(x1);
        if p0 == 0.0 || p0 * p1 < 0.0 {
            let (mut a, mut b, mut pa) = (x0, x1, p0);
            for _ in 0..80 {
                let m = 0.5 * (a + b);
                let pm = p(m);
                let before = (a, b, pa);
                if pa * pm <= 0.0 {
                    b = m;
                } else {
                    a = m;
                    pa = pm;
                }
                // Once an iteration changes nothing, none of the rest would (the same a, b
                // and p(a) give the same step): stop there, with the same root. On the M4F
                // this is soft f64, and the bracket is down to adjacent doubles after ~55.
                if (a, b, pa) == before {
                    break;
                }
            }
            found(0.5 * (a + b));
        }
        x0 = x1;
        p0 = p1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn duffing(k1: f64, k3: f64, offset: f64) -> RestoringForce {
        RestoringForce::from_terms(
            [
                (Term::Monomial { px: 1, pv: 0 }, k1),
                (Term::Monomial { px: 3, pv: 0 }, k3),
            ],
            offset,
        )
    }

    #[test]
    fn a_single_well_has_one_stable_equilibrium_and_a_resonance() {
        let f = duffing(-400.0, -4e4, 0.0);
        let mut found = Vec::new();
        f.equilibria(-1.0, 1.0, |e| found.push(e));
        assert_eq!(
            found,
            [Equilibrium {
                x: 0.0,
                stable: true
            }]
        );
        let hz = f.resonance_hz().expect("single well");
        assert!((hz - 20.0 / (2.0 * core::f64::consts::PI)).abs() < 1e-12);
        assert_eq!(f.wells(), None);
        assert_eq!(f.well_resonance_hz(), None);
    }

    #[test]
    fn a_double_well_has_two_wells_and_a_saddle() {
        let f = duffing(100.0, -1e6, -0.5);
        let w = f.wells().expect("double well");
        assert!((w - 0.01).abs() < 1e-15);
        let mut found = Vec::new();
        f.equilibria(-1.0, 1.0, |e| found.push(e));
        assert_eq!(found.len(), 3);
        assert!((found[0].x + 0.51).abs() < 1e-12 && found[0].stable);
        assert!(found[1].x == -0.5 && !found[1].stable);
        assert!((found[2].x + 0.49).abs() < 1e-12 && found[2].stable);
        let hz = f.well_resonance_hz().expect("in-well");
        assert!((hz - 200f64.sqrt() / (2.0 * core::f64::consts::PI)).abs() < 1e-12);
        // The potential: zero at the saddle, lower in the wells, by c₁²/(4|c₃|).
        assert_eq!(f.potential(-0.5), 0.0);
        let depth = f.potential(-0.49);
        assert!((depth + 100.0 * 100.0 / 4e6).abs() < 1e-15, "{depth}");
        // p = −dU/dx.
        let h = 1e-6;
        let x = -0.493;
        let du = (f.potential(x + h) - f.potential(x - h)) / (2.0 * h);
        assert!((du + f.force(x)).abs() < 1e-6, "{du} {}", f.force(x));
        assert!(f.slope(found[0].x) < 0.0);
    }

    #[test]
    fn a_constant_force_has_no_equilibria() {
        let f = RestoringForce::from_terms([(Term::Constant, 2.0)], 0.0);
        assert!(f.is_constant());
        let mut n = 0;
        f.equilibria(-1.0, 1.0, |_| n += 1);
        assert_eq!(n, 0);
        assert_eq!(f.coefficient(0), 2.0);
        assert_eq!(f.coefficient(99), 0.0);
    }

    #[test]
    fn bracket_roots_finds_each_sign_change() {
        let mut roots = Vec::new();
        bracket_roots(
            |x| (x - 0.25) * (x + 0.5) * (x - 0.9),
            -1.0,
            1.0,
            256,
            |r| roots.push(r),
        );
        assert_eq!(roots.len(), 3);
        for (r, e) in roots.iter().zip([-0.5, 0.25, 0.9]) {
            assert!((r - e).abs() < 1e-12, "{r} {e}");
        }
    }
}
