//! Output-error refinement: the streaming model's coefficients refined on simulation error.
//!
//! The identifier fits the equation x'' = Σ ξⱼ θⱼ(x, x', t, u) to derivatives estimated from
//! the data (equation error). What a user checks is whether the equation, *simulated*,
//! reproduces the recording; and where derivatives are biased (coarse sampling, noise on x
//! alone) the equation-error fit is biased too. This module keeps the support the sparse
//! selection chose and refines its coefficients, in f64, by minimising the simulation error
//! of x (the maximum-likelihood estimate under white measurement noise):
//!
//! - **Multiple shooting.** The data is cut into segments of a few periods, each simulated
//!   from its own initial state (x₀, v₀), which is a parameter too. Short segments keep a
//!   poor starting model (or a chaotic system) from running away; a second pass with
//!   segments four times as long tightens what short segments leave loose.
//! - **Levenberg–Marquardt** on the block-sparse normal equations (the coefficients are
//!   shared, the initial states belong to one segment each), written here on nalgebra: a
//!   generic solver would form the dense Jacobian (10⁵ residuals × hundreds of initial states).
//!   Derivatives by central differences of the RK4 simulation (four steps per sample; the
//!   input u is interpolated between samples by a cubic through its neighbours).
//! - **Held out.** [`refine_and_check`] refines on the first half and compares both models'
//!   simulation error on the second half (initial states fitted, coefficients fixed); the
//!   refined model is taken unless it predicts worse (by more than 0.5 %: both usually reach
//!   the noise floor there), and then refined once more on the whole recording. A record
//!   the streaming model cannot follow over a segment (NRMSE over 25 %: chaos) is not refined.
//! - **Supports.** [`refine_and_check_among`] refines, beside the streaming support, the
//!   solutions of the identifier's sweep one term away from it ([`crate::identify::supports`]),
//!   each on the first half from its least-squares start, and takes the sparsest whose
//!   held-out error is within [`SUPPORT_PARSIMONY`] of the best, a term it adds being at
//!   least [`SIGNIFICANT_SE`] standard errors from zero: at 10 % noise on x alone the
//!   streaming selection loses the harvester's damping on some seeds, and this brings it
//!   back (`examples/refine_noise.rs`) without letting a spurious term in. It also drops,
//!   one at a time, the least significant refined term (backward elimination) and judges
//!   each sparser support by the same held-out comparison. A term the streaming selection
//!   picked out of the library is dropped under [`selection_bar`] of its standard errors,
//!   Bonferroni's bar over the library's terms (3.67σ for 11, where [`SIGNIFICANT_SE`]'s 3σ
//!   is a single test's): the largest of ten candidates the record does not need is 3σ by
//!   chance far more often than one term fixed in advance (issue 25, hostile seed 20741: a
//!   spurious v² at 3.3σ kept, the truth's support never tried). The oscillator's x and v,
//!   which every model has, keep 3σ.
//! - **Standard errors** of the coefficients of the pass reported, from the Jacobian J
//!   recomputed at its optimum: seⱼ² = σ² [(JᵀJ)⁻¹]ⱼⱼ + Δcⱼ² + Vᵤⱼ, where
//!   - JᵀJ is the normal matrix of *all* the parameters estimated: the coefficients, every
//!     segment's initial state and, when the model has a sin/cos term, the excitation
//!     frequency Ω; [(JᵀJ)⁻¹]ⱼⱼ is the marginal variance (the coefficients' own block alone
//!     would be 2–4 times too small: they are correlated with the states);
//!   - σ² is the residual variance per degree of freedom, inflated by 1 + 2Σρₖ, the
//!     residuals' autocorrelation (a coloured residual carries less information than its
//!     count says; for a model that fits, the residual is the white measurement noise and the
//!     factor is 1);
//!   - Δc is what the coefficients would move by were Ω refined too (one Gauss–Newton step
//!     from the optimum with Ω free): refinement keeps the streaming model's Ω, and its error
//!     is not noise the residual shows. Near resonance it dominates: from x alone at 2 %
//!     noise the streaming Ω is off by 10⁻⁵–10⁻⁴ rad/s, which moved the damping coefficient
//!     over 20 seeds 4–7 times as far as σ²(JᵀJ)⁻¹ allowed (3 standard errors held the truth
//!     for 61 of 80 coefficients, 10 seeds of each well); with Δc, for 80 of 80, the standard
//!     errors' RMS within 25 % of the errors' (`tests/standard_errors.rs`,
//!     `examples/refine_noise.rs`).
//!
//!   - Vᵤ, with a measured u, is the variance u's own noise puts on the coefficients: the
//!     simulation is driven by u as if it were exact, and the response to u's noise
//!     (narrow-band at the resonance) barely shows in the residual while it moves the
//!     damping and the stiffness; the mean square of the coefficients' shift (one
//!     Gauss–Newton step, the states refitted) when u gets noise of its own white floor's
//!     level once more, over eight draws (`errors::input_noise_shift`; issue 25, hostile
//!     seeds 20108 and 20153: 1 % and 5 % noise on u, the damping and the stiffness 3–6 of
//!     the former standard errors off).
//!
//!   A sandwich (Newey–West) estimate on the per-sample contributions, at any bandwidth up to
//!   1000 samples, agrees with σ²(JᵀJ)⁻¹ within 20 % there: the residual is white (|ρₖ| under
//!   0.015), and the shortfall was the fixed Ω, not the residual's correlation.

