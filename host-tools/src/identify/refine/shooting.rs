//! Multiple shooting: the model simulated over segments of the data, each from its own
//! initial state, and Levenberg–Marquardt over the coefficients and the states.

use lssi_core::Term;
use rayon::prelude::*;

use super::normal::BlockNormal;
use super::{Data, Span};
use crate::identify::simulate::SimModel;

/// The model being refined: its support and everything but the coefficients.
#[derive(Clone, Debug)]
pub(crate) struct Shape {
    pub(crate) terms: Vec<Term>,
    pub(crate) omega: f64,
    pub(crate) offsets: [f64; 2],
    /// RK4 steps per sample interval ([`substeps_for`]).
    pub(crate) substeps: usize,
}

/// `base`ⁿ by products (no powi call).
fn power(base: f64, n: u8) -> f64 {
    (0..n).fold(1.0, |p, _| p * base)
}

/// One library term's value with the excitation's phase given as (sin Ωt, cos Ωt): a
/// harmonic by complex powers of it, a monomial by products.
fn term_value(term: Term, (s1, c1): (f64, f64), x: f64, v: f64, u: f64) -> f64 {
    match term {
        Term::Constant => 1.0,
        Term::Monomial { px, pv } => power(x, px) * power(v, pv),
        Term::Sin(k) | Term::Cos(k) => {
            let (s, c) = (1..k).fold((s1, c1), |(s, c), _| (s * c1 + c * s1, c * c1 - s * s1));
            if matches!(term, Term::Sin(_)) { s } else { c }
        }
        Term::Input => u,
    }
}

/// The most RK4 steps per sample interval.
pub(crate) const MAX_SUBSTEPS: usize = 8;

/// RK4 steps per sample interval for a record with `samples_per_period` samples a period at
/// the top of its band: each step at most 1/128 of that period (RK4's error per period,
/// about (2π/128)⁴/... ≈ 10⁻⁶ relative, far below any sensor's noise), 1 to [`MAX_SUBSTEPS`].
pub(crate) fn substeps_for(samples_per_period: Option<f64>) -> usize {
    match samples_per_period {
        Some(spp) if spp.is_finite() && spp > 0.0 => {
            ((128.0 / spp).ceil() as usize).clamp(1, MAX_SUBSTEPS)
        }
        _ => 4,
    }
}

impl Shape {
    pub(crate) fn of(model: &SimModel) -> (Self, Vec<f64>) {
        let (terms, coefficients) = model
            .terms
            .iter()
            .filter(|(_, c)| *c != 0.0)
            .copied()
            .unzip();
        (
            Self {
                terms,
                omega: model.omega,
                offsets: model.offsets,
                substeps: 4,
            },
            coefficients,
        )
    }

    /// [`Shape::of`] with as many RK4 steps per sample as `data`'s band needs
    /// ([`substeps_for`]).
    pub(crate) fn on(model: &SimModel, data: &Data) -> (Self, Vec<f64>) {
        let (mut shape, c) = Self::of(model);
        shape.substeps = substeps_for(super::samples_per_period_at_top(data.x));
        (shape, c)
    }

    pub(crate) fn model(&self, coefficients: &[f64]) -> SimModel {
        SimModel {
            terms: self
                .terms
                .iter()
                .copied()
                .zip(coefficients.iter().copied())
                .collect(),
            omega: self.omega,
            offsets: self.offsets,
        }
    }

    /// x'' with the excitation's phase given as (sin Ωt, cos Ωt): the harmonics by complex
    /// powers of it and the monomials by products, without a sin, cos or powi call (the
    /// simulations here make 16 evaluations a sample, and libm's cos was half the time).
    pub(crate) fn acceleration(&self, c: &[f64], phase: (f64, f64), x: f64, v: f64, u: f64) -> f64 {
        self.terms
            .iter()
            .zip(c)
            .map(|(&term, &c)| c * term_value(term, phase, x, v, u))
            .sum()
    }

