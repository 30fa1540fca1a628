//! The choice between the streaming model and the refined ones.

use lssi_core::Term;
use serde::Serialize;

use super::shooting::Shape;
use super::summary::SupportChange;
use super::{
    Data, Fit, Refined, Settings, Windows, free_run, free_run_after_fitted_start, refine,
    samples_per_period_at_top, window_errors,
};
use crate::identify::simulate::SimModel;
use crate::identify::supports::{self, Candidates};

/// Which model [`refine_and_check`] reports.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Chosen {
    /// The refined model predicts the held-out half better.
    Refined,
    /// The streaming model: refinement did not lower the held-out error (or failed).
    Streaming,
}

/// What [`refine_and_check`] found.
#[derive(Clone, Debug)]
pub struct Check {
    /// The model to report (the refined one, refit on all the data, or the streaming one).
    pub model: SimModel,
    /// Standard errors of `model`'s nonzero coefficients, in order (when refined).
    pub standard_errors: Option<Vec<f64>>,
    /// Which one it is.
    pub chosen: Chosen,
    /// Why, in one sentence.
    pub reason: String,
    /// Held-out simulation error (second half; initial state of each segment fitted) of
    /// the streaming model and of the model refined on the first half (the support chosen).
    pub held_out: [Option<Fit>; 2],
    /// The reported model's prediction error over the comparison's windows ([`Horizon`]).
    pub prediction: Option<Fit>,
    /// The horizon of the comparison.
    pub horizon: Horizon,
    /// The reported (or, when the streaming model was kept, the refined streaming support's)
    /// paired comparison with the streaming model.
    pub paired: Option<Paired>,
    /// The reported model's prediction error over the first half (the one it was fitted on),
    /// in windows of the comparison's length, each from its fitted state (its NRMSE with a
    /// window alone in missing capped at its neighbours', `Windows::contiguous`):
    /// a model that only the record's steady part admits misses a transient there
    /// ([`crate::identify::quality::misses_first_half`]).
    pub first_half: Option<Fit>,
    /// The reported model's free run over the whole held-out half (one initial state fitted):
    /// long-range behaviour, which a chaotic record does not share with any model.
    pub free_run: Option<Fit>,
    /// The reported model's free run over the whole record from the state x shows at its
    /// start: the RMS about its mean of the run's last half and of x over the same samples
    /// (the run's RMS infinite when it diverges). A model of the harvester reaches the orbit
    /// the harvester was recorded on from where it started
    /// ([`crate::identify::orbit::orbit_not_reached`]).
    pub from_start: Option<(f64, f64)>,
    /// Samples per period at the top of x's band (under ~20: derivatives are biased).
    pub samples_per_period: Option<f64>,
    /// When the reported model damps through higher terms (v³, x²·v, ...) in place of v and,
    /// refined with v beside them, resolves none of them: those terms and their standard
    /// errors from 0 ("v at 0.9, v^3 at 1.2").
    pub unresolved_damping: Option<String>,
    /// Every support refined on the first half, the streaming one first.
    pub supports: Vec<Tried>,
    /// The terms the reported model has and the streaming model has not (added) and the
    /// other way round (removed); both empty when the support is the streaming one.
    pub support_change: (Vec<Term>, Vec<Term>),
    /// A term the record resolves that the printed model lacks and that moves a printed
    /// coefficient beyond its ± ([`unsettled_term`]): the sentence.
    pub unsettled: Option<String>,
}

/// One support [`refine_and_check_among`] refined on the first half.
#[derive(Clone, Debug, PartialEq)]
pub struct Tried {
    /// Its terms.
    pub terms: Vec<Term>,
    /// Its coefficients refined on the first half, with their standard errors (`None`: the
    /// refinement failed or was not run).
    pub refined: Option<Vec<(Term, f64, f64)>>,
    /// Its paired comparison with the streaming model over the held-out windows.
    pub paired: Option<Paired>,
    /// Its held-out simulation error (`None`: the refinement or its prediction failed).
    pub held_out: Option<Fit>,
    /// |coefficient| ÷ standard error, on the first half, of each term it adds to the
    /// streaming model's support (in its order).
    pub added_significance: Vec<f64>,
}

/// How much larger than the best held-out simulation error (RMS) a sparser support's may be
/// and still be taken, beside the paired test ([`Z_BETTER`]): more terms must earn their
/// place by more than this. 0.5 % (was 0.2 %): at 5 % noise on x and on u a hard-driven
/// single well's true support predicted 0.33 % worse than one with a spurious x² and v²
/// (10–15 standard errors each, at an origin 5·10⁻⁴ off), a difference hundreds of windows
/// make "significant" that no user would trade two terms for (issue 25, hostile seed 20448;
/// seeds 20001–20240 and 20481–20560 unchanged by it).
pub const SUPPORT_PARSIMONY: f64 = 0.005;

/// How many of its standard errors (fitted on the first half) a term that another support
/// adds to the streaming model's must be away from zero; a term a support drops must be
/// closer to zero than this in the streaming support refined.
pub const SIGNIFICANT_SE: f64 = 3.0;

/// The two-sided probability of a term [`SIGNIFICANT_SE`] standard errors from zero by
/// chance (0.27 %), the false-alarm rate one test at that bar allows.
const SINGLE_TEST_ALPHA: f64 = 0.0027;

/// The share of x'''s RMS (the model's right-hand side over the fitted half) below which a
/// term other than the oscillator's x and v and the forcing is dropped by backward
/// elimination however many standard errors it clears ([`negligible_term`]).
pub const NEGLIGIBLE_SHARE: f64 = 1e-4;

/// How much more prediction error (a fraction of the best trial's) a support that dropped
/// negligible terms ([`negligible_term`]) may have and still be taken as the sparser.
pub const NEGLIGIBLE_ERROR_RISE: f64 = 0.05;

/// The term of `model` (not x, v, u or a harmonic of Ω) whose contribution to x'' over `data`
/// (velocity by central differences) is the smallest, when it is under [`NEGLIGIBLE_SHARE`] of
/// the right-hand side's RMS: on a clean record the refinement fixes such a term to hundreds of
/// standard errors while it makes up for a part in a million of x'' (fresh hostile 22282, a
/// clean bistable beam at 16 bits: `0.86 x·v²` beside the truth's four terms, 277 standard
/// errors, 5e-6 of x''), which is no term of the harvester's.
fn negligible_term(model: &SimModel, data: &Data) -> Option<Term> {
    let n = data.t.len().min(data.x.len());
    if n < 3 || model.terms.is_empty() {
        return None;
    }
    let k = model.terms.len();
    let mut sums = vec![0.0; k];
    let mut total = 0.0;
    for i in 1..n - 1 {
        let dt = data.t[i + 1] - data.t[i - 1];
        if !(dt > 0.0) {
            continue;
        }
        let x = data.x[i] - model.offsets[0];
        let v = (data.x[i + 1] - data.x[i - 1]) / dt - model.offsets[1];
        let u = data.u.map_or(0.0, |u| u[i]);
        let mut rhs = 0.0;
        for (j, (term, c)) in model.terms.iter().enumerate() {
            let y = c * crate::identify::simulate::evaluate(*term, model.omega, data.t[i], x, v, u);
            sums[j] += y * y;
            rhs += y;
        }
        total += rhs * rhs;
    }
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    model
        .terms
        .iter()
        .zip(&sums)
        .filter(|((t, c), _)| {
            *c != 0.0
                && !oscillator_term(*t)
                && !matches!(t, Term::Input | Term::Sin(_) | Term::Cos(_))
        })
        .map(|((t, _), s)| (*t, (s / total).sqrt()))
        .filter(|&(_, share)| share < NEGLIGIBLE_SHARE)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(t, _)| t)
}