mod choose;
mod errors;
pub(crate) use errors::white_noise_sd;
mod normal;
mod shooting;
mod summary;
#[cfg(test)]
mod tests;

pub use choose::{
    Check, Chosen, ESCAPE_RANGES, Horizon, NEGLIGIBLE_SHARE, NOT_WORSE_Z, NUMERICAL_NRMSE_PERCENT,
    PREDICTABLE_NRMSE_PERCENT, Paired, SIGNIFICANT_SE, SUPPORT_PARSIMONY, Tried, Z_BETTER,
    refine_and_check, refine_and_check_among, refine_recording, selection_bar,
};
pub use summary::{Candidate, Summary, SupportChange, TermSummary};

use serde::Serialize;

use crate::identify::simulate::SimModel;
use shooting::{Shape, Solution, least_squares, segments};

/// Samples `[a, b)` of a recording.
type Span = (usize, usize);
/// A state (x, x').
type State = (f64, f64);

/// A recording, or a stretch of it.
#[derive(Clone, Copy, Debug)]
pub struct Data<'a> {
    /// Sample times, seconds (uniform or not).
    pub t: &'a [f64],
    /// Measured displacement.
    pub x: &'a [f64],
    /// Measured excitation, when the model has a `u` term.
    pub u: Option<&'a [f64]>,
}

impl<'a> Data<'a> {
    /// The samples `[a, b)`.
    pub fn slice(&self, a: usize, b: usize) -> Data<'a> {
        Data {
            t: &self.t[a..b],
            x: &self.x[a..b],
            u: self.u.map(|u| &u[a..b]),
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.t.len().min(self.x.len())
    }

    /// u at `s` ∈ [0, 1] of the way from sample `i` to `i + 1`: a cubic (Catmull–Rom)
    /// through u[i−1..=i+2] (linear interpolation would low-pass a band-limited input).
    pub(crate) fn input(&self, i: usize, s: f64) -> f64 {
        let Some(u) = self.u else { return 0.0 };
        let n = u.len();
        let at = |k: isize| u[k.clamp(0, n as isize - 1) as usize];
        let i = i as isize;
        let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
        let s2 = s * s;
        let s3 = s2 * s;
        0.5 * ((2.0 * p1)
            + (-p0 + p2) * s
            + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * s2
            + (-p0 + 3.0 * p1 - 3.0 * p2 + p3) * s3)
    }
}

/// Settings of [`refine`].
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Samples per shooting segment in the first pass (the second uses four times as many).
    pub segment: usize,
    /// Levenberg–Marquardt iterations per pass, at most.
    pub iterations: usize,
    /// Whether a second pass with segments four times as long follows (kept when it fits
    /// about as well per sample): the final refinement makes it, candidates do not.
    pub long_pass: bool,
}

impl Settings {
    /// Segments of two mean periods of x (at least 64 samples).
    pub fn for_data(data: &Data) -> Self {
        let period = mean_period_samples(data.x).unwrap_or(64.0);
        Self {
            segment: ((2.0 * period) as usize).max(64),
            iterations: 20,
            long_pass: true,
        }
    }
}

/// The period of x's strongest spectral line, in samples (zero crossings would count the
/// noise's).
pub fn mean_period_samples(x: &[f64]) -> Option<f64> {
    let power = spectrum(x)?;
    let n = 2 * (power.len() + 1);
    let (peak, _) = power.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    Some(n as f64 / (peak + 1) as f64)
}

/// Power at the bins 1..n/2 of x's mean-free spectrum (its first 2¹⁶ samples, an even count).
fn spectrum(x: &[f64]) -> Option<Vec<f64>> {
    use rustfft::{FftPlanner, num_complex::Complex};
    let n = x.len().min(1 << 16) & !1;
    if n < 16 {
        return None;
    }
    let x = &x[..n];
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<Complex<f64>> = x.iter().map(|v| Complex::new(v - mean, 0.0)).collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    Some(buf[1..n / 2].iter().map(|c| c.norm_sqr()).collect())
}

