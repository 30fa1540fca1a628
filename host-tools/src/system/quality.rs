//! The quality gate for systems: before a harvester's model is printed, does it explain the
//! recording? The single equation's gate ([`crate::identify::quality`]) in spirit, judged on
//! every recorded state. A failed check withholds the model (exit status 3, "no
//! deterministic dynamics found in FILE: …", one sentence naming the check; `--json` gives
//! `"withheld": true`, the reason, and the model under `"withheld_model"`).
//!
//! 1. **Every channel varies**: x (as the single gate) and each electrical channel; a
//!    constant V carries no electrical dynamics.
//! 2. **Every equation has terms**: an electrical equation with none says the channel is
//!    explained by nothing the library holds (a V of noise).
//! 3. **The free run stays bounded**: the system integrated from the record's first row,
//!    driven by the excitation alone (u or its harmonics), stays finite and within
//!    [`MAX_EXCURSION`] recorded ranges of each recorded state.
//! 4. **The free run follows the held-out part**: over the record's second half (the part
//!    the streaming identifier's A/B split last tested on, and the half the refinement holds
//!    out), windows of [`HORIZON_PERIODS`] periods of the dominant frequency or the forcing,
//!    each simulated from the recorded state at its start (smoothed: a Savitzky–Golay
//!    estimate) and the excitation alone; each recorded state's median window NRMSE must be
//!    at most [`MAX_SHORT_HORIZON_NRMSE`] % of its standard deviation. A V unrelated to the
//!    motion, or of noise, is not followed.
//! 5. **Each equation's terms are not collinear**: its chosen terms' columns on the recording
//!    (low-passed at four times the dominant frequency), each scaled to unit RMS, have a
//!    condition number at most [`MAX_SYSTEM_CONDITION`] when a state term is involved; over
//!    the single equation's [`MAX_CONDITION`] the report warns (their split is poorly
//!    determined). A harvester's x'' holds the electrical state, which in a single-tone
//!    steady state is nearly a combination of x and v: only the transient tells them apart,
//!    and a model with V, x and v conditioned 360–380 predicts the record within 1 % (`lssi
//!    gen piezo --observe v`, `lssi gen electromagnetic --delta 0.01 --observe v`, seed 1:
//!    the seeds the threshold was set on; the figures are on others).
//! 6. **An electrical channel proportional to the velocity** has no dynamics of its own
//!    ([`electrical_follows_velocity`]); else **a harvester's coupling acts both ways**
//!    ([`coupling_both_ways`]), and **its beam's damping is there beside its coupling**
//!    ([`damping_beside_coupling`]), and **its coupling passive** ([`coupling_not_passive`]:
//!    x'' holds χ·E and E' holds κ·v with χ·κ < 0).
//! 7. **Each electrical equation's terms are determined** ([`undetermined_electrical_terms`]):
//!    in an electrical equation holding the excitation's harmonics, refitted on the record
//!    (or as refined), none is within [`MIN_ELECTRICAL_T`] standard errors of 0 (a
//!    spurious V' = … + x + sin + cos, nearly 0 on a single tone's steady state, passes every
//!    other check), and **no electrical equation holds the excitation**
//!    ([`excitation_in_circuit`]: a circuit is driven through the motion).
//! 8. **Every printed term is determined** ([`undetermined_terms`]): a refined model's terms
//!    (± widened to the move between the first half's and the whole record's refinement) and a
//!    streaming model's constant and nonlinear terms at least [`MIN_DETERMINED_T`] of their ±
//!    from 0; a damping/coupling pair that is not is named as the single tone's split.
//! 9. **A model of v integrated is confirmed by refinement** ([`integrated_unconfirmed`]).

use serde::Serialize;

use super::simulate::State;
use super::simulate::{SimTerm, SystemSim, first_state};
use super::{SystemData, SystemReport};
pub use crate::identify::quality::{
    HORIZON_PERIODS, MAX_CONDITION, MAX_EXCURSION, MAX_SHORT_HORIZON_NRMSE, MIN_VARIATION,
};
use lssi_core::derivative::Taps;

/// Largest condition number of an equation's terms (a state term among the collinear ones)
/// before the system is withheld; over [`MAX_CONDITION`] it is a warning.
pub const MAX_SYSTEM_CONDITION: f64 = 1000.0;

/// At most this many windows of the short-horizon check (spread evenly over the half).
const HORIZON_WINDOWS: usize = 48;

/// One recorded state's short-horizon fit.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StateFit {
    /// `x`, `v`, `V` or `i`.
    pub state: String,
    /// The median window's NRMSE, % of the state's standard deviation over the half
    /// (infinite: the simulation diverged in most windows).
    pub nrmse_percent: f64,
}

/// One equation's collinearity.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Conditioning {
    /// The equation's target.
    pub target: String,
    /// The condition number of its terms' columns (absent: fewer than two terms).
    pub condition: Option<f64>,
    /// The terms in the direction of the least singular value (weight ≥ 0.2).
    pub collinear: Vec<String>,
}

/// What the checks measured (the `"quality"` object of `--json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SystemQuality {
    /// Whether the free run from the first row stayed bounded (absent: not run).
    pub stable: Option<bool>,
    /// Each recorded state's short-horizon fit over the record's second half.
    pub short_horizon: Vec<StateFit>,
    /// A window's length, seconds.
    pub horizon_s: f64,
    /// Windows simulated.
    pub windows: usize,
    /// Each equation's collinearity.
    pub conditioning: Vec<Conditioning>,
    /// The reasons the model is withheld (empty: it passed).
    #[serde(skip)]
    pub failures: Vec<String>,
    /// What the report warns of (nearly collinear terms).
    #[serde(skip)]
    pub warnings: Vec<String>,
}

impl SystemQuality {
    /// Whether every check passed.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }
}

/// Smoothed estimates of a recording's states (x, v, e₁, e₂, x2, v2) at any sample: a local
/// polynomial (Savitzky–Golay) fit of a window centred there, chosen as the standard errors'
/// window is ([`lssi_core::tuning::choose_window`] on x, or v when recorded).
pub struct StateEstimator<'a> {
    data: &'a SystemData,
    taps: Box<Taps<f64, { super::WINDOW_CAPACITY }>>,
    len: usize,
}

impl<'a> StateEstimator<'a> {
    /// The estimator for `data` at sample period `dt`; `None` when no window fits.
    pub fn new(data: &'a SystemData, dt: f64) -> Option<Self> {
        let r = &data.recording;
        let (source, order) = match &r.v {
            Some(v) => (v.as_slice(), 1),
            None => (r.x.as_slice(), 2),
        };
        let source: Vec<f64> = source.iter().copied().filter(|q| q.is_finite()).collect();
        let choice = lssi_core::tuning::choose_window::<f64, { super::WINDOW_CAPACITY }>(
            &source,
            order,
            dt,
            source.len(),
        )?;
        let taps = Box::new(Taps::design(choice.window, usize::from(choice.degree), dt).ok()?);
        Some(Self {
            data,
            taps,
            len: choice.window,
        })
    }

    /// Half the window: the first sample with an estimate.
    pub fn margin(&self) -> usize {
        self.len / 2
    }

