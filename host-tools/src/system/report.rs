//! What `lssi identify` reports for a system: each equation on its own line with ±
//! standard errors, the solutions of each equation's sweep, and the `--json` object
//! `{"equations": [{"target": "x''", "terms": [...]}, {"target": "V'", "terms": [...]}], …}`.
//!
//! The coefficients are refined on simulation error ([`super::refine`]), or with
//! `--no-refine` the streaming system identifier's (what a device computes), whose standard
//! errors come from a least-squares
//! fit, on the host, of each equation's selected terms on regression rows a derivative window
//! apart (Savitzky–Golay estimates of the states and targets over disjoint windows, so that
//! the rows' estimation errors are nearly independent): σ² (AᵀA)⁻¹ with σ² the residual
//! variance. They measure how well the record pins the selected terms down; they do not
//! cover the selection itself.

use lssi_core::derivative::Taps;
use lssi_core::{Real, SystemConfig, SystemModel};
use serde::Serialize;

use super::SystemData;
use super::power::Harvester;
use super::simulate::{SimTerm, State};
use crate::identify::{SolutionReport, TermReport};

/// What a report of the streaming model (`--no-refine`) says of it.
pub const NOT_REFINED: &str =
    "not refined (--no-refine): this is the streaming system identifier's model";

/// One equation of the report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EquationReport {
    /// `x''`, `V'` or `i'`.
    pub target: String,
    /// The selected terms, with their coefficients (target's unit over the term's) and
    /// standard errors.
    pub terms: Vec<TermReport>,
    /// The solutions of this equation's threshold sweep, dense to sparse.
    pub solutions: Vec<SolutionReport>,
    /// Index of the solution MES selected.
    pub selected: usize,
}

/// Everything `lssi identify` reports for a system (the `--json` object).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SystemReport {
    /// x'' first, then each electrical channel's equation.
    pub equations: Vec<EquationReport>,
    /// `"refined"` (on simulation error, [`super::refine`]) or `"streaming"`.
    pub model: String,
    /// What refinement did (absent with `--no-refine`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refinement: Option<super::refine::Refinement>,
    /// What the text report says of the model after "model: ".
    #[serde(skip)]
    pub note: String,
    /// The states, in the library's order: `x`, `v`, then the electrical ones.
    pub states: Vec<String>,
    /// How x was obtained when the file has only v (else absent).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub x_from_v: Option<String>,
    /// Base angular frequency Ω of the harmonics, rad/s.
    pub omega: f64,
    /// Whether Ω was estimated from the data.
    pub omega_estimated: bool,
    /// Samples fed in.
    pub samples: u64,
    /// Samples rejected.
    pub rejected: u64,
    /// Derivative window (samples).
    pub window: usize,
    /// Local polynomial degree.
    pub degree: u8,
    /// Rows per test function (0: rows as they are).
    pub test_rows: u16,
    /// Sample period, seconds.
    pub sample_period: f64,
    /// `f32` or `f64`.
    pub precision: String,
    /// The highest degree of a term holding an electrical state.
    pub coupling_order: u8,
    /// How the standard errors were computed (rows, window), or why there are none.
    pub standard_errors: String,
    /// The harvester in physical terms (`--load-ohms`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub harvester: Option<Harvester>,
    /// What the quality gate measured ([`super::quality`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<super::quality::SystemQuality>,
    /// An electrical channel proportional to the velocity: its equation is algebraic (`V = c
    /// v`, target without a prime), x'' the mechanical channels' single equation
    /// ([`super::proportional`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub algebraic: Option<super::proportional::Algebraic>,
    /// Sensor offsets (x, v) the single equation found (an algebraic model's x'' only): x''
    /// is in x − oₓ and v − oᵥ, and x' = v − oᵥ.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offsets: Option<[f64; 2]>,
    /// The references subtracted from recorded channels far from zero (raw ADC counts, a
    /// sensor's offset) before identification, by state name: every equation is in the
    /// channels less them ([`super::references`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<std::collections::BTreeMap<String, f64>>,
    /// One-way coupling: x'' without the electrical states (the single equation of the
    /// mechanical channels), the electrical equations still driven by the motion, because
    /// the two-way model's coupling failed the mechanical energy balance
    /// ([`super::quality::energy_balance`]): the sentence saying so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub one_way: Option<String>,
    /// Warnings (the model is not refined, x integrated from v, …).
    pub warnings: Vec<String>,
    /// One sentence per rejected sample; not part of the JSON.
    #[serde(skip)]
    pub rejections: Vec<String>,
}

