//! The harvester in physical terms, for the load R the voltage was recorded across
//! (`lssi identify --load-ohms R`).
//!
//! With the piezoelectric form x'' = … + χ V and V' = −λ V − κ v (per unit mass in the
//! mechanical equation; Erturk–Inman: m x'' + … − θ V = F, C_p V' + V/R + θ x' = 0):
//!
//! - C_p = 1 / (λ R), θ = κ C_p, m = θ / χ (F, C/m = N/V and kg when x is in metres and V
//!   in volts);
//! - the electrical time constant R C_p = 1/λ;
//! - the coupling factor k² = θ² / (C_p k + θ²) = κ χ / (k/m + κ χ), with k/m the linear
//!   stiffness per unit mass of the mechanical equation at its stable equilibrium nearest
//!   the record's mean x (−∂x''/∂x there: ω² for a linear beam, the stiffness in a well
//!   for a bistable one);
//! - the mean power V²/R, measured and predicted (the identified system's free run from
//!   the record's first state, driven by its u or harmonics), over the record's second half
//!   (the free run's transient left out);
//! - the predicted mean power against the load, λ(R′) = 1/(R′ C_p) and κ unchanged, and the
//!   optimal load; and against the forcing frequency (the harmonics' Ω scaled, or u replaced
//!   by a tone of u's RMS at that frequency, from half to one and a half times u's strongest
//!   line); both only when the free run's power at the recorded load is within
//!   [`MAX_POWER_MISS`] of the measured one (else a note gives the miss).
//!
//! With the electromagnetic form (a magnet in a coil of resistance R_c and inductance L
//! across the load R: m x'' + … + Φ i = F, L i' + (R_c + R) i − Φ x' = 0), recorded as the
//! current i, x'' = … + χ i and i' = −λ i − κ v with χ = −Φ/m, λ = (R_c + R)/L, κ = −Φ/L:
//!
//! - the electrical time constant L/(R_c + R) = 1/λ, the coupling factor
//!   k² = Φ²/(k L + Φ²) = κ χ / (k/m + κ χ) and the mean power R i² need no more;
//! - λ alone cannot tell R_c from L, so the inductance L = (R_c + R)/λ, Φ = −κ L, m = −Φ/χ
//!   and the power against the load (λ(R′) = (R_c + R′)/L, κ and χ unchanged) need the coil's
//!   resistance (`--coil-ohms R_c`);
//! - a voltage V = R i across the load with `--coil-ohms` is read as this form, not the
//!   piezoelectric one: i = V/R, so χ_i = R χ, κ_i = κ/R, and at R′ the V equation's χ and κ
//!   scale by R/R′ and R′/R.

use serde::Serialize;

use super::simulate::{SimTerm, SystemSim, first_state, rms};
use super::{SystemData, SystemReport};
use lssi_core::library::Electrical;

/// One point of a sweep.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PowerPoint {
    /// The load, ohms (load sweep) or the forcing frequency, rad/s (frequency sweep).
    pub at: f64,
    /// Predicted mean power, W (absent: the free run diverged).
    pub power_w: Option<f64>,
}

/// Which transducer the electrical equation is read as.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Transducer {
    /// A piezoelectric patch (capacitance C_p) across the load: V' = −V/(R C_p) − κ v.
    Piezoelectric,
    /// A coil (resistance R_c, inductance L) across the load: i' = −(R_c + R)/L i − κ v.
    Electromagnetic,
}