/// The bar (standard errors from zero) a term the streaming selection picked out of `library`
/// candidate terms must clear to stay in backward elimination: the single test's 3σ
/// ([`SIGNIFICANT_SE`]) at Bonferroni's rate, two-sided [`SINGLE_TEST_ALPHA`] ÷ `library`
/// (3.67σ for 11 terms, 3.71σ for 13; never under 3σ, and 3σ when `library` is unknown).
///
/// A term is picked because it looked large: among ten or so library terms that the record
/// does not need, the largest |coefficient| ÷ standard error is ~3σ about one time in
/// thirty, not one in 370, so the 3σ bar of a term fixed in advance lets the selection's own
/// choice through (issue 25, hostile seed 20741: v² at 3.3σ of its refined standard error
/// kept beside the truth's x, v, x³, u, printed as −143 ± 35; the true support was never
/// tried). The linear stiffness x and damping v are no such choice: every oscillator has
/// them, and they keep the single test's bar.
pub fn selection_bar(library: usize) -> f64 {
    if library <= 1 {
        return SIGNIFICANT_SE;
    }
    let alpha = SINGLE_TEST_ALPHA / library as f64;
    // The two-sided normal tail, 2·Q(z) = erfc(z/√2), is decreasing in z: bisect.
    let (mut lo, mut hi) = (SIGNIFICANT_SE, 10.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if libm::erfc(mid / std::f64::consts::SQRT_2) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Whether a term keeps the single test's bar in backward elimination ([`selection_bar`]):
/// the oscillator's own linear stiffness and damping.
fn oscillator_term(term: Term) -> bool {
    matches!(term, Term::Monomial { px, pv } if px + pv == 1)
}

/// How many standard errors of the mean paired difference (window by window of the held-out
/// half) a model's prediction error must be below another's to count as better: a tie keeps
/// the streaming model.
pub const Z_BETTER: f64 = 2.0;

/// How far (standard errors of the paired difference) a refined model of the streaming
/// support whose coefficients disagree with the streaming model's may predict worse and still
/// be taken.
pub const NOT_WORSE_Z: f64 = 1.0;

/// The fewest windows of the held-out half the comparison uses (the horizon is shortened to
/// give as many): a paired test over three windows has no spread to speak of.
pub const MIN_WINDOWS: usize = 12;

/// A prediction error (NRMSE, %) below which differences are the arithmetic's, not the
/// data's (a noiseless simulated record): a sparser support that predicts this well is not
/// beaten by a denser one (an x·v of 10⁻¹¹ is no term of the system).
pub const NUMERICAL_NRMSE_PERCENT: f64 = 1e-4;

/// The largest median NRMSE (%) of the streaming model's windows at which a horizon is taken:
/// over a longer one the record is not predictable (a chaotic trajectory parts from any
/// model), and the horizon is halved.
pub const PREDICTABLE_NRMSE_PERCENT: f64 = 25.0;

/// Two models' prediction errors window by window over the same held-out windows.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Paired {
    /// Mean over the windows of (first's − second's) residual sum of squares ÷ the first's
    /// mean: positive when the second predicts better.
    pub gain: f64,
    /// The gain over its standard error (the windows' spread ÷ √windows).
    pub z: f64,
}

impl Paired {
    /// `first` against `second`, window by window (`None` when the windows differ).
    pub fn of(first: &Windows, second: &Windows) -> Option<Self> {
        let m = first.rss.len();
        if m == 0 || second.rss.len() != m {
            return None;
        }
        let d: Vec<f64> = first
            .rss
            .iter()
            .zip(&second.rss)
            .map(|(a, b)| a - b)
            .collect();
        let mean = d.iter().sum::<f64>() / m as f64;
        let scale = first.rss.iter().sum::<f64>() / m as f64;
        let var = if m > 1 {
            d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (m - 1) as f64
        } else {
            f64::INFINITY
        };
        let se = (var / m as f64).sqrt();
        let z = if se > 0.0 {
            mean / se
        } else if mean > 0.0 {
            f64::INFINITY
        } else if mean < 0.0 {
            f64::NEG_INFINITY
        } else {
            0.0
        };
        Some(Self {
            gain: if scale > 0.0 { mean / scale } else { 0.0 },
            z,
        })
    }
}

/// Refines on the first half, checks on the second, and refines on everything when the
/// refined model predicts better (the streaming support alone: [`refine_and_check_among`]
/// with no other candidate).
pub fn refine_and_check(model: &SimModel, data: &Data) -> Check {
    refine_and_check_among(model, &Candidates::none(), data)
}

/// The horizon of the comparison: two mean periods of x, halved while the streaming model's
/// median window misses by more than [`PREDICTABLE_NRMSE_PERCENT`] (down to an eighth), and
/// the streaming model's windows at it; `None` windows when it diverges.
fn horizon(model: &SimModel, held: &Data, settings: &Settings) -> (usize, Option<Windows>) {
    let floor = (settings.segment / 8).max(16);
    // At least MIN_WINDOWS windows, so that the paired test has a spread to go by.
    let mut length = settings
        .segment
        .min(held.len() / MIN_WINDOWS)
        .max(floor.min(settings.segment));
    loop {
        let windows = window_errors(model, held, length);
        let followed = windows
            .as_ref()
            .is_some_and(|w| w.median_nrmse_percent() <= PREDICTABLE_NRMSE_PERCENT);
        if followed || length / 2 < floor {
            return (length, windows);
        }
        length /= 2;
    }
}

/// One support tried: refined on the first half, and its windows on the second.
struct Trial {
    support: Vec<Term>,
    refined: Option<Refined>,
    windows: Option<Windows>,
    /// The trial it is by backward elimination (one insignificant term fewer).
    parent: Option<usize>,
    /// The origin (x offset) its chain of trials started from: the streaming model's, or the
    /// centre of symmetry of [`recentred`] (the refinement fits the offset when the support
    /// leaves it free, and moves it a little from there).
    origin: f64,
    /// Whether it dropped a term of its parent's that moved x'' by a negligible share
    /// ([`negligible_term`]).
    negligible: bool,
}

/// Terms backward elimination drops at most ([`refine_and_check_among`]).
pub const PRUNE_ROUNDS: usize = 4;

/// Refines the streaming model's support and each of `candidates`' on the first half (each
/// from its least-squares start) and predicts the second half over short windows, each from
/// its own fitted state (the horizon: [`horizon`]). A refined model is taken when its
/// prediction error is below the streaming model's by [`Z_BETTER`] standard errors of the
/// paired difference (or, for a sparser support whose dropped terms the refinement finds
/// insignificant, when it is not above it); among those, the sparsest that the best does not
/// beat by the same test; it is then refined on everything. A tie keeps the streaming model.
pub fn refine_and_check_among(model: &SimModel, candidates: &Candidates, data: &Data) -> Check {
    let n = data.len();
    let half = n / 2;
    let settings = Settings::for_data(data);
    let (train, held) = (data.slice(0, half), data.slice(half, n));
    let (length, streaming_windows) = horizon(model, &held, &settings);
    let predictable = streaming_windows
        .as_ref()
        .is_some_and(|w| w.median_nrmse_percent() <= PREDICTABLE_NRMSE_PERCENT);
    let on_half = Settings {
        segment: length,
        long_pass: false,
        ..settings
    };
    let (streaming_shape, _) = Shape::of(model);
    let mut starts: Vec<(Vec<Term>, Option<SimModel>)> =
        vec![(streaming_shape.terms.clone(), Some(model.clone()))];
    if predictable {
        for support in &candidates.supports {
            let start = supports::least_squares_start(support, model, &train, candidates);
            starts.push((support.clone(), start));
        }
    }
    let mut trials: Vec<Trial> = starts
        .into_iter()
        .map(|(support, start)| {
            let refined = start
                .filter(|_| predictable)
                .and_then(|m| refine(&m, &train, &on_half));
            let windows = refined
                .as_ref()
                .and_then(|r| window_errors(&r.model, &held, length));
            Trial {
                support,
                refined,
                windows,
                parent: None,
                origin: model.offsets[0],
                negligible: false,
            }
        })
        .collect();
    // Backward elimination from the streaming support refined: its least significant term,
    // when under its bar (`selection_bar` over the library for a term the selection picked,
    // SIGNIFICANT_SE for x and v), dropped and the rest refined again
    // (from their refined coefficients), and so on. The streaming selection keeps a spurious
    // term of the equation error at a few percent of noise (a constant, v², x·v² beside the
    // harvester's damping at 2 %: each within one or two of its refined standard errors) that
    // no other support of the sweep leaves out; one at a time, as a term collinear with
    // another (v and x²·v) is insignificant only beside it.
    // And the same from the model recentred on its restoring force's centre of symmetry
    // ([`recentred`]), when it has one off the origin the identifier chose.
    let mut roots = vec![0];
    let mut damping_root = None;
    let recentred_start = recentred(model, data.x).filter(|_| predictable);
    if let Some(start) = &recentred_start {
        let refined = refine(start, &train, &on_half);
        let windows = refined
            .as_ref()
            .and_then(|r| window_errors(&r.model, &held, length));
        trials.push(Trial {
            support: start.terms.iter().map(|(t, _)| *t).collect(),
            refined,
            windows,
            parent: Some(0),
            origin: start.offsets[0],
            negligible: false,
        });
        roots.push(trials.len() - 1);
    }
    // And from that model (recentred, or the streaming one) with the linear damping v added,
    // when its support has none but damps through higher terms (x·v, v³, x²·v): at 2 % noise
    // on a single well driven hard the streaming selection took x·v + v³ in place of v
    // (issue 25), and no support one term away has v without them.
    let damping = Term::Monomial { px: 0, pv: 1 };
    // Or when it has no term odd in v at all while it is driven (sin/cos or u): a forced
    // model that cannot dissipate lost its damping (issue 25: at a field device's rate, 23
    // samples a forcing period, the streaming selection kept x³, x·v², cos(Ωt) and neither x
    // nor v); the linear stiffness x is then added too when it is missing, and backward
    // elimination drops whichever of the two the record does not resolve.
    let driven = |m: &SimModel| {
        m.terms
            .iter()
            .any(|(t, c)| *c != 0.0 && matches!(t, Term::Sin(_) | Term::Cos(_) | Term::Input))
    };
    let odd_in_v = |m: &SimModel| {
        m.terms
            .iter()
            .any(|(t, c)| *c != 0.0 && matches!(t, Term::Monomial { pv, .. } if pv % 2 == 1))
    };
    let undamped = |m: &SimModel| {
        !m.terms.iter().any(|(t, c)| *t == damping && *c != 0.0) && (odd_in_v(m) || driven(m))
    };
    let stiffness = Term::Monomial { px: 1, pv: 0 };
    let base_model = recentred_start.as_ref().unwrap_or(model);
    if predictable && undamped(base_model) {
        let mut support: Vec<Term> = base_model
            .terms
            .iter()
            .filter(|(_, c)| *c != 0.0)
            .map(|(t, _)| *t)
            .collect();
        // In the library's order: after the constant and x.
        let at = support
            .iter()
            .position(|t| !matches!(t, Term::Constant | Term::Monomial { px: 1, pv: 0 }))
            .unwrap_or(support.len());
        support.insert(at, damping);
        if !odd_in_v(base_model) && !support.contains(&stiffness) {
            let at = support
                .iter()
                .position(|t| *t != Term::Constant)
                .unwrap_or(support.len());
            support.insert(at, stiffness);
        }
        // A support already tried (a sweep's neighbour of the streaming one) is that trial.
        if let Some(seen) = trials.iter().position(|t| t.support == support) {
            if !roots.contains(&seen) {
                roots.push(seen);
            }
            damping_root = Some(seen);
        } else if let Some(start) =
            supports::least_squares_start(&support, base_model, &train, candidates)
        {
            let refined = refine(&start, &train, &on_half);
            let windows = refined
                .as_ref()
                .and_then(|r| window_errors(&r.model, &held, length));
            trials.push(Trial {
                support,
                refined,
                windows,
                parent: Some(*roots.last().unwrap_or(&0)),
                origin: start.offsets[0],
                negligible: false,
            });
            roots.push(trials.len() - 1);
            damping_root = Some(trials.len() - 1);
        }
    }
    let picked_bar = selection_bar(candidates.library);
    let drop_bar = |t: Term| {
        if oscillator_term(t) {
            SIGNIFICANT_SE
        } else {
            picked_bar
        }
    };
    for root in roots.into_iter().filter(|_| predictable) {
        let mut base = root;
        // The damping's root has v to add and as many higher terms to drop.
        // The damping's root keeps the v it adds: dropped, its chain would only go back to
        // the streaming support (beside v³, v is the less significant of two collinear
        // dampings on a short record, issue 25), and no support with v in place of v³ would
        // be tried.
        let adds_damping =
            trials[root].support.contains(&damping) && !streaming_shape.terms.contains(&damping);
        let rounds = if adds_damping {
            2 * PRUNE_ROUNDS
        } else {
            PRUNE_ROUNDS
        };
        for _ in 0..rounds {
            let Some(r) = trials[base].refined.as_ref() else {
                break;
            };
            // The least significant of the terms under their bar: a term the selection
            // picked out of the library under `selection_bar`, x and v under the single test's.
            let least = r
                .model
                .terms
                .iter()
                .zip(&r.standard_errors)
                .filter(|((t, c), se)| {
                    *c != 0.0 && se.is_finite() && **se > 0.0 && !(adds_damping && *t == damping)
                })
                .map(|((t, c), se)| (*t, c.abs() / se))
                .filter(|&(t, z)| z < drop_bar(t))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            // Or, when every term clears its bar, one that moves x'' by a negligible share
            // however precisely the record fixes it ([`negligible_term`]).
            let negligible = least.is_none();
            let Some(drop) = least
                .map(|(t, _)| t)
                .or_else(|| negligible_term(&r.model, &train))
            else {
                break;
            };
            let support: Vec<Term> = trials[base]
                .support
                .iter()
                .filter(|t| **t != drop)
                .copied()
                .collect();
            let origin = trials[base].origin;
            if support.is_empty()
                || trials
                    .iter()
                    .any(|t| t.support == support && t.origin == origin && t.refined.is_some())
            {
                break;
            }
            let start = SimModel {
                terms: r
                    .model
                    .terms
                    .iter()
                    .filter(|(t, _)| *t != drop)
                    .copied()
                    .collect(),
                ..r.model.clone()
            };
            let refined = refine(&start, &train, &on_half);
            let windows = refined
                .as_ref()
                .and_then(|r| window_errors(&r.model, &held, length));
            trials.push(Trial {
                support,
                refined,
                windows,
                parent: Some(base),
                origin,
                negligible,
            });
            base = trials.len() - 1;
        }
    }
    let trials = trials;
    let against_streaming: Vec<Option<Paired>> = trials
        .iter()
        .map(|t| Paired::of(streaming_windows.as_ref()?, t.windows.as_ref()?))
        .collect();
    // A term a support adds must be significant where it was fitted (the first half): its
    // standard errors count the error of the streaming model's Ω, so a sin(Ωt) beside
    // cos(Ωt) that only makes up for that error is not taken.
    let streaming_terms = &trials[0].support;
    let significance = |t: &Trial, term: Term| -> Option<f64> {
        let r = t.refined.as_ref()?;
        let j = r.model.terms.iter().position(|(x, _)| *x == term)?;
        let se = r.standard_errors.get(j)?;
        se.is_finite().then(|| r.model.terms[j].1.abs() / se)
    };
    // A sin(kΩt) added beside cos(kΩt) (or the other way round) shifts the forcing's phase;
    // by less than kΩ times a sample period that is where the samples fall, not a term of the
    // system (paper eq. 17: sin(2t) of 0.009 beside 5 cos(2t), 10 standard errors, a phase of
    // half a sample).
    let period = {
        let mut steps: Vec<f64> = data.t.windows(2).map(|w| w[1] - w[0]).collect();
        steps.sort_by(f64::total_cmp);
        steps.get(steps.len() / 2).copied().unwrap_or(0.0)
    };
    let within_a_sample = |t: &Trial, term: Term| -> bool {
        let (k, partner) = match term {
            Term::Sin(k) => (k, Term::Cos(k)),
            Term::Cos(k) => (k, Term::Sin(k)),
            _ => return false,
        };
        let Some(r) = t.refined.as_ref() else {
            return false;
        };
        let coef = |x: Term| r.model.terms.iter().find(|(y, _)| *y == x).map(|(_, c)| *c);
        match (coef(term), coef(partner)) {
            (Some(c), Some(p)) if p != 0.0 => {
                (c / p).atan().abs() <= f64::from(k) * model.omega * period
            }
            _ => false,
        }
    };
    let adds_significant = |t: &Trial| {
        t.support
            .iter()
            .filter(|x| !streaming_terms.contains(x))
            .all(|&x| {
                significance(t, x).is_some_and(|z| z >= SIGNIFICANT_SE) && !within_a_sample(t, x)
            })
    };
    // A term dropped must be insignificant in the streaming support refined.
    let drops_insignificant = |t: &Trial| {
        streaming_terms
            .iter()
            .filter(|x| !t.support.contains(x))
            .all(|&x| significance(&trials[0], x).is_some_and(|z| z < SIGNIFICANT_SE))
    };
    // The streaming support refined is the maximum-likelihood estimate under white
    // measurement noise, which the streaming (equation-error) estimate is not: where the two
    // disagree by more than the refined model's own standard errors, the data resolves the
    // streaming model's bias, and the refined one is taken unless it predicts worse.
    let disagreement = disagreement(model, trials[0].refined.as_ref());
    let eligible: Vec<usize> = (0..trials.len())
        .filter(|&i| {
            let Some(p) = against_streaming[i] else {
                return false;
            };
            let sparser = trials[i].support.len() < streaming_terms.len();
            // As many terms as the streaming support but of a lower total degree (v in place of
            // v³ for a weak damping the record cannot tell apart: a steady oscillation's v³ is
            // ¾ A² v), reached by backward elimination from the root with v added.
            let simpler = trials[i].support.len() == streaming_terms.len()
                && degree(&trials[i].support) < degree(streaming_terms);
            let resolved = i == 0 && disagreement.is_some_and(|d| d >= SIGNIFICANT_SE);
            // A term added must also earn its place against the same support without it,
            // refined the same way (the streaming support refined).
            let adds = trials[i]
                .support
                .iter()
                .any(|x| !streaming_terms.contains(x));
            let beats_its_base = |pruned: bool| {
                !adds
                    // A sparser support reached by backward elimination, every term it adds
                    // significant, that predicts no worse: the data resolves the terms it
                    // adds better than the ones it drops (v for x·v + v³, or for v³).
                    || (pruned && (sparser || simpler))
                    || match (&trials[0].windows, &trials[i].windows) {
                        (Some(w0), Some(wi)) => {
                            Paired::of(w0, wi).is_some_and(|q| q.z >= Z_BETTER)
                        }
                        _ => true,
                    }
            };
            // A term dropped by backward elimination was insignificant where it was
            // dropped: the sparser model is taken unless it predicts worse than the one it
            // came from (by NOT_WORSE_Z) or than the streaming model.
            // (or by the parsimony margin: a tie of RMS errors is no reason for more terms).
            // v in place of v³ (`simpler`) is taken unless the prediction separates them (by
            // Z_BETTER, the test a better model passes): the lower degree when the record
            // cannot tell them apart (issue 25: at 5 % noise on a slow double well, v and v³
            // predict the held-out half within a fraction of a per cent of each other, and the
            // paired test's z between such nearly equal models is mostly chance).
            // So is the model recentred on its restoring force's centre of symmetry (and its
            // chain), which writes a double well about its middle with no x² and no constant
            // where the streaming model wrote it about a well: against the streaming model, a
            // difference the paired test does not separate by Z_BETTER is no reason for the
            // two terms (issue 25, hostile seed 22738: 10 periods in one well at 2 % noise,
            // the truth recentred predicted 1.1 % worse at z = −1.5, and the model about the
            // well was printed).
            let recentred = trials[i].origin != model.offsets[0];
            let tolerance = if simpler || recentred {
                Z_BETTER
            } else {
                NOT_WORSE_Z
            };
            let not_worse = |wj: Option<&Windows>| match (wj, &trials[i].windows) {
                (Some(wj), Some(wi)) => {
                    Paired::of(wj, wi).is_some_and(|q| q.z >= -tolerance)
                        || wi.rms() <= wj.rms() * (1.0 + SUPPORT_PARSIMONY)
                }
                _ => false,
            };
            // A simpler support is held to the models of its size it replaces (the streaming
            // support, refined or not), not to its parent, which has both dampings (v and v³)
            // and always predicts a little better for its extra term: that term was found
            // insignificant where it was fitted, and the paired test between nested models
            // separates differences of 0.2 % (issue 25).
            let pruned = trials[i].parent.is_some_and(|parent| {
                (simpler || not_worse(trials[parent].windows.as_ref()))
                    && not_worse(trials[0].windows.as_ref())
                    && not_worse(streaming_windows.as_ref())
            });
            adds_significant(&trials[i])
                && beats_its_base(pruned)
                && (p.z >= Z_BETTER
                    || (resolved && p.z >= -NOT_WORSE_Z)
                    || (sparser && p.gain >= 0.0 && drops_insignificant(&trials[i]))
                    || pruned)
        })
        .collect();
    let error = |i: usize| {
        trials[i]
            .windows
            .as_ref()
            .map_or(f64::INFINITY, Windows::rms)
    };
    // The sparsest of those the best does not beat (paired test, and the parsimony margin);
    // among equally sparse, the lowest degree (v before x²·v for a damping the data cannot
    // tell apart), then the least error; the streaming support first among equals.
    let nrmse = |i: usize| {
        trials[i]
            .windows
            .as_ref()
            .map_or(f64::INFINITY, Windows::nrmse_percent)
    };
    if std::env::var_os("LSSI_REFINE_DEBUG").is_some() {
        for (i, t) in trials.iter().enumerate() {
            let names: Vec<String> = t
                .support
                .iter()
                .map(|x| x.name(model.omega).to_string())
                .collect();
            let z: Vec<String> = t.refined.as_ref().map_or(vec![], |r| {
                r.model
                    .terms
                    .iter()
                    .zip(&r.standard_errors)
                    .map(|((_, c), se)| format!("{c:.4e}@{:.1}", c.abs() / se))
                    .collect()
            });
            eprintln!(
                "refine trial {i} parent {:?} origin {:.4e} [{}] z [{}] nrmse {:.6} vs streaming z {:?} eligible {}",
                t.parent,
                t.origin,
                names.join(", "),
                z.join(", "),
                nrmse(i),
                against_streaming[i].map(|p| (p.gain, p.z)),
                eligible.contains(&i)
            );
        }
    }
    // Another support of the sweep (not one backward elimination reached) that leaves out a
    // streaming term its own refinement holds beyond the bar a picked term clears is not
    // taken for sparsity alone: over the held-out windows, each from its fitted state, a term
    // that acts on the record's transient or its larger swings can hide (fresh hostile seed
    // 21030, a clean bistable beam's well: x³ at 4,236 standard errors in the streaming
    // support refined, dropped for a support of the sweep that predicted the windows within
    // 0.001 %, and whose free run from the record's start diverges).
    let keeps_resolved = |i: usize| {
        trials[i].parent.is_some()
            || streaming_terms
                .iter()
                .filter(|x| !trials[i].support.contains(x))
                .all(|&x| significance(&trials[0], x).is_none_or(|z| z < picked_bar))
    };
    let eligible: Vec<usize> = eligible
        .into_iter()
        .filter(|&i| {
            keeps_resolved(i)
                || trials[0]
                    .windows
                    .as_ref()
                    .zip(trials[i].windows.as_ref())
                    .and_then(|(w0, wi)| Paired::of(w0, wi))
                    .is_some_and(|q| q.z >= Z_BETTER)
        })
        .collect();
    let best = eligible
        .iter()
        .copied()
        .min_by(|&a, &b| error(a).total_cmp(&error(b)));
    // A chain of negligible terms dropped ([`negligible_term`]) predicts within
    // [`NEGLIGIBLE_ERROR_RISE`] of the best: on a clean record the term made up for a part in
    // a million of x'' (22282: 0.002265 % against 0.002220 %).
    let negligibly_worse = |i: usize| {
        let mut at = i;
        while trials[at].negligible {
            match trials[at].parent {
                Some(p) => at = p,
                None => return false,
            }
        }
        at != i && best.is_some_and(|b| error(i) <= error(b) * (1.0 + NEGLIGIBLE_ERROR_RISE))
    };
    let pick = best.and_then(|b| {
        eligible
            .iter()
            .copied()
            .filter(|&i| {
                i == b
                    || error(i) <= error(b) * (1.0 + SUPPORT_PARSIMONY)
                    || nrmse(i) <= NUMERICAL_NRMSE_PERCENT
                    || negligibly_worse(i)
                    || trials[b]
                        .windows
                        .as_ref()
                        .zip(trials[i].windows.as_ref())
                        .and_then(|(wb, wi)| Paired::of(wi, wb))
                        .is_some_and(|p| p.z < Z_BETTER)
            })
            .min_by(|&a, &b| {
                trials[a]
                    .support
                    .len()
                    .cmp(&trials[b].support.len())
                    .then(degree(&trials[a].support).cmp(&degree(&trials[b].support)))
                    .then(error(a).total_cmp(&error(b)))
            })
    });
    let change = |support: &[Term]| {
        (
            support
                .iter()
                .filter(|t| !streaming_terms.contains(t))
                .copied()
                .collect::<Vec<Term>>(),
            streaming_terms
                .iter()
                .filter(|t| !support.contains(t))
                .copied()
                .collect::<Vec<Term>>(),
        )
    };
    let support_change = pick.map_or((vec![], vec![]), |i| change(&trials[i].support));
    // v beside the higher dampings (v³, x²·v, ...) of a model that damps without it, refined
    // together: when neither v nor any of them is resolved there (each under SIGNIFICANT_SE)
    // the record cannot tell which damps, and a model reported with a higher damping in place
    // of v (the v-model predicting worse by Z_BETTER, or not tried) is that choice made by
    // the noise (issue 25: 5 % noise, 222 Hz, 6 s: v at 0.9 and v³ at 1.2 standard errors
    // together, each over 4 alone).
    let reported_support = &trials[pick.unwrap_or(0)].support;
    let higher_damping =
        |t: &Term| matches!(t, Term::Monomial { pv, .. } if pv % 2 == 1) && *t != damping;
    // The root is the trial that added v, or else the nearest trial on the reported one's
    // chain of backward elimination whose support held v beside a higher damping: the
    // streaming support with both, from which elimination dropped v as the less significant
    // of two collinear dampings (issue 25, hostile seed 20179: 9 periods at 5 % noise, v at
    // 0.2 and v³ at 0.3 standard errors together, v³ printed in place of v).
    let chain_root = || {
        let mut at = trials[pick.unwrap_or(0)].parent;
        while let Some(i) = at {
            let s = &trials[i].support;
            if s.contains(&damping) && s.iter().any(higher_damping) {
                return Some(i);
            }
            at = trials[i].parent;
        }
        None
    };
    let unresolved_damping = damping_root
        .or_else(chain_root)
        .filter(|_| {
            !reported_support.contains(&damping) && reported_support.iter().any(higher_damping)
        })
        .and_then(|root| {
            let r = trials[root].refined.as_ref()?;
            let z: Vec<(Term, f64)> = r
                .model
                .terms
                .iter()
                .zip(&r.standard_errors)
                .filter(|((t, c), _)| *c != 0.0 && (*t == damping || higher_damping(t)))
                .map(|((t, c), se)| (*t, c.abs() / se))
                .collect();
            (z.len() >= 2 && z.iter().all(|(_, z)| z.is_finite() && *z < SIGNIFICANT_SE)).then(
                || {
                    z.iter()
                        .map(|(t, z)| format!("{} at {z:.1}", t.name(model.omega)))
                        .collect::<Vec<_>>()
                        .join(", ")
                },
            )
        });
    let held_streaming = streaming_windows.as_ref().map(Windows::fit);
    let held_refined = trials[pick.unwrap_or(0)].windows.as_ref().map(Windows::fit);
    let paired = against_streaming[pick.unwrap_or(0)];
    let others = trials.len() - 1;
    let seconds = held
        .t
        .get(length.min(held.len()).saturating_sub(1))
        .copied()
        .unwrap_or(0.0)
        - held.t.first().copied().unwrap_or(0.0);
    let windows_count = streaming_windows.as_ref().map_or(0, |w| w.rss.len());
    let over = format!(
        "over {windows_count} windows of {length} samples ({seconds:.3} s) of the held-out half, each from its fitted state"
    );
    let z_text =
        |p: Option<Paired>| p.map_or("no paired test".to_owned(), |p| format!("z = {:.1}", p.z));
    let reason = match (predictable, held_streaming, held_refined) {
        (false, Some(s), _) => format!(
            "not refined: even over {length} samples ({seconds:.3} s) the streaming model's prediction misses the held-out half by {:.0} % (median window over {PREDICTABLE_NRMSE_PERCENT} %: the record is not predictable by this model)",
            streaming_windows
                .as_ref()
                .map_or(s.nrmse_percent, Windows::median_nrmse_percent)
        ),
        (false, None, _) => {
            "not refined: the streaming model's prediction diverges on the held-out half".to_owned()
        }
        (true, Some(s), Some(r)) if pick.is_some() => {
            let mut text = format!(
                "refined: prediction error {:.3} % against the streaming model's {:.3} % {over} ({})",
                r.nrmse_percent,
                s.nrmse_percent,
                z_text(paired)
            );
            if pick == Some(0)
                && let Some(d) = disagreement
            {
                text.push_str(&format!(
                    "; the streaming coefficients lie up to {d:.1} standard errors from the refined ones"
                ));
            }
            if pick != Some(0) {
                let on_streaming = match &trials[0].windows {
                    Some(w) => format!("{:.3} %", w.nrmse_percent()),
                    None => "no fit".to_owned(),
                };
                let picked = &trials[pick.unwrap_or(0)];
                let origin = picked.origin;
                let how = if origin != model.offsets[0] {
                    format!(
                        "the model recentred on its restoring force's centre of symmetry (x = {origin:.4e}), then terms insignificant in the refinement dropped"
                    )
                } else if picked.parent.is_some() {
                    "terms insignificant in the refinement dropped one at a time".to_owned()
                } else {
                    "another support of the sweep".to_owned()
                };
                text.push_str(&format!(
                    ", on {how} ({}; the streaming support refined: {on_streaming})",
                    describe_change(&support_change, model.omega)
                ));
            }
            if others > 0 {
                text.push_str(&format!(
                    "; {others} other support{} tried",
                    if others == 1 { "" } else { "s" }
                ));
            }
            text
        }
        (true, Some(s), Some(r)) => format!(
            "streaming model kept: the refined one predicts {:.3} % against {:.3} % {over} ({}; {Z_BETTER} needed), and {}",
            r.nrmse_percent,
            s.nrmse_percent,
            z_text(paired),
            match disagreement {
                Some(d) if d >= SIGNIFICANT_SE => format!(
                    "though the streaming coefficients lie up to {d:.1} of its standard errors away, it predicts worse"
                ),
                Some(d) =>
                    format!("the streaming coefficients lie within {d:.1} of its standard errors"),
                None => "its standard errors could not be estimated".to_owned(),
            }
        ),
        _ => "not refined: the refinement did not converge".to_owned(),
    };
    let supports = trials
        .iter()
        .zip(&against_streaming)
        .map(|(t, paired)| Tried {
            terms: t.support.clone(),
            refined: t.refined.as_ref().map(|r| {
                r.model
                    .terms
                    .iter()
                    .zip(&r.standard_errors)
                    .map(|((term, c), se)| (*term, *c, *se))
                    .collect()
            }),
            paired: *paired,
            held_out: t.windows.as_ref().map(Windows::fit),
            added_significance: t.refined.as_ref().map_or(vec![], |r| {
                r.model
                    .terms
                    .iter()
                    .zip(&r.standard_errors)
                    .filter(|((x, _), _)| !streaming_shape.terms.contains(x))
                    .map(|((_, c), se)| c.abs() / se)
                    .collect()
            }),
        })
        .collect();
    let on_all = Settings {
        segment: length,
        // Segments four times as long only where the streaming model follows them (a chaotic
        // record parts from any model well before).
        long_pass: length == settings.segment
            && window_errors(model, &held, 4 * length)
                .is_some_and(|w| w.median_nrmse_percent() <= PREDICTABLE_NRMSE_PERCENT),
        ..settings
    };
    let chosen_half = pick.and_then(|i| trials.into_iter().nth(i).and_then(|t| t.refined));
    let (model, standard_errors, chosen) = match chosen_half {
        Some(half_model) => match refine(&half_model.model, data, &on_all) {
            Some(all) => {
                let se = widen_by_half(&all, &half_model);
                (all.model, Some(se), Chosen::Refined)
            }
            None => (
                half_model.model,
                Some(half_model.standard_errors),
                Chosen::Refined,
            ),
        },
        None => (model.clone(), None, Chosen::Streaming),
    };
    let support_change = if chosen == Chosen::Refined {
        support_change
    } else {
        (vec![], vec![])
    };
    let prediction = window_errors(&model, &held, length).map(|w| w.fit());
    let first_half = window_errors(&model, &train, length).map(|w| w.contiguous().fit());
    if std::env::var_os("LSSI_REFINE_DEBUG").is_some() {
        eprintln!(
            "lssi: first half {:?} held-out {:?}",
            first_half.map(|f| f.nrmse_percent),
            prediction.map(|f| f.nrmse_percent)
        );
    }
    let free_run = free_run_after_fitted_start(&model, &held, length);
    let from_start = run_from_recorded_start(&model, data);
    let mut check = Check {
        model,
        standard_errors,
        chosen,
        reason,
        held_out: [held_streaming, held_refined],
        prediction,
        horizon: Horizon {
            samples: length,
            seconds,
            windows: windows_count,
        },
        paired,
        first_half,
        free_run,
        from_start,
        samples_per_period: samples_per_period_at_top(data.x),
        unresolved_damping,
        supports,
        support_change,
        unsettled: None,
    };
    check.unsettled = unsettled_term(&check, picked_bar);
    check
}

/// The least move of a printed coefficient, as a fraction of it, that [`unsettled_term`]
/// counts: on a clean record the printed ± are a numerical floor (hostile seeds 20073, 21157:
/// an x·v² at 9–11 standard errors moved x and x³ by 10⁻⁶ of themselves, beyond two of
/// theirs), and a move of a per cent is below anything a user reads as another model.
pub const UNSETTLED_MOVE: f64 = 0.01;

/// Whether a support the refinement tried holds every printed term and more, each term it
/// adds resolved beyond `bar` standard errors on the first half, and moves a printed
/// coefficient by more than two of its printed standard errors: the record resolves a term
/// the held-out half did not take (it acts on the transient, or the larger swings, where the
/// held-out windows are steady), and the printed ± does not cover what it does to the others.
/// Fresh hostile seed 21120 (a single well forced at 2.5 times its resonance, 1 % noise,
/// 10-bit ADC): `(−13,431 ± 46) x − 22.4 v + 3.12 cos(284.3t)` with exit 0; x³ refined at 13.4
/// standard errors, and with it x is −12,947 (truth −12,930, x³ −7.87e10). The sentence, or
/// `None`.
fn unsettled_term(check: &Check, bar: f64) -> Option<String> {
    let omega = check.model.omega;
    let printed: Vec<(Term, f64, f64)> = check
        .model
        .terms
        .iter()
        .filter(|(_, c)| *c != 0.0)
        .enumerate()
        .map(|(j, (t, c))| {
            let se = match (&check.standard_errors, check.chosen) {
                (Some(se), Chosen::Refined) => se.get(j).copied(),
                _ => streaming_standard_error(check, *t, *c),
            };
            (*t, *c, se.unwrap_or(0.0))
        })
        .collect();
    check.supports.iter().find_map(|tried| {
        let refined = tried.refined.as_ref()?;
        if !printed
            .iter()
            .all(|(t, _, _)| tried.terms.contains(t))
            || tried.terms.len() <= printed.len()
        {
            return None;
        }
        let added: Vec<&(Term, f64, f64)> = refined
            .iter()
            .filter(|(t, _, _)| !printed.iter().any(|(p, _, _)| p == t))
            .collect();
        // A constant or x² added moves the model's origin (a bistable beam's intrawell motion
        // is described about its well as well as about the midpoint: hostile seed 20051, x²
        // at 1,826 standard errors and x from +982 to −1,965): not another term of the same
        // equation.
        let moves_origin = |t: &Term| matches!(t, Term::Monomial { px, pv: 0 } if px % 2 == 0);
        if added.is_empty()
            || added.iter().any(|(t, _, _)| moves_origin(t))
            || !added
                .iter()
                .all(|(_, c, se)| *se > 0.0 && c.abs() >= bar * se)
        {
            return None;
        }
        let (term, c, se, other) = printed.iter().find_map(|&(t, c, se)| {
            let (_, other, _) = refined.iter().find(|(r, _, _)| *r == t)?;
            let moved = (other - c).abs();
            (moved > 2.0 * se && moved > UNSETTLED_MOVE * c.abs())
                .then_some((t, c, se, *other))
        })?;
        let names: Vec<String> = added
            .iter()
            .map(|(t, c, se)| {
                format!("{} ({:.1} standard errors)", t.name(omega), c.abs() / se)
            })
            .collect();
        Some(format!(
            "the record resolves {} on its first half, which the held-out half did not take, and with {} the printed {} moves from {c:.5e} ± {se:.2e} to {other:.5e}: the record cannot settle the model (a longer record, or one with larger swings)",
            names.join(", "),
            if added.len() == 1 { "it" } else { "them" },
            term.name(omega)
        ))
    })
}

/// `model`'s free run over all of `data` from the state x shows at its start (a cubic fitted
/// to its first quarter-period of samples, by x's crossings of its mean, 5 at least: its
/// value and slope): the RMS about its mean of the run's last half and of `data`'s x over
/// the same samples (the run's infinite when it diverges or goes [`ESCAPE_RANGES`] of x's
/// range beyond it), or `None` when x does not cross
/// its mean a few times. Not the state the model's own fit to the first window gives: a
/// model with another orbit beside the recorded one is fitted onto it from a state the
/// samples contradict (hostile seed 20925: x₀ 2.64e-3 fitted, 1.86e-3 recorded, noise 8e-5).
fn run_from_recorded_start(model: &SimModel, data: &Data) -> Option<(f64, f64)> {
    // Up to the record's first gap (samples left out: a stuck sensor, a burst, a dropped
    // stretch): the simulation steps over a gap in one long step, which is no free run of the
    // harvester (a bistable record with 1,000 stuck rows left out "diverged" there).
    let mut steps: Vec<f64> = data.t.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return None;
    }
    let middle = steps.len() / 2;
    let typical = *steps.select_nth_unstable_by(middle, f64::total_cmp).1;
    let n = data
        .t
        .windows(2)
        .position(|w| !(w[1] - w[0] <= 1.5 * typical))
        .map_or(data.len(), |i| i + 1);
    let data = &data.slice(0, n);
    let mean = crate::identify::stretch::mean(data.x);
    let rms = crate::identify::stretch::rms(data.x);
    let crossings = data
        .x
        .windows(2)
        .filter(|w| (w[0] - mean) < 0.0 && (w[1] - mean) >= 0.0)
        .count();
    if crossings < 4 || !(rms > 0.0) {
        return None;
    }
    let m = (n / crossings / 4).clamp(5, 64).min(n);
    let t0 = data.t[0];
    let first: Vec<(f64, f64)> = (0..m).map(|i| (data.t[i] - t0, data.x[i])).collect();
    let start = crate::identify::blemish::cubic_fit_slope_at(&first, 0.0)?;
    if std::env::var_os("LSSI_REFINE_DEBUG").is_some() {
        eprintln!("lssi: recorded start {start:?} (a cubic over {m} samples)");
    }
    let half = n / 2;
    let recorded = crate::identify::stretch::rms(&data.x[half..]);
    let (lo, hi) = data
        .x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(*x), hi.max(*x))
        });
    let reach = ESCAPE_RANGES * (hi - lo);
    let simulated = free_run(model, data, start)
        .filter(|run| run.iter().all(|x| *x > lo - reach && *x < hi + reach))
        .map_or(f64::INFINITY, |run| {
            crate::identify::stretch::rms(&run[half..])
        });
    (recorded > 0.0).then_some((simulated, recorded))
}