    /// The states at sample `i` (`None` near the ends or for non-finite values).
    pub fn at(&self, i: usize) -> Option<State> {
        let a = i.checked_sub(self.len / 2)?;
        let b = a + self.len;
        let r = &self.data.recording;
        if b > r.len() {
            return None;
        }
        let x = &r.x[a..b];
        let (xh, vh) = match &r.v {
            Some(v) => (
                self.taps.apply(0, x, &[]),
                self.taps.apply(0, &v[a..b], &[]),
            ),
            None => (self.taps.apply(0, x, &[]), self.taps.apply(1, x, &[])),
        };
        let mut s = [xh, vh, 0.0, 0.0, 0.0, 0.0];
        for (k, e) in self.data.electrical.iter().enumerate().take(2) {
            s[2 + k] = self.taps.apply(0, &e.values[a..b], &[]);
        }
        if let Some(second) = &self.data.second {
            let x2 = &second.x[a..b];
            s[4] = self.taps.apply(0, x2, &[]);
            s[5] = match &second.v {
                Some((_, v2)) => self.taps.apply(0, &v2[a..b], &[]),
                None => self.taps.apply(1, x2, &[]),
            };
        }
        s.iter().all(|q| q.is_finite()).then_some(s)
    }
}

/// The recorded states: (index in the simulated state, name, values).
pub fn recorded_states(data: &SystemData) -> Vec<(usize, String, &[f64])> {
    let r = &data.recording;
    let names = data.mechanical_names();
    let mut out = vec![(0, names[0].to_owned(), r.x.as_slice())];
    if let Some(v) = &r.v {
        out.push((1, names[1].to_owned(), v.as_slice()));
    }
    if let Some(second) = &data.second {
        out.push((4, "x2".to_owned(), second.x.as_slice()));
        if let Some((_, v2)) = &second.v {
            out.push((5, "v2".to_owned(), v2.as_slice()));
        }
    }
    for (k, e) in data.electrical.iter().enumerate().take(2) {
        out.push((2 + k, e.kind.symbol().to_owned(), e.values.as_slice()));
    }
    out
}

/// Mean and standard deviation of the finite values of `s`.
fn mean_sd(s: &[f64]) -> (f64, f64) {
    let f: Vec<f64> = s.iter().copied().filter(|q| q.is_finite()).collect();
    let n = f.len().max(1) as f64;
    let mean = f.iter().sum::<f64>() / n;
    let sd = (f.iter().map(|q| (q - mean).powi(2)).sum::<f64>() / n).sqrt();
    (mean, sd)
}

/// The short-horizon window length in samples: [`HORIZON_PERIODS`] periods of x's dominant
/// frequency, or of the forcing's when the model has harmonics and that is shorter.
pub fn horizon_samples(sim: &SystemSim, data: &SystemData, omega: f64, dt: f64) -> usize {
    let period = crate::identify::refine::mean_period_samples(&data.recording.x).unwrap_or(64.0);
    let forcing = sim
        .equations
        .iter()
        .flatten()
        .filter_map(|(t, c)| match t {
            SimTerm::Sin(w) | SimTerm::Cos(w) if *c != 0.0 && *w > 0.0 => Some(*w),
            _ => None,
        })
        .fold(None, |m: Option<f64>, w| Some(m.map_or(w, |m| m.max(w))))
        .filter(|_| omega > 0.0 && dt > 0.0)
        .map(|w| std::f64::consts::TAU / w / dt);
    // A measured excitation's own period too: a chaotic double well's strongest line is its
    // slow hopping between the wells, over which no model follows it.
    let input = sim
        .uses_input()
        .then_some(data.recording.u.as_deref())
        .flatten()
        .and_then(crate::identify::refine::mean_period_samples);
    let horizon = [forcing, input]
        .into_iter()
        .flatten()
        .fold(period, f64::min);
    ((HORIZON_PERIODS * horizon).round() as usize).max(16)
}

/// Each recorded state's median window NRMSE (%) of `sim` over samples `[from, to)`: windows
/// of `length` samples, each simulated from the smoothed recorded state at its start; and
/// the number of windows. `None` when no window fits.
pub fn window_fits(
    sim: &SystemSim,
    data: &SystemData,
    estimator: &StateEstimator,
    (from, to): (usize, usize),
    length: usize,
) -> Option<(Vec<StateFit>, usize)> {
    let r = &data.recording;
    let from = from.max(estimator.margin());
    if to <= from || to - from < length {
        return None;
    }
    let slots = (to - from) / length;
    let windows = slots.min(HORIZON_WINDOWS);
    let states = recorded_states(data);
    let sds: Vec<f64> = states
        .iter()
        .map(|(_, _, s)| mean_sd(&s[from..to]).1)
        .collect();
    let u = r.u.as_deref().unwrap_or(&[]);
    let bound = 10.0
        * states
            .iter()
            .map(|(_, _, s)| mean_sd(s).1)
            .fold(0.0, f64::max);
    let mut each: Vec<Vec<f64>> = vec![Vec::new(); states.len()];
    for w in 0..windows {
        let a = from + (w * slots / windows) * length;
        let b = a + length;
        let Some(start) = estimator.at(a) else {
            continue;
        };
        let run = sim.run(
            &r.t[a..b],
            if u.is_empty() { u } else { &u[a..b] },
            start,
            bound,
        );
        for (k, (j, _, s)) in states.iter().enumerate() {
            let e: f64 = run
                .iter()
                .zip(&s[a..b])
                .map(|(q, m)| (q[*j] - m).powi(2))
                .sum::<f64>();
            let nrmse = 100.0 * (e / length as f64).sqrt() / sds[k];
            each[k].push(if nrmse.is_finite() {
                nrmse
            } else {
                f64::INFINITY
            });
        }
    }
    if each[0].is_empty() {
        return None;
    }
    let fits = states
        .iter()
        .zip(each)
        .map(|((_, name, _), mut e)| {
            e.sort_by(f64::total_cmp);
            StateFit {
                state: name.clone(),
                nrmse_percent: e[(e.len() - 1) / 2],
            }
        })
        .collect();
    Some((fits, windows))
}