/// The harvester in physical terms (see the module's documentation).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Harvester {
    /// How the electrical equation is read: piezoelectric (a voltage without `--coil-ohms`)
    /// or electromagnetic (a current, or a voltage with `--coil-ohms`).
    pub transducer: Transducer,
    /// The load the voltage was recorded across, ohms.
    pub load_ohms: f64,
    /// The coil's resistance R_c (`--coil-ohms`), ohms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coil_ohms: Option<f64>,
    /// The electrical channel: `V` or `i`.
    pub channel: &'static str,
    /// The displacement the transducer sits on: `x`, or with two displacements the one
    /// whose velocity drives the electrical equation (`x2`, a secondary beam).
    pub displacement: &'static str,
    /// −(the V or i term of V' or i'), 1/s.
    pub lambda: Option<f64>,
    /// −(the v term of V' or i'), V (or A) per unit of v.
    pub kappa: Option<f64>,
    /// The V (or i) term of x'' (per unit mass), units of x'' per volt (or ampere).
    pub chi: Option<f64>,
    /// The linear stiffness per unit mass at the stable equilibrium, 1/s².
    pub stiffness_per_mass: Option<f64>,
    /// The stable equilibrium it is taken at, units of x.
    pub equilibrium: Option<f64>,
    /// Capacitance C_p = 1/(λ R), F.
    pub capacitance_f: Option<f64>,
    /// Coupling θ = κ C_p, C per unit of x.
    pub theta: Option<f64>,
    /// Electromagnetic, with `--coil-ohms`: the coil's inductance L = (R_c + R)/λ, H.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inductance_h: Option<f64>,
    /// Electromagnetic, with `--coil-ohms`: the transduction factor Φ = −κ_i L, N/A (V s/m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phi: Option<f64>,
    /// Mass m = θ/χ, or −Φ/χ_i (kg when x is in metres).
    pub mass: Option<f64>,
    /// Electromechanical coupling factor k² = κχ / (k/m + κχ).
    pub coupling_k2: Option<f64>,
    /// Electrical time constant R C_p, or L/(R_c + R): 1/λ, s.
    pub time_constant_s: Option<f64>,
    /// Measured mean power at the load (V²/R or R i²) over the record's second half, W.
    pub power_measured_w: f64,
    /// Predicted mean power at the load (the free run) over the same span, W.
    pub power_predicted_w: Option<f64>,
    /// Predicted mean power against the load.
    pub load_sweep: Vec<PowerPoint>,
    /// The load of the most power (the sweep's best, refined between its neighbours), ohms.
    pub optimal_load_ohms: Option<f64>,
    /// The predicted mean power at the optimal load, W.
    pub optimal_power_w: Option<f64>,
    /// Predicted mean power against the forcing frequency (rad/s).
    pub frequency_sweep: Vec<PowerPoint>,
    /// An algebraic electrical equation (`V = c v`, a coil of negligible inductance): c, V
    /// (or A) per unit of v.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gain: Option<f64>,
    /// With an algebraic electrical equation: −(the v coefficient of x''), the beam's damping and
    /// the electrical damping together, per unit mass, 1/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub damping_per_mass: Option<f64>,
    /// What could not be computed and why.
    pub notes: Vec<String>,
}

/// The largest relative miss of the measured mean power at the recorded load that the free
/// run may make before the power against load and frequency is withheld.
pub const MAX_POWER_MISS: f64 = 0.25;

/// The free run's relative miss of the measured power (`predicted / measured − 1`) when it is
/// over [`MAX_POWER_MISS`]; `None` when within it (or nothing was predicted).
fn power_miss(measured: f64, predicted: Option<f64>) -> Option<f64> {
    let miss = predicted? / measured - 1.0;
    (!(miss.abs() <= MAX_POWER_MISS) && measured > 0.0).then_some(miss)
}

/// The coefficient of `term` in equation `k` (0 when absent).
fn coefficient(sim: &SystemSim, k: usize, term: SimTerm) -> f64 {
    sim.equations
        .get(k)
        .and_then(|e| e.iter().find(|(t, _)| *t == term))
        .map_or(0.0, |(_, c)| *c)
}

/// Mechanical equation `k`'s part in its own displacement alone, f(x) (state index `s`: 0
/// for x, 4 for x2; any other displacement held at 0), and its stable equilibrium nearest
/// `mean` within ±`span` of it: (x_eq, −f'(x_eq)).
fn stable_equilibrium(
    sim: &SystemSim,
    k: usize,
    s: usize,
    mean: f64,
    span: f64,
) -> Option<(f64, f64)> {
    let f = |x: f64| -> f64 {
        sim.equations[k]
            .iter()
            .filter_map(|(t, c)| match t {
                SimTerm::Constant => Some(*c),
                SimTerm::Monomial(p) if p.iter().enumerate().all(|(j, &q)| j == s || q == 0) => {
                    Some(c * x.powi(i32::from(p[s])))
                }
                _ => None,
            })
            .sum()
    };
    let n = 4000;
    let (lo, hi) = (mean - span, mean + span);
    let step = (hi - lo) / f64::from(n);
    let mut best: Option<(f64, f64)> = None;
    for i in 0..n {
        let (a, b) = (lo + step * f64::from(i), lo + step * f64::from(i + 1));
        let (fa, fb) = (f(a), f(b));
        // Stable: f goes from + to − (a restoring force).
        if fa > 0.0 && fb <= 0.0 {
            let mut x = a + (b - a) * fa / (fa - fb);
            for _ in 0..30 {
                let h = 1e-6 * span.max(1e-300);
                let d = (f(x + h) - f(x - h)) / (2.0 * h);
                if d == 0.0 {
                    break;
                }
                x -= f(x) / d;
            }
            let h = 1e-5 * span.max(1e-300);
            let k = -(f(x + h) - f(x - h)) / (2.0 * h);
            if best.is_none_or(|(b, _)| (x - mean).abs() < (b - mean).abs()) {
                best = Some((x, k));
            }
        }
    }
    best
}