/// How many of x's ranges beyond them a free run from the record's start may go before it
/// counts as escaped ([`run_from_recorded_start`]: its RMS then infinite).
pub const ESCAPE_RANGES: f64 = 10.0;

/// The standard errors of the model refined on the whole record, each widened to the distance
/// between its coefficient and the first half's refinement of the same term where that is
/// larger (as the systems' `widen_by_half`): refinement's ± is the noise's alone, and a bias
/// the record's length does not average out (the derivatives' at a few tens of samples a
/// period, a drift) moves the coefficient between the half and the whole by more. At 125–500
/// Hz the damping was printed with a ± of 0.1 % for an error of 0.1–1.7 %
/// (`scripts/lowest-rate.sh`). Two estimates of one coefficient from nested records differ by
/// about the whole record's standard error when the noise alone parts them, so this widens
/// only where something else does.
fn widen_by_half(all: &Refined, half: &Refined) -> Vec<f64> {
    all.standard_errors
        .iter()
        .enumerate()
        .map(|(j, &se)| {
            let spread = match (all.model.terms.get(j), half.model.terms.get(j)) {
                (Some((a, ca)), Some((b, cb))) if a == b => (ca - cb).abs(),
                _ => return se,
            };
            if spread.is_finite() && !(se >= spread) {
                spread
            } else {
                se
            }
        })
        .collect()
}