/// Samples per period of the highest frequency present: the frequency under which 99 % of
/// x's (mean-free) power lies. Under about 20, derivatives from the samples are biased.
pub fn samples_per_period_at_top(x: &[f64]) -> Option<f64> {
    let power = spectrum(x)?;
    let n = 2 * (power.len() + 1);
    let total: f64 = power.iter().sum();
    if total == 0.0 {
        return None;
    }
    let mut acc = 0.0;
    for (j, p) in power.iter().enumerate() {
        acc += p;
        if acc >= 0.99 * total {
            return Some(n as f64 / (j + 1) as f64);
        }
    }
    None
}

/// A refined model.
#[derive(Clone, Debug)]
pub struct Refined {
    /// The model with refined coefficients.
    pub model: SimModel,
    /// Standard error of each of `model.terms`' coefficients (same order).
    pub standard_errors: Vec<f64>,
    /// RMS simulation error over the data, in x's unit.
    pub rms: f64,
    /// Levenberg–Marquardt iterations, both passes.
    pub iterations: usize,
}

/// Refines `model`'s nonzero coefficients on `data` (two multiple-shooting passes); `None`
/// when even the starting model diverges on every segment length tried.
pub fn refine(model: &SimModel, data: &Data, settings: &Settings) -> Option<Refined> {
    let (shape, start) = Shape::on(model, data);
    let n = data.len();
    if start.is_empty() || n < 16 {
        return None;
    }
    // Each pass fits the segments' states alone first: from states guessed off noisy data the
    // first joint steps would bend the coefficients to make up for the states.
    // A segment whose states alone cannot be fitted (a local minimum of its own, or a
    // stretch the model cannot follow) is left out of the joint fit: one such segment would
    // otherwise pull every coefficient.
    // x's offset, when free (Shape::offset_is_free), is fitted with the coefficients, and the
    // second pass starts from the first's.
    let pass = |shape: &Shape, c: &[f64], segs: &[(usize, usize)]| {
        let fitted = least_squares(shape, c, data, segs, true, settings.iterations, None)?;
        let mut seg_rss: Vec<f64> = segs
            .iter()
            .scan(0usize, |at, &(a, b)| {
                let r = &fitted.residuals[*at..*at + (b - a)];
                *at += b - a;
                Some(r.iter().map(|e| e * e).sum::<f64>())
            })
            .collect();
        // A segment's state landing in a local minimum is fitted again from other starts
        // (as the windows of [`window_errors`] are): over more than half the segments it
        // moved the median itself, no segment was left out, and the joint fit bent the
        // coefficients to another optimum (a single well driven hard at 800 Hz: x at −2696
        // for −337, from a start at the truth refined on the first half, issue 25).
        let mut fitted_states = fitted.states;
        refit_from_other_starts(shape, c, data, segs, &mut seg_rss, &mut fitted_states);
        let rms: Vec<f64> = segs
            .iter()
            .zip(&seg_rss)
            .map(|(&(a, b), r)| (r / (b - a).max(1) as f64).sqrt())
            .collect();
        let mut sorted = rms.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let (kept, states): (Vec<Span>, Vec<State>) = segs
            .iter()
            .zip(&fitted_states)
            .zip(&rms)
            .filter(|&(_, &r)| r <= 3.0 * median)
            .map(|(pair, _)| (*pair.0, *pair.1))
            .unzip();
        least_squares(
            shape,
            c,
            data,
            &kept,
            false,
            settings.iterations,
            Some(states),
        )
    };
    let first = segments(0, n, settings.segment);
    let one = pass(&shape, &start, &first)?;
    let second_segs = segments(0, n, settings.segment.saturating_mul(4));
    let two = if settings.long_pass && second_segs.len() < first.len() {
        let after_one = Shape {
            offsets: one.offsets,
            ..shape.clone()
        };
        pass(&after_one, &one.coefficients, &second_segs)
    } else {
        None
    };
    let best = match two {
        // Longer segments see more of the dynamics; keep them unless they fit worse per sample.
        // (per sample: each pass leaves out the segments it cannot fit, not the same ones).
        Some(two)
            if two.rss / two.residuals.len().max(1) as f64
                <= 1.1 * one.rss / one.residuals.len().max(1) as f64 =>
        {
            Solution {
                iterations: one.iterations + two.iterations,
                ..two
            }
        }
        _ => one,
    };
    let shape = Shape {
        offsets: best.offsets,
        ..shape
    };
    let standard_errors = errors::standard_errors(&shape, data, &best)
        .unwrap_or_else(|| vec![f64::NAN; best.coefficients.len()]);
    Some(Refined {
        model: shape.model(&best.coefficients),
        standard_errors,
        rms: (best.rss / best.residuals.len().max(1) as f64).sqrt(),
        iterations: best.iterations,
    })
}