/// Whether the free run from the first row stays finite and within [`MAX_EXCURSION`]
/// recorded ranges of each recorded state about its midpoint.
pub fn free_run_bounded(sim: &SystemSim, data: &SystemData) -> Option<bool> {
    let r = &data.recording;
    let states = recorded_states(data);
    let u = r.u.as_deref().unwrap_or(&[]);
    let run = sim.run(&r.t, u, first_state(data), 0.0);
    let mut ok = true;
    for (j, _, s) in &states {
        let (lo, hi) = s
            .iter()
            .filter(|q| q.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let range = hi - lo;
        if !(range > 0.0) {
            return None;
        }
        let centre = 0.5 * (lo + hi);
        ok &= run
            .iter()
            .all(|q| q[*j].is_finite() && (q[*j] - centre).abs() <= MAX_EXCURSION * range);
    }
    Some(ok)
}

/// `s` low-passed: its transform's bins above `cut` (and their mirror images) zeroed.
fn low_pass(s: &[f64], cut: usize) -> Vec<f64> {
    use rustfft::{FftPlanner, num_complex::Complex};
    let n = s.len();
    let mut buf: Vec<Complex<f64>> = s.iter().map(|v| Complex::new(*v, 0.0)).collect();
    let mut planner = FftPlanner::new();
    planner.plan_fft_forward(n).process(&mut buf);
    for (k, c) in buf.iter_mut().enumerate() {
        if k > cut && k < n - cut {
            *c = Complex::new(0.0, 0.0);
        }
    }
    planner.plan_fft_inverse(n).process(&mut buf);
    buf.iter().map(|c| c.re / n as f64).collect()
}

/// The condition number of the columns (each scaled to unit RMS) and the indices in the
/// direction of the least singular value (weight ≥ 0.2); `None` for a zero column.
pub fn condition(columns: &mut [Vec<f64>]) -> Option<(f64, Vec<usize>)> {
    for c in columns.iter_mut() {
        let rms = (c.iter().map(|a| a * a).sum::<f64>() / c.len().max(1) as f64).sqrt();
        if !(rms > 0.0 && rms.is_finite()) {
            return None;
        }
        c.iter_mut().for_each(|a| *a /= rms);
    }
    let q = columns.len();
    let m = columns.first()?.len() as f64;
    let mut g = nalgebra::DMatrix::<f64>::zeros(q, q);
    for i in 0..q {
        for j in 0..=i {
            let d = columns[i]
                .iter()
                .zip(&columns[j])
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / m;
            g[(i, j)] = d;
            g[(j, i)] = d;
        }
    }
    let eigen = nalgebra::SymmetricEigen::new(g);
    let values = eigen.eigenvalues;
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let least = (0..q).min_by(|&a, &b| values[a].total_cmp(&values[b]))?;
    let lo = values[least].max(hi * 1e-32);
    let involved = (0..q)
        .filter(|&i| eigen.eigenvectors[(i, least)].abs() >= 0.2)
        .collect();
    Some(((hi / lo).sqrt(), involved))
}

/// Each equation's collinearity (see the module's documentation).
pub fn conditioning(
    sim: &SystemSim,
    report: &SystemReport,
    data: &SystemData,
) -> Vec<Conditioning> {
    let r = &data.recording;
    let n = r.len().min(1 << 16);
    let empty = |target: &str| Conditioning {
        target: target.to_owned(),
        condition: None,
        collinear: Vec::new(),
    };
    let targets: Vec<String> = report.equations.iter().map(|e| e.target.clone()).collect();
    let Some(period) = crate::identify::refine::mean_period_samples(&r.x[..n]) else {
        return targets.iter().map(|t| empty(t)).collect();
    };
    let cut = ((4.0 * n as f64 / period).ceil() as usize).max(1);
    let finite = |s: &[f64]| -> Vec<f64> {
        s[..n]
            .iter()
            .map(|q| if q.is_finite() { *q } else { 0.0 })
            .collect()
    };
    let x = low_pass(&finite(&r.x), cut);
    let t = &r.t[..n];
    let v = match &r.v {
        Some(v) => low_pass(&finite(v), cut),
        None => (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                (x[b] - x[a]) / (t[b] - t[a])
            })
            .collect(),
    };
    let e: Vec<Vec<f64>> = data
        .electrical
        .iter()
        .map(|c| low_pass(&finite(&c.values), cut))
        .collect();
    let u = r.u.as_ref().map(|u| low_pass(&finite(u), cut));
    let (x2, v2) = match &data.second {
        Some(second) => {
            let x2 = low_pass(&finite(&second.x), cut);
            let v2 = match &second.v {
                Some((_, v2)) => low_pass(&finite(v2), cut),
                None => (0..n)
                    .map(|i| {
                        let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                        (x2[b] - x2[a]) / (t[b] - t[a])
                    })
                    .collect(),
            };
            (x2, v2)
        }
        None => (vec![0.0; n], vec![0.0; n]),
    };
    let edge = (period.ceil() as usize).min(n / 8);
    let rows = edge..n - edge;
    sim.equations
        .iter()
        .zip(&targets)
        .map(|(eq, target)| {
            let terms: Vec<SimTerm> = eq
                .iter()
                .filter(|(_, c)| *c != 0.0)
                .map(|(t, _)| *t)
                .collect();
            if terms.len() < 2 {
                return empty(target);
            }
            let mut columns: Vec<Vec<f64>> = terms
                .iter()
                .map(|term| {
                    rows.clone()
                        .map(|i| {
                            let s = [
                                x[i],
                                v[i],
                                e.first().map_or(0.0, |c| c[i]),
                                e.get(1).map_or(0.0, |c| c[i]),
                                x2[i],
                                v2[i],
                            ];
                            term.eval(&s, t[i], u.as_ref().map_or(0.0, |u| u[i]))
                        })
                        .collect()
                })
                .collect();
            match condition(&mut columns) {
                Some((c, involved)) => {
                    let dynamics = involved
                        .iter()
                        .any(|&i| matches!(terms[i], SimTerm::Monomial(_)));
                    Conditioning {
                        target: target.clone(),
                        condition: Some(c),
                        collinear: involved
                            .iter()
                            .filter(|_| dynamics)
                            .map(|&i| terms[i].name_in(&sim.electrical, sim.displacements))
                            .collect(),
                    }
                }
                None => Conditioning {
                    target: target.clone(),
                    condition: Some(f64::INFINITY),
                    collinear: terms
                        .iter()
                        .map(|t| t.name_in(&sim.electrical, sim.displacements))
                        .collect(),
                },
            }
        })
        .collect()
}

/// Whether a channel is constant, or constant to within [`MIN_VARIATION`] of its level: the
/// sentence.
fn constant_channel(name: &str, s: &[f64]) -> Option<String> {
    let (mean, sd) = mean_sd(s);
    let first = s.iter().copied().find(|q| q.is_finite())?;
    if sd == 0.0 || s.iter().filter(|q| q.is_finite()).all(|&q| q == first) {
        return Some(format!(
            "the electrical channel {name} is constant ({name} = {first} in every sample): it carries no electrical dynamics"
        ));
    }
    (sd <= MIN_VARIATION * mean.abs()).then(|| {
        format!(
            "the electrical channel {name} is nearly constant (its standard deviation {sd:.2e} is {:.1e} of its level {mean:.6e}): it carries no electrical dynamics",
            sd / mean.abs()
        )
    })
}

