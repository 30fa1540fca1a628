//! The quality gate of `lssi identify`: before a model is reported, does it explain the data?
//!
//! Four checks, each a reason to withhold the model (exit status 3, "no deterministic
//! dynamics found in …"):
//!
//! 1. **Held-out fit against a no-model baseline** (which is also the agreement of the A/B
//!    halves): the identifier's held-out error of the selected model (A's fit tested on B and
//!    B's on A, [`lssi_core::Model::solutions`]) over the variance of the same targets (x'', or
//!    its test-function sums) computed here from the recording. A model that leaves more than
//!    [`MAX_UNEXPLAINED`] of that variance explains nothing the mean does not.
//! 2. **Free-run stability**: the model integrated from the recording's first state over the
//!    record must stay finite and within [`MAX_EXCURSION`] times the recorded range of x.
//! 3. **f32 against f64**: the other precision must select the same terms.
//! 4. **Something selected**: a model with no terms is no model.

use crate::identify::blemish::{CleanWindows, Scan};
use crate::identify::{Report, WINDOW_CAPACITY};
use crate::recording::Recording;
use lssi_core::Config;
use lssi_core::derivative::Taps;

/// Largest fraction of the target's variance the held-out error may leave.
pub const MAX_UNEXPLAINED: f64 = 0.5;
/// How far (in recorded ranges of x, about the record's midpoint) a free run may go.
pub const MAX_EXCURSION: f64 = 10.0;

/// What the checks measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Quality {
    /// Held-out error of the selected model over the target's variance (`None`: unknown).
    pub unexplained: Option<f64>,
    /// Whether the free run stayed finite and bounded (`None`: not run).
    pub stable: Option<bool>,
    /// Whether the other precision selected the same terms (`None`: not compared).
    pub precisions_agree: Option<bool>,
    /// The reasons the model is withheld: empty when it passed.
    pub failures: Vec<String>,
}

impl Quality {
    /// Whether every check passed.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }
}

/// The variance of the identifier's targets over the clean stretches: x'' (or v') from the
/// configuration's derivative taps, summed under its test function when it has one.
pub fn target_variance(recording: &Recording, config: &Config) -> Option<f64> {
    let n = config.window;
    let taps: Taps<f64, WINDOW_CAPACITY> = Taps::design(
        n,
        usize::from(config.derivative_degree),
        config.sample_period,
    )
    .ok()?;
    let scan = Scan::of(recording);
    let clean = CleanWindows::new(&scan, n);
    let (source, order) = match &recording.v {
        Some(v) => (v.as_slice(), 1),
        None => (recording.x.as_slice(), 2),
    };
    // Runs of consecutive clean targets.
    let mut runs: Vec<Vec<f64>> = vec![Vec::new()];
    for start in 0..source.len().saturating_sub(n - 1) {
        let y = if clean.ok(start) {
            Some(taps.apply(order, &source[start..start + n], &[]))
        } else {
            None
        };
        match y.filter(|y| y.is_finite()) {
            Some(y) => runs.last_mut()?.push(y),
            None => {
                if !runs.last()?.is_empty() {
                    runs.push(Vec::new());
                }
            }
        }
    }
    let width = usize::from(config.test_rows);
    let targets: Vec<f64> = if width == 0 {
        runs.into_iter().flatten().collect()
    } else {
        // The test function's weights (lssi_core::weak): (1 − τ²)⁴ on the row centres,
        // normalised to sum 1; a sum every quarter width.
        let l = width as f64;
        let mut weights: Vec<f64> = (0..width)
            .map(|i| {
                let tau = (2.0 * i as f64 + 1.0) / l - 1.0;
                (1.0 - tau * tau).powi(4)
            })
            .collect();
        let total: f64 = weights.iter().sum();
        weights.iter_mut().for_each(|w| *w /= total);
        let quarter = (width / 4).max(1);
        runs.iter()
            .flat_map(|run| {
                let weights = &weights;
                (0..run.len().saturating_sub(width - 1))
                    .step_by(quarter)
                    .map(move |s| {
                        run[s..s + width]
                            .iter()
                            .zip(weights)
                            .map(|(y, w)| y * w)
                            .sum::<f64>()
                    })
            })
            .collect()
    };
    if targets.len() < 8 {
        return None;
    }
    let count = targets.len() as f64;
    let mean = targets.iter().sum::<f64>() / count;
    let variance = targets.iter().map(|y| (y - mean) * (y - mean)).sum::<f64>() / count;
    (variance.is_finite() && variance > 0.0).then_some(variance)
}