/// The model with its origin moved to the centre of symmetry of its restoring force, the
/// inflection point of a cubic a·x + b·x² + c·x³ (x shifted by −b/(3c), where its x² term
/// vanishes), with no x² and no constant: a symmetric double well's model about the middle.
/// The identifier places the origin at an equilibrium, which for a double well can be a well
/// (then the same restoring force takes an x² term and moves the wells' midpoint off 0; a
/// slight miss of the well takes spurious terms too). `None` without x² and x³ terms, or
/// when the centre lies outside the recorded range of x (an asymmetric force's x², not a
/// shifted origin). Other terms keep their coefficients as a start.
pub fn recentred(model: &SimModel, x: &[f64]) -> Option<SimModel> {
    let coef = |px: u8| {
        model
            .terms
            .iter()
            .find(|(t, c)| *t == Term::Monomial { px, pv: 0 } && *c != 0.0)
            .map(|(_, c)| *c)
    };
    let (a, b, c) = (coef(1)?, coef(2)?, coef(3)?);
    let shift = -b / (3.0 * c);
    let (lo, hi) = x
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let centre = model.offsets[0] + shift;
    if !(shift.is_finite() && centre >= lo && centre <= hi) {
        return None;
    }
    let terms = model
        .terms
        .iter()
        .filter(|(t, c)| {
            *c != 0.0 && !matches!(t, Term::Constant | Term::Monomial { px: 2, pv: 0 })
        })
        .map(|&(t, k)| match t {
            Term::Monomial { px: 1, pv: 0 } => (t, a + 2.0 * b * shift + 3.0 * c * shift * shift),
            _ => (t, k),
        })
        .collect();
    Some(SimModel {
        terms,
        omega: model.omega,
        offsets: [centre, model.offsets[1]],
    })
}