/// Runs the checks on the printed system `report` of `data`.
pub fn assess(report: &SystemReport, data: &SystemData) -> SystemQuality {
    let mut q = SystemQuality {
        stable: None,
        short_horizon: Vec::new(),
        horizon_s: 0.0,
        windows: 0,
        conditioning: Vec::new(),
        failures: Vec::new(),
        warnings: Vec::new(),
    };
    if let Some(why) = crate::identify::quality::constant(&data.recording) {
        q.failures.push(why);
        return q;
    }
    if let Some(second) = &data.second
        && let Some(why) = constant_channel(&second.x_name, &second.x)
    {
        q.failures
            .push(why.replace("electrical channel", "displacement").replace(
                "it carries no electrical dynamics",
                "it carries no dynamics",
            ));
        return q;
    }
    for e in &data.electrical {
        if let Some(why) = constant_channel(e.kind.symbol(), &e.values) {
            q.failures.push(why);
            return q;
        }
    }
    for e in &report.equations {
        if e.terms.is_empty() {
            q.failures.push(if e.target.ends_with("''") {
                format!("the {} equation has no terms", e.target)
            } else {
                let s = e.target.trim_end_matches('\'');
                format!(
                    "the {} equation has no terms: nothing in the library (the states, the excitation) explains the recorded {s}",
                    e.target
                )
            });
        }
    }
    if !q.failures.is_empty() {
        return q;
    }
    let Some(sim) = SystemSim::of_report(report) else {
        q.failures
            .push("the model has a term the simulator does not know".into());
        return q;
    };
    q.stable = free_run_bounded(&sim, data);
    if q.stable == Some(false) {
        q.failures.push(format!(
            "the system's free run from the recording's first row, driven by the excitation alone, diverges (leaves {MAX_EXCURSION} times the recorded range of a state)"
        ));
    }
    let dt = report.sample_period;
    let n = data.recording.len();
    if q.stable != Some(false)
        && let Some(estimator) = StateEstimator::new(data, dt)
    {
        let length = horizon_samples(&sim, data, report.omega, dt);
        if let Some((fits, windows)) = window_fits(&sim, data, &estimator, (n / 2, n), length) {
            q.horizon_s = length as f64 * dt;
            q.windows = windows;
            let bad: Vec<&StateFit> = fits
                .iter()
                .filter(|f| !(f.nrmse_percent <= MAX_SHORT_HORIZON_NRMSE))
                .collect();
            if !bad.is_empty() {
                let named: Vec<String> = bad
                    .iter()
                    .map(|f| {
                        if f.nrmse_percent.is_finite() {
                            format!("{} (median NRMSE {:.0} %)", f.state, f.nrmse_percent)
                        } else {
                            format!("{} (the simulation diverges)", f.state)
                        }
                    })
                    .collect();
                q.failures.push(format!(
                    "the system's free run from the excitation alone cannot follow the recorded {} over the record's second half ({windows} windows of {:.3} s, each from the recorded state at its start; at most {MAX_SHORT_HORIZON_NRMSE:.0} %)",
                    named.join(" and "),
                    q.horizon_s
                ));
            }
            q.short_horizon = fits;
        }
    }
    q.conditioning = conditioning(&sim, report, data);
    for c in &q.conditioning {
        if let Some(k) = c.condition
            && k > MAX_CONDITION
            && !c.collinear.is_empty()
        {
            if k > MAX_SYSTEM_CONDITION {
                q.failures.push(format!(
                    "the {} equation's terms {} are collinear on this recording (condition number {k:.2e} of their columns, at most {MAX_SYSTEM_CONDITION:.0}): the data cannot tell them apart",
                    c.target,
                    c.collinear.join(", ")
                ));
            } else {
                q.warnings.push(format!(
                    "the {} equation's terms {} are nearly collinear on this recording (condition number {k:.0} of their columns): the split between them is poorly determined (their standard errors say how poorly)",
                    c.target,
                    c.collinear.join(", ")
                ));
            }
        }
    }
    if report.equations.iter().any(super::report::is_algebraic) {
        // V = c v (super::proportional): no electrical dynamics, no coupling term to check.
    } else if let Some(why) = electrical_follows_velocity(&sim, report, data) {
        q.failures.push(why);
    } else if report.one_way.is_none()
        && let Some(why) = coupling_both_ways(&sim, report, data)
    {
        q.failures.push(why);
    } else if let Some(why) = damping_beside_coupling(&sim, report, data) {
        q.failures.push(why);
    } else if let Some(why) = coupling_not_passive(&sim, report) {
        q.failures.push(why);
    }
    if let Some(why) = undetermined_electrical_terms(&sim, report, data) {
        q.failures.push(why);
    } else if let Some(why) = excitation_in_circuit(&sim, report) {
        q.failures.push(why);
    }
    if q.failures.is_empty()
        && let Some(why) = undetermined_terms(&sim, report)
    {
        q.failures.push(why);
    }
    if q.failures.is_empty()
        && let Some(why) = integrated_unconfirmed(report, data)
    {
        q.failures.push(why);
    }
    q
}

/// A streaming model of v integrated that predicts the held-out half within this NRMSE (%)
/// is confirmed by the prediction itself: `lssi gen piezo --input --observe v` (clean)
/// predicts it at 0.09 % with the true model (χ 2.9 % off), which this check had withheld;
/// the wrong models it was made for predicted at 1.06–1.99 % (seeds 9974, 9910, 9978). Set on
/// those four records, none held out.
pub const CONFIRMED_BY_PREDICTION: f64 = 0.5;

/// See [`assess`]: a model of a recording whose x is v integrated, when refinement on
/// simulation error did not confirm it (refined on the first half, it predicted the second
/// half worse than the streaming model). The integral's offset is not measured (the
/// transient's start and the mean are lost with the drift removal), so the streaming fit's
/// terms in x carry a constant the record cannot place, and its least-squares ± (rows of
/// differentiated data) do not cover it: `scripts/hostile-system.sh` printed x'' with a
/// spurious sin Ωt, a constant, x² or v², or χ 20–90 % off with exit 0 on records of v alone at
/// 0–0.5 % noise (seeds 9910, 9974, 9978), each after refinement was not taken, and gave a
/// true model on none of its 11 records of v alone.
pub fn integrated_unconfirmed(report: &SystemReport, data: &SystemData) -> Option<String> {
    data.x_from_v.as_ref()?;
    let r = report.refinement.as_ref()?;
    (!r.taken && !(r.held_out_streaming_percent < CONFIRMED_BY_PREDICTION)).then(|| {
        format!(
            "x is v integrated (its offset is not measured), and refined on simulation error the model predicted the record's second half no better than the streaming fit (NRMSE {:.2} % against {:.2} %): the streaming model's terms rest on the integral's unmeasured offset, and nothing on the record confirms them (record x beside v)",
            r.held_out_refined_percent, r.held_out_streaming_percent
        )
    })
}

/// See [`assess`]: an electrical equation holding the excitation (sin Ωt, cos Ωt or u). A
/// harvester's circuit is driven by the motion alone (V' = −λ V − κ v, or its current's
/// equation): the excitation reaches it only through the beam. Under a single forcing tone in
/// steady state x, v, the electrical state and the forcing's harmonics move as one sinusoid,
/// so V' = a x + b v + c sin Ωt + d cos Ωt (without V) follows the record as well as the
/// circuit's equation does, and its free run passes every other check
/// (`scripts/hostile-system.sh`, seeds 9907, 9929, 9964: such equations printed with exit 0,
/// x'''s coupling then 1.6–5.7 times off).
pub fn excitation_in_circuit(sim: &SystemSim, report: &SystemReport) -> Option<String> {
    let d = sim.displacements;
    let mut found = Vec::new();
    for (k, eq) in sim.equations.iter().enumerate().skip(d) {
        let driven: Vec<String> = active(eq)
            .iter()
            .filter(|t| matches!(t, SimTerm::Sin(_) | SimTerm::Cos(_) | SimTerm::Input))
            .map(|t| t.name_in(&sim.electrical, d))
            .collect();
        if driven.is_empty() {
            continue;
        }
        let target = report
            .equations
            .get(k)
            .map_or("the electrical equation", |e| e.target.as_str());
        found.push(format!(
            "{target} holds the excitation ({})",
            driven.join(", ")
        ));
    }
    (!found.is_empty()).then(|| {
        format!(
            "{}, which reaches a harvester's circuit only through the motion: under a single forcing tone x, v, the electrical state and the forcing move as one sinusoid, and such an equation follows the record as well as the circuit's own, so neither it nor the coupling in the motion's equation is the harvester's (a transient, a sweep or a broadband excitation separates them)",
            found.join("; ")
        )
    })
}

/// A printed coefficient must be at least this many of its standard errors from 0
/// ([`undetermined_terms`]): within two, the record does not fix even its sign.
pub const MIN_DETERMINED_T: f64 = 2.0;

