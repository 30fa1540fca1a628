//! One steady orbit explained without forcing: when x repeats one oscillation of steady
//! amplitude (a forced steady state, or a self-excited limit cycle), every point of the orbit
//! is a distinct (x, v), so some x'' = f(x, v) always fits it, and a library's polynomial
//! terms can stand in for the forcing. A model with no forcing term (no u, no harmonic) and
//! terms in v is then a fit of that one orbit, not the harvester's equation: a self-sustained
//! oscillation whose energy the v terms feed and drain.
//!
//! Found on a measured magneto-mechanical beam (FrID's record, its forced first 11 s: 42.05
//! Hz, amplitude steady to 0.2 %): with the forcing's command as u, `lssi identify` printed
//! `x'' = 4.11 + 2.54e5 x − 3.61 v − 2.0e8 x² − 1007 v² − 6.4e12 x³ − 8.5e7 x·v² + 2584 v³`
//! with exit 0 (a double well at ±2.0e-4 for a single-well beam of 37 Hz, u dropped); without
//! u, the harmonics dropped by refinement, an autonomous model again. A conservative model
//! (terms in x alone) is let through: an undamped free oscillation is such an orbit, and its
//! model keeps its energy without any term feeding it.

use crate::identify::Report;
use crate::identify::stretch;
use crate::recording::Recording;

/// Cycles of x needed to call its oscillation steady.
pub const MIN_CYCLES: usize = 10;

/// The largest coefficient of variation of x's RMS cycle by cycle for one steady orbit: a
/// forced steady state or a limit cycle holds it to a fraction of a percent (FrID's beam:
/// 0.2 %); a ringdown, a transient, a random or chaotic response move it by tens of percent.
pub const MAX_CYCLE_SPREAD: f64 = 0.02;

/// x's cycles on the record's longest clean stretch: the number of whole cycles (between
/// upward crossings of its mean, with a hysteresis of 0.3 RMS against noise), their mean
/// frequency (Hz) and the spread of their RMS (its coefficient of variation, or the change
/// of its mean from the first quarter of the cycles to the last, whichever is larger).
/// `None` with fewer than
/// [`MIN_CYCLES`] cycles.
pub fn cycles(recording: &Recording) -> Option<(usize, f64, f64)> {
    let stretch = stretch::longest(recording)?;
    let x = recording.x.get(stretch.clone())?;
    let t = recording.t.get(stretch)?;
    let mean = stretch::mean(x);
    let rms = stretch::rms(x);
    if !(rms > 0.0) {
        return None;
    }
    let h = 0.3 * rms;
    let mut up = Vec::new();
    let mut below = false;
    for (i, v) in x.iter().enumerate() {
        let d = v - mean;
        if d < -h {
            below = true;
        } else if below && d > h {
            below = false;
            up.push(i);
        }
    }
    if up.len() < MIN_CYCLES + 1 {
        return None;
    }
    let per_cycle = stretch::cycles_rms(x, &up, mean);
    let m = stretch::mean(&per_cycle);
    let sd = stretch::rms(&per_cycle);
    // A slow ringdown or growth is not one orbit however small its spread: the mean RMS of
    // the last quarter of the cycles against the first's counts as a spread too.
    let q = per_cycle.len() / 4;
    let trend = (stretch::mean(&per_cycle[per_cycle.len() - q..]) - stretch::mean(&per_cycle[..q]))
        .abs()
        / m;
    let (first, last) = (*up.first()?, *up.last()?);
    let seconds = t.get(last)? - t.get(first)?;
    let hz = per_cycle.len() as f64 / seconds;
    (m > 0.0 && hz.is_finite()).then_some((per_cycle.len(), hz, (sd / m).max(trend)))
}

/// Whether the printed model explains one steady orbit of x with no forcing term and terms
/// in v (module docs). The sentence, or `None`.
pub fn unforced_orbit(recording: &Recording, report: &Report) -> Option<String> {
    use lssi_core::Term;
    let active = || report.model.iter().filter(|(_, c)| *c != 0.0);
    let driven = active().any(|(t, _)| matches!(t, Term::Sin(_) | Term::Cos(_) | Term::Input));
    let in_v = active().any(|(t, _)| matches!(t, Term::Monomial { pv, .. } if *pv > 0));
    if driven || !in_v {
        return None;
    }
    steady_orbit(recording)
}

/// The sentence for one steady orbit of x that the model explains with no forcing term
/// (when x's cycles spread at most [`MAX_CYCLE_SPREAD`]), or `None`.
fn steady_orbit(recording: &Recording) -> Option<String> {
    let (count, hz, spread) = cycles(recording)?;
    (spread <= MAX_CYCLE_SPREAD).then(|| {
        format!(
            "x repeats one steady oscillation ({count} cycles at {hz:.4} Hz, their RMS steady to {:.2} %) and the model explains it with no forcing term{}: one steady orbit cannot tell a restoring force from a forcing or from terms that sustain the orbit by themselves (a self-excited oscillator), so this is a fit of the orbit, not the harvester's equation (if it is forced, give the excitation as u and record its transient or decay as well, or several forcing amplitudes)",
            100.0 * spread,
            if recording.u.is_some() {
                " (u was dropped)"
            } else {
                " (no harmonic of Ω)"
            }
        )
    })
}