/// Whether the model's free run from the recording's first clean state stays finite and
/// within [`MAX_EXCURSION`] recorded ranges of x.
pub fn free_run_stable(recording: &Recording, report: &Report) -> Option<bool> {
    let scan = Scan::of(recording);
    let stretch = scan.stretches().into_iter().max_by_key(|r| r.len())?;
    if stretch.len() < 8 {
        return None;
    }
    let t = &recording.t[stretch.clone()];
    let x = &recording.x[stretch.clone()];
    let u = recording.u.as_ref().map(|u| &u[stretch.clone()]);
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let range = hi - lo;
    if !(range > 0.0) {
        return None;
    }
    // The initial velocity: measured, or the central difference of x.
    let v0 = match &recording.v {
        Some(v) => v[stretch.start],
        None => (x[2] - x[0]) / (t[2] - t[0]),
    };
    let model = crate::identify::simulate::SimModel::from_report(report);
    let run = crate::identify::simulate::simulate(&model, t, u, (x[0], v0), 2);
    let centre = 0.5 * (lo + hi);
    Some(
        run.diverged_at.is_none()
            && run
                .x
                .iter()
                .all(|s| s.is_finite() && (s - centre).abs() <= MAX_EXCURSION * range),
    )
}

/// Runs the checks on `report` (made from `recording` with `config`); `other` is the same
/// recording identified in the other precision, if it was.
pub fn assess(
    recording: &Recording,
    config: &Config,
    report: &Report,
    other: Option<&Report>,
) -> Quality {
    let mut quality = Quality {
        unexplained: None,
        stable: None,
        precisions_agree: None,
        failures: Vec::new(),
    };
    if report.terms.is_empty() {
        quality
            .failures
            .push("the selected model has no terms".into());
        return quality;
    }
    let held_out = report.solutions.get(report.selected).map(|s| s.mean_error);
    quality.unexplained = held_out
        .zip(target_variance(recording, config))
        .map(|(e, var)| e / var);
    if let Some(r) = quality.unexplained
        && !(r <= MAX_UNEXPLAINED)
    {
        quality.failures.push(format!(
            "the model leaves {:.0} % of the variance of x'' unexplained on held-out data (at most {:.0} % allowed)",
            100.0 * r,
            100.0 * MAX_UNEXPLAINED
        ));
    }
    quality.stable = free_run_stable(recording, report);
    if quality.stable == Some(false) {
        quality.failures.push(format!(
            "the model's free run from the recording's first state diverges (leaves {MAX_EXCURSION} times the recorded range of x)"
        ));
    }
    if let Some(other) = other {
        let names = |r: &Report| r.terms.iter().map(|t| t.term.clone()).collect::<Vec<_>>();
        let agree = names(report) == names(other);
        quality.precisions_agree = Some(agree);
        if !agree {
            quality.failures.push(format!(
                "{} selects {} but {} selects {}",
                report.precision,
                names(report).join(", "),
                other.precision,
                names(other).join(", ")
            ));
        }
    }
    quality
}

/// Configures and runs the identifier on a recording in the precision asked for, runs it
/// again in the other precision, and checks the model ([`assess`]).
pub fn identify_checked(
    recording: &Recording,
    options: &crate::identify::Options,
) -> Result<(Report, Quality), crate::identify::IdentifyError> {
    use crate::identify::run;
    let (config, estimated) = crate::identify::configure(recording, options)?;
    let (report, other) = if options.f32 {
        let report = run::<f32>(recording, config, estimated)?;
        (report, run::<f64>(recording, config, estimated).ok())
    } else {
        let report = run::<f64>(recording, config, estimated)?;
        (report, run::<f32>(recording, config, estimated).ok())
    };
    let quality = assess(recording, &config, &report, other.as_ref());
    Ok((report, quality))
}

/// The refusal of a model that failed the gate: "no deterministic dynamics found in FILE: …".
pub fn refusal(recording: &Recording, quality: &Quality) -> String {
    format!(
        "no deterministic dynamics found in {}: {}.",
        recording.path.display(),
        quality.failures.join("; ")
    )
}