/// See [`assess`]: any equation's terms whose printed coefficient is within
/// [`MIN_DETERMINED_T`] standard errors of 0 (the report's: the refinement's, widened to the
/// move between the first half's and the whole record's refinement and when refinement did
/// not predict the held-out half better, or the streaming least-squares fit's). Under a
/// single forcing tone in steady state the electrical state is nearly a lagged copy of the
/// velocity, and the beam's damping −c v and the coupling χV trade against each other:
/// `scripts/hostile-system.sh` printed x'' = … (−2.1 ± 9.4) v + (0.15 ± 4.3) V … (seed 9907,
/// truth −1.26 v − 0.25 V) and (−1.08 ± 12) v + (−0.33 ± 5.3) V (seed 9915) with exit 0. The
/// model is withheld, naming the terms and, for a displacement's damping or coupling, the
/// split. A higher threshold (10) did not part right from wrong on the refinement's own ±:
/// right couplings were 8.7 of them from 0 where a wrong one was 8.6 (seed 9706).
pub fn undetermined_terms(sim: &SystemSim, report: &SystemReport) -> Option<String> {
    let d = sim.displacements;
    let mut found = Vec::new();
    let mut split = false;
    // The streaming least-squares ± (rows of differentiated data) are far wider than what the
    // record allows for the states' linear terms (a chaotic record's true coupling i −225 ±
    // 300, a broadband record's true damping 2 of them from 0): of a model not refined, only
    // the constant and the nonlinear terms are held to them (seed 9977: x² 5101 ± 16000
    // beside the truth's x and x³).
    let refined = report.model == "refined";
    for (k, e) in report.equations.iter().enumerate() {
        let weak: Vec<String> = e
            .terms
            .iter()
            .filter(|t| refined || t.term == "1" || t.term.contains(['^', '*']))
            .filter_map(|t| {
                let se = t.se.filter(|s| s.is_finite())?;
                (!(t.coef.abs() >= MIN_DETERMINED_T * se))
                    .then(|| format!("{} ({:.3e} ± {se:.1e})", t.term, t.coef))
            })
            .collect();
        if weak.is_empty() {
            continue;
        }
        // A displacement's damping or coupling among them: the single tone's split.
        if k < d
            && let Some(eq) = sim.equations.get(k)
        {
            split |= active_monomials(eq).into_iter().any(|m| {
                let linear = m.iter().sum::<u8>() == 1;
                let name = SimTerm::Monomial(m).name_in(&sim.electrical, d).to_string();
                let named = weak.iter().any(|w| w.starts_with(&format!("{name} (")));
                named && linear && (m[1] == 1 || m[5] == 1 || m[2] == 1 || m[3] == 1)
            });
        }
        found.push(format!("{}'s {}", e.target, weak.join(", ")));
    }
    if found.is_empty() {
        return None;
    }
    Some(format!(
        "the recording does not determine the terms {} (each within {MIN_DETERMINED_T:.0} standard errors of 0: the record does not fix even its sign){}",
        found.join("; "),
        if split {
            ": the electrical state follows the velocity closely (its equation filters it; under a single forcing tone it is nearly a lagged copy), so the beam's damping and the coupling trade against each other and the record determines mainly their combined effect; a transient, a sweep, a broader excitation or less noise separates them"
        } else {
            ""
        }
    ))
}

/// An equation's active terms (non-zero coefficients).
fn active(eq: &[(SimTerm, f64)]) -> Vec<SimTerm> {
    eq.iter()
        .filter(|(_, c)| *c != 0.0)
        .map(|(t, _)| *t)
        .collect()
}

/// An equation's active monomials, as exponents over the simulator's state (x, v, e₁, e₂,
/// x2, v2).
fn active_monomials(eq: &[(SimTerm, f64)]) -> Vec<[u8; 6]> {
    active(eq)
        .into_iter()
        .filter_map(|t| match t {
            SimTerm::Monomial(m) => Some(m),
            _ => None,
        })
        .collect()
}

/// The state in `slot` of the simulator's state as a term (x, v, e₁, … to the first power).
fn state_term(slot: usize) -> SimTerm {
    let mut state = [0u8; 6];
    state[slot] = 1;
    SimTerm::Monomial(state)
}

/// Equation `m` refitted by least squares with its active terms and `extra`
/// ([`super::report::refit`]): `extra`'s coefficient and standard error.
fn refit_with(
    sim: &SystemSim,
    report: &SystemReport,
    data: &SystemData,
    m: usize,
    extra: SimTerm,
) -> Option<(f64, f64)> {
    let mut terms = active(&sim.equations[m]);
    terms.push(extra);
    let (beta, se) = super::report::refit(report.sample_period, data, m, &terms)?;
    Some((*beta.last()?, *se.last()?))
}

/// An electrical equation's term is undetermined when, refitted by least squares with the
/// equation's other terms on the record ([`super::report::refit`]), or as the report gives it
/// (a refined model's standard errors), it is within this many standard errors of 0.
pub const MIN_ELECTRICAL_T: f64 = 2.0;

/// See [`assess`]: the electrical equations' terms the record does not determine. In a
/// single-tone steady state x, sin Ωt and cos Ωt are one sinusoid, so V' = −λ V − κ v can gain
/// a combination of them that is nearly 0 on the record (only the noise and the transient
/// set it): refitted, each such term is within [`MIN_ELECTRICAL_T`] standard errors of 0,
/// and its free run still follows the record, so only this check tells it from the harvester's
/// equation. The true terms of a harvester's electrical equation are tens to thousands of
/// standard errors from 0 (`lssi gen electromagnetic`/`piezo` at 0–5 % noise).
pub fn undetermined_electrical_terms(
    sim: &SystemSim,
    report: &SystemReport,
    data: &SystemData,
) -> Option<String> {
    let mut found = Vec::new();
    for (k, eq) in sim.equations.iter().enumerate().skip(1).take(2) {
        let terms = active(eq);
        // Only an equation driven by the excitation's harmonics, as a circuit is not (the
        // excitation reaches it through the motion): there the steady state's sinusoid makes
        // the spurious combinations (a real record's small constant or input terms elsewhere
        // are left to the other checks).
        let driven = terms
            .iter()
            .any(|t| matches!(t, SimTerm::Sin(_) | SimTerm::Cos(_)));
        if terms.len() < 2 || !driven {
            continue;
        }
        let Some((beta, se)) = super::report::refit(report.sample_period, data, k, &terms) else {
            continue;
        };
        // The refit's standard errors, and the report's own (the refinement's) where it
        // gives them: a term undetermined by either is.
        let reported = report.equations.get(k);
        let weak: Vec<String> = terms
            .iter()
            .zip(beta.iter().zip(&se))
            .filter_map(|(t, (b, e))| {
                let name = t.name(&sim.electrical);
                let own = reported
                    .and_then(|r| r.terms.iter().find(|q| q.term == name))
                    .and_then(|q| Some((q.coef, q.se?)));
                if !(b.abs() >= MIN_ELECTRICAL_T * e) {
                    Some(format!("{name} ({b:.3e} ± {e:.1e})"))
                } else if let Some((c, s)) = own
                    && !(c.abs() >= MIN_ELECTRICAL_T * s)
                {
                    Some(format!("{name} ({c:.3e} ± {s:.1e})"))
                } else {
                    None
                }
            })
            .collect();
        if !weak.is_empty() {
            let target = report
                .equations
                .get(k)
                .map_or("the electrical equation", |e| e.target.as_str());
            found.push(format!(
                "{target}'s terms {} are each within {MIN_ELECTRICAL_T:.0} standard errors of 0 (refitted on the record, or as refined): the recording does not determine them, so {target} is not the harvester's equation (in a single-tone steady state x, v and the forcing's harmonics move as one sinusoid, and a combination of them nearly 0 on the record fits as well)",
                weak.join(", ")
            ));
        }
    }
    (!found.is_empty()).then(|| found.join("; "))
}