/// The total polynomial degree of a support's monomials.
fn degree(support: &[Term]) -> u32 {
    support
        .iter()
        .map(|t| match t {
            Term::Monomial { px, pv } => u32::from(*px) + u32::from(*pv),
            _ => 0,
        })
        .sum()
}

/// The largest |streaming − refined| ÷ standard error over the streaming model's terms, the
/// refined model being the streaming support refined (on the first half).
fn disagreement(streaming: &SimModel, refined: Option<&Refined>) -> Option<f64> {
    let refined = refined?;
    let mut largest: Option<f64> = None;
    for ((term, c), se) in refined.model.terms.iter().zip(&refined.standard_errors) {
        let Some((_, s)) = streaming.terms.iter().find(|(t, _)| t == term) else {
            continue;
        };
        if !(se.is_finite() && *se > 0.0) {
            return None;
        }
        let d = (s - c).abs() / se;
        largest = Some(largest.map_or(d, |l: f64| l.max(d)));
    }
    largest
}

/// The horizon the models were compared over.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Horizon {
    /// Samples per window.
    pub samples: usize,
    /// Seconds per window.
    pub seconds: f64,
    /// Windows of the held-out half.
    pub windows: usize,
}

impl Check {
    /// The change of support, terms named at Ω = `omega`; `None` when the reported support
    /// is the streaming model's.
    pub fn support_changed(&self, omega: f64) -> Option<SupportChange> {
        let (added, removed) = &self.support_change;
        let names = |terms: &[Term]| terms.iter().map(|t| t.name(omega).to_string()).collect();
        (!added.is_empty() || !removed.is_empty()).then(|| SupportChange {
            added: names(added),
            removed: names(removed),
        })
    }
}