impl SystemReport {
    /// The report of a system model.
    pub fn of<T: Real, const P: usize, const E: usize>(
        model: &SystemModel<T, P, E>,
        config: &SystemConfig,
        omega_estimated: bool,
        rejected: u64,
        precision: &str,
        data: &SystemData,
    ) -> Self {
        let omega = model.omega;
        let name = |j: usize| {
            let mut s = String::new();
            let _ =
                model.terms[j].write_name_in(&mut s, omega, &model.electrical, model.displacements);
            s
        };
        let names = |support: u32| -> Vec<String> {
            (0..model.terms.len())
                .filter(|j| support & (1 << j) != 0)
                .map(name)
                .collect()
        };
        let equations = model
            .equations
            .iter()
            .enumerate()
            .map(|(k, e)| EquationReport {
                target: model
                    .target_name(k)
                    .map_or_else(|| e.target.to_string(), |t| t.to_string()),
                terms: (0..model.terms.len())
                    .filter(|j| e.support() & (1 << j) != 0)
                    .map(|j| TermReport {
                        term: name(j),
                        coef: e.coefficients[j].to_f64(),
                        se: None,
                    })
                    .collect(),
                solutions: e
                    .solutions
                    .iter()
                    .map(|s| SolutionReport {
                        threshold: s.threshold.to_f64(),
                        mean_error: s.mean_error.to_f64(),
                        terms: names(s.support),
                    })
                    .collect(),
                selected: e.selected,
            })
            .collect();
        let mut states: Vec<String> = data
            .mechanical_names()
            .into_iter()
            .map(str::to_owned)
            .collect();
        states.extend(data.electrical.iter().map(|e| e.kind.symbol().to_owned()));
        let warnings: Vec<String> = data.x_from_v.iter().cloned().collect();
        let base = &config.base;
        Self {
            equations,
            model: "streaming".into(),
            refinement: None,
            note: NOT_REFINED.into(),
            states,
            x_from_v: data.x_from_v.clone(),
            omega,
            omega_estimated,
            samples: model.samples,
            rejected,
            window: base.window,
            degree: base.derivative_degree,
            test_rows: base.test_rows,
            sample_period: base.sample_period,
            precision: precision.to_owned(),
            coupling_order: config.coupling_order,
            standard_errors: String::new(),
            harvester: None,
            quality: None,
            algebraic: None,
            offsets: None,
            reference: None,
            one_way: None,
            warnings,
            rejections: Vec::new(),
        }
    }

