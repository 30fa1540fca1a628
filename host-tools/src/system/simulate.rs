//! A system model's free run: `lssi simulate MODEL.json FILE.csv` when MODEL.json holds
//! `"equations"` (what `lssi identify --json` prints for a recording with an electrical
//! channel).
//!
//! The state is (x, v, e₁, e₂, x2, v2) (the core's order; e₂, x2 and v2 0 where there are
//! none) with x' = v, v' = the x'' equation, eₖ' = its equation, and with two displacements
//! x2' = v2, v2' = the x2'' equation;
//! classical RK4 on the recording's time grid, u interpolated linearly between samples (its
//! midpoint at half steps). The initial state is the file's first row: x (or x integrated
//! from v, as `identify` does), v (measured, or x's first-derivative estimate over the
//! first samples) and the electrical channels. Only u comes from the file afterwards: the
//! prediction from the excitation alone.

use std::fmt::Write as _;

use lssi_core::library::Electrical;

/// A simulated state: (x, v, e₁, e₂, x2, v2), as the core's [`lssi_core::library::STATES`].
pub type State = [f64; 6];

use super::{SimulateSystemArgs, SystemData, SystemReport};
use crate::error::CliError;
use crate::identify::terms::frequency_text;
use crate::recording::ColumnNames;

/// A term of a system's library, ready to evaluate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SimTerm {
    /// 1.
    Constant,
    /// x^p₀ v^p₁ e₁^p₂ e₂^p₃ x2^p₄ v2^p₅.
    Monomial([u8; 6]),
    /// sin(W t), W in rad/s.
    Sin(f64),
    /// cos(W t).
    Cos(f64),
    /// The measured excitation u.
    Input,
}

impl SimTerm {
    /// The term a name stands for (`1`, `u`, `x^3`, `x*V`, `x1*x2^2`, `cos(6.28319t)`), with
    /// `electrical` the system's electrical states in order (`x1`, `v1` are `x`, `v`);
    /// `None` for a name it is not.
    pub fn parse(name: &str, electrical: &[Electrical]) -> Option<Self> {
        match name {
            "1" => return Some(SimTerm::Constant),
            "u" => return Some(SimTerm::Input),
            _ => {}
        }
        for (prefix, sin) in [("sin(", true), ("cos(", false)] {
            if let Some(rest) = name.strip_prefix(prefix) {
                let inner = rest.strip_suffix("t)")?;
                let w = if inner.is_empty() {
                    1.0
                } else {
                    inner.parse().ok()?
                };
                return Some(if sin {
                    SimTerm::Sin(w)
                } else {
                    SimTerm::Cos(w)
                });
            }
        }
        let mut powers = [0u8; 6];
        for factor in name.split('*') {
            let (symbol, power) = match factor.split_once('^') {
                Some((s, p)) => (s, p.parse::<u8>().ok()?),
                None => (factor, 1),
            };
            let state = match symbol {
                "x" | "x1" => 0,
                "v" | "v1" => 1,
                "x2" => 4,
                "v2" => 5,
                s => 2 + electrical.iter().position(|e| e.symbol() == s)?,
            };
            powers[state] = powers[state].checked_add(power)?;
        }
        (powers.iter().any(|&p| p > 0)).then_some(SimTerm::Monomial(powers))
    }

    /// Its value at state `s`, time `t`, input `u`.
    pub fn eval(&self, s: &State, t: f64, u: f64) -> f64 {
        match *self {
            SimTerm::Sin(w) => (w * t).sin(),
            SimTerm::Cos(w) => (w * t).cos(),
            _ => self.eval_algebraic(s, u),
        }
    }

    /// [`Self::eval`] with the harmonics' values at `t` taken from (and kept in) `trig`: a
    /// free run evaluates every equation's harmonics at the same few times of each step.
    /// Bit for bit the same value.
    fn eval_cached(&self, s: &State, t: f64, u: f64, trig: &mut Trig) -> f64 {
        match *self {
            SimTerm::Sin(w) => trig.value(w, t, true),
            SimTerm::Cos(w) => trig.value(w, t, false),
            _ => self.eval_algebraic(s, u),
        }
    }

