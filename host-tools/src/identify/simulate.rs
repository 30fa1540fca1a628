//! Free simulation of an identified model, and the error of that simulation against a record.
//!
//! An identified model x'' = Σ cⱼ θⱼ(x, x', t, u) is integrated from initial conditions with
//! classical RK4 on the recording's own time grid (optionally several equal sub-steps per
//! sample interval). A measured excitation `u` is interpolated linearly between samples, so
//! the half-step stages of RK4 see u at the interval's midpoint. Nothing of the measured
//! response is fed back: this is the *free-run* (simulation) error, the strict test of a
//! model, not the one-step prediction error.
//!
//! The model is in the identifier's coordinates, x − offset_x and x' − offset_v (the sensor
//! offsets it found, [`crate::identify::Report::offsets`]); [`simulate`] integrates there and
//! returns x and v in the recording's coordinates.
//!
//! ```
//! use lssi_core::Term;
//! use lssi_host::identify::simulate::{SimModel, nrmse, simulate};
//!
//! // x'' = -x from x = 1, v = 0 is cos(t).
//! let model = SimModel {
//!     terms: vec![(Term::Monomial { px: 1, pv: 0 }, -1.0)],
//!     omega: 1.0,
//!     offsets: [0.0, 0.0],
//! };
//! let t: Vec<f64> = (0..=1000).map(|k| k as f64 * 0.01).collect();
//! let run = simulate(&model, &t, None, (1.0, 0.0), 1);
//! assert!(run.diverged_at.is_none());
//! let exact: Vec<f64> = t.iter().map(|t| t.cos()).collect();
//! assert!(nrmse(&run.x, &exact).unwrap() < 1e-6);
//! ```

use lssi_core::Term;

use crate::identify::Report;

/// A model to simulate: terms with coefficients in physical units, Ω, and the offsets of the
/// coordinates the model is written in.
#[derive(Clone, Debug, PartialEq)]
pub struct SimModel {
    /// Active terms and their coefficients (terms with a zero coefficient may be left in).
    pub terms: Vec<(Term, f64)>,
    /// Base angular frequency Ω of the sin/cos terms, rad/s.
    pub omega: f64,
    /// Sensor offsets (x, v): the model is in x − offsets[0], x' − offsets[1].
    pub offsets: [f64; 2],
}

impl SimModel {
    /// The model an `identify` run selected.
    pub fn from_report(report: &Report) -> Self {
        Self {
            terms: report.model.clone(),
            omega: report.omega,
            offsets: report.offsets,
        }
    }

    /// Whether the model has a measured-excitation term `u`.
    pub fn uses_input(&self) -> bool {
        self.terms
            .iter()
            .any(|(t, c)| *t == Term::Input && *c != 0.0)
    }

    /// x'' at time `t`, in model coordinates (`x`, `v` already shifted by the offsets).
    pub fn acceleration(&self, t: f64, x: f64, v: f64, u: f64) -> f64 {
        self.terms
            .iter()
            .map(|&(term, c)| c * evaluate(term, self.omega, t, x, v, u))
            .sum()
    }
}

/// The value of one library term.
pub fn evaluate(term: Term, omega: f64, t: f64, x: f64, v: f64, u: f64) -> f64 {
    match term {
        Term::Constant => 1.0,
        Term::Monomial { px, pv } => x.powi(i32::from(px)) * v.powi(i32::from(pv)),
        Term::Sin(k) => (f64::from(k) * omega * t).sin(),
        Term::Cos(k) => (f64::from(k) * omega * t).cos(),
        Term::Input => u,
    }
}

/// A free simulation on a time grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    /// Displacement at each time of the grid, in the recording's coordinates (NaN after a
    /// divergence).
    pub x: Vec<f64>,
    /// Velocity at each time of the grid, in the recording's coordinates (NaN after a
    /// divergence).
    pub v: Vec<f64>,
    /// Index of the first sample at which the state left the finite numbers, if it did.
    pub diverged_at: Option<usize>,
}

/// Integrates `model` over the time grid `t` from `initial` = (x, v) at `t[0]`, both in the
/// recording's coordinates, with `substeps` equal RK4 steps per sample interval (at least 1).
///
/// `u` is the measured excitation on the same grid; it is needed only when the model has a
/// `u` term (without it u reads as 0). Between samples u is interpolated linearly. The output
/// has the length of `t`; once the state is not finite every later sample is NaN and
/// [`Simulation::diverged_at`] says where that began.
pub fn simulate(
    model: &SimModel,
    t: &[f64],
    u: Option<&[f64]>,
    initial: (f64, f64),
    substeps: usize,
) -> Simulation {
    let n = t.len();
    let mut out = Simulation {
        x: Vec::with_capacity(n),
        v: Vec::with_capacity(n),
        diverged_at: None,
    };
    if n == 0 {
        return out;
    }
    let [ox, ov] = model.offsets;
    let substeps = substeps.max(1);
    let input = |i: usize| u.and_then(|u| u.get(i).copied()).unwrap_or(0.0);
    // Model coordinates.
    let (mut x, mut v) = (initial.0 - ox, initial.1 - ov);
    out.x.push(initial.0);
    out.v.push(initial.1);
    for i in 1..n {
        let (t0, t1) = (t[i - 1], t[i]);
        let (u0, u1) = (input(i - 1), input(i));
        let span = t1 - t0;
        if out.diverged_at.is_none() {
            let h = span / substeps as f64;
            // u at a time inside [t0, t1], linearly interpolated.
            let u_at = |s: f64| {
                if span > 0.0 {
                    u0 + (u1 - u0) * ((s - t0) / span)
                } else {
                    u1
                }
            };
            let f = |s: f64, x: f64, v: f64| model.acceleration(s, x, v, u_at(s));
            for k in 0..substeps {
                let s = t0 + k as f64 * h;
                let next = crate::synth::ode::rk4_step(&f, s, crate::synth::ode::State { x, v }, h);
                x = next.x;
                v = next.v;
            }
            if !(x.is_finite() && v.is_finite()) {
                out.diverged_at = Some(i);
            }
        }
        if out.diverged_at.is_some() {
            out.x.push(f64::NAN);
            out.v.push(f64::NAN);
        } else {
            out.x.push(x + ox);
            out.v.push(v + ov);
        }
    }
    out
}