    /// Whether the x offset is a parameter of its own beside the coefficients: unless the
    /// support is closed under a shift of x (every x^j·v^b below each x^a·v^b present, the
    /// constant among them), where a shift of the origin is a change of coefficients and the
    /// offset would be redundant. An origin fixed a little off the truth biases the rest: at
    /// F = 3, 2 % noise, a single well's centre 1.5 × 10⁻⁶ off (0.1 % of the amplitude) made
    /// an x·v² of 4 standard errors (issue 25).
    pub(crate) fn offset_is_free(&self) -> bool {
        !self.terms.iter().all(|t| match *t {
            Term::Monomial { px, pv } => (0..px).all(|j| {
                self.terms.contains(&if j == 0 && pv == 0 {
                    Term::Constant
                } else {
                    Term::Monomial { px: j, pv }
                })
            }),
            _ => true,
        })
    }

    /// Whether the model has a sin or cos term.
    pub(crate) fn has_harmonics(&self) -> bool {
        self.terms
            .iter()
            .any(|t| matches!(t, Term::Sin(_) | Term::Cos(_)))
    }

    /// x'' as [`Shape::acceleration`] gives it, with its partial derivatives ∂x''/∂x and
    /// ∂x''/∂x' and, into `theta` (one per coefficient, as many as `theta` holds), the terms'
    /// values: what the variational equations of [`Shape::simulate_sensitivities`] need.
    fn stage(
        &self,
        c: &[f64],
        phase: (f64, f64),
        (x, v, u): (f64, f64, f64),
        theta: &mut [f64],
    ) -> (f64, f64, f64) {
        let (mut a, mut ax, mut av) = (0.0, 0.0, 0.0);
        for (j, (&term, &c)) in self.terms.iter().zip(c).enumerate() {
            let value = term_value(term, phase, x, v, u);
            let (dx, dv) = match term {
                Term::Monomial { px, pv } => (
                    if px > 0 {
                        f64::from(px) * power(x, px - 1) * power(v, pv)
                    } else {
                        0.0
                    },
                    if pv > 0 {
                        f64::from(pv) * power(x, px) * power(v, pv - 1)
                    } else {
                        0.0
                    },
                ),
                _ => (0.0, 0.0),
            };
            a += c * value;
            ax += c * dx;
            av += c * dv;
            if let Some(slot) = theta.get_mut(j) {
                *slot = value;
            }
        }
        (a, ax, av)
    }

    /// Simulates `data[a..b)` from (x₀, v₀) (recording coordinates) into `out` (b − a
    /// values: out[0] is sample a); false when the state left the finite numbers.
    pub(crate) fn simulate(
        &self,
        c: &[f64],
        data: &Data,
        span: (usize, usize),
        start: (f64, f64),
        out: &mut [f64],
    ) -> bool {
        self.step_through(c, data, span, start, out, 0, None)
            .is_some()
    }

    /// The state (x, x') at the last sample of `span` (recording coordinates) of a simulation
    /// from `start` at its first: `None` when the state left the finite numbers.
    pub(crate) fn state_after(
        &self,
        c: &[f64],
        data: &Data,
        span: (usize, usize),
        start: (f64, f64),
    ) -> Option<(f64, f64)> {
        let mut out = vec![0.0; span.1.saturating_sub(span.0).max(1)];
        self.step_through(c, data, span, start, &mut out, 0, None)
    }