    /// The value of a term that is not a harmonic.
    #[inline(always)]
    fn eval_algebraic(&self, s: &State, u: f64) -> f64 {
        match *self {
            SimTerm::Constant => 1.0,
            SimTerm::Monomial(p) => s
                .iter()
                .zip(p)
                .filter(|(_, p)| *p > 0)
                .map(|(q, p)| powi(*q, p))
                .product(),
            SimTerm::Input => u,
            SimTerm::Sin(_) | SimTerm::Cos(_) => unreachable!("harmonics are evaluated at t"),
        }
    }

    /// Its name, as the reports spell it (of a system with one displacement).
    pub fn name(&self, electrical: &[Electrical]) -> String {
        self.name_in(electrical, 1)
    }

    /// Its name in a system of `displacements` displacements (`x1*x2^2` with two).
    pub fn name_in(&self, electrical: &[Electrical], displacements: usize) -> String {
        match *self {
            SimTerm::Constant => "1".into(),
            SimTerm::Input => "u".into(),
            SimTerm::Sin(w) | SimTerm::Cos(w) => {
                let f = if matches!(self, SimTerm::Sin(_)) {
                    "sin"
                } else {
                    "cos"
                };
                let w = frequency_text(w);
                if w == "1" {
                    format!("{f}(t)")
                } else {
                    format!("{f}({w}t)")
                }
            }
            SimTerm::Monomial(p) => {
                let mut out = String::new();
                let two = displacements > 1;
                for k in [0, 1, 4, 5, 2, 3] {
                    let q = p[k];
                    if q == 0 {
                        continue;
                    }
                    let symbol = match k {
                        0 if two => "x1",
                        1 if two => "v1",
                        0 => "x",
                        1 => "v",
                        4 => "x2",
                        5 => "v2",
                        k => electrical.get(k - 2).map_or("e", |e| e.symbol()),
                    };
                    if !out.is_empty() {
                        out.push('*');
                    }
                    out.push_str(symbol);
                    if q > 1 {
                        let _ = write!(out, "^{q}");
                    }
                }
                out
            }
        }
    }
}

/// `q^p` by the square-and-multiply that `f64::powi` runs (compiler-builtins' `__powidf2`),
/// so bit for bit its value, inlined: the free run's inner loop called `powi` for every factor.
#[inline(always)]
fn powi(q: f64, p: u8) -> f64 {
    let (mut r, mut a, mut n) = (1.0f64, q, p);
    loop {
        if n & 1 == 1 {
            r *= a;
        }
        n >>= 1;
        if n == 0 {
            return r;
        }
        a *= a;
    }
}

/// The harmonics' values at one time, computed once and shared by every equation and every
/// RK4 stage at that time (k2 and k3 share theirs).
struct Trig {
    /// The time the values are for (NaN: none yet).
    t: f64,
    /// (W, sin?, value) at `t`.
    values: Vec<(f64, bool, f64)>,
}

impl Trig {
    fn new() -> Self {
        Trig {
            t: f64::NAN,
            values: Vec::new(),
        }
    }

    fn value(&mut self, w: f64, t: f64, sin: bool) -> f64 {
        if t.to_bits() != self.t.to_bits() {
            self.t = t;
            self.values.clear();
        }
        if let Some(&(_, _, v)) = self
            .values
            .iter()
            .find(|(x, s, _)| x.to_bits() == w.to_bits() && *s == sin)
        {
            return v;
        }
        let v = if sin { (w * t).sin() } else { (w * t).cos() };
        self.values.push((w, sin, v));
        v
    }
}

/// A system model to simulate: x'' first (x1'' then x2'' with two displacements), then each
/// electrical channel's equation.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemSim {
    /// Displacements: 1, or 2 (x2'' is then the second equation).
    pub displacements: usize,
    /// The electrical states, in order.
    pub electrical: Vec<Electrical>,
    /// Each equation's terms and coefficients.
    pub equations: Vec<Vec<(SimTerm, f64)>>,
    /// Which electrical channels are algebraic (`V = c v`, target `V` without a prime: a
    /// coil of negligible inductance), each computed from the other states at every step
    /// instead of integrated.
    pub algebraic: [bool; 2],
    /// Sensor offsets (x, v) of the first displacement's equation: x'' is evaluated at x − oₓ,
    /// v − oᵥ, and x' = v − oᵥ (the single equation's coordinates, as `lssi identify` without
    /// the electrical column gives them: [`crate::identify::Report::offsets`]); the states stay
    /// in the recording's coordinates. Zero but for an algebraic model.
    pub offsets: [f64; 2],
    /// The references subtracted from the recorded channels before identification (indices
    /// of [`State`]; [`super::references`]): the equations are in the channels less them,
    /// and a free run takes and gives states in the recording's coordinates.
    pub reference: State,
}