    /// The `--json` object, one line.
    pub fn json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }

    /// The text report.
    pub fn render(&self) -> String {
        let mut out = String::new();
        for e in &self.equations {
            out.push_str(&equation_text(e));
            if is_algebraic(e) {
                out.push_str("   (algebraic)");
            }
            out.push('\n');
        }
        if let Some(a) = &self.algebraic {
            out.push_str(&format!(
                "  algebraic: {} follows v within {:.1} % of its RMS (a coil of negligible inductance, or a time constant far under the forcing's period): no dynamics of its own for an equation {}' to identify; {}\n",
                a.channel, a.nrmse_percent, a.channel, a.damping
            ));
        }
        if let Some(w) = &self.one_way {
            out.push_str(&format!("  one-way coupling: {w}\n"));
        }
        out.push_str(&format!("model: {}\n", self.note));
        out.push_str(&format!("  ± {}\n", self.standard_errors));
        let mut inputs = Vec::new();
        let harmonic = self
            .equations
            .iter()
            .any(|e| e.terms.iter().any(|t| t.term.contains("t)")));
        if harmonic {
            inputs.push(format!("harmonics of Ω = {} rad/s", number(self.omega)));
        }
        if self
            .equations
            .iter()
            .any(|e| e.terms.iter().any(|t| t.term == "u"))
        {
            inputs.push("u".to_owned());
        }
        out.push_str(&format!(
            "states: {}{}\n",
            self.states.join(", "),
            if inputs.is_empty() {
                String::new()
            } else {
                format!("   inputs: {}", inputs.join(", "))
            }
        ));
        if let Some(s) = &self.x_from_v {
            out.push_str(&format!("  {s}\n"));
        }
        if let Some(reference) = &self.reference {
            let named: Vec<String> = reference
                .iter()
                .map(|(k, v)| format!("{k} {}", number(*v)))
                .collect();
            let less: Vec<String> = reference
                .iter()
                .map(|(k, v)| format!("{k} − {}", number(*v)))
                .collect();
            out.push_str(&format!(
                "references removed: {} (each the channel's mean, as it lay off zero: raw counts or a sensor's offset; the equations are in {}; lssi simulate and Model.simulate take and give the recording's values)\n",
                named.join(", "),
                less.join(", ")
            ));
        }
        if let Some([ox, ov]) = self.offsets {
            out.push_str(&format!(
                "sensor offsets: x {}, v {} (x'' is in x − {0} and v − {1}, and x' = v − {1})\n",
                number(ox),
                number(ov)
            ));
        }
        out.push_str(&format!(
            "window: {} samples, degree {}{}   {}   samples: {} ({} rejected)   coupling order {}   {}\n",
            self.window,
            self.degree,
            if self.test_rows > 0 {
                format!(", test function {} samples", self.test_rows)
            } else {
                String::new()
            },
            crate::identify::omega_text(self.omega, self.omega_estimated, harmonic),
            self.samples,
            self.rejected,
            self.coupling_order,
            self.precision
        ));
        for e in self.equations.iter().filter(|e| !is_algebraic(e)) {
            out.push_str(&format!(
                "\n{}:  #  threshold   mean error  terms\n",
                e.target
            ));
            for (i, s) in e.solutions.iter().enumerate() {
                let mark = if i == e.selected { "*" } else { " " };
                out.push_str(&format!(
                    "{mark}{i:>2}  {:>9.3e}  {:>11.4e}  {}\n",
                    s.threshold,
                    s.mean_error,
                    s.terms.join(", ")
                ));
            }
        }
        out.push_str(
            "  (* = selected by MES, each equation on its own: the sparsest solution within 5 % of the least held-out error)\n",
        );
        if let Some(h) = &self.harvester {
            out.push('\n');
            out.push_str(&h.render());
        }
        out
    }
}

impl SystemReport {
    /// Takes the refined model's coefficients and standard errors.
    pub fn take_refined(&mut self, refined: &super::refine::Refined) {
        for ((e, eq), se) in self
            .equations
            .iter_mut()
            .zip(&refined.sim.equations)
            .zip(&refined.standard_errors)
        {
            for ((t, (_, c)), s) in e.terms.iter_mut().zip(eq).zip(se) {
                t.coef = *c;
                t.se = s.is_finite().then_some(*s);
            }
        }
        self.model = "refined".into();
        self.standard_errors = format!(
            "standard errors of the refinement: σ² [S⁻¹]ⱼⱼ, S the Schur complement of the normal matrix over the coefficients and {} segments' initial states, σ² the residual variance per degree of freedom (each state's error over its standard deviation); they do not cover the selection",
            refined.segments
        );
    }
}

/// Whether an equation is algebraic (`V = c v`: its target has no prime).
pub fn is_algebraic(e: &EquationReport) -> bool {
    !e.target.ends_with('\'')
}