/// A harvester's coupling acts both ways: when an electrical equation depends on the motion
/// (V' = … − κ x') but x'' has no term in that electrical state, and the recording cannot tell
/// that state from the mechanical equation's own terms (their columns with the state's are
/// collinear, condition number over [`MAX_CONDITION`]: a single tone in steady state, where x,
/// v, V and the forcing move as one sinusoid), the reaction χV has gone into the stiffness,
/// damping and forcing, and the printed x'' holds for this forcing alone: the sentence saying so.
/// Below this many standard errors from 0, a refitted coupling is not told apart by the record.
pub const MIN_COUPLING_T: f64 = 3.0;

/// See [`assess`]: the coupling's reaction in x''.
pub fn coupling_both_ways(
    sim: &SystemSim,
    report: &SystemReport,
    data: &SystemData,
) -> Option<String> {
    let d = sim.displacements;
    // Every displacement's equation: a coupling term in any of them answers the check.
    if sim
        .equations
        .iter()
        .take(d)
        .any(|eq| active_monomials(eq).iter().any(|m| m[2] > 0 || m[3] > 0))
    {
        return None;
    }
    for (k, eq) in sim.equations.iter().enumerate().skip(d).take(2) {
        let moved = active_monomials(eq)
            .iter()
            .any(|m| (m[0] > 0 || m[1] > 0 || m[4] > 0 || m[5] > 0) && m[2] == 0 && m[3] == 0);
        if !moved {
            continue;
        }
        let coupling = state_term(2 + k - d);
        let name = coupling.name_in(&sim.electrical, d);
        // The mechanical equation the refitted coupling is strongest in.
        let mut best: Option<(f64, f64, f64, usize)> = None;
        for m in 0..d {
            let Some((b, e)) = refit_with(sim, report, data, m, coupling) else {
                continue;
            };
            let t = b.abs() / e;
            if best.is_none_or(|(bt, ..)| t > bt || !bt.is_finite()) {
                best = Some((t, b, e, m));
            }
        }
        let (t, b, e, m) = best?;
        let mechanical_target = report.equations.get(m).map_or("x''", |e| e.target.as_str());
        let target = report
            .equations
            .get(k)
            .map_or("the electrical equation", |e| e.target.as_str());
        if d > 1 {
            // Two displacements: the coupling may sit in either; name the one refitted.
            return Some(if t < MIN_COUPLING_T || !t.is_finite() {
                format!(
                    "no displacement's equation has a term in {name} although {target} depends on the motion, and this recording cannot tell {name}'s share (refitted with the {mechanical_target} equation's terms, its coefficient is {b:.3e} ± {e:.1e})"
                )
            } else {
                format!(
                    "no displacement's equation has a term in {name} although {target} depends on the motion, and refitted with the {mechanical_target} equation's terms {name}'s coefficient is {b:.3e} ± {e:.1e}, {t:.0} standard errors from 0: the selection dropped the coupling"
                )
            });
        }
        return Some(if t < MIN_COUPLING_T || !t.is_finite() {
            format!(
                "x'' has no term in {name} although {target} depends on the motion: a harvester's coupling acts both ways, and this recording cannot tell {name}'s share from the stiffness, damping and forcing (refitted with the x'' equation's terms, its coefficient is {b:.3e} ± {e:.1e}); the printed x'' holds for this forcing alone (a transient, a sweep or a broadband excitation separates the coupling)"
            )
        } else {
            format!(
                "x'' has no term in {name} although {target} depends on the motion, and refitted with the x'' equation's terms {name}'s coefficient is {b:.3e} ± {e:.1e}, {t:.0} standard errors from 0: the selection dropped the coupling"
            )
        });
    }
    None
}

/// An electrical channel within this NRMSE of a multiple of the velocity is proportional to it:
/// a first-order lag of v by φ leaves sin φ, so 5 % is a lag under 3° (an electrical time
/// constant under 1/20 of the forcing's radian period), where the channel has no dynamics of
/// its own for an equation to identify.
pub const PROPORTIONAL_NRMSE: f64 = 0.05;

/// See [`assess`]: an electrical channel proportional to the first displacement's velocity (an
/// electromagnetic coil of negligible inductance: V = R Φ v / (R + R_c)). Its equation V' = c
/// x'' is a copy of the mechanical one, and x'' cannot part the beam's damping from χV (only
/// their sum acts): the model is withheld, the sentence giving the proportion, which is the
/// electrical equation of such a harvester (`lssi gen electromagnetic --coil negligible`).
pub fn electrical_follows_velocity(
    sim: &SystemSim,
    report: &SystemReport,
    data: &SystemData,
) -> Option<String> {
    let d = sim.displacements;
    for (k, e) in data.electrical.iter().enumerate().take(2) {
        let Some((c, se, nrmse)) =
            super::report::proportional(report.sample_period, data, 2 + k, 1)
        else {
            continue;
        };
        if !(nrmse <= PROPORTIONAL_NRMSE) {
            continue;
        }
        let v = state_term(1).name_in(&sim.electrical, d);
        let name = e.kind.symbol();
        return Some(format!(
            "{name} is proportional to {v} on this recording ({name} = ({c:.4e} ± {se:.1e}) {v}, within {:.1} % of {name}'s RMS), as across a coil of negligible inductance: {name} has no dynamics of its own for an equation {name}' to identify, and x'' cannot part the beam's damping from the coupling (only their sum acts); the harvester's electrical equation is that proportion, and its x'' the single equation `lssi identify` gives without the {name} column",
            100.0 * nrmse
        ));
    }
    None
}

/// The velocity's slot in the simulator's state (x, v, e1, e2, x2, v2) when displacement
/// `m`'s equation holds a coupling (a term in an electrical state) but no damping: a beam's
/// damping is viscous, a term in v itself (x²·v, v³ beside it are nonlinear damping; alone
/// they were the selection's stand-in for a lost −c v). `None` otherwise.
fn coupled_without_damping(sim: &SystemSim, m: usize) -> Option<usize> {
    let velocity = if m == 0 { 1 } else { 5 };
    let live = active_monomials(&sim.equations[m]);
    let coupled = live.iter().any(|q| q[2] > 0 || q[3] > 0);
    let damped = live
        .iter()
        .any(|q| q[velocity] == 1 && q.iter().sum::<u8>() == 1);
    (coupled && !damped).then_some(velocity)
}