/// How well a model's simulation reproduces a stretch of data.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Fit {
    /// RMS error ÷ standard deviation of x, in %.
    pub nrmse_percent: f64,
    /// RMS error in x's unit.
    pub rms: f64,
}

fn fit_of(rss: f64, x: &[f64]) -> Fit {
    let n = x.len().max(1) as f64;
    let mean = x.iter().sum::<f64>() / n;
    let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    let rms = (rss / n).sqrt();
    Fit {
        nrmse_percent: if sd > 0.0 { 100.0 * rms / sd } else { f64::NAN },
        rms,
    }
}

/// Short-horizon prediction errors: `data` cut into windows of `length` samples, the model
/// simulated over each from its own fitted initial state (its coefficients fixed).
#[derive(Clone, Debug, PartialEq)]
pub struct Windows {
    /// Residual sum of squares of each window.
    pub rss: Vec<f64>,
    /// Samples in all windows.
    pub samples: usize,
    /// Standard deviation of x over the data.
    pub sd: f64,
}

impl Windows {
    /// NRMSE over all windows, %.
    pub fn nrmse_percent(&self) -> f64 {
        100.0 * self.rms() / self.sd
    }

    /// RMS error over all windows, in x's unit.
    pub fn rms(&self) -> f64 {
        (self.rss.iter().sum::<f64>() / self.samples.max(1) as f64).sqrt()
    }

    /// The median window's NRMSE, %.
    pub fn median_nrmse_percent(&self) -> f64 {
        let per = self.samples as f64 / self.rss.len().max(1) as f64;
        let mut each: Vec<f64> = self.rss.iter().map(|r| (r / per).sqrt()).collect();
        each.sort_by(f64::total_cmp);
        100.0 * each.get(each.len() / 2).copied().unwrap_or(f64::NAN) / self.sd
    }

    /// The windows with each one's residual capped at the larger of its neighbours': a
    /// window alone in missing (a state fit caught in a local minimum, one chaotic stretch)
    /// counts as its neighbours do, while a run of windows that a model misses (a transient
    /// it does not follow) counts in full.
    pub fn contiguous(&self) -> Windows {
        let rss = (0..self.rss.len())
            .map(|i| {
                let left = i.checked_sub(1).map(|j| self.rss[j]);
                let right = self.rss.get(i + 1).copied();
                left.into_iter()
                    .chain(right)
                    .reduce(f64::max)
                    .map_or(self.rss[i], |neighbour| self.rss[i].min(neighbour))
            })
            .collect();
        Windows { rss, ..*self }
    }

    /// As a [`Fit`].
    pub fn fit(&self) -> Fit {
        Fit {
            nrmse_percent: self.nrmse_percent(),
            rms: self.rms(),
        }
    }
}

/// How many times the lowest window's residual sum of squares (the noise's, for a model that
/// follows the record) a window's may be before [`window_errors`] fits its state again from
/// other starts.
pub const REFIT_ABOVE_LOWEST: f64 = 2.0;

