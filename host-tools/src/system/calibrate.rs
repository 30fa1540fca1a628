//! A chaotic record's one-way x'' calibrated on a statistic of its own record (issue 26).
//!
//! On a chaotic record one free run is one sample of the model's attractor: it cannot follow
//! the record, and the least-squares damping (from differentiated rows) or the energy
//! balance's (measured ⟨f v⟩ / ⟨v²⟩, [`super::with_damping`]) does not make the model's
//! attractor as energetic as the beam's: on BistableX's chaotic records the free runs harvest
//! 9–40 % less than the record they were identified on. The damping is the term that sets the
//! attractor's energy, and the record a model was identified on gives the statistic to set it
//! by: the mean square of the electrical state, ⟨E²⟩ (the harvested power's, load
//! independent). Its electrical equation is the record's own (V' driven by the measured
//! motion predicts the power within 4–8 % on BistableX), while v's mean square carries what a
//! single-mode x'' lacks (the vibrometer's heavy-tailed noise, the beam's higher modes: the
//! measured rms v is 0.40–0.42 m/s where free runs harvesting the recorded power move at
//! 0.30–0.37).
//!
//! [`calibrate_damping`]: the mean ⟨E²⟩ over [`super::simulate::ENSEMBLE_RUNS`] free runs
//! (the starts of `lssi simulate`'s ensemble) over the record, for the damping scaled by the
//! factors of [`FACTORS`] in the direction that closes the gap, the first within
//! [`TOLERANCE`] of the record's taken (the smallest change that does), else the closest.

use rayon::prelude::*;

use super::SystemData;
use super::simulate::{ENSEMBLE_RUNS, SimTerm, SystemSim, ensemble_start, first_state, rms};

/// The relative distance of the free runs' mean ⟨E²⟩ from the record's within which the
/// damping is left as it is or the scan stops: about the spread of the true model's own
/// ensemble about a chaotic record's 40 s (`lssi gen piezo --wells bistable --amplitude 1.65 …
/// 2.55 --x0 0.003 --seed 101 --t-end 80`: −3.5 to +6.2 %, 9 of 10 within 5 %).
pub const TOLERANCE: f64 = 0.05;

/// The damping's factors tried, in order, when the free runs harvest too little (less
/// damping) and too much (more).
pub const FACTORS: ([f64; 8], [f64; 5]) = (
    [0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.25],
    [1.15, 1.3, 1.5, 1.75, 2.0],
);

/// What [`calibrate_damping`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// x'''s damping (v's coefficient) before and after.
    pub before: f64,
    /// After.
    pub after: f64,
    /// The free runs' mean ⟨E²⟩ over the record's, before and after.
    pub ratio_before: f64,
    /// After.
    pub ratio_after: f64,
}

/// The mean over the ensemble's free runs of the electrical state's mean square over the
/// record, `sim` driven by the record's u; `None` when a run diverges.
pub fn ensemble_mean_square(sim: &SystemSim, data: &SystemData) -> Option<f64> {
    let r = &data.recording;
    let u = r.u.clone().unwrap_or_default();
    let start = first_state(data);
    let v_rms = r.v.as_ref().map_or(0.0, |v| rms(v));
    let scale = [rms(&r.x), v_rms];
    let bound = rms(&r.x) + 1.0;
    let slot = 2 * sim.displacements;
    let each: Vec<Option<f64>> = (0..ENSEMBLE_RUNS)
        .into_par_iter()
        .map(|j| {
            let run = sim.run(&r.t, &u, ensemble_start(start, scale, j), bound);
            let e: Vec<f64> = run.iter().map(|q| q[slot]).collect();
            e.iter()
                .all(|q| q.is_finite())
                .then(|| e.iter().map(|q| q * q).sum::<f64>() / e.len().max(1) as f64)
        })
        .collect();
    let each: Vec<f64> = each.into_iter().collect::<Option<_>>()?;
    Some(each.iter().sum::<f64>() / each.len() as f64)
}

/// x'''s damping (the coefficient of v in `sim`'s first equation, negative) scaled so that
/// the free runs' mean ⟨E²⟩ over `data`'s record comes within [`TOLERANCE`] of the record's
/// (see the module's text). `None` when x'' has no damping, the model has no electrical
/// state, two displacements or an algebraic one, or a free run diverges from the start;
/// `Some` with `after == before` when the model is within tolerance already.
pub fn calibrate_damping(sim: &SystemSim, data: &SystemData) -> Option<Calibration> {
    if sim.displacements != 1 || sim.has_algebraic() || sim.electrical.is_empty() {
        return None;
    }
    let e = &data.electrical.first()?.values;
    let recorded = e.iter().map(|q| q * q).sum::<f64>() / e.len().max(1) as f64;
    if !(recorded > 0.0 && recorded.is_finite()) {
        return None;
    }
    let v = SimTerm::Monomial([0, 1, 0, 0, 0, 0]);
    let at = sim.equations.first()?.iter().position(|(t, _)| *t == v)?;
    let before = sim.equations[0][at].1;
    if before >= 0.0 {
        return None;
    }
    let ratio_with = |c: f64| {
        let mut s = sim.clone();
        s.equations[0][at].1 = c;
        ensemble_mean_square(&s, data).map(|m| m / recorded)
    };
    let ratio_before = ratio_with(before)?;
    let off = |ratio: f64| (ratio.ln()).abs();
    let mut best = (before, ratio_before);
    if off(ratio_before) > (1.0 + TOLERANCE).ln() {
        let factors: &[f64] = if ratio_before < 1.0 {
            &FACTORS.0
        } else {
            &FACTORS.1
        };
        for &f in factors {
            let Some(ratio) = ratio_with(f * before) else {
                continue;
            };
            if off(ratio) < off(best.1) {
                best = (f * before, ratio);
            }
            if off(ratio) <= (1.0 + TOLERANCE).ln() {
                break;
            }
        }
    }
    Some(Calibration {
        before,
        after: best.0,
        ratio_before,
        ratio_after: best.1,
    })
}