/// See [`assess`]: a displacement's equation holding the coupling (V or i) but no linear term
/// in its own velocity. Every harvester's beam loses energy to its own damping beside what the
/// transducer takes, and under a single forcing tone in steady state the electrical state is
/// nearly a lagged copy of v (exactly proportional to v for an electromagnetic coil of
/// negligible inductance), so a selection can trade the damping −c v for an inflated χV: the
/// free run still follows the record, and the coupling printed is several times the true one
/// (`scripts/hostile-system.sh`, seeds 9701–9730: 6 such models printed with exit 0). The
/// equation is refitted with v added ([`super::report::refit`]): v at [`MIN_COUPLING_T`] or
/// more standard errors from 0 means the selection dropped the damping, under it (or no refit:
/// v and the electrical state collinear) that the record cannot part damping from coupling;
/// both withhold the model, naming the refitted coefficient.
pub fn damping_beside_coupling(
    sim: &SystemSim,
    report: &SystemReport,
    data: &SystemData,
) -> Option<String> {
    let d = sim.displacements;
    for m in 0..d {
        let Some(velocity) = coupled_without_damping(sim, m) else {
            continue;
        };
        let v = state_term(velocity).name_in(&sim.electrical, d);
        let target = report.equations.get(m).map_or("x''", |e| e.target.as_str());
        let coupling: Vec<String> = active_monomials(&sim.equations[m])
            .iter()
            .filter(|q| q[2] > 0 || q[3] > 0)
            .map(|q| {
                SimTerm::Monomial(*q)
                    .name_in(&sim.electrical, d)
                    .to_string()
            })
            .collect();
        let refitted = refit_with(sim, report, data, m, state_term(velocity))
            .filter(|(b, e)| b.is_finite() && e.is_finite() && *e > 0.0);
        let coupling = coupling.join(", ");
        return Some(match refitted {
            Some((b, e)) if b.abs() / e >= MIN_COUPLING_T => format!(
                "{target} has the coupling {coupling} but no damping term in {v}, and refitted with {v} added its coefficient is {b:.3e} ± {e:.1e}, {:.0} standard errors from 0: the selection traded the beam's damping for the coupling, whose printed coefficient is then not the harvester's",
                b.abs() / e
            ),
            Some((b, e)) => format!(
                "{target} has the coupling {coupling} but no damping term in {v}, and this recording cannot part the beam's damping from the coupling (refitted with {v} added, its coefficient is {b:.3e} ± {e:.1e}): under a single forcing tone the electrical state moves nearly as a copy of {v}; a transient, a sweep or a broadband excitation separates them"
            ),
            None => format!(
                "{target} has the coupling {coupling} but no damping term in {v}, and this recording cannot part the beam's damping from the coupling ({v} and {coupling} are collinear on it, as for a coil of negligible inductance, whose voltage is proportional to the velocity): only their sum is determined"
            ),
        });
    }
    None
}

/// See [`assess`]: a coupling that would feed the beam energy the circuit never gave. A
/// harvester's transducer (piezo or coil) couples its beam and circuit as a gyrator: x'' holds
/// χ·E and E' holds κ·v with χ·κ < 0 (piezo x'' = … + (θ/m) V, V' = −(θ/C) v − V/(RC); coil
/// x'' = … − (Bl/m) i, i' = (Bl/L) v − (R/L) i), whatever the sensors' polarities (reversing
/// x or E flips both signs). A pair of one sign is not a passive harvester's: the selection
/// traded the coupling for the beam's damping, which a lagged copy of v can stand in for under
/// one forcing tone (`scripts/hostile-system.sh` seed 10126: an inductive coil at 0 % noise
/// printed x'' = … − 2.50 v + 243.5 i with i' = 0.5 v − 200 i, truth −1.26 v − 250 i, exit 0).
/// The sentence, or `None`.
pub fn coupling_not_passive(sim: &SystemSim, report: &SystemReport) -> Option<String> {
    let d = sim.displacements;
    let coef = |eq: &[(SimTerm, f64)], term: SimTerm| {
        eq.iter()
            .find(|(t, c)| *t == term && *c != 0.0)
            .map(|(_, c)| *c)
    };
    for m in 0..d {
        let velocity = if m == 0 { 1 } else { 5 };
        for k in 0..sim.electrical.len().min(2) {
            if sim.algebraic[k] {
                continue;
            }
            let (Some(eq_m), Some(eq_e)) = (sim.equations.get(m), sim.equations.get(d + k)) else {
                continue;
            };
            let (Some(chi), Some(kappa)) = (
                coef(eq_m, state_term(2 + k)),
                coef(eq_e, state_term(velocity)),
            ) else {
                continue;
            };
            if chi * kappa > 0.0 {
                let target = |j: usize| report.equations.get(j).map_or("?", |e| e.target.as_str());
                let e = state_term(2 + k).name_in(&sim.electrical, d);
                let v = state_term(velocity).name_in(&sim.electrical, d);
                return Some(format!(
                    "the coupling is not a passive harvester's: {} has {chi:+.4e} {e} and {} has {kappa:+.4e} {v}, of one sign, so the transducer would feed the beam energy the circuit never gave (a piezo's or a coil's pair has opposite signs, whatever the sensors' polarities): the selection traded the coupling for the beam's damping, which {e}, nearly a lagged copy of {v} under one forcing tone, can stand in for",
                    target(m),
                    target(d + k),
                ));
            }
        }
    }
    None
}

/// The mechanical energy balance of a one-displacement model's x'' over its record: the mean
/// power per unit mass its excitation terms put into the beam (u, sin Ωt, cos Ωt, each times
/// v), and the mean power its coupling terms (those holding an electrical state) take out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnergyBalance {
    /// ⟨f(u, t) v⟩ over the record, W/kg.
    pub input: f64,
    /// −⟨χ(…) E v⟩ over the record, W/kg (positive: the coupling takes energy out).
    pub extraction: f64,
    /// The mechanical energy (½ v² and the potential of x'''s terms in x alone) the beam
    /// lost from the record's start to its end, over its duration, W/kg: a transient's
    /// source (0 in a steady state).
    pub released: f64,
    /// ⟨v²⟩ over the record, m²/s².
    pub mean_square_v: f64,
}

/// A coupling whose extraction is over this many times the excitation's input (and what a
/// transient's decay releases) fails the balance ([`coupling_beyond_input`]). A passive beam's
/// balance is input + release = extraction + its own dissipation, the dissipation ≥ 0, so the
/// extraction is at most what comes in; the
/// margin leaves room for a noisy fit's error. (The measured BistableX chaotic records: 2.5
/// and 4.4; generated harvesters' true models: at most 1 by construction.)
pub const MAX_EXTRACTION_RATIO: f64 = 1.5;

/// [`EnergyBalance`] of `sim`'s x'' on `data`'s record (v measured, or x's central
/// differences); `None` for two displacements, an algebraic electrical channel or a model
/// without a coupling term in x''.
pub fn energy_balance(sim: &SystemSim, data: &SystemData) -> Option<EnergyBalance> {
    if sim.displacements != 1 || sim.has_algebraic() {
        return None;
    }
    let eq = sim.equations.first()?;
    let coupling = |t: &SimTerm| matches!(t, SimTerm::Monomial(m) if m[2] > 0 || m[3] > 0);
    if !eq.iter().any(|(t, c)| *c != 0.0 && coupling(t)) {
        return None;
    }
    balance_of(eq, data)
}