/// `x'' = (c ± se) x + …`, or plain coefficients where a term has no standard error.
pub fn equation_text(e: &EquationReport) -> String {
    let mut s = format!("{} =", e.target);
    for (i, t) in e.terms.iter().enumerate() {
        let term = if t.term == "1" {
            String::new()
        } else {
            format!(" {}", t.term)
        };
        let sep = if i == 0 { " " } else { " + " };
        match t.se {
            Some(se) => s.push_str(&format!("{sep}({:.6e} ± {se:.2e}){term}", t.coef)),
            None => s.push_str(&format!("{sep}{}{term}", number(t.coef))),
        }
    }
    if e.terms.is_empty() {
        s.push_str(" 0");
    }
    s
}

/// A number with 5 significant digits.
pub fn number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let magnitude = v.abs().log10().floor();
    if (-3.0..6.0).contains(&magnitude) {
        let decimals = (4.0 - magnitude).max(0.0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.4e}")
    }
}

/// One regression row of the host's estimates: states (x, v, e₁, e₂, x2, v2), targets in
/// the equations' order (x'' (x1'', x2''), e₁', e₂'), time and input.
struct Row {
    states: State,
    targets: [f64; 4],
    t: f64,
    u: f64,
}

/// The estimates over disjoint windows of `len` samples.
fn rows(data: &SystemData, len: usize, degree: usize, dt: f64) -> Option<Vec<Row>> {
    let taps: Box<Taps<f64, { super::WINDOW_CAPACITY }>> =
        Box::new(Taps::design(len, degree, dt).ok()?);
    let r = &data.recording;
    let mut out = Vec::new();
    let mut start = 0;
    while start + len <= r.len() {
        let window = start..start + len;
        let c = start + len / 2;
        start += len;
        let x = &r.x[window.clone()];
        let (xh, vh, ah) = match &r.v {
            Some(v) => {
                let v = &v[window.clone()];
                (
                    taps.apply(0, x, &[]),
                    taps.apply(0, v, &[]),
                    taps.apply(1, v, &[]),
                )
            }
            None => (
                taps.apply(0, x, &[]),
                taps.apply(1, x, &[]),
                taps.apply(2, x, &[]),
            ),
        };
        let mut states = [xh, vh, 0.0, 0.0, 0.0, 0.0];
        let mut targets = [ah, 0.0, 0.0, 0.0];
        let d = usize::from(data.displacements());
        if let Some(second) = &data.second {
            let x2 = &second.x[window.clone()];
            let (x2h, v2h, a2h) = match &second.v {
                Some((_, v2)) => {
                    let v2 = &v2[window.clone()];
                    (
                        taps.apply(0, x2, &[]),
                        taps.apply(0, v2, &[]),
                        taps.apply(1, v2, &[]),
                    )
                }
                None => (
                    taps.apply(0, x2, &[]),
                    taps.apply(1, x2, &[]),
                    taps.apply(2, x2, &[]),
                ),
            };
            states[4] = x2h;
            states[5] = v2h;
            targets[1] = a2h;
        }
        for (k, e) in data.electrical.iter().enumerate().take(2) {
            let w = &e.values[window.clone()];
            states[2 + k] = taps.apply(0, w, &[]);
            targets[d + k] = taps.apply(1, w, &[]);
        }
        let u = r.u.as_ref().map_or(0.0, |u| u[c]);
        let row = Row {
            states,
            targets,
            t: r.t[c],
            u,
        };
        if row.states.iter().chain(&row.targets).all(|q| q.is_finite()) && u.is_finite() {
            out.push(row);
        }
    }
    Some(out)
}