/// Whether x keeps oscillating over the record (its last quarter's RMS at least
/// [`crate::identify::sweep::KEEPS`] of its first's) while the model has no forcing term and
/// its free run cannot follow it (`follows`, [`crate::identify::sweep::model_follows`]), and
/// no u column was given: the record is driven by a forcing it does not hold, random or
/// broadband (ambient vibration), which no autonomous model and no harmonic of one Ω stands
/// for. Found on a bistable beam under white base acceleration (u not given): `x'' = −7.81e8
/// x^3` was printed with exit 0 (truth 332 x − 0.40 v − 7.96e8 x³ + u). The sentence, or
/// `None`.
pub fn unrecorded_forcing(
    recording: &Recording,
    report: &Report,
    follows: impl FnOnce() -> Option<bool>,
) -> Option<String> {
    use lssi_core::Term;
    let driven = report
        .model
        .iter()
        .any(|(t, c)| *c != 0.0 && matches!(t, Term::Sin(_) | Term::Cos(_) | Term::Input));
    // A conservative model (no term in v) keeps its energy: a record whose oscillation keeps
    // more than [`crate::identify::quality::DECAYS`] allows a decay to lose is not one it
    // can die out with ([`crate::identify::quality::undamped_decay`] names the rest). Between
    // the two (0.8–0.9 of the first quarter's RMS kept) neither check named a bistable beam
    // under white base acceleration, printed as `x'' = −7.88e8 x^3` with exit 0 once the
    // sweep detector no longer called it a chirp.
    let conservative = !report
        .model
        .iter()
        .any(|(t, c)| *c != 0.0 && matches!(t, Term::Monomial { pv, .. } if *pv > 0));
    let keeps = if conservative {
        crate::identify::stretch::quarters_rms(recording)
            .is_some_and(|(first, last)| last * crate::identify::quality::DECAYS >= first)
    } else {
        crate::identify::sweep::keeps_amplitude(recording)
    };
    if recording.u.is_some()
        || driven
        || report.model.iter().all(|(_, c)| *c == 0.0)
        || !keeps
        || follows() != Some(false)
    {
        return None;
    }
    steady_orbit(recording).or_else(|| Some(
        "x keeps oscillating over the record but the model, with no forcing term, cannot follow it from its own state (its free run parts from the recording): the motion is driven by a forcing the recording does not hold and that is not one steady tone (swept, random or broadband vibration), so no model without it stands for the harvester; give the excitation's column as u (--u-col)".to_owned(),
    ))
}

/// How far (a factor either way) the RMS of a free run's last half may be from x's before
/// the run is on another orbit than the recorded one: a model that reaches the recorded orbit
/// matches its RMS to its coefficients' error, whatever its phase; a forced run in a well
/// beside a cross-well orbit, or on the other branch of a hardening resonance, is off by
/// several times.
pub const ORBIT_RMS_FACTOR: f64 = 2.0;

/// Whether x repeats one steady oscillation (as [`orbit_not_followed`]) while the printed
/// model, run over the record from the state x shows at its start, settles on another orbit
/// (its last half's RMS off x's by more than [`ORBIT_RMS_FACTOR`]), or, on any record,
/// diverges: the harvester reached the recorded orbit from there, so its equation does too.
/// Fresh hostile seed 20925 (a hardening single well forced hard through u, 5 % noise, 10-bit
/// ADC, 9.3 samples a period at the top of its band): `+1491 x − 4.16e8 x³ − 2.18e4 x²·v −
/// 9.07e4 x·v² + 0.0169 u` (a double well entrained by a weak forcing; truth −1029 x − 4.0 v −
/// 2.6e8 x³ + u) followed the held-out half from a state fitted there (6.5 %) but from the
/// record's start fell into a well. The sentence, or `None`.
pub fn orbit_not_reached(
    recording: &Recording,
    check: &crate::identify::refine::Check,
) -> Option<String> {
    let (simulated, recorded) = check.from_start?;
    if std::env::var_os("LSSI_REFINE_DEBUG").is_some() {
        eprintln!(
            "lssi: orbit from the start: run RMS {simulated:.4e}, x's {recorded:.4e}; cycles {:?}",
            cycles(recording)
        );
    }
    let ratio = simulated / recorded;
    if (1.0 / ORBIT_RMS_FACTOR..=ORBIT_RMS_FACTOR).contains(&ratio) {
        return None;
    }
    if !simulated.is_finite() {
        // Whatever the record does (a transient, a chaotic motion), the harvester stayed
        // within its range from that start, and so does its equation.
        return Some(format!(
            "the model's free run over the record from the state x shows at its start diverges (it goes {} of x's ranges beyond them), where the harvester stayed within them: this model is not its equation",
            crate::identify::refine::ESCAPE_RANGES
        ));
    }
    let (count, hz, spread) = cycles(recording)?;
    (spread <= MAX_CYCLE_SPREAD).then(|| {
        format!(
            "x repeats one steady oscillation ({count} cycles at {hz:.4} Hz, their RMS steady to {:.2} %) but the model's free run over the record from the state x shows at its start settles on an oscillation of RMS {simulated:.4e} where x's is {recorded:.4e}: the harvester reached the orbit it was recorded on from there, so this model, which holds another, is not its equation",
            100.0 * spread
        )
    })
}