/// A report's references by state name as a [`State`] (zeros without); `None` for a name the
/// model's states do not have.
fn reference_state(
    reference: &Option<std::collections::BTreeMap<String, f64>>,
    electrical: &[Electrical],
    displacements: usize,
) -> Option<State> {
    let mut out = [0.0; 6];
    for (name, value) in reference.iter().flatten() {
        let j = match (name.as_str(), displacements) {
            ("x", 1) | ("x1", 2) => 0,
            ("v", 1) | ("v1", 2) => 1,
            ("x2", 2) => 4,
            ("v2", 2) => 5,
            (s, _) => 2 + electrical.iter().position(|e| e.symbol() == s)?,
        };
        out[j] = *value;
    }
    Some(out)
}

impl SystemSim {
    /// The model of a report.
    pub fn of_report(report: &SystemReport) -> Option<Self> {
        let displacements = if report.states.iter().any(|s| s == "x2") {
            2
        } else {
            1
        };
        let electrical: Vec<Electrical> = report.states[2 * displacements..]
            .iter()
            .map(|s| match s.as_str() {
                "V" => Some(Electrical::Voltage),
                "i" => Some(Electrical::Current),
                _ => None,
            })
            .collect::<Option<_>>()?;
        let mut algebraic = [false; 2];
        for (k, e) in report
            .equations
            .iter()
            .skip(displacements)
            .take(2)
            .enumerate()
        {
            algebraic[k] = !e.target.ends_with('\'');
        }
        let equations = report
            .equations
            .iter()
            .map(|e| {
                e.terms
                    .iter()
                    .map(|t| Some((SimTerm::parse(&t.term, &electrical)?, t.coef)))
                    .collect::<Option<Vec<_>>>()
            })
            .collect::<Option<Vec<_>>>()?;
        let reference = reference_state(&report.reference, &electrical, displacements)?;
        Some(Self {
            displacements,
            electrical,
            equations,
            algebraic,
            offsets: report.offsets.unwrap_or([0.0, 0.0]),
            reference,
        })
    }