    /// [`Shape::simulate`], and beside x its derivatives with respect to the first `k`
    /// coefficients and to the initial state (x₀, v₀): `sens[(i − a)·(k + 2) + p]`. They come
    /// from the variational equations stepped by the same RK4 as the state, which is the
    /// exact derivative of the discrete simulation (an explicit Runge–Kutta method commutes
    /// with differentiation), at about the cost of two simulations whatever `k` is: central
    /// differences took 2k + 4.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn simulate_sensitivities(
        &self,
        c: &[f64],
        data: &Data,
        span: (usize, usize),
        start: (f64, f64),
        out: &mut [f64],
        k: usize,
        sens: &mut [f64],
    ) -> bool {
        self.step_through(c, data, span, start, out, k, Some(sens))
            .is_some()
    }

    #[allow(clippy::too_many_arguments)]
    fn step_through(
        &self,
        c: &[f64],
        data: &Data,
        span: (usize, usize),
        start: (f64, f64),
        out: &mut [f64],
        k: usize,
        mut sens: Option<&mut [f64]>,
    ) -> Option<(f64, f64)> {
        let substeps = self.substeps.clamp(1, MAX_SUBSTEPS);
        let (a, b) = span;
        let [ox, ov] = self.offsets;
        let (mut x, mut v) = (start.0 - ox, start.1 - ov);
        out[0] = start.0;
        // Sensitivities: (∂x/∂p, ∂x'/∂p) for the k coefficients, then x₀ and v₀.
        let m = k + 2;
        let (mut sx, mut sv) = (vec![0.0; m], vec![0.0; m]);
        sx[k] = 1.0;
        sv[k + 1] = 1.0;
        let mut stages = vec![(0.0, 0.0); 4 * m];
        let mut theta = vec![0.0; k];
        if let Some(s) = sens.as_deref_mut() {
            s[..m].copy_from_slice(&sx);
        }
        let harmonics = self.has_harmonics();
        // (sin Ωs, cos Ωs) at the 2·substeps + 1 half-steps s = t0 + j·h/2 of a sample
        // interval: one sin/cos pair at t0 and one for the half-step's rotation, instead of
        // one per term and stage (the rotations' rounding, 10⁻¹⁵, is far below the data's).
        let mut phases = [(0.0, 1.0); 2 * MAX_SUBSTEPS + 1];
        let last = 2 * substeps;
        let (mut rotation, mut rotation_for) = ((0.0, 1.0), f64::NAN.to_bits());
        for i in a..b.saturating_sub(1) {
            let (t0, t1) = (data.t[i], data.t[i + 1]);
            let h = (t1 - t0) / substeps as f64;
            if harmonics {
                // The phase carries on from the last interval's end, recomputed every 64
                // samples; the rotation is recomputed only when the interval changes.
                phases[0] = if (i - a) % 64 == 0 {
                    (self.omega * t0).sin_cos()
                } else {
                    phases[last]
                };
                if h.to_bits() != rotation_for {
                    rotation = (self.omega * 0.5 * h).sin_cos();
                    rotation_for = h.to_bits();
                }
                let (sr, cr) = rotation;
                for j in 1..=last {
                    let (s, c) = phases[j - 1];
                    phases[j] = (s * cr + c * sr, c * cr - s * sr);
                }
            }
            let frac = |j: usize| j as f64 / last as f64;
            if sens.is_none() {
                // Stage at half-step j (0..=2·substeps).
                let f = |j: usize, x: f64, v: f64| {
                    self.acceleration(c, phases[j], x, v, data.input(i, frac(j)))
                };
                for q in 0..substeps {
                    let j = 2 * q;
                    let k1 = (v, f(j, x, v));
                    let k2 = (
                        v + 0.5 * h * k1.1,
                        f(j + 1, x + 0.5 * h * k1.0, v + 0.5 * h * k1.1),
                    );
                    let k3 = (
                        v + 0.5 * h * k2.1,
                        f(j + 1, x + 0.5 * h * k2.0, v + 0.5 * h * k2.1),
                    );
                    let k4 = (v + h * k3.1, f(j + 2, x + h * k3.0, v + h * k3.1));
                    x += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
                    v += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
                }
            } else {
                for q in 0..substeps {
                    let j = 2 * q;
                    // The four stages: where each is taken (a fraction of h along the last
                    // stage's slope) and at which half-step.
                    let mut slope = (0.0, 0.0);
                    let mut k_state = [(0.0, 0.0); 4];
                    for (stage, (along, half)) in
                        [(0.0, j), (0.5, j + 1), (0.5, j + 1), (1.0, j + 2)]
                            .into_iter()
                            .enumerate()
                    {
                        let (xs, vs) = (x + along * h * slope.0, v + along * h * slope.1);
                        let (acc, ax, av) = self.stage(
                            c,
                            phases[half],
                            (xs, vs, data.input(i, frac(half))),
                            &mut theta,
                        );
                        for p in 0..m {
                            let (dx_prev, dv_prev) = if stage == 0 {
                                (0.0, 0.0)
                            } else {
                                stages[(stage - 1) * m + p]
                            };
                            let sxs = sx[p] + along * h * dx_prev;
                            let svs = sv[p] + along * h * dv_prev;
                            let forcing = if p < k { theta[p] } else { 0.0 };
                            stages[stage * m + p] = (svs, ax * sxs + av * svs + forcing);
                        }
                        slope = (vs, acc);
                        k_state[stage] = slope;
                    }
                    let [k1, k2, k3, k4] = k_state;
                    x += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
                    v += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
                    for p in 0..m {
                        let d = |s: usize| stages[s * m + p];
                        sx[p] += h / 6.0 * (d(0).0 + 2.0 * d(1).0 + 2.0 * d(2).0 + d(3).0);
                        sv[p] += h / 6.0 * (d(0).1 + 2.0 * d(1).1 + 2.0 * d(2).1 + d(3).1);
                    }
                }
                if let Some(s) = sens.as_deref_mut() {
                    let row = (i + 1 - a) * m;
                    s[row..row + m].copy_from_slice(&sx);
                }
            }
            if !(x.is_finite() && v.is_finite()) {
                return None;
            }
            out[i + 1 - a] = x + ox;
        }
        Some((x + ox, v + ov))
    }
}