/// A free run's NRMSE (%) beyond which it is not the recorded steady orbit with its phase
/// drifted: two sinusoids of one amplitude out of phase differ by √2 of it (141 %), so a model
/// that settles onto the recorded orbit stays under this however its phase drifts.
pub const ORBIT_FREE_RUN_PERCENT: f64 = 150.0;

/// How closely (NRMSE, %) a forced model's free run must follow a steady orbit locked to its
/// forcing ([`orbit_not_followed`]): as a model must follow a whole record to explain a
/// drifting line (`sweep::FOLLOWS_PERCENT`).
pub const LOCKED_FREE_RUN_PERCENT: f64 = 30.0;

/// How close (a fraction) x's cycles' frequency must be to the model's forcing frequency for
/// the orbit to count as locked to it ([`orbit_not_followed`]).
pub const LOCKED_TOLERANCE: f64 = 0.02;

/// Whether x repeats one steady oscillation (its cycles' RMS steady to
/// [`MAX_CYCLE_SPREAD`]) while the printed model's free run over the held-out half misses it
/// by more than any phase drift can ([`ORBIT_FREE_RUN_PERCENT`]): a model of the harvester
/// settles onto the orbit it was recorded on (a chaotic or transient record has no steady
/// cycles and is not judged). Fresh hostile seed 20610 (a hardening single well forced at
/// 10.83 rad/s, 5 % noise, x and v): Ω was taken at the third harmonic, 32.49 rad/s, and
/// `0.060 v − 1.41e9 x³ − 0.0069 cos(32.49t)` (a negative damping) was printed with exit 0,
/// its free run at 1032 %. The sentence, or `None`.
///
/// When x's cycles come at the model's own forcing frequency (within [`LOCKED_TOLERANCE`]),
/// the orbit is locked to the forcing and its phase cannot drift: the free run must then
/// follow it within [`LOCKED_FREE_RUN_PERCENT`]. Hostile 20925's harvester without u (noise
/// seed 1: 133 s of one orbit after half a second of transient, on which x, x³, x·v² and v,
/// x²·v are nearly collinear) printed `−1.04 v − 3.29e8 x³ − 5.2e5 x²·v − 5.6e4 x·v² + 2.40
/// cos(25.08t)` for `−1029 x − 4.0 v − 2.6e8 x³ + 3.81 cos`, its free run parting from the
/// record by 55 %; the true models of the hostile sets whose free run parted by 30 % or more
/// had no steady cycles (spread 0.055–0.145).
pub fn orbit_not_followed(
    recording: &Recording,
    check: &crate::identify::refine::Check,
) -> Option<String> {
    let free = check.free_run?.nrmse_percent;
    if !(free > LOCKED_FREE_RUN_PERCENT) {
        return None;
    }
    let (count, hz, spread) = cycles(recording)?;
    let forced = recording.u.is_none()
        && check.model.terms.iter().any(|(t, c)| {
            *c != 0.0 && matches!(t, lssi_core::Term::Sin(_) | lssi_core::Term::Cos(_))
        });
    let omega_hz = check.model.omega / (2.0 * std::f64::consts::PI);
    let locked = forced && (hz / omega_hz - 1.0).abs() <= LOCKED_TOLERANCE;
    if !(locked || free > ORBIT_FREE_RUN_PERCENT) {
        return None;
    }
    (spread <= MAX_CYCLE_SPREAD).then(|| {
        if locked && free <= ORBIT_FREE_RUN_PERCENT {
            return format!(
                "x repeats one steady oscillation at the forcing's frequency ({count} cycles at {hz:.4} Hz, their RMS steady to {:.2} %), locked to the forcing so that its phase cannot drift, but the model's free run over the held-out half parts from it by an NRMSE of {free:.0} % (at most {LOCKED_FREE_RUN_PERCENT:.0} %): the model holds another orbit, so it is not this harvester's equation (one steady orbit does not tell the terms apart: a record with more of its transient, or with larger swings)",
                100.0 * spread
            );
        }
        format!(
            "x repeats one steady oscillation ({count} cycles at {hz:.4} Hz, their RMS steady to {:.2} %) but the model's free run over the held-out half misses it by an NRMSE of {free:.0} %, more than any drift of its phase could (141 %): a model of this harvester settles onto the orbit it was recorded on, so this one is not its equation (check Ω against the forcing's frequency, or give --omega)",
            100.0 * spread
        )
    })
}