/// The mean of the square of `v` over its second half; `None` when it holds non-finite
/// values.
fn mean_square(v: &[f64]) -> Option<f64> {
    let half = &v[v.len() / 2..];
    half.iter()
        .all(|q| q.is_finite())
        .then(|| half.iter().map(|q| q * q).sum::<f64>() / half.len().max(1) as f64)
}

/// How the electrical channel maps to the power at a load and how the electrical
/// equation changes with the load.
#[derive(Clone, Copy, Debug)]
struct Circuit {
    transducer: Transducer,
    /// The channel is a current (else a voltage across the load).
    current: bool,
    /// The recorded load, ohms.
    ohms: f64,
    /// The coil's resistance, when given.
    coil: Option<f64>,
}

impl Circuit {
    /// The mean power at `load` of a channel whose mean square is `ms`.
    fn power(&self, ms: f64, load: f64) -> f64 {
        if self.current { ms * load } else { ms / load }
    }

    /// The factors (λ, κ, χ) scale by at the load `load`, or `None` when they cannot be
    /// known (an electromagnetic harvester without its coil resistance).
    fn scaling(&self, load: f64) -> Option<(f64, f64, f64)> {
        match self.transducer {
            // λ = 1/(R C_p).
            Transducer::Piezoelectric => Some((self.ohms / load, 1.0, 1.0)),
            Transducer::Electromagnetic => {
                let rc = self.coil?;
                let lambda = (rc + load) / (rc + self.ohms);
                // A voltage V = R i: κ_V = R κ_i, χ_V = χ_i / R.
                if self.current {
                    Some((lambda, 1.0, 1.0))
                } else {
                    Some((lambda, load / self.ohms, self.ohms / load))
                }
            }
        }
    }
}

/// The forcing's angular frequency, rad/s: Ω of the model's harmonics, or with a measured
/// excitation u (the report's Ω is then 1, unused) u's strongest spectral line.
fn forcing_omega(sim: &SystemSim, report: &SystemReport, data: &SystemData) -> f64 {
    let harmonics = sim
        .equations
        .iter()
        .flatten()
        .any(|(t, _)| matches!(t, SimTerm::Sin(_) | SimTerm::Cos(_)));
    if harmonics || !sim.uses_input() {
        return report.omega;
    }
    data.recording
        .u
        .as_deref()
        .and_then(crate::identify::refine::mean_period_samples)
        .filter(|p| *p > 0.0 && report.sample_period > 0.0)
        .map_or(report.omega, |p| {
            std::f64::consts::TAU / (p * report.sample_period)
        })
}