/// Fills in each term's standard error (see the module's documentation), and the sentence
/// saying how, or why there are none.
pub fn add_standard_errors(report: &mut SystemReport, data: &SystemData) {
    let (rows, choice) = match regression_rows(report.sample_period, data) {
        Ok(found) => found,
        Err(why) => {
            report.standard_errors = why.into();
            return;
        }
    };
    let electrical: Vec<_> = data.electrical.iter().map(|e| e.kind).collect();
    let mut all = true;
    for (k, e) in report.equations.iter_mut().enumerate() {
        let terms: Option<Vec<SimTerm>> = e
            .terms
            .iter()
            .map(|t| SimTerm::parse(&t.term, &electrical))
            .collect();
        let Some(terms) = terms else {
            all = false;
            continue;
        };
        let a: Vec<Vec<f64>> = rows
            .iter()
            .map(|row| {
                terms
                    .iter()
                    .map(|t| t.eval(&row.states, row.t, row.u))
                    .collect()
            })
            .collect();
        let y: Vec<f64> = rows.iter().map(|row| row.targets[k]).collect();
        match least_squares_se(&a, &y) {
            Some(se) => {
                for (t, s) in e.terms.iter_mut().zip(se) {
                    t.se = Some(s);
                }
            }
            None => all = false,
        }
    }
    report.standard_errors = format!(
        "standard errors of a least-squares fit of each equation's selected terms on {} rows a derivative window apart ({} samples, degree {}){}; they do not cover the selection",
        rows.len(),
        choice.window,
        choice.degree,
        if all {
            ""
        } else {
            "; an equation without them has too few rows or collinear terms"
        }
    );
}

/// The regression rows of the standard errors: the estimates over disjoint derivative
/// windows, and the window chosen; or the sentence saying why there are none.
fn regression_rows(
    dt: f64,
    data: &SystemData,
) -> Result<(Vec<Row>, lssi_core::tuning::WindowChoice), &'static str> {
    let r = &data.recording;
    let (source, order) = match &r.v {
        Some(v) => (v.clone(), 1),
        None => (r.x.clone(), 2),
    };
    let source: Vec<f64> = source.into_iter().filter(|q| q.is_finite()).collect();
    let choice = lssi_core::tuning::choose_window::<f64, { super::WINDOW_CAPACITY }>(
        &source,
        order,
        dt,
        source.len(),
    )
    .ok_or("no standard errors: too few samples for a derivative window")?;
    let rows = rows(data, choice.window, usize::from(choice.degree), dt)
        .ok_or("no standard errors: no derivative window fits")?;
    Ok((rows, choice))
}

/// The least-squares fit of equation `k`'s target on `terms` over the standard errors' rows:
/// each coefficient and its standard error; `None` with too few rows or collinear terms.
pub fn refit(
    dt: f64,
    data: &SystemData,
    k: usize,
    terms: &[SimTerm],
) -> Option<(Vec<f64>, Vec<f64>)> {
    let (rows, _) = regression_rows(dt, data).ok()?;
    let a: Vec<Vec<f64>> = rows
        .iter()
        .map(|row| {
            terms
                .iter()
                .map(|t| t.eval(&row.states, row.t, row.u))
                .collect()
        })
        .collect();
    let y: Vec<f64> = rows.iter().map(|row| row.targets[k]).collect();
    least_squares(&a, &y)
}

/// The state in slot `a` of the simulator's state (x, v, e₁, e₂, x2, v2) as a multiple of the
/// one in slot `b` over the standard errors' rows: c ≈ Σ aᵢbᵢ / Σ bᵢ², its standard error and
/// the fit's NRMSE (the residual's RMS over a's RMS); `None` without rows or with b ≡ 0.
pub fn proportional(dt: f64, data: &SystemData, a: usize, b: usize) -> Option<(f64, f64, f64)> {
    let (rows, _) = regression_rows(dt, data).ok()?;
    let design: Vec<Vec<f64>> = rows.iter().map(|r| vec![r.states[b]]).collect();
    let y: Vec<f64> = rows.iter().map(|r| r.states[a]).collect();
    let (beta, se) = least_squares(&design, &y)?;
    let c = *beta.first()?;
    let rss: f64 = rows
        .iter()
        .map(|r| (r.states[a] - c * r.states[b]).powi(2))
        .sum();
    let total: f64 = y.iter().map(|q| q * q).sum();
    (total > 0.0).then(|| (c, *se.first().unwrap_or(&f64::NAN), (rss / total).sqrt()))
}

/// The standard errors of the least-squares coefficients of `y ≈ A β`: σ² (AᵀA)⁻¹ with σ² =
/// RSS / (n − p); `None` with too few rows or a singular AᵀA.
pub fn least_squares_se(a: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
    least_squares(a, y).map(|(_, se)| se)
}

