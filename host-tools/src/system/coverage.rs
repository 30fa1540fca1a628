//! Standard errors of a refined system that cover its coefficients' spread, and the coupling
//! they must then determine (issue 25: "± that cover the truth"; issue 26: the coupling a
//! harvester designer asks for first).
//!
//! The refinement's own ± (the curvature of its cost at its minimum, σ² [S⁻¹]ⱼⱼ) assume
//! independent residuals; a simulation fit's are not (a measured excitation's noise drives
//! the simulation, segments' fitted states absorb part of the error), and at 5 % noise its
//! estimates spread over noise draws about twice those ± (`scripts/hostile-system.sh`, seeds
//! 9958 and 9979: the coupling V in x'' 22 % and 17 % off at 2.9 and 1.8 of its ±).
//! [`super::widen_by_half`] took each term's ± to at least its own move between the first
//! half's and the whole record's refinement: one draw of |N(0, σ)| per term, under σ half of
//! the time, so it rarely widened what it should.
//!
//! Pooled over every refined term instead: for nested fits the move between the first half's
//! and the whole record's coefficient has about the whole record's variance, so the RMS over
//! the terms of move ÷ ± estimates how far the refinement's ± fall short of the spread ([`split_factor`],
//! a χ with as many degrees of freedom as terms); every ± is scaled by it when it is over 1.
//! On seeds 9958 and 9979 it is under 1 (the split moved the terms less than their ±): their
//! couplings' ± stay too small, and what makes them so is not found yet.

use super::SystemReport;
use super::simulate::{SimTerm, SystemSim};

/// The RMS over `report`'s terms of (whole record's coefficient − first half's) ÷ ±; `None`
/// with fewer than three terms to pool or no ±.
pub fn split_factor(report: &SystemReport, first_half: &[Vec<f64>]) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0usize;
    for (e, half) in report.equations.iter().zip(first_half) {
        for (t, &c1) in e.terms.iter().zip(half) {
            let Some(se) = t.se.filter(|s| s.is_finite() && *s > 0.0) else {
                continue;
            };
            let z = (t.coef - c1) / se;
            if z.is_finite() {
                sum += z * z;
                n += 1;
            }
        }
    }
    (n >= 3).then(|| (sum / n as f64).sqrt())
}

/// Scales every term's ± by [`split_factor`] when that is over 1, and says so.
pub fn scale_by_split(report: &mut SystemReport, first_half: &[Vec<f64>]) {
    let Some(k) = split_factor(report, first_half).filter(|k| *k > 1.0) else {
        return;
    };
    for e in &mut report.equations {
        for t in &mut e.terms {
            if let Some(se) = &mut t.se {
                *se *= k;
            }
        }
    }
    report.standard_errors = format!(
        "{}; scaled by {k:.2}, the RMS over the terms of their move between the first half's and the whole record's refinement in their own ±",
        report.standard_errors
    );
}

/// A refined coupling (an electrical state's linear term in a displacement's equation) must
/// be at least this many of its ± from 0: its ± at most 1/7 of it. Set on
/// `scripts/hostile-system.sh`'s seed 9976 (a coupling 14 % off, 4.8 of its ± from 0, beside a
/// spurious constant) and 10001–10040 (true couplings 15.3–156 of their ± from 0). It does
/// not withhold seeds 9958 and 9979 (couplings 22 % and 17 % off, 10.0 and 11.9 of their ±
/// from 0, whose pooled [`split_factor`] is under 1, so their ± are not scaled): still printed.
pub const MIN_COUPLING_PRECISION_T: f64 = 7.0;

/// A refined model whose coupling in x'' the record determines only loosely (within
/// [`MIN_COUPLING_PRECISION_T`] of its ±): the sentence saying so.
pub fn coupling_imprecise(sim: &SystemSim, report: &SystemReport) -> Option<String> {
    if report.model != "refined" {
        return None;
    }
    let d = sim.displacements;
    let mut found = Vec::new();
    for (k, e) in report.equations.iter().enumerate().take(d) {
        let Some(eq) = sim.equations.get(k) else {
            continue;
        };
        for ((term, _), t) in eq.iter().zip(&e.terms) {
            let SimTerm::Monomial(m) = term else {
                continue;
            };
            let coupling = m.iter().sum::<u8>() == 1 && (m[2] == 1 || m[3] == 1);
            let Some(se) = t.se.filter(|s| s.is_finite() && *s > 0.0) else {
                continue;
            };
            if coupling && t.coef != 0.0 && !(t.coef.abs() >= MIN_COUPLING_PRECISION_T * se) {
                found.push(format!(
                    "{}'s {} ({:.3e} ± {se:.1e}, ± {:.0} % of it)",
                    e.target,
                    t.term,
                    t.coef,
                    100.0 * se / t.coef.abs()
                ));
            }
        }
    }
    (!found.is_empty()).then(|| {
        format!(
            "the recording determines the coupling {} only loosely (its ± over 1/{MIN_COUPLING_PRECISION_T:.0} of it): noise of this level over this record leaves the coupling's value to within that ±, and a harvester's model rests on it (a longer record, less noise or a transient determines it)",
            found.join(", ")
        )
    })
}