/// [`EnergyBalance`] of the equation `eq` (x'''s terms over the simulator's state) on
/// `data`'s record; see [`energy_balance`].
pub fn balance_of(eq: &[(SimTerm, f64)], data: &SystemData) -> Option<EnergyBalance> {
    let coupling = |t: &SimTerm| matches!(t, SimTerm::Monomial(m) if m[2] > 0 || m[3] > 0);
    let r = &data.recording;
    let n = r.len();
    if n < 3 {
        return None;
    }
    let v: Vec<f64> = match &r.v {
        Some(v) => v.clone(),
        None => (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                (r.x[b] - r.x[a]) / (r.t[b] - r.t[a])
            })
            .collect(),
    };
    let (mut input, mut extraction) = (0.0, 0.0);
    for i in 0..n {
        let mut s: State = [r.x[i], v[i], 0.0, 0.0, 0.0, 0.0];
        for (k, e) in data.electrical.iter().enumerate().take(2) {
            s[2 + k] = e.values[i];
        }
        let u = r.u.as_ref().map_or(0.0, |u| u[i]);
        for (term, c) in eq {
            let p = c * term.eval(&s, r.t[i], u) * v[i];
            match term {
                SimTerm::Input | SimTerm::Sin(_) | SimTerm::Cos(_) => input += p,
                t if coupling(t) => extraction -= p,
                _ => {}
            }
        }
    }
    // The mechanical energy E = ½ v² + U(x), U from x'''s terms in x alone (U' = −their sum),
    // averaged over the first and the last 2 % of the record: what a transient releases.
    let energy = |i: usize| -> f64 {
        let mut e = 0.5 * v[i] * v[i];
        for (term, c) in eq {
            match term {
                SimTerm::Constant => e -= c * r.x[i],
                SimTerm::Monomial(m) if m[1..].iter().all(|&p| p == 0) => {
                    let p = i32::from(m[0]) + 1;
                    e -= c * r.x[i].powi(p) / f64::from(p);
                }
                _ => {}
            }
        }
        e
    };
    let edge = (n / 50).max(1);
    let mean_energy = |range: std::ops::Range<usize>| {
        let k = range.len() as f64;
        range.map(energy).sum::<f64>() / k
    };
    let span = r.t[n - 1] - r.t[0];
    let released = if span > 0.0 {
        (mean_energy(0..edge) - mean_energy(n - edge..n)) / span
    } else {
        0.0
    };
    let (input, extraction) = (input / n as f64, extraction / n as f64);
    let mean_square_v = v.iter().map(|q| q * q).sum::<f64>() / n as f64;
    (input.is_finite() && extraction.is_finite() && released.is_finite()).then_some(EnergyBalance {
        input,
        extraction,
        released,
        mean_square_v,
    })
}

/// The sentence when x'''s coupling takes out more than [`MAX_EXTRACTION_RATIO`] times the
/// power its excitation puts in ([`energy_balance`]): such an x'' balances only through a
/// negative damping (an energy source a passive beam does not have), and χ V is a filter state
/// absorbing dynamics the library lacks, not the transducer's reaction. Measured on BistableX's
/// chaotic records (../shared/data/real/bistablex; docs/figures.md): x'' = … + 3.4 v − 62 V, the
/// coupling taking 2.5–4.4 times the base's input, while the harvested power (1.6 × 10⁻⁸ W) is
/// negligible for the beam. `None` when the balance holds or cannot be made.
pub fn coupling_beyond_input(sim: &SystemSim, data: &SystemData) -> Option<String> {
    let b = energy_balance(sim, data)?;
    let available = b.input.max(0.0) + b.released.max(0.0);
    if !(b.extraction > 0.0 && b.extraction > MAX_EXTRACTION_RATIO * available) {
        return None;
    }
    let ratio = if available > 0.0 {
        format!("{:.1} times", b.extraction / available)
    } else {
        "more than".into()
    };
    Some(format!(
        "x'''s coupling would take {:.3e} W/kg from the beam, {ratio} the {:.3e} W/kg the excitation puts in{}, so x'' balances only through a negative damping: its coupling is not the transducer's reaction (it absorbs dynamics the library lacks), and x'' is the single equation of the mechanical channels without it (one-way coupling: the electrical equation is still driven by the motion)",
        b.extraction,
        b.input.max(0.0),
        if b.released > 0.0 {
            format!(
                " and the {:.3e} W/kg its motion's decay releases",
                b.released
            )
        } else {
            String::new()
        }
    ))
}

/// The refusal of a system that failed the gate: "no deterministic dynamics found in FILE: …".
pub fn refusal(data: &SystemData, quality: &SystemQuality) -> String {
    format!(
        "no deterministic dynamics found in {}: {}.",
        data.recording.path.display(),
        quality.failures.join("; ")
    )
}

/// A term the selection dropped that the physics of a passive transducer requires, found on
/// the printed model `sim`: the coupling (V or i) missing from x'' while an electrical
/// equation depends on the motion and, refitted with x'''s terms, it is [`MIN_COUPLING_T`] or
/// more standard errors from 0 ([`coupling_both_ways`]'s "the selection dropped the
/// coupling"), or the beam's damping v missing beside a coupling while, refitted, v is as far
/// from 0 ([`damping_beside_coupling`]'s "the selection traded the beam's damping"). The
/// equation's index, the term, and the sentence saying what was added (see
/// [`super::repair`]); `None` when neither applies.
pub fn dropped_term(
    sim: &SystemSim,
    report: &SystemReport,
    data: &SystemData,
) -> Option<(usize, SimTerm, String)> {
    if report.equations.iter().any(super::report::is_algebraic) {
        return None;
    }
    let d = sim.displacements;
    let named = |m: usize| report.equations.get(m).map_or("x''", |e| e.target.as_str());
    let coupled_anywhere = sim
        .equations
        .iter()
        .take(d)
        .any(|eq| active_monomials(eq).iter().any(|m| m[2] > 0 || m[3] > 0));
    if !coupled_anywhere {
        for (k, eq) in sim.equations.iter().enumerate().skip(d).take(2) {
            let moved = active_monomials(eq)
                .iter()
                .any(|m| (m[0] > 0 || m[1] > 0 || m[4] > 0 || m[5] > 0) && m[2] == 0 && m[3] == 0);
            if !moved {
                continue;
            }
            let coupling = state_term(2 + k - d);
            let mut best: Option<(f64, f64, f64, usize)> = None;
            for m in 0..d {
                let Some((b, e)) = refit_with(sim, report, data, m, coupling) else {
                    continue;
                };
                let t = b.abs() / e;
                if t.is_finite() && best.is_none_or(|(bt, ..)| t > bt) {
                    best = Some((t, b, e, m));
                }
            }
            let (t, b, e, m) = best?;
            if t < MIN_COUPLING_T {
                return None;
            }
            let name = coupling.name_in(&sim.electrical, d);
            let target = named(k);
            return Some((
                m,
                coupling,
                format!(
                    "the selection dropped the coupling {name} from {} although {target} depends on the motion (refitted with that equation's terms, {name}'s coefficient is {b:.3e} ± {e:.1e}, {t:.0} standard errors from 0): {name} was added and the model refined with it",
                    named(m)
                ),
            ));
        }
    }
    for m in 0..d {
        let Some(velocity) = coupled_without_damping(sim, m) else {
            continue;
        };
        let term = state_term(velocity);
        let (b, e) = refit_with(sim, report, data, m, term)
            .filter(|(b, e)| b.is_finite() && e.is_finite() && *e > 0.0)?;
        let t = b.abs() / e;
        if t < MIN_COUPLING_T {
            return None;
        }
        let v = term.name_in(&sim.electrical, d);
        return Some((
            m,
            term,
            format!(
                "the selection traded the beam's damping {v} in {} for the coupling (refitted with {v} added, its coefficient is {b:.3e} ± {e:.1e}, {t:.0} standard errors from 0): {v} was added and the model refined with it",
                named(m)
            ),
        ));
    }
    None
}