    /// The model of an `lssi identify --json` object with `"equations"`.
    pub fn from_json(value: &serde_json::Value, path: &str) -> Result<Self, CliError> {
        let bad = |why: String| CliError::Input(format!("{path}: {why}."));
        let equations = value
            .get("equations")
            .and_then(|e| e.as_array())
            .ok_or_else(|| bad("it has no \"equations\" list".into()))?;
        let target = |k: usize| equations.get(k).and_then(|e| e.get("target")?.as_str());
        let displacements = match (target(0), target(1)) {
            (Some("x''"), _) => 1,
            (Some("x1''"), Some("x2''")) => 2,
            _ => {
                return Err(bad(
                    "its first equation is not x'' (nor x1'' followed by x2'')".into(),
                ));
            }
        };
        let mut electrical = Vec::new();
        let mut algebraic = [false; 2];
        for k in displacements..equations.len() {
            let (kind, proportional) = match target(k) {
                Some("V'") => (Electrical::Voltage, false),
                Some("i'") => (Electrical::Current, false),
                Some("V") => (Electrical::Voltage, true),
                Some("i") => (Electrical::Current, true),
                other => {
                    return Err(bad(format!(
                        "an equation's target is {other:?}, but after the displacements' a system's are \"V'\" or \"i'\" (or \"V\", \"i\": algebraic)"
                    )));
                }
            };
            if electrical.len() < 2 {
                algebraic[electrical.len()] = proportional;
            }
            electrical.push(kind);
        }
        let mut out = Vec::new();
        for e in equations {
            let terms = e
                .get("terms")
                .and_then(|t| t.as_array())
                .ok_or_else(|| bad("an equation has no \"terms\" list".into()))?;
            let mut eq = Vec::new();
            for t in terms {
                let name = t
                    .get("term")
                    .and_then(|n| n.as_str())
                    .ok_or_else(|| bad("a term has no \"term\" name".into()))?;
                let coef = t
                    .get("coef")
                    .and_then(|c| c.as_f64())
                    .ok_or_else(|| bad(format!("the term {name} has no numeric \"coef\"")))?;
                let term = SimTerm::parse(name, &electrical)
                    .ok_or_else(|| bad(format!("the term {name:?} is not one lssi knows")))?;
                eq.push((term, coef));
            }
            out.push(eq);
        }
        let offsets = match value.get("offsets") {
            None | Some(serde_json::Value::Null) => [0.0, 0.0],
            Some(o) => {
                let pair = o
                    .as_array()
                    .filter(|a| a.len() == 2)
                    .and_then(|a| Some([a[0].as_f64()?, a[1].as_f64()?]))
                    .ok_or_else(|| bad("its \"offsets\" is not a pair of numbers [x, v]".into()))?;
                if displacements > 1 && pair != [0.0, 0.0] {
                    return Err(bad(
                        "it has sensor offsets, which a system of two displacements does not take"
                            .into(),
                    ));
                }
                pair
            }
        };
        let reference = match value.get("reference") {
            None | Some(serde_json::Value::Null) => [0.0; 6],
            Some(r) => {
                let map = r
                    .as_object()
                    .and_then(|o| {
                        o.iter()
                            .map(|(k, v)| Some((k.clone(), v.as_f64()?)))
                            .collect::<Option<std::collections::BTreeMap<String, f64>>>()
                    })
                    .ok_or_else(|| {
                        bad("its \"reference\" is not an object of numbers by state name".into())
                    })?;
                reference_state(&Some(map), &electrical, displacements).ok_or_else(|| {
                    bad("its \"reference\" names a state the model does not have".into())
                })?
            }
        };
        let sim = Self {
            displacements,
            electrical,
            equations: out,
            algebraic,
            offsets,
            reference,
        };
        // An algebraic channel is a function of the mechanical states alone.
        for k in 0..sim.electrical.len().min(2) {
            if sim.algebraic[k]
                && sim.equations[displacements + k]
                    .iter()
                    .any(|(t, _)| matches!(t, SimTerm::Monomial(m) if m[2] > 0 || m[3] > 0))
            {
                return Err(bad(format!(
                    "the algebraic equation {} holds an electrical state; it takes the mechanical states and the excitation only",
                    sim.electrical[k].symbol()
                )));
            }
        }
        Ok(sim)
    }

    /// Whether a term of the model reads u.
    pub fn uses_input(&self) -> bool {
        self.equations
            .iter()
            .flatten()
            .any(|(t, _)| *t == SimTerm::Input)
    }

    /// Whether an electrical channel is algebraic (computed from the other states).
    pub fn has_algebraic(&self) -> bool {
        self.algebraic.iter().any(|a| *a)
    }

    /// `s` with each algebraic channel set to its equation's value at `s`, `t`, `u`.
    pub fn complete(&self, s: &State, t: f64, u: f64) -> State {
        self.complete_with(s, t, u, &mut Trig::new())
    }

    fn complete_with(&self, s: &State, t: f64, u: f64, trig: &mut Trig) -> State {
        let mut out = *s;
        let d = self.displacements;
        for k in 0..self.electrical.len().min(2) {
            if self.algebraic[k]
                && let Some(eq) = self.equations.get(d + k)
            {
                out[2 + k] = eq
                    .iter()
                    .map(|(term, c)| c * term.eval_cached(s, t, u, trig))
                    .sum();
            }
        }
        out
    }

    /// The state's derivative (an algebraic channel's is 0: it is set from the others).
    fn rate(&self, s: &State, t: f64, u: f64, trig: &mut Trig) -> State {
        let completed;
        let s = if self.has_algebraic() {
            completed = self.complete_with(s, t, u, trig);
            &completed
        } else {
            s
        };
        let [ox, ov] = self.offsets;
        let shifted = [s[0] - ox, s[1] - ov, s[2], s[3], s[4], s[5]];
        let mut f = |k: usize| -> f64 {
            if k >= self.displacements && self.algebraic.get(k - self.displacements) == Some(&true)
            {
                return 0.0;
            }
            let at = if k == 0 { &shifted } else { s };
            self.equations.get(k).map_or(0.0, |eq| {
                eq.iter()
                    .map(|(term, c)| c * term.eval_cached(at, t, u, trig))
                    .sum()
            })
        };
        let d = self.displacements;
        if d > 1 {
            [s[1], f(0), f(d), f(d + 1), s[5], f(1)]
        } else {
            [s[1] - ov, f(0), f(1), f(2), 0.0, 0.0]
        }
    }