/// [`Windows`] of `model` on `data`, windows of `length` samples, each from its own fitted
/// state (the best of the samples' guess, the previous window carried on and the state fitted
/// over the window's first quarter); `None` when a simulation diverges.
pub fn window_errors(model: &SimModel, data: &Data, length: usize) -> Option<Windows> {
    let (shape, c) = Shape::on(model, data);
    let segs = segments(0, data.len(), length.min(data.len()));
    let s = least_squares(&shape, &c, data, &segs, true, 20, None)?;
    let mut at = 0;
    let mut rss: Vec<f64> = segs
        .iter()
        .map(|&(a, b)| {
            let r: f64 = s.residuals[at..at + (b - a)].iter().map(|e| e * e).sum();
            at += b - a;
            r
        })
        .collect();
    let mut states = s.states;
    refit_from_other_starts(&shape, &c, data, &segs, &mut rss, &mut states);
    let n = data.len().max(1) as f64;
    let mean = data.x.iter().sum::<f64>() / n;
    let sd = (data.x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    Some(Windows {
        rss,
        samples: at,
        sd,
    })
}

/// The residual sum of squares of `model` over each of `spans` of `data` (spans in order, not
/// overlapping, not necessarily contiguous), each from its own fitted state, with the
/// multi-start of [`window_errors`] over them all (a window over [`REFIT_ABOVE_LOWEST`] times
/// the lowest fitted again from other starts); `None` for a window whose every start
/// diverges. The gate's short-horizon check fitted its spread windows one at a time, so no
/// window had another to compare with and none was fitted again: a single well driven hard
/// (amplitude 2.2, 800 Hz) was withheld at a median 70 % for the true model (issue 25).
pub fn spread_window_errors(model: &SimModel, data: &Data, spans: &[Span]) -> Vec<Option<f64>> {
    let (shape, c) = Shape::on(model, data);
    let guesses = shooting::initial_states(data, spans);
    let (mut rss, mut states): (Vec<f64>, Vec<State>) = spans
        .iter()
        .zip(guesses)
        .map(|(&span, guess)| {
            least_squares(&shape, &c, data, &[span], true, 20, None)
                .map_or((f64::INFINITY, guess), |s| (s.rss, s.states[0]))
        })
        .unzip();
    refit_from_other_starts(&shape, &c, data, spans, &mut rss, &mut states);
    rss.into_iter()
        .map(|r| r.is_finite().then_some(r))
        .collect()
}

/// A window's state fitted from the samples' guess can land in a local minimum (a stiff
/// single well driven hard, 1 % noise: a near-true model missed 7 of 12 windows by 70 %, the
/// streaming model none, and the comparison went by whose fits landed, issue 25). Each window
/// whose `rss` is over [`REFIT_ABOVE_LOWEST`] times the lowest (or infinite: its fit diverged)
/// is fitted again from the previous window's simulation carried on to its start, which a
/// model that follows the record leaves near the truth, and from the state fitted over its
/// first quarter (a shorter stretch has fewer local minima); the best fit is kept.
fn refit_from_other_starts(
    shape: &Shape,
    c: &[f64],
    data: &Data,
    segs: &[Span],
    rss: &mut [f64],
    states: &mut [State],
) {
    let lowest = rss.iter().copied().fold(f64::INFINITY, f64::min);
    for w in 0..segs.len() {
        if !(rss[w] > REFIT_ABOVE_LOWEST * lowest) && rss[w].is_finite() {
            continue;
        }
        let (a, b) = segs[w];
        let carried = w
            .checked_sub(1)
            .filter(|&p| rss[p].is_finite())
            .and_then(|p| shape.state_after(c, data, (segs[p].0, a + 1), states[p]));
        let quarter = ((b - a) / 4 >= 8)
            .then(|| least_squares(shape, c, data, &[(a, a + (b - a) / 4)], true, 20, None))
            .flatten()
            .map(|q| q.states[0]);
        for start in [carried, quarter].into_iter().flatten() {
            if let Some(again) =
                least_squares(shape, c, data, &[(a, b)], true, 20, Some(vec![start]))
                && again.rss < rss[w]
            {
                rss[w] = again.rss;
                states[w] = again.states[0];
            }
        }
    }
}

/// A free run of `model` over all of `data` from the initial state fitted on its first
/// `segment` samples (fitting one state to a long free run lands in local minima).
pub fn free_run_after_fitted_start(model: &SimModel, data: &Data, segment: usize) -> Option<Fit> {
    let (shape, c) = Shape::on(model, data);
    let first = [(0, segment.min(data.len()))];
    let start = least_squares(&shape, &c, data, &first, true, 20, None)?;
    free_run_fit(model, data, *start.states.first()?)
}

/// A free run of `model` over `data`'s time grid (driven by its `u`) from `start` (recording
/// coordinates): the simulated x, or `None` when it diverges.
pub fn free_run(model: &SimModel, data: &Data, start: (f64, f64)) -> Option<Vec<f64>> {
    let (shape, c) = Shape::on(model, data);
    let n = data.len();
    let mut out = vec![0.0; n];
    shape
        .simulate(&c, data, (0, n), start, &mut out)
        .then_some(out)
}

/// A free run of `model` on `data` from rest (x₀ = v₀ = 0 in recording coordinates) or from
/// a given state: the error of a simulation from the input alone.
pub fn free_run_fit(model: &SimModel, data: &Data, start: (f64, f64)) -> Option<Fit> {
    let simulated = free_run(model, data, start)?;
    let rss = simulated
        .iter()
        .zip(data.x)
        .map(|(s, x)| (s - x).powi(2))
        .sum::<f64>();
    rss.is_finite().then(|| fit_of(rss, data.x))
}