/// Normalised root-mean-square error of `simulated` against `measured`:
/// RMS(simulated − measured) / standard deviation of `measured`.
///
/// 0 is a perfect fit and 1 is no better than predicting the mean of the record. `None` when
/// the lengths differ, the record is shorter than 2 samples or constant, or the simulation is
/// not finite somewhere (a diverged simulation has no error to speak of).
pub fn nrmse(simulated: &[f64], measured: &[f64]) -> Option<f64> {
    let n = measured.len();
    if simulated.len() != n || n < 2 {
        return None;
    }
    let spread = std_dev(measured)?;
    rmse(simulated, measured).map(|e| e / spread)
}

/// Root-mean-square error of `simulated` against `measured` (same units), `None` when the
/// lengths differ, they are empty, or a value is not finite.
pub fn rmse(simulated: &[f64], measured: &[f64]) -> Option<f64> {
    if simulated.len() != measured.len() || measured.is_empty() {
        return None;
    }
    let sum: f64 = simulated
        .iter()
        .zip(measured)
        .map(|(s, m)| (s - m) * (s - m))
        .sum();
    let e = (sum / measured.len() as f64).sqrt();
    e.is_finite().then_some(e)
}

/// Standard deviation of a series (population), `None` if empty, not finite or zero.
fn std_dev(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    let s = var.sqrt();
    (s.is_finite() && s > 0.0).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forced_oscillator_with_input_matches_the_harmonic_forcing() {
        // x'' = -4x - 0.1v + cos(3t) written once with cos(3t) and once with u = cos(3t).
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 0.005).collect();
        let u: Vec<f64> = t.iter().map(|t| (3.0 * t).cos()).collect();
        let base = vec![
            (Term::Monomial { px: 1, pv: 0 }, -4.0),
            (Term::Monomial { px: 0, pv: 1 }, -0.1),
        ];
        let mut harmonic = base.clone();
        harmonic.push((Term::Cos(1), 1.0));
        let mut measured = base;
        measured.push((Term::Input, 1.0));
        let a = SimModel {
            terms: harmonic,
            omega: 3.0,
            offsets: [0.0, 0.0],
        };
        let b = SimModel {
            terms: measured,
            omega: 1.0,
            offsets: [0.0, 0.0],
        };
        assert!(b.uses_input() && !a.uses_input());
        let ra = simulate(&a, &t, None, (0.2, 0.0), 4);
        let rb = simulate(&b, &t, Some(&u), (0.2, 0.0), 4);
        // Linear interpolation of u costs O(h²) per step: small, not zero.
        assert!(nrmse(&rb.x, &ra.x).unwrap() < 1e-3);
    }

    #[test]
    fn offsets_shift_the_coordinates() {
        let model = SimModel {
            terms: vec![(Term::Monomial { px: 1, pv: 0 }, -1.0)],
            omega: 1.0,
            offsets: [5.0, 0.0],
        };
        let t: Vec<f64> = (0..=100).map(|k| k as f64 * 0.01).collect();
        let run = simulate(&model, &t, None, (6.0, 0.0), 1);
        // About x = 5: 5 + cos t.
        assert!((run.x[100] - (5.0 + 1f64.cos())).abs() < 1e-9);
    }

    #[test]
    fn divergence_is_reported_and_nan_filled() {
        let model = SimModel {
            terms: vec![(Term::Monomial { px: 3, pv: 0 }, 1.0)],
            omega: 1.0,
            offsets: [0.0, 0.0],
        };
        let t: Vec<f64> = (0..=1000).map(|k| k as f64 * 0.1).collect();
        let run = simulate(&model, &t, None, (10.0, 0.0), 1);
        let at = run.diverged_at.unwrap();
        assert!(run.x[at].is_nan() && run.x[1000].is_nan());
        assert_eq!(nrmse(&run.x, &t), None);
    }

    #[test]
    fn nrmse_edge_cases() {
        assert_eq!(nrmse(&[1.0, 2.0], &[1.0, 2.0]), Some(0.0));
        assert_eq!(nrmse(&[1.0], &[1.0, 2.0]), None);
        assert_eq!(nrmse(&[1.0, 1.0], &[1.0, 1.0]), None);
        // Predicting the mean scores 1.
        assert!((nrmse(&[1.5, 1.5], &[1.0, 2.0]).unwrap() - 1.0).abs() < 1e-12);
    }
}