    /// The index in [`State`] of each simulated state, in the order the reports list them:
    /// x, v (x1, v1, x2, v2 with two displacements), then the electrical ones.
    pub fn state_indices(&self) -> Vec<usize> {
        let mut out = vec![0, 1];
        if self.displacements > 1 {
            out.extend([4, 5]);
        }
        out.extend((0..self.electrical.len()).map(|k| 2 + k));
        out
    }

    /// The free run over the grid `t` from `start`, driven by `u` (one value per time;
    /// empty: 0). States after a divergence (non-finite, or beyond 1e6 times the largest
    /// initial magnitude plus `bound`) are NaN. Returns one state per time.
    pub fn run(&self, t: &[f64], u: &[f64], start: State, bound: f64) -> Vec<State> {
        self.run_substeps(t, u, start, bound, 1)
    }

    /// [`Self::run`] with each sample interval split into `substeps` RK4 steps (u a cubic
    /// between samples): for a stiff equation (an electrical decay λ with λ h beyond RK4's
    /// stability, as a load sweep's smallest loads give), the states at the samples.
    pub fn run_substeps(
        &self,
        t: &[f64],
        u: &[f64],
        start: State,
        bound: f64,
        substeps: usize,
    ) -> Vec<State> {
        let substeps = substeps.max(1);
        let mut out = Vec::with_capacity(t.len());
        // In the equations' coordinates (the channels less their references), and back.
        let reference = self.reference;
        let mut s: State = std::array::from_fn(|j| start[j] - reference[j]);
        let limit = 1e6 * (start.iter().fold(0.0f64, |m, q| m.max(q.abs())) + bound);
        // u[i], the last sample beyond the end (0 without an input).
        let at = |i: usize| {
            u.get(i.min(u.len().saturating_sub(1)))
                .copied()
                .unwrap_or(0.0)
        };
        let mut dead = false;
        let mut trig = Trig::new();
        for i in 0..t.len() {
            if !dead && self.has_algebraic() {
                s = self.complete_with(&s, t[i], at(i), &mut trig);
            }
            out.push(if dead {
                [f64::NAN; 6]
            } else {
                std::array::from_fn(|j| s[j] + reference[j])
            });
            if i + 1 == t.len() || dead {
                continue;
            }
            let span = t[i + 1] - t[i];
            let h = span / substeps as f64;
            // u between samples: the Catmull–Rom cubic through u[i − 1..=i + 2] (as
            // refinement of one equation takes it, [`crate::identify::refine`]); linear was
            // O(h²): 0.2 % of a 20 Hz tone's amplitude at 1 kHz, and refined systems took
            // that bias into their coefficients.
            let (p0, p1, p2, p3) = (at(i.saturating_sub(1)), at(i), at(i + 1), at(i + 2));
            let u_at = |f: f64| {
                let (f2, f3) = (f * f, f * f * f);
                0.5 * (2.0 * p1
                    + (p2 - p0) * f
                    + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f2
                    + (3.0 * p1 - p0 - 3.0 * p2 + p3) * f3)
            };
            let add = |a: &State, k: &State, c: f64| -> State {
                core::array::from_fn(|j| a[j] + c * k[j])
            };
            for step in 0..substeps {
                let f0 = step as f64 / substeps as f64;
                let f1 = (step + 1) as f64 / substeps as f64;
                let t0 = t[i] + f0 * span;
                let (u0, um, u1) = (u_at(f0), u_at(0.5 * (f0 + f1)), u_at(f1));
                let k1 = self.rate(&s, t0, u0, &mut trig);
                let k2 = self.rate(&add(&s, &k1, 0.5 * h), t0 + 0.5 * h, um, &mut trig);
                let k3 = self.rate(&add(&s, &k2, 0.5 * h), t0 + 0.5 * h, um, &mut trig);
                let k4 = self.rate(&add(&s, &k3, h), t0 + h, u1, &mut trig);
                for j in 0..6 {
                    s[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
                }
            }
            if s.iter().any(|q| !q.is_finite() || q.abs() > limit) {
                dead = true;
            }
        }
        out
    }
}

/// The recording's first state (x, v, e₁, e₂, x2, v2): v measured, or x's slope over its
/// first samples (a line through the first five).
pub fn first_state(data: &SystemData) -> State {
    let r = &data.recording;
    let slope = |x: &[f64]| {
        let n = r.len().min(5);
        let (t, x) = (&r.t[..n], &x[..n]);
        let tm = t.iter().sum::<f64>() / n as f64;
        let xm = x.iter().sum::<f64>() / n as f64;
        let sxy: f64 = t.iter().zip(x).map(|(a, b)| (a - tm) * (b - xm)).sum();
        let sxx: f64 = t.iter().map(|a| (a - tm).powi(2)).sum();
        if sxx > 0.0 { sxy / sxx } else { 0.0 }
    };
    let v0 = match &r.v {
        Some(v) => v[0],
        None => slope(&r.x),
    };
    let mut s = [r.x[0], v0, 0.0, 0.0, 0.0, 0.0];
    if let Some(second) = &data.second {
        s[4] = second.x[0];
        s[5] = match &second.v {
            Some((_, v)) => v[0],
            None => slope(&second.x),
        };
    }
    for (k, e) in data.electrical.iter().enumerate().take(2) {
        s[2 + k] = e.values[0];
    }
    s
}

/// The RMS of the finite values of `s`.
pub fn rms(s: &[f64]) -> f64 {
    let f: Vec<f64> = s.iter().copied().filter(|q| q.is_finite()).collect();
    (f.iter().map(|q| q * q).sum::<f64>() / f.len().max(1) as f64).sqrt()
}

/// NRMSE of `sim` against `rec`: RMS of the difference over the RMS of `rec` about its
/// mean; NaN when the simulation diverged.
pub fn nrmse(sim: &[f64], rec: &[f64]) -> f64 {
    let n = rec.len().min(sim.len());
    let mean = rec[..n].iter().sum::<f64>() / n.max(1) as f64;
    let mut e = 0.0;
    let mut d = 0.0;
    for i in 0..n {
        e += (sim[i] - rec[i]).powi(2);
        d += (rec[i] - mean).powi(2);
    }
    (e / d.max(f64::MIN_POSITIVE)).sqrt()
}

/// Free runs whose mean power `lssi simulate --load-ohms` prints beside the first run's.
pub const ENSEMBLE_RUNS: usize = 8;

/// How far the other runs start from the first row's state, a fraction of x's and v's RMS
/// (on a circle in the (x, v) plane).
pub const ENSEMBLE_NUDGE: f64 = 0.01;

/// The ensemble's `j`th start: `start` with x and v moved [`ENSEMBLE_NUDGE`] of `scale` (their
/// RMS) around a circle, j of [`ENSEMBLE_RUNS`] − 1 steps (j = 0 and the last are the same
/// nudge as the circle closes; the runs take j from 1, or 0 for the start itself).
pub fn ensemble_start(start: State, scale: [f64; 2], j: usize) -> State {
    let mut s = start;
    if j > 0 {
        let angle = std::f64::consts::TAU * j as f64 / (ENSEMBLE_RUNS - 1) as f64;
        s[0] += ENSEMBLE_NUDGE * scale[0] * angle.cos();
        s[1] += ENSEMBLE_NUDGE * scale[1] * angle.sin();
    }
    s
}

/// `lssi simulate MODEL.json FILE.csv` for a system: prints each state's NRMSE against the
/// recording (and the mean power with `--load-ohms`); `out` gets t and every simulated
/// state (CSV).
pub fn simulate_command(
    value: &serde_json::Value,
    model_path: &str,
    file: &std::path::Path,
    columns: &ColumnNames,
    args: &SimulateSystemArgs,
    out: Option<&std::path::Path>,
) -> Result<(), CliError> {
    let sim = SystemSim::from_json(value, model_path)?;
    let data = super::read_if_system(file, columns, &args.columns)?.ok_or_else(|| {
        CliError::Input(format!(
            "{}: the model is a system with {}, but the file has no such column (name it with --V-col or --i-col).",
            file.display(),
            sim.electrical
                .iter()
                .map(|e| format!("'{}'", e.symbol()))
                .collect::<Vec<_>>()
                .join(" and ")
        ))
    })?;
    let kinds: Vec<Electrical> = data.electrical.iter().map(|e| e.kind).collect();
    if kinds != sim.electrical {
        return Err(CliError::Input(format!(
            "{}: the model's electrical states are {:?}, but the file's are {:?}.",
            file.display(),
            sim.electrical
                .iter()
                .map(|e| e.symbol())
                .collect::<Vec<_>>(),
            kinds.iter().map(|e| e.symbol()).collect::<Vec<_>>()
        )));
    }
    let r = &data.recording;
    let u = match (&r.u, sim.uses_input()) {
        (Some(u), _) => u.clone(),
        (None, false) => Vec::new(),
        (None, true) => {
            return Err(CliError::Input(format!(
                "{}: the model has a u term, but the file has no 'u' column (name it with --u-col).",
                file.display()
            )));
        }
    };
    if let Some(r) = args.load_ohms
        && !(r.is_finite() && r > 0.0)
    {
        return Err(CliError::BadFlag {
            flag: "--load-ohms",
            value: r.to_string(),
            requirement: "a positive resistance in ohms".into(),
        });
    }
    if usize::from(data.displacements()) != sim.displacements {
        return Err(CliError::Input(format!(
            "{}: the model has {} displacement(s), but the file has {} ({}).",
            file.display(),
            sim.displacements,
            data.displacements(),
            data.mechanical_names()
                .iter()
                .step_by(2)
                .copied()
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let start = first_state(&data);
    let states = sim.run(&r.t, &u, start, rms(&r.x) + 1.0);
    let indices = sim.state_indices();
    let column = |k: usize| -> Vec<f64> { states.iter().map(|s| s[indices[k]]).collect() };
    let names: Vec<String> = data
        .mechanical_names()
        .into_iter()
        .map(str::to_owned)
        .chain(sim.electrical.iter().map(|e| e.symbol().to_owned()))
        .collect();
    let diverged = states.iter().position(|s| !s[0].is_finite());
    let mut text = format!(
        "{}: simulated from the first row ({}) over {} samples, driven by {}\n",
        file.display(),
        names
            .iter()
            .zip(&indices)
            .map(|(name, &j)| format!("{name} {}", start[j]))
            .collect::<Vec<_>>()
            .join(", "),
        r.len(),
        if sim.uses_input() {
            "the file's u"
        } else {
            "the model's harmonics"
        }
    );
    if let Some(i) = diverged {
        text.push_str(&format!(
            "  the free run diverged at t = {} s; the states after it are not numbers\n",
            r.t[i]
        ));
    }
    text.push_str("  state  NRMSE      RMS simulated  RMS recorded\n");
    let mut recorded: Vec<Option<&Vec<f64>>> = vec![Some(&r.x), r.v.as_ref()];
    if let Some(second) = &data.second {
        recorded.push(Some(&second.x));
        recorded.push(second.v.as_ref().map(|(_, v)| v));
    }
    recorded.extend(data.electrical.iter().map(|e| Some(&e.values)));
    for (k, name) in names.iter().enumerate() {
        let sim_k = column(k);
        match recorded[k] {
            Some(rec) => text.push_str(&format!(
                "  {name:<5}  {:<9.4}  {:<13.4e}  {:.4e}\n",
                nrmse(&sim_k, rec),
                rms(&sim_k),
                rms(rec)
            )),
            None => text.push_str(&format!(
                "  {name:<5}  -          {:<13.4e}  (not recorded)\n",
                rms(&sim_k)
            )),
        }
    }
    if let Some(ohms) = args.load_ohms
        && let Some(k) = sim
            .electrical
            .iter()
            .position(|e| *e == Electrical::Voltage)
            .or_else(|| {
                sim.electrical
                    .iter()
                    .position(|e| *e == Electrical::Current)
            })
    {
        // V²/R across the load, or R i² through it.
        let (formula, power): (&str, fn(f64, f64) -> f64) =
            if sim.electrical[k] == Electrical::Current {
                ("R i²", |ms, r| ms * r)
            } else {
                ("V²/R", |ms, r| ms / r)
            };
        let slot = 2 * sim.displacements + k;
        let p_sim = power(rms(&column(slot)).powi(2), ohms);
        let p_rec = power(rms(&data.electrical[k].values).powi(2), ohms);
        text.push_str(&format!(
            "  mean power {formula} at {ohms} Ω: simulated {p_sim:.4e} W, recorded {p_rec:.4e} W ({:+.1} %)\n",
            100.0 * (p_sim / p_rec - 1.0)
        ));
        // One free run's power is one sample of a chaotic attractor's: the mean over free
        // runs from starts a little apart, with its spread (a periodic response's runs
        // converge and agree).
        if diverged.is_none() {
            let scale = [rms(&column(0)), rms(&column(1))];
            let mut powers = vec![p_sim];
            for j in 1..ENSEMBLE_RUNS {
                let run = sim.run(&r.t, &u, ensemble_start(start, scale, j), rms(&r.x) + 1.0);
                let e: Vec<f64> = run.iter().map(|q| q[indices[slot]]).collect();
                if e.iter().all(|q| q.is_finite()) {
                    powers.push(power(rms(&e).powi(2), ohms));
                }
            }
            let n = powers.len() as f64;
            let mean = powers.iter().sum::<f64>() / n;
            let sd = (powers.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0))
                .sqrt();
            let (lo, hi) = powers
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &p| {
                    (a.min(p), b.max(p))
                });
            text.push_str(&format!(
                "  mean power over {} free runs (the first row's state and {} starts {:.0} % of x's and v's RMS away): {mean:.4e} W, sd {sd:.2e} W ({lo:.4e} to {hi:.4e} W), recorded {p_rec:.4e} W ({:+.1} %)\n",
                powers.len(),
                powers.len() - 1,
                100.0 * ENSEMBLE_NUDGE,
                100.0 * (mean / p_rec - 1.0)
            ));
        }
    }
    crate::out!("{text}");
    if let Some(path) = out {
        let mut csv = format!("t,{}\n", names.join(","));
        for (i, s) in states.iter().enumerate() {
            let _ = write!(csv, "{}", r.t[i]);
            for &j in &indices {
                let _ = write!(csv, ",{}", s[j]);
            }
            csv.push('\n');
        }
        std::fs::write(path, csv).map_err(|source| CliError::Write {
            path: path.to_path_buf(),
            source,
        })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        let e = [Electrical::Voltage];
        for name in [
            "1",
            "u",
            "x",
            "v^3",
            "x*V",
            "x^2*v",
            "V",
            "cos(6.28319t)",
            "sin(t)",
        ] {
            let t = SimTerm::parse(name, &e).unwrap();
            assert_eq!(t.name(&e), name);
        }
        assert_eq!(SimTerm::parse("i", &e), None);
        assert_eq!(SimTerm::parse("cos(2", &e), None);
    }

    #[test]
    fn a_linear_decay_follows_its_exponential() {
        // V' = -2 V from V = 1: exp(-2t).
        let sim = SystemSim {
            displacements: 1,
            electrical: vec![Electrical::Voltage],
            equations: vec![vec![], vec![(SimTerm::Monomial([0, 0, 1, 0, 0, 0]), -2.0)]],
            algebraic: [false; 2],
            offsets: [0.0, 0.0],
            reference: [0.0; 6],
        };
        let t: Vec<f64> = (0..=100).map(|i| f64::from(i) * 0.01).collect();
        let s = sim.run(&t, &[], [0.0, 0.0, 1.0, 0.0, 0.0, 0.0], 1.0);
        assert!((s[100][2] - (-2.0f64).exp()).abs() < 1e-8);
    }

    /// Two displacements: x2 is the fifth state, x2'' the second equation, names x1, x2.
    #[test]
    fn two_displacements_run_in_their_places() {
        let e = [Electrical::Voltage];
        for name in ["x1", "v2", "x1*x2^2", "x2*V", "v1"] {
            let t = SimTerm::parse(name, &e).unwrap();
            assert_eq!(t.name_in(&e, 2), name);
        }
        // x1'' = 0, x2'' = -x2 (x2 = cos t from 1), V' = v2.
        let x2 = SimTerm::parse("x2", &e).unwrap();
        let v2 = SimTerm::parse("v2", &e).unwrap();
        let sim = SystemSim {
            displacements: 2,
            electrical: vec![Electrical::Voltage],
            equations: vec![vec![], vec![(x2, -1.0)], vec![(v2, 1.0)]],
            algebraic: [false; 2],
            offsets: [0.0, 0.0],
            reference: [0.0; 6],
        };
        let t: Vec<f64> = (0..=1000).map(|i| f64::from(i) * 0.001).collect();
        let s = sim.run(&t, &[], [0.0, 0.0, 0.0, 0.0, 1.0, 0.0], 1.0);
        assert!((s[1000][4] - 1.0f64.cos()).abs() < 1e-9);
        assert!((s[1000][2] - (1.0f64.cos() - 1.0)).abs() < 1e-9);
        assert_eq!(sim.state_indices(), [0, 1, 4, 5, 2]);
    }
}
