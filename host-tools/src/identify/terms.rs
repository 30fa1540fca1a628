//! Names of library terms, the columns of Θ(X, t) (eq. 12 and eq. 18), as the whole project
//! spells them: in truth files, identified models and reports.
//!
//! The convention: `1`; monomials with x before v, powers as `^k` and factors joined by `*`
//! (`x`, `v`, `x^2`, `x*v`, `x^2*v`, `v^3`); `u` for the measured excitation; harmonics as
//! `cos(Wt)` / `sin(Wt)` with the angular frequency W in rad/s written with at most six
//! significant digits and no trailing zeros, and `cos(t)` when W is 1.
//!
//! ```
//! use lssi_host::identify::terms::{Harmonic, harmonic_name, monomial_name};
//!
//! assert_eq!(monomial_name(2, 1), "x^2*v");
//! assert_eq!(monomial_name(0, 0), "1");
//! assert_eq!(harmonic_name(Harmonic::Cos, 2.0), "cos(2t)");
//! assert_eq!(harmonic_name(Harmonic::Sin, 21.400000001), "sin(21.4t)");
//! assert_eq!(harmonic_name(Harmonic::Cos, 1.0), "cos(t)");
//! ```

/// Which trigonometric function a harmonic term uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Harmonic {
    /// cos(W t).
    Cos,
    /// sin(W t).
    Sin,
}

/// The name of the monomial x^`x_power` · v^`v_power`, e.g. `x*v^2`; `1` for the constant.
pub fn monomial_name(x_power: u32, v_power: u32) -> String {
    let factor = |symbol: &str, power: u32| match power {
        0 => None,
        1 => Some(symbol.to_owned()),
        p => Some(format!("{symbol}^{p}")),
    };
    let factors: Vec<String> = [factor("x", x_power), factor("v", v_power)]
        .into_iter()
        .flatten()
        .collect();
    if factors.is_empty() {
        "1".to_owned()
    } else {
        factors.join("*")
    }
}

/// Formats an angular frequency (rad/s) with at most six significant digits and no trailing
/// zeros: `2`, `21.4`, `0.125`.
pub fn frequency_text(omega: f64) -> String {
    if !omega.is_finite() {
        return format!("{omega}");
    }
    // Round to six significant digits through the exponent form, then print the shortest
    // decimal that round-trips, which drops the trailing zeros.
    let rounded: f64 = format!("{omega:.5e}").parse().unwrap_or(omega);
    format!("{rounded}")
}

/// The name of the harmonic term cos(W t) or sin(W t) for angular frequency `omega` (rad/s).
pub fn harmonic_name(kind: Harmonic, omega: f64) -> String {
    let function = match kind {
        Harmonic::Cos => "cos",
        Harmonic::Sin => "sin",
    };
    let frequency = frequency_text(omega);
    if frequency == "1" {
        format!("{function}(t)")
    } else {
        format!("{function}({frequency}t)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monomials_follow_the_convention() {
        let names: Vec<String> = [
            (1, 0),
            (0, 1),
            (2, 0),
            (1, 1),
            (0, 2),
            (3, 0),
            (1, 2),
            (0, 3),
        ]
        .into_iter()
        .map(|(p, q)| monomial_name(p, q))
        .collect();
        assert_eq!(
            names,
            ["x", "v", "x^2", "x*v", "v^2", "x^3", "x*v^2", "v^3"]
        );
    }

    #[test]
    fn frequencies_keep_six_significant_digits() {
        assert_eq!(frequency_text(2.0), "2");
        assert_eq!(frequency_text(21.4), "21.4");
        assert_eq!(frequency_text(2.0 * std::f64::consts::PI), "6.28319");
        assert_eq!(frequency_text(1234567.0), "1234570");
        assert_eq!(frequency_text(0.000123456789), "0.000123457");
        assert_eq!(harmonic_name(Harmonic::Sin, 0.9999999), "sin(t)");
    }
}