/// The least-squares coefficients β of `y ≈ A β` and their standard errors (see
/// [`least_squares_se`]).
pub fn least_squares(a: &[Vec<f64>], y: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = a.len();
    let p = a.first().map_or(0, Vec::len);
    if p == 0 || n <= p + 2 {
        return None;
    }
    // Columns scaled to unit RMS for the conditioning.
    let scale: Vec<f64> = (0..p)
        .map(|j| {
            let s = (a.iter().map(|r| r[j] * r[j]).sum::<f64>() / n as f64).sqrt();
            if s > 0.0 { s } else { 1.0 }
        })
        .collect();
    let mut g = vec![vec![0.0; p]; p];
    let mut b = vec![0.0; p];
    for (row, &yi) in a.iter().zip(y) {
        for i in 0..p {
            let ri = row[i] / scale[i];
            b[i] += ri * yi;
            for j in 0..p {
                g[i][j] += ri * row[j] / scale[j];
            }
        }
    }
    let inv = invert(g)?;
    let beta: Vec<f64> = (0..p)
        .map(|i| (0..p).map(|j| inv[i][j] * b[j]).sum())
        .collect();
    let rss: f64 = a
        .iter()
        .zip(y)
        .map(|(row, &yi)| {
            let fit: f64 = (0..p).map(|j| row[j] / scale[j] * beta[j]).sum();
            (yi - fit).powi(2)
        })
        .sum();
    let sigma2 = rss / (n - p) as f64;
    Some((
        (0..p).map(|j| beta[j] / scale[j]).collect(),
        (0..p)
            .map(|j| (sigma2 * inv[j][j]).max(0.0).sqrt() / scale[j])
            .collect(),
    ))
}

/// The inverse of a symmetric positive definite matrix by Gauss–Jordan with partial
/// pivoting; `None` when it is singular to working precision.
fn invert(mut g: Vec<Vec<f64>>) -> Option<Vec<Vec<f64>>> {
    let p = g.len();
    let mut inv: Vec<Vec<f64>> = (0..p)
        .map(|i| (0..p).map(|j| f64::from(u8::from(i == j))).collect())
        .collect();
    let largest = g
        .iter()
        .enumerate()
        .map(|(i, r)| r[i].abs())
        .fold(0.0, f64::max);
    for col in 0..p {
        let pivot_row = (col..p).max_by(|&i, &j| g[i][col].abs().total_cmp(&g[j][col].abs()))?;
        if g[pivot_row][col].abs() <= 1e-12 * largest {
            return None;
        }
        g.swap(col, pivot_row);
        inv.swap(col, pivot_row);
        let pivot = g[col][col];
        for j in 0..p {
            g[col][j] /= pivot;
            inv[col][j] /= pivot;
        }
        for row in 0..p {
            if row != col {
                let f = g[row][col];
                if f != 0.0 {
                    for j in 0..p {
                        g[row][j] -= f * g[col][j];
                        inv[row][j] -= f * inv[col][j];
                    }
                }
            }
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_standard_errors_match_the_textbook_line() {
        // y = 2 + 3 s + e with e alternating ±1: the slope's standard error is
        // σ / sqrt(Σ (s − s̄)²).
        let s: Vec<f64> = (0..100).map(f64::from).collect();
        let a: Vec<Vec<f64>> = s.iter().map(|&q| vec![1.0, q]).collect();
        let y: Vec<f64> = s
            .iter()
            .enumerate()
            .map(|(i, &q)| 2.0 + 3.0 * q + if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let se = least_squares_se(&a, &y).unwrap();
        let mean = s.iter().sum::<f64>() / 100.0;
        let sxx: f64 = s.iter().map(|q| (q - mean).powi(2)).sum();
        // The residuals are ±1 around the fitted line (nearly the true one): σ² ≈ 100 / 98.
        let expected = (100.0 / 98.0 / sxx).sqrt();
        assert!(
            (se[1] / expected - 1.0).abs() < 0.01,
            "{se:?} vs {expected}"
        );
    }
}