/// The harvester in physical terms for load `ohms` and, for an electromagnetic harvester,
/// the coil's resistance `coil_ohms` (see the module's documentation).
pub fn harvester(
    report: &SystemReport,
    data: &SystemData,
    ohms: f64,
    coil_ohms: Option<f64>,
) -> Harvester {
    let mut h = Harvester {
        transducer: Transducer::Piezoelectric,
        load_ohms: ohms,
        coil_ohms,
        channel: "V",
        displacement: "x",
        lambda: None,
        kappa: None,
        chi: None,
        stiffness_per_mass: None,
        equilibrium: None,
        capacitance_f: None,
        theta: None,
        inductance_h: None,
        phi: None,
        mass: None,
        coupling_k2: None,
        time_constant_s: None,
        power_measured_w: f64::NAN,
        power_predicted_w: None,
        load_sweep: Vec::new(),
        optimal_load_ohms: None,
        optimal_power_w: None,
        frequency_sweep: Vec::new(),
        gain: None,
        damping_per_mass: None,
        notes: Vec::new(),
    };
    let Some(sim) = SystemSim::of_report(report) else {
        h.notes
            .push("the model has a term the simulator does not know".into());
        return h;
    };
    // The voltage across the load if recorded, else the current.
    let Some(kv) = sim
        .electrical
        .iter()
        .position(|e| *e == Electrical::Voltage)
        .or_else(|| {
            sim.electrical
                .iter()
                .position(|e| *e == Electrical::Current)
        })
    else {
        h.notes
            .push("the load analysis needs an electrical channel (V or i)".into());
        return h;
    };
    let current = sim.electrical[kv] == Electrical::Current;
    // The electrical equation, and the displacement the transducer sits on: x, or with two
    // displacements the one whose velocity drives the electrical equation (a two-degree-of-
    // freedom harvester's secondary beam, x2).
    let d = sim.displacements;
    let ke = d + kv;
    let velocity_of = |k: usize| {
        SimTerm::Monomial(if k == 0 {
            [0, 1, 0, 0, 0, 0]
        } else {
            [0, 0, 0, 0, 0, 1]
        })
    };
    let km = (0..d)
        .max_by_key(|&k| coefficient(&sim, ke, velocity_of(k)) != 0.0)
        .unwrap_or(0);
    let (x_name, v_name) = match (d, km) {
        (1, _) => ("x", "v"),
        (_, 0) => ("x1", "v1"),
        _ => ("x2", "v2"),
    };
    let target = format!("{x_name}''");
    h.displacement = x_name;
    let algebraic = sim.algebraic.get(kv) == Some(&true);
    if current || coil_ohms.is_some() || algebraic {
        h.transducer = Transducer::Electromagnetic;
    }
    if current {
        h.channel = "i";
    }
    let circuit = Circuit {
        transducer: h.transducer,
        current,
        ohms,
        coil: coil_ohms,
    };
    let measured = &data.electrical[kv].values;
    h.power_measured_w = mean_square(measured).map_or(f64::NAN, |m| circuit.power(m, ohms));
    let mut powers = [0u8; 6];
    powers[2 + kv] = 1;
    let e_term = SimTerm::Monomial(powers);
    let v_term = velocity_of(km);
    let lambda = -coefficient(&sim, ke, e_term);
    let kappa = -coefficient(&sim, ke, v_term);
    let chi = coefficient(&sim, km, e_term);
    let e = h.channel;
    let r = &data.recording;
    let omega = forcing_omega(&sim, report, data);
    let xs: &[f64] = match (km, &data.second) {
        (1, Some(second)) => &second.x,
        _ => &r.x,
    };
    let mean_x = xs.iter().filter(|q| q.is_finite()).sum::<f64>() / xs.len().max(1) as f64;
    let span = 4.0 * rms(&xs.iter().map(|q| q - mean_x).collect::<Vec<_>>());
    // The physical reading assumes a beam that dissipates: x'' ∋ −c v with c ≥ 0.
    let damping = coefficient(&sim, km, v_term);
    if damping > 0.0 {
        h.notes.push(format!(
            "{target} has a negative damping (+{} {v_name}), which a passive harvester's beam does not have: unless it is self-excited (galloping, flutter), check that {x_name} and {v_name} are relative to the base (an absolute velocity, as a vibrometer measures, is not), and read the constants above as the formulas' values only",
            super::report::number(damping)
        ));
    }
    if d == 2 {
        h.notes.push(format!(
            "with two displacements the beam the transducer sits on is {x_name} ({e}' is driven by {v_name}): its stiffness per mass k/m is −∂{target}/∂{x_name} with the other displacement held, and k² that beam's own coupling factor"
        ));
    }
    let x_index = if km == 0 { 0 } else { 4 };
    if let Some((x_eq, k)) = stable_equilibrium(&sim, km, x_index, mean_x, span) {
        h.equilibrium = Some(x_eq);
        h.stiffness_per_mass = Some(k);
    } else {
        h.notes.push(
            format!("{target} has no stable equilibrium within 4 RMS of the mean {x_name}, so no stiffness and no k²"),
        );
    }
    if algebraic {
        proportional_terms(&mut h, &sim, report, (kv, km, v_term), omega);
    } else if kappa != 0.0 {
        h.kappa = Some(kappa);
    } else {
        h.notes
            .push(format!("{e}' has no {v_name} term (κ = 0), so no coupling"));
    }
    if algebraic {
        // χ, λ and κ belong to an electrical equation with dynamics: see proportional_terms.
    } else if chi != 0.0 {
        h.chi = Some(chi);
    } else {
        h.notes.push(format!(
            "{target} has no {e} term (χ = 0), so no mass and no k²"
        ));
    }
    if let (Some(k), true) = (h.stiffness_per_mass, kappa * chi != 0.0) {
        h.coupling_k2 = Some(kappa * chi / (k + kappa * chi));
    }
    if algebraic {
    } else if lambda > 0.0 {
        h.lambda = Some(lambda);
        h.time_constant_s = Some(1.0 / lambda);
        match (h.transducer, coil_ohms) {
            (Transducer::Piezoelectric, _) => {
                let cp = 1.0 / (lambda * ohms);
                h.capacitance_f = Some(cp);
                if kappa != 0.0 {
                    h.theta = Some(kappa * cp);
                    if chi != 0.0 {
                        h.mass = Some(kappa * cp / chi);
                    }
                }
            }
            (Transducer::Electromagnetic, Some(rc)) => {
                let l = (rc + ohms) / lambda;
                h.inductance_h = Some(l);
                // In amperes: i = V/R.
                let s = if current { 1.0 } else { ohms };
                if kappa != 0.0 {
                    let phi = -kappa / s * l;
                    h.phi = Some(phi);
                    if chi != 0.0 {
                        h.mass = Some(-phi / (chi * s));
                    }
                }
            }
            (Transducer::Electromagnetic, None) => h.notes.push(format!(
                "the inductance L, Φ, the mass and the power against the load need the coil's resistance (--coil-ohms R_c): λ = (R_c + R)/L = {} 1/s cannot tell R_c from L",
                super::report::number(lambda)
            )),
        }
    } else {
        h.notes.push(format!(
            "{e}' has no decay term −λ {e} with λ > 0 (λ = {lambda}), so no time constant and no load sweep"
        ));
    }
    let u: Vec<f64> = r.u.clone().unwrap_or_default();
    let start = first_state(data);
    let bound = rms(&r.x) + rms(measured) + 1.0;
    let power_of = |model: &SystemSim, u: &[f64], load: f64| -> Option<f64> {
        // A small load's fast electrical decay λ′ is stiff for RK4 at the sample period
        // (stable while λ′ h ≲ 2.8): steps of λ′ h ≤ 1.
        let decay = coefficient(model, ke, e_term).abs() * report.sample_period;
        let substeps = (decay.ceil() as usize).clamp(1, 1024);
        let states = model.run_substeps(&r.t, u, start, bound, substeps);
        let v: Vec<f64> = states.iter().map(|s| s[2 + kv]).collect();
        mean_square(&v).map(|m| circuit.power(m, load))
    };
    h.power_predicted_w = power_of(&sim, &u, ohms);
    if h.power_predicted_w.is_none() {
        h.notes.push(
            "the free run at the recorded load diverged, so no power against load or frequency"
                .into(),
        );
        return h;
    }
    // The sweeps are the free run at other loads and frequencies: when it misses the one
    // power the record measures, at the recorded load, they are not to be trusted.
    if let Some(miss) = power_miss(h.power_measured_w, h.power_predicted_w) {
        h.notes.push(format!(
            "no power against load or frequency: at the recorded load the free run's mean power {} W misses the measured {} W by {:+.0} % (more than {:.0} %), so the model's power at other loads and frequencies is not to be trusted",
            super::report::number(h.power_predicted_w.unwrap_or(f64::NAN)),
            super::report::number(h.power_measured_w),
            100.0 * miss,
            100.0 * MAX_POWER_MISS
        ));
        return h;
    }
    // The model at another load: λ, κ and χ scaled as the circuit says.
    let at_load = |load: f64| -> Option<SystemSim> {
        let (fl, fk, fc) = circuit.scaling(load)?;
        let mut model = sim.clone();
        for (t, c) in model.equations[ke].iter_mut() {
            if *t == e_term {
                *c = -lambda * fl;
            } else if *t == v_term {
                *c *= fk;
            }
        }
        for (t, c) in model.equations[km].iter_mut() {
            if *t == e_term {
                *c *= fc;
            }
        }
        Some(model)
    };
    let power_at =
        |load: f64| -> Option<f64> { at_load(load).and_then(|m| power_of(&m, &u, load)) };
    if lambda > 0.0 && circuit.scaling(ohms).is_some() {
        // Centred on the impedance matching the source's at Ω: 1/(Ω C_p), or
        // |R_c + jΩL| for a coil.
        let centre = match (h.transducer, h.capacitance_f, h.inductance_h, coil_ohms) {
            (Transducer::Piezoelectric, Some(cp), _, _) if omega > 0.0 => 1.0 / (omega * cp),
            (Transducer::Electromagnetic, _, Some(l), Some(rc)) => {
                rc.hypot(omega * l).max(1e-3 * ohms)
            }
            _ => ohms,
        };
        let mut loads: Vec<f64> = (-8..=8)
            .map(|k| centre * 10f64.powf(f64::from(k) / 4.0))
            .collect();
        loads.push(ohms);
        loads.sort_by(f64::total_cmp);
        for &load in &loads {
            h.load_sweep.push(PowerPoint {
                at: load,
                power_w: power_at(load),
            });
        }
        let best = h
            .load_sweep
            .iter()
            .enumerate()
            .filter_map(|(i, p)| Some((i, p.power_w?)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|p| p.0);
        // Refined between the grid's neighbours of the best load (golden section on ln R).
        if let Some(i) = best {
            let lo = h.load_sweep[i.saturating_sub(1)].at.ln();
            let hi = h.load_sweep[(i + 1).min(h.load_sweep.len() - 1)].at.ln();
            let at = crate::identify::golden(
                |r| power_at(r.exp()).map_or(f64::INFINITY, |p| -p),
                lo,
                hi,
                12,
            )
            .exp();
            let refined = power_at(at);
            let grid = h.load_sweep[i].power_w;
            if refined.zip(grid).is_some_and(|(r, g)| r >= g) {
                h.optimal_load_ohms = Some(at);
                h.optimal_power_w = refined;
            } else {
                h.optimal_load_ohms = Some(h.load_sweep[i].at);
                h.optimal_power_w = grid;
            }
        }
    }
    // The frequency sweep.
    let has_harmonics = sim
        .equations
        .iter()
        .flatten()
        .any(|(t, _)| matches!(t, SimTerm::Sin(_) | SimTerm::Cos(_)));
    if omega > 0.0 && (has_harmonics || sim.uses_input()) {
        let amplitude = std::f64::consts::SQRT_2 * rms(&u);
        for k in 0..=20 {
            let scale = 0.5 + 0.05 * f64::from(k);
            let w = omega * scale;
            let mut model = sim.clone();
            for (t, _) in model.equations.iter_mut().flatten() {
                match t {
                    SimTerm::Sin(f) | SimTerm::Cos(f) => *f *= scale,
                    _ => {}
                }
            }
            let tone: Vec<f64> = if sim.uses_input() {
                r.t.iter().map(|t| amplitude * (w * t).cos()).collect()
            } else {
                Vec::new()
            };
            h.frequency_sweep.push(PowerPoint {
                at: w,
                power_w: power_of(&model, &tone, ohms),
            });
        }
    } else {
        h.notes
            .push("the model has no forcing term (harmonic or u), so no frequency sweep".into());
    }
    h
}

/// The harvester of an algebraic electrical equation `V = c v` (or `i = c v`): a coil of
/// negligible inductance across the load R, V = R Φ v/(R_c + R) (i = Φ v/(R_c + R)). The
/// gain c; with `--coil-ohms` the transduction factor Φ = c (R_c + R)/R (or c (R_c + R)); the
/// damping per unit mass −(the v coefficient of x''), the beam's and the electrical one together;
/// an upper bound on the time constant from how closely the channel follows v. The power
/// against the load needs the beam's damping parted from the electrical damping Φ²/(m (R_c +
/// R)), which changes with the load and which this record cannot part: a note says so (the
/// frequency sweep, at the recorded load, needs neither).
fn proportional_terms(
    h: &mut Harvester,
    sim: &SystemSim,
    report: &SystemReport,
    (kv, km, v_term): (usize, usize, SimTerm),
    omega: f64,
) {
    let c = coefficient(sim, sim.displacements + kv, v_term);
    let e = h.channel;
    if c != 0.0 {
        h.gain = Some(c);
    }
    let damping = -coefficient(sim, km, v_term);
    if damping != 0.0 {
        h.damping_per_mass = Some(damping);
    }
    match h.coil_ohms {
        Some(rc) if c != 0.0 => {
            let s = if e == "i" { 1.0 } else { h.load_ohms };
            h.phi = Some(c * (rc + h.load_ohms) / s);
        }
        Some(_) => {}
        None => h.notes.push(
            "the transduction factor Φ = c (R_c + R)/R needs the coil's resistance (--coil-ohms R_c)"
                .into(),
        ),
    }
    if let Some(a) = &report.algebraic
        && omega > 0.0
    {
        // A first-order lag τ of v leaves sin φ of the channel, tan φ = Ω τ.
        let sin = (a.nrmse_percent / 100.0).min(0.999);
        let tau = sin / (1.0 - sin * sin).sqrt() / omega;
        h.notes.push(format!(
            "{e} follows v within {:.1} % of its RMS: the electrical time constant (L/(R_c + R) for a coil) is under about {} s at Ω = {} rad/s, negligible",
            a.nrmse_percent,
            super::report::number(tau),
            super::report::number(omega)
        ));
    }
    h.notes.push(format!(
        "no coupling factor k², mass or power against the load: with {e} = c v the coupling's reaction in x'' is a multiple of v, so the record gives the beam's damping and the electrical damping Φ²/(m (R_c + R)) only as their sum (−(the v coefficient of x'')); the electrical part, which changes with the load, is parted by a record at a second load"
    ));
}

impl Harvester {
    /// How the mean power at the load is written: `V²/R` or `R i²`.
    pub fn power_formula(&self) -> &'static str {
        if self.channel == "i" {
            "R i²"
        } else {
            "V²/R"
        }
    }

    /// The text table.
    pub fn render(&self) -> String {
        let n = |v: Option<f64>| v.map_or("-".to_owned(), super::report::number);
        let e = self.channel;
        if self.gain.is_some() || self.damping_per_mass.is_some() {
            return self.render_proportional();
        }
        let x = self.displacement;
        let v = x.replacen('x', "v", 1);
        let mut out = match self.transducer {
            Transducer::Piezoelectric => format!(
                "harvester at the recorded load R = {} Ω (per-unit-mass forms: {x}'' ∋ χ V, V' = −λ V − κ {v}; SI units when {x} is in m and V in V)\n",
                super::report::number(self.load_ohms)
            ),
            Transducer::Electromagnetic => format!(
                "electromagnetic harvester at the recorded load R = {} Ω, {} (per-unit-mass forms: {x}'' ∋ χ {e}, {e}' = −λ {e} − κ {v}; SI units when {x} is in m)\n",
                super::report::number(self.load_ohms),
                self.coil_text()
            ),
        };
        out.push_str(&format!(
            "  λ = {} 1/s   κ = {}   χ = {}   stiffness per mass k/m = {} 1/s² (at {x} = {})\n",
            n(self.lambda),
            n(self.kappa),
            n(self.chi),
            n(self.stiffness_per_mass),
            n(self.equilibrium)
        ));
        match self.transducer {
            Transducer::Piezoelectric => {
                out.push_str(&format!(
                    "  C_p = 1/(λR) = {} F   θ = κ C_p = {} N/V   m = θ/χ = {} kg   time constant R C_p = {} s\n",
                    n(self.capacitance_f),
                    n(self.theta),
                    n(self.mass),
                    n(self.time_constant_s)
                ));
                out.push_str(&format!(
                    "  coupling factor k² = θ²/(C_p k + θ²) = κχ/(k/m + κχ) = {}\n",
                    n(self.coupling_k2)
                ));
            }
            Transducer::Electromagnetic => {
                out.push_str(&format!(
                    "  L = (R_c + R)/λ = {} H   Φ = −κ L = {} N/A   m = −Φ/χ = {} kg   time constant L/(R_c + R) = {} s\n",
                    n(self.inductance_h),
                    n(self.phi),
                    n(self.mass),
                    n(self.time_constant_s)
                ));
                out.push_str(&format!(
                    "  coupling factor k² = Φ²/(k L + Φ²) = κχ/(k/m + κχ) = {}\n",
                    n(self.coupling_k2)
                ));
            }
        }
        out.push_str(&self.render_power());
        out
    }

    /// The coil's resistance as the text tables name it.
    fn coil_text(&self) -> String {
        self.coil_ohms
            .map_or("coil resistance not given".to_owned(), |c| {
                format!("coil R_c = {} Ω", super::report::number(c))
            })
    }

    /// The text table of an algebraic electrical equation's harvester ([`proportional_terms`]).
    fn render_proportional(&self) -> String {
        let n = |v: Option<f64>| v.map_or("-".to_owned(), super::report::number);
        let e = self.channel;
        let mut out = format!(
            "electromagnetic harvester at the recorded load R = {} Ω, {}, of negligible inductance (x'' over the mechanical states, {e} = c v algebraic; SI units when x is in m)\n",
            super::report::number(self.load_ohms),
            self.coil_text()
        );
        out.push_str(&format!(
            "  {e} = c v: c = {} {}   Φ = c (R_c + R){} = {} N/A   stiffness per mass k/m = {} 1/s² (at x = {})   damping per mass, beam + electrical = {} 1/s\n",
            n(self.gain),
            if e == "i" { "A s/m" } else { "V s/m" },
            if e == "i" { "" } else { "/R" },
            n(self.phi),
            n(self.stiffness_per_mass),
            n(self.equilibrium),
            n(self.damping_per_mass)
        ));
        out.push_str(&self.render_power());
        out
    }

    /// The mean power, the sweeps and the notes (the text table's end).
    fn render_power(&self) -> String {
        let mut out = String::new();
        let n = |v: Option<f64>| v.map_or("-".to_owned(), super::report::number);
        out.push_str(&format!(
            "  mean power {} over the second half: measured {} W, predicted {} W (free run from the first row)\n",
            self.power_formula(),
            super::report::number(self.power_measured_w),
            n(self.power_predicted_w)
        ));
        if !self.load_sweep.is_empty() {
            out.push_str("\n  load R (Ω)    predicted mean power (W)\n");
            for p in &self.load_sweep {
                let mark = if p.at == self.load_ohms {
                    "  <- recorded"
                } else {
                    ""
                };
                out.push_str(&format!(
                    "  {:<12.4e}  {}{mark}\n",
                    p.at,
                    p.power_w
                        .map_or("diverged".to_owned(), |w| format!("{w:.4e}"))
                ));
            }
        }
        if !self.frequency_sweep.is_empty() {
            out.push_str(
                "\n  Ω (rad/s)     f (Hz)      predicted mean power (W) at the recorded load\n",
            );
            for p in &self.frequency_sweep {
                out.push_str(&format!(
                    "  {:<12.5}  {:<10.4}  {}\n",
                    p.at,
                    p.at / std::f64::consts::TAU,
                    p.power_w
                        .map_or("diverged".to_owned(), |w| format!("{w:.4e}"))
                ));
            }
        }
        for note in &self.notes {
            out.push_str(&format!("  note: {note}\n"));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::{MAX_POWER_MISS, power_miss};

    #[test]
    fn a_free_run_that_misses_the_measured_power_is_named_with_its_miss() {
        // Within the limit either way: the sweeps are kept.
        assert_eq!(power_miss(1.0, Some(1.0 + 0.9 * MAX_POWER_MISS)), None);
        assert_eq!(power_miss(1.0, Some(1.0 - 0.9 * MAX_POWER_MISS)), None);
        // Beyond it either way: the miss, signed.
        let over = power_miss(2.0, Some(3.62)).unwrap();
        assert!((over - 0.81).abs() < 1e-12, "{over}");
        let under = power_miss(2.0, Some(0.5)).unwrap();
        assert!((under + 0.75).abs() < 1e-12, "{under}");
        // A non-finite prediction is a miss; nothing predicted, or nothing measured, is not.
        assert!(power_miss(1.0, Some(f64::NAN)).is_some());
        assert_eq!(power_miss(1.0, None), None);
        assert_eq!(power_miss(0.0, Some(1.0)), None);
    }
}