/// "added v, removed x^2*v" (the terms named at Ω = `omega`).
fn describe_change((added, removed): &(Vec<Term>, Vec<Term>), omega: f64) -> String {
    let names = |terms: &[Term]| {
        terms
            .iter()
            .map(|t| t.name(omega).to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    match (added.is_empty(), removed.is_empty()) {
        (false, true) => format!("added {}", names(added)),
        (true, false) => format!("removed {}", names(removed)),
        (false, false) => format!("added {}, removed {}", names(added), names(removed)),
        (true, true) => "none".to_owned(),
    }
}

/// Samples a period of the fastest line above which a record is refined on every s-th
/// sample ([`refine_recording`]).
pub const DECIMATE_ABOVE: f64 = 1024.0;
/// Samples a period of the fastest line that such a record keeps for refinement.
pub const REFINE_SAMPLES_PER_PERIOD: f64 = 256.0;

/// [`refine_and_check`] on a recording, from the streaming identifier's report: the samples
/// the identifier left out (non-finite values, isolated spikes, samples too early; see
/// [`crate::identify::blemish`]) are left out here too, so a spike is not fitted and a NaN
/// does not stop the simulation (the simulation steps over a left-out sample; a time gap is
/// one longer step).
pub fn refine_recording(
    recording: &crate::recording::Recording,
    report: &crate::identify::Report,
) -> Check {
    let scan = crate::identify::blemish::Scan::of(recording);
    let keep: Vec<usize> = (0..recording.len())
        .filter(|&i| {
            !scan.skip.get(i).copied().unwrap_or(false)
                && recording.t[i].is_finite()
                && recording.x[i].is_finite()
                && recording.u.as_ref().is_none_or(|u| u[i].is_finite())
        })
        .collect();
    // A record sampled far finer than its dynamics need (eq. 17 at 3,150 samples a period)
    // is refined on every s-th sample, about 256 a period of its fastest line: the
    // simulations cost in samples, and the samples left still pin every coefficient (on
    // eq. 17, clean, seeds 1 and 3: 1.5–1.7 × 10⁻⁶ % instead of 1.2–1.3 × 10⁻⁹ %, in 0.4 s
    // of CPU instead of 2.2). Not with a measured u, whose band the fastest line of the
    // model does not bound.
    let stride = match (report.device_rate(), &recording.u) {
        (Some(rate), None) => {
            let per_period = 1.0 / (report.sample_period * rate.line_hz);
            if per_period.is_finite() && per_period >= DECIMATE_ABOVE {
                (per_period / REFINE_SAMPLES_PER_PERIOD).floor() as usize
            } else {
                1
            }
        }
        _ => 1,
    };
    let keep: Vec<usize> = keep.into_iter().step_by(stride.max(1)).collect();
    let pick = |c: &[f64]| keep.iter().map(|&i| c[i]).collect::<Vec<f64>>();
    let (t, x) = (pick(&recording.t), pick(&recording.x));
    let u = recording.u.as_deref().map(pick);
    let data = Data {
        t: &t,
        x: &x,
        u: u.as_deref(),
    };
    // The candidates' least-squares starts differentiate the samples kept: every s-th, at s
    // times the period (at the recording's, every window looked like one across a time gap,
    // and no support that adds a term, the lost damping of a ringdown at 5 kHz, was tried).
    let mut candidates = Candidates::of(report, channel_scales(recording, &keep));
    candidates.sample_period *= stride.max(1) as f64;
    refine_and_check_among(&SimModel::from_report(report), &candidates, &data)
}

/// x's and v's RMS about their means over the samples `keep` (v as recorded, or x's
/// differences over t): the scales [`Candidates::of`] holds the sensor offsets to.
fn channel_scales(recording: &crate::recording::Recording, keep: &[usize]) -> [f64; 2] {
    let x: Vec<f64> = keep.iter().map(|&i| recording.x[i]).collect();
    let v: Vec<f64> = match &recording.v {
        Some(v) => keep
            .iter()
            .map(|&i| v[i])
            .filter(|a| a.is_finite())
            .collect(),
        None => keep
            .windows(2)
            .filter(|w| recording.t[w[1]] > recording.t[w[0]])
            .map(|w| {
                (recording.x[w[1]] - recording.x[w[0]]) / (recording.t[w[1]] - recording.t[w[0]])
            })
            .collect(),
    };
    let scale = |c: &[f64]| {
        if c.len() >= 2 {
            crate::identify::stretch::rms(c)
        } else {
            0.0
        }
    };
    [scale(&x), scale(&v)]
}

/// A kept streaming coefficient's ± : its support refined on simulation error over the first
/// half gives each term a standard error, and the streaming estimate (equation error,
/// derivatives from samples) and that refinement are two estimates of one coefficient; the ±
/// is that standard error plus the distance between the two, so that a bias the
/// estimators do not share shows (issue 25: a kept streaming model printed its damping 25 %
/// off with no ± at all, `scripts/hostile-more.sh` seed 20108). `None` for a term the
/// refinement did not carry.
fn streaming_standard_error(check: &Check, term: Term, coef: f64) -> Option<f64> {
    let refined = check.supports.first()?.refined.as_ref()?;
    let (_, c, se) = refined.iter().find(|(t, _, _)| *t == term)?;
    // The sum, not the larger: the streaming estimate is off the truth by at most its
    // distance to the refined one plus the refined one's error, so twice this ± covers the
    // truth wherever twice the refined standard error does (issue 25, hostile seed 20108: a
    // kept damping 2.2 of the larger from the truth, the refined one 1.8 of its own).
    let spread = (coef - c).abs();
    let se = if se.is_finite() { se + spread } else { spread };
    (se.is_finite() && se > 0.0).then_some(se)
}

impl crate::identify::Report {
    /// Takes the refined model of `check` as the reported one (`terms`, with standard errors,
    /// and the resonance and wells computed from it) when the check chose it; the streaming
    /// model stays in `streaming_terms` (and in the simulation model). A check that kept the
    /// streaming model changes nothing.
    pub fn take_refined(&mut self, check: &Check) {
        if check.chosen != Chosen::Refined {
            self.streaming_uncertainty(check);
            return;
        }
        let omega = check.model.omega;
        self.terms = check
            .model
            .terms
            .iter()
            .enumerate()
            .filter(|(_, (_, c))| *c != 0.0)
            .map(|(j, (term, coef))| crate::identify::TermReport {
                term: term.name(omega).to_string(),
                coef: *coef,
                se: check
                    .standard_errors
                    .as_ref()
                    .and_then(|se| se.get(j).copied()),
            })
            .collect();
        self.reported = Chosen::Refined;
        // A model recentred on its centre of symmetry has its own origin.
        self.offsets = check.model.offsets;
        // The simulation model follows: what is printed is what is simulated and drawn.
        self.model = check
            .model
            .terms
            .iter()
            .filter(|(_, c)| *c != 0.0)
            .copied()
            .collect();
        let force = lssi_core::RestoringForce::from_terms(
            check.model.terms.iter().copied(),
            check.model.offsets[0],
        );
        self.resonance_hz = force.resonance_hz();
        self.wells = force.wells();
        self.well_resonance_hz = force.well_resonance_hz();
        self.device_rate_hz = self.device_rate().map(|r| r.hz);
    }

    /// The kept streaming model's terms with a ± each ([`streaming_standard_error`]), where
    /// its support was refined; the model is unchanged.
    fn streaming_uncertainty(&mut self, check: &Check) {
        if check.chosen != Chosen::Streaming {
            return;
        }
        let omega = check.model.omega;
        for t in &mut self.terms {
            if t.se.is_some() {
                continue;
            }
            t.se = check
                .model
                .terms
                .iter()
                .find(|(term, c)| *c != 0.0 && term.name(omega).to_string() == t.term)
                .and_then(|(term, _)| streaming_standard_error(check, *term, t.coef));
        }
    }
}