/// `[a, b)` cut into segments of about `length` samples (the last one takes the remainder).
pub(crate) fn segments(a: usize, b: usize, length: usize) -> Vec<(usize, usize)> {
    let length = length.max(8);
    let count = ((b - a) / length).max(1);
    (0..count)
        .map(|s| {
            (
                a + s * length,
                if s + 1 == count {
                    b
                } else {
                    a + (s + 1) * length
                },
            )
        })
        .collect()
}

/// A starting state for each segment: x and x' at its first sample from a quadratic fitted
/// to its first sixteenth (at least 5 samples): a difference of noisy samples is no velocity.
pub(crate) fn initial_states(data: &Data, segments: &[(usize, usize)]) -> Vec<(f64, f64)> {
    segments
        .iter()
        .map(|&(a, b)| {
            let w = ((b - a) / 16).clamp(5, 400).min(b - a);
            let t0 = data.t[a];
            // Normal equations of x ≈ p0 + p1 τ + p2 τ², τ = t − t0.
            let mut m = nalgebra::Matrix3::<f64>::zeros();
            let mut r = nalgebra::Vector3::<f64>::zeros();
            for i in a..a + w {
                let tau = data.t[i] - t0;
                let phi = nalgebra::Vector3::new(1.0, tau, tau * tau);
                m += phi * phi.transpose();
                r += phi * data.x[i];
            }
            match m.cholesky() {
                Some(ch) => {
                    let p = ch.solve(&r);
                    (p[0], p[1])
                }
                None => (data.x[a], 0.0),
            }
        })
        .collect()
}

/// What a least-squares run ends with.
pub(crate) struct Solution {
    pub(crate) coefficients: Vec<f64>,
    pub(crate) states: Vec<(f64, f64)>,
    pub(crate) rss: f64,
    pub(crate) iterations: usize,
    /// The residuals at the optimum, segment after segment.
    pub(crate) residuals: Vec<f64>,
    /// The segments fitted.
    pub(crate) segments: Vec<Span>,
    /// The sensor offsets the solution's model is in (x's fitted when
    /// [`Shape::offset_is_free`] and the coefficients were fitted).
    pub(crate) offsets: [f64; 2],
    /// Whether x's offset was fitted.
    pub(crate) offset_fitted: bool,
}

/// The residual sum of squares of all segments; `None` if a simulation diverged. The
/// segments (ascending, disjoint, as `segments` cuts them) are simulated in parallel on every
/// core, each into its own part of `out`; their sums are added in segment order, so the
/// result does not depend on the number of threads.
pub(crate) fn rss(
    shape: &Shape,
    c: &[f64],
    data: &Data,
    segs: &[(usize, usize)],
    states: &[(f64, f64)],
    out: &mut [f64],
) -> Option<f64> {
    let mut pieces = Vec::with_capacity(segs.len());
    let mut rest = out;
    let mut at = 0;
    for (&(a, b), &start) in segs.iter().zip(states) {
        if a < at || b < a || b - at > rest.len() {
            return None;
        }
        let (_, tail) = std::mem::take(&mut rest).split_at_mut(a - at);
        let (piece, tail) = tail.split_at_mut(b - a);
        rest = tail;
        at = b;
        pieces.push(((a, b), start, piece));
    }
    let sums: Vec<Option<f64>> = pieces
        .into_par_iter()
        .map(|((a, b), start, piece)| {
            if !shape.simulate(c, data, (a, b), start, piece) {
                return None;
            }
            Some(
                piece
                    .iter()
                    .zip(&data.x[a..b])
                    .map(|(s, x)| (s - x).powi(2))
                    .sum::<f64>(),
            )
        })
        .collect();
    let mut sum = 0.0;
    for part in sums {
        sum += part?;
    }
    sum.is_finite().then_some(sum)
}

/// The Jacobian of the simulated x, column by column: the `k` first coefficients, then x₀
/// and v₀ of the segments (a segment's state moves only that segment, so all segments'
/// state derivatives fit in two columns), from the variational equations
/// ([`Shape::simulate_sensitivities`]), the segments in parallel. `None` if a simulation
/// diverged.
pub(crate) fn jacobian(
    shape: &Shape,
    c: &[f64],
    data: &Data,
    segs: &[(usize, usize)],
    states: &[(f64, f64)],
    k: usize,
) -> Option<Vec<Vec<f64>>> {
    let n = data.len();
    let m = k + 2;
    let pieces: Vec<Option<Vec<f64>>> = segs
        .par_iter()
        .zip(states)
        .map(|(&(a, b), &start)| {
            let mut out = vec![0.0; b - a];
            let mut sens = vec![0.0; (b - a) * m];
            shape
                .simulate_sensitivities(c, data, (a, b), start, &mut out, k, &mut sens)
                .then_some(sens)
        })
        .collect();
    let mut columns = vec![vec![0.0; n]; m];
    for (&(a, b), piece) in segs.iter().zip(pieces) {
        let piece = piece?;
        for i in a..b {
            let row = &piece[(i - a) * m..(i - a + 1) * m];
            for (column, value) in columns.iter_mut().zip(row) {
                column[i] = *value;
            }
        }
    }
    Some(columns)
}

/// Levenberg–Marquardt over the coefficients (unless `fixed`) and every segment's state.
pub(crate) fn least_squares(
    shape: &Shape,
    start: &[f64],
    data: &Data,
    segs: &[(usize, usize)],
    fixed: bool,
    iterations: usize,
    states: Option<Vec<(f64, f64)>>,
) -> Option<Solution> {
    let n = data.len();
    let k = if fixed { 0 } else { start.len() };
    let mut shape = shape.clone();
    let free = !fixed && shape.offset_is_free();
    let shape = &mut shape;
    let mut c = start.to_vec();
    let mut states = states.unwrap_or_else(|| initial_states(data, segs));
    let mut base = vec![0.0; n];
    let mut plus = vec![0.0; n];
    let mut current = rss(shape, &c, data, segs, &states, &mut base)?;
    let mut lambda = 1e-3;
    let mut done = 0;
    for iteration in 0..iterations {
        done = iteration + 1;
        let mut columns = jacobian(shape, &c, data, segs, &states, k)?;
        if free {
            columns.push(offset_column(&columns[k], segs, n));
        }
        let mut shared: Vec<&[f64]> = columns[..k].iter().map(Vec::as_slice).collect();
        if free {
            shared.push(&columns[k + 2]);
        }
        let normal = BlockNormal::assemble(
            &shared,
            [&columns[k], &columns[k + 1]],
            |i| base[i] - data.x[i],
            segs,
        );
        // Damped steps until one lowers the error.
        let mut accepted = false;
        for _ in 0..12 {
            let Some((step_c, step_s)) = normal.solve(lambda) else {
                lambda *= 10.0;
                continue;
            };
            let trial_c: Vec<f64> = (0..c.len())
                .map(|j| if j < k { c[j] + step_c[j] } else { c[j] })
                .collect();
            let trial_states: Vec<(f64, f64)> = states
                .iter()
                .zip(&step_s)
                .map(|(&(x, v), d)| (x + d[0], v + d[1]))
                .collect();
            let trial_shape = Shape {
                offsets: [
                    shape.offsets[0] + if free { step_c[k] } else { 0.0 },
                    shape.offsets[1],
                ],
                ..shape.clone()
            };
            match rss(&trial_shape, &trial_c, data, segs, &trial_states, &mut plus) {
                Some(trial) if trial < current => {
                    let gain = (current - trial) / current;
                    *shape = trial_shape;
                    c = trial_c;
                    states = trial_states;
                    current = trial;
                    std::mem::swap(&mut base, &mut plus);
                    lambda = (lambda / 3.0).max(1e-12);
                    accepted = true;
                    // A relative gain under 10⁻⁷ moves the parameters by far less than their
                    // standard errors (one standard error is about 1/N of the RSS).
                    if gain < 1e-7 {
                        return finish(c, states, current, done, &base, data, segs)
                            .map(|sol| sol.in_offsets(shape.offsets, free));
                    }
                    break;
                }
                _ => lambda *= 4.0,
            }
        }
        if !accepted {
            break;
        }
    }
    finish(c, states, current, done, &base, data, segs)
        .map(|sol| sol.in_offsets(shape.offsets, free))
}

/// The derivative of the simulated x with respect to x's offset, the initial states (in
/// recording coordinates) held: the model's state starts at x₀ − offset and is shifted back
/// by it, so the column is 1 − ∂x/∂x₀ over the segments (`state_column`).
pub(crate) fn offset_column(state_column: &[f64], segs: &[Span], n: usize) -> Vec<f64> {
    let mut column = vec![0.0; n];
    for &(a, b) in segs {
        for i in a..b {
            column[i] = 1.0 - state_column[i];
        }
    }
    column
}

impl Solution {
    fn in_offsets(self, offsets: [f64; 2], fitted: bool) -> Self {
        Self {
            offsets,
            offset_fitted: fitted,
            ..self
        }
    }
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn finish(
    coefficients: Vec<f64>,
    states: Vec<(f64, f64)>,
    rss: f64,
    iterations: usize,
    simulated: &[f64],
    data: &Data,
    segs: &[(usize, usize)],
) -> Option<Solution> {
    let residuals = segs
        .iter()
        .flat_map(|&(a, b)| (a..b).map(move |i| simulated[i] - data.x[i]))
        .collect();
    Some(Solution {
        coefficients,
        states,
        rss,
        iterations,
        residuals,
        segments: segs.to_vec(),
        offsets: [f64::NAN; 2],
        offset_fitted: false,
    })
}
