//! `lssi identify`: a recording through the streaming identifier, as a device would see it.
//!
//! What the paper leaves to the user is decided from the data here, once, before streaming:
//! the sample period (median interval), the derivative window and degree
//! ([`lssi_core::tuning::choose_window`]) and, without `--omega`, the excitation frequency
//! (the peak of the spectrum of what a polynomial model of the same library cannot explain).
//! The identifier then runs sample by sample and the model at the end of the file is reported.
//!
//! Around it: [`batch`] (many recordings in parallel), [`track`] (the model over time and the settle time after a change), [`simulate`]
//! (a free run of an identified model, its NRMSE), [`refine`] (output-error refinement of the
//! selected terms) and [`terms`] (how library terms are named across the project).

pub mod batch;
pub mod blemish;
pub mod burst;
pub mod device_rate;
mod omega;
pub mod orbit;
pub mod periodic;
pub mod pipeline;
pub mod polish;
pub mod quality;
pub mod refine;
pub mod simulate;
pub mod stream;
pub mod stretch;
pub mod supports;
pub mod sweep;
pub mod terms;
pub mod track;

use lssi_core::{Channels, Config, Identifier, LibraryConfig, PolyFamily, Real, Sample, Term};
use serde::Serialize;

use crate::recording::Recording;
pub use omega::estimate_omega;

/// Window capacity of the host identifier (samples).
pub const WINDOW_CAPACITY: usize = 1023;
/// Library capacity of the host identifier (terms).
pub const TERM_CAPACITY: usize = 32;

/// What the user chose (everything else comes from the data).
#[derive(Clone, Debug)]
pub struct Options {
    /// Base excitation frequency, rad/s (`None`: estimated).
    pub omega: Option<f64>,
    /// sin/cos harmonics of Ω (`None`: the default, [`Options::harmonics_for`]).
    pub harmonics: Option<u8>,
    /// Highest polynomial order.
    pub poly_order: u8,
    /// Which monomials.
    pub family: PolyFamily,
    /// Compute in f32 (what a device runs) rather than f64.
    pub f32: bool,
    /// k-neighbour smoothing on (off only for the ablation).
    pub smoothing: bool,
    /// Forgetting time constant, seconds.
    pub memory: Option<f64>,
    /// Errors-in-variables correction of the normal equations (experimental).
    pub noise_correction: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            omega: None,
            harmonics: None,
            poly_order: 3,
            family: PolyFamily::All,
            f32: true,
            smoothing: true,
            memory: None,
            noise_correction: false,
        }
    }
}

impl Options {
    /// The harmonics of Ω in the library: those asked for, or by default one (a forcing
    /// cos(Ωt) to find) without a measured excitation u and none with one (u is the forcing;
    /// cos(Ωt) beside it is the same signal twice, and the selection would split the forcing
    /// between them).
    pub fn harmonics_for(&self, input: bool) -> u8 {
        self.harmonics.unwrap_or(u8::from(!input))
    }
}

/// Why a recording cannot be identified: one sentence naming the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct IdentifyError(pub String);

/// One term of the selected model.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TermReport {
    /// Name (`x`, `x^2*v`, `cos(2t)`, …).
    pub term: String,
    /// Coefficient in physical units.
    pub coef: f64,
    /// Its standard error (a refined model's, or a kept streaming model's: its support
    /// refined, widened to the two estimates' distance; absent from the JSON with
    /// `--no-refine`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub se: Option<f64>,
}

/// One solution of the sweep.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SolutionReport {
    /// Threshold on scaled coefficients.
    pub threshold: f64,
    /// Held-out mean squared error of x''.
    pub mean_error: f64,
    /// Active term names.
    pub terms: Vec<String>,
}

/// K per channel.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct KReport {
    /// K for x.
    pub x: u8,
    /// K for v.
    pub v: u8,
}

/// Everything `identify` reports (the `--json` object).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// Always `x''`.
    pub target: String,
    /// The reported model's active terms: the refined model when refinement was taken
    /// ([`Report::take_refined`]), else the streaming identifier's.
    pub terms: Vec<TermReport>,
    /// The streaming identifier's model (what a device reports for the same samples),
    /// whichever model `terms` is.
    pub streaming_terms: Vec<TermReport>,
    /// Which model `terms` is: `"refined"` (on simulation error, on the host) or
    /// `"streaming"` (the identifier's, as a device computes it).
    #[serde(rename = "model")]
    pub reported: crate::identify::refine::Chosen,
    /// All solutions, dense to sparse.
    pub solutions: Vec<SolutionReport>,
    /// Index of the selected solution.
    pub selected: usize,
    /// K per channel.
    pub k: KReport,
    /// Base angular frequency Ω, rad/s.
    pub omega: f64,
    /// Whether Ω was estimated from the data.
    pub omega_estimated: bool,
    /// Linear resonance, Hz (when ξ_x < 0), of the reported model (`terms`).
    pub resonance_hz: Option<f64>,
    /// Well positions ±w (double well), in the model's coordinates.
    pub wells: Option<f64>,
    /// Small-oscillation frequency in a well, Hz.
    pub well_resonance_hz: Option<f64>,
    /// The row rate a device needs for this harvester, Hz ([`device_rate`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device_rate_hz: Option<f64>,
    /// Sensor offsets found (x, v): the model is in x − offset_x, v − offset_v.
    pub offsets: [f64; 2],
    /// Samples fed in.
    pub samples: u64,
    /// Samples rejected (non-finite, absurd, out of order).
    pub rejected: u64,
    /// Derivative window (samples) and degree chosen from the data.
    pub window: usize,
    /// Local polynomial degree.
    pub degree: u8,
    /// Rows per test function (the weak form; 0: rows as they are), one row per sample
    /// when it is on.
    pub test_rows: u16,
    /// Sample period, seconds.
    pub sample_period: f64,
    /// `f32` or `f64`.
    pub precision: String,
    /// The selected model as library terms and coefficients (physical units, inactive terms
    /// left out), for [`crate::identify::simulate`]; not part of the JSON.
    #[serde(skip)]
    pub model: Vec<(Term, f64)>,
    /// One sentence per rejected sample, in order (which sample and why); not part of the
    /// JSON (which carries the count), printed as warnings by `lssi identify`.
    #[serde(skip)]
    pub rejections: Vec<String>,
}

/// The configuration `identify` derives from a recording and the options.
pub fn configure(
    recording: &Recording,
    options: &Options,
) -> Result<(Config, bool), IdentifyError> {
    let file = recording.path.display();
    let finite_t: Vec<f64> = recording
        .t
        .iter()
        .copied()
        .filter(|t| t.is_finite())
        .collect();
    let mut steps: Vec<f64> = finite_t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if steps.len() < 64 {
        // Rows enough, but t does not go forward: the rows are out of time order.
        let back = finite_t.windows(2).filter(|w| w[1] <= w[0]).count();
        if finite_t.len() > 64 && back >= finite_t.len() / 2 {
            return Err(IdentifyError(format!(
                "{file}: t does not increase: it falls or stays at {back} of its {} steps (t from {} to {}), so the rows are not in time order; sort them by t.",
                finite_t.len() - 1,
                finite_t[0],
                finite_t[finite_t.len() - 1]
            )));
        }
        return Err(IdentifyError(format!(
            "{file}: only {} usable samples; the identifier needs a few hundred at least.",
            steps.len() + 1
        )));
    }
    if let Some(why) = magnitude(recording, options) {
        return Err(IdentifyError(format!("{file}: {why}")));
    }
    steps.sort_by(f64::total_cmp);
    let dt = steps[steps.len() / 2];
    let channels = Channels {
        velocity: recording.v.is_some(),
        input: recording.u.is_some(),
    };
    // The window from the data: the target comes from v when it is measured.
    // Blemished samples (non-finite, spikes, too early) are left out (`crate::identify::blemish`).
    // A repaired spike counts with its repaired value.
    let scan = crate::identify::blemish::Scan::of(recording);
    let kept_scan = scan.with_repairs_kept();
    let kept = |c: &[f64]| -> Vec<f64> {
        c.iter()
            .zip(&kept_scan.skip)
            .filter(|(s, skip)| s.is_finite() && !**skip)
            .map(|(s, _)| *s)
            .collect()
    };
    let channel = usize::from(recording.v.is_some());
    let source_values = scan
        .repaired(recording, channel)
        .unwrap_or_else(|| recording.x.clone());
    let (source, order): (Vec<f64>, usize) = (kept(&source_values), 2 - channel);
    let memory_samples = options
        .memory
        .map_or(source.len(), |m| ((m / dt) as usize).min(source.len()));
    let choice = lssi_core::tuning::choose_window::<f64, WINDOW_CAPACITY>(
        &source,
        order,
        dt,
        memory_samples,
    )
    .ok_or_else(|| {
        IdentifyError(format!(
            "{file}: too few samples to choose a derivative window."
        ))
    })?;
    let library = LibraryConfig {
        poly_order: options.poly_order,
        family: options.family,
        constant: true,
        harmonics: options.harmonics_for(channels.input),
        input: channels.input,
    };
    let mut config = Config {
        sample_period: dt,
        window: choice.window,
        derivative_degree: choice.degree,
        library,
        omega: 1.0,
        channels,
        memory: options.memory,
        smoothing: options.smoothing,
        noise_correction: options.noise_correction,
        ..Config::default()
    };
    // A row every fourth sample saves a device's time on a long record; a record of a few
    // hundred samples needs every one (its 64 warm-up rows and both halves' rows).
    if source.len() < 128 * usize::from(config.row_stride) {
        config.row_stride = 1;
    }
    let mut estimated = false;
    if config.library.harmonics > 0 {
        config.omega = match options.omega {
            // Above the Nyquist frequency sin(Ωt) and cos(Ωt) alias onto a lower frequency:
            // the model's forcing would not be the one asked for.
            Some(w) if w >= std::f64::consts::PI / dt => {
                return Err(IdentifyError(format!(
                    "{file}: --omega {w} rad/s is at or above the Nyquist frequency of this recording (π / {dt:.4e} s = {:.6} rad/s), so sin(Ωt) and cos(Ωt) would alias; give an Ω below it.",
                    std::f64::consts::PI / dt
                )));
            }
            Some(w) => w,
            None => {
                estimated = true;
                // A broken time axis is named as such, not as a reason to give --omega.
                match estimate_omega(recording, &config) {
                    Ok(w) => w,
                    // A constant x has no frequency: any Ω, and the gate names the constant.
                    Err(_) if crate::identify::quality::constant(recording).is_some() => 1.0,
                    Err(e) => {
                        return Err(time_axis(recording)
                            .map_or(e, |why| IdentifyError(format!("{file}: {why}"))));
                    }
                }
            }
        };
    }
    // The weak form when the signal is sampled finely enough: a row every sample, summed
    // over a test function a third of the period long, under a short derivative window
    // (after Ω's estimate, which is made on the window chosen for rows as they are). The
    // noise correction (an experiment) works on rows as they are only.
    let test =
        lssi_core::tuning::choose_test_rows::<WINDOW_CAPACITY>(choice.period, memory_samples);
    if let Some(test) = test.filter(|_| !options.noise_correction) {
        config.test_rows = test.test_rows;
        config.row_stride = 1;
        config.window = test.window;
        config.derivative_degree = test.degree;
    }
    // Ω from the spectrum is 10⁻³ rad/s off on a 20 s record; the weak form's rows find it
    // closer (`polish`).
    if estimated {
        config.omega = polish::polish_omega(recording, &config, config.omega, &[]);
    }
    crate::identify::blemish::refuse_if_broken(&scan, &config, &recording.path).map_err(|e| {
        time_axis(recording).map_or(e, |why| {
            IdentifyError(format!("{file}: too broken to identify: {why}"))
        })
    })?;
    config
        .validate::<WINDOW_CAPACITY, TERM_CAPACITY, 3>()
        .map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    Ok((config, estimated))
}

/// A channel the identifier cannot compute with, named with the unit change that mends it:
/// most of its values (less the [`Reference`] taken off x and v) beyond the largest magnitude
/// a sample may have (`Config::max_abs`, each such sample rejected), or x (or v) so small or
/// so large that the library's highest power of the level 99 % of its samples stay within,
/// |x|^P, is under the smallest normal number of the precision (f32: 1.2e-38, at |x| under
/// 2.3e-13 for P = 3) or over its largest (f32: 3.4e38, at |x| over 4.4e7 for P = 5), where
/// every regression row is lost. `None` for a usable range.
fn magnitude(recording: &Recording, options: &Options) -> Option<String> {
    let limit = Config::default().max_abs;
    // As the identifier is fed: x and v less the reference `identify` takes off them (none
    // off a constant x, which the gate names as such).
    let reference = Reference::of(recording);
    let channels = [
        ("x", Some(&recording.x), reference.x, true),
        ("v", recording.v.as_ref(), reference.v, true),
        ("u", recording.u.as_ref(), 0.0, false),
    ];
    for (name, values, reference, base) in channels {
        let Some(values) = values else { continue };
        let fed: Vec<f64> = values
            .iter()
            .filter(|v| v.is_finite())
            .map(|v| (v - reference).abs())
            .collect();
        let finite = fed.len();
        if finite == 0 {
            continue;
        }
        let beyond = fed.iter().filter(|v| **v > limit).count();
        // The level 99 % of the samples stay within: a spike of 1e300 (repaired, or left
        // out) is no unit.
        let mut sorted = fed;
        sorted.sort_by(f64::total_cmp);
        let max = sorted[(finite - 1) * 99 / 100];
        if 2 * beyond > finite {
            return Some(format!(
                "{name} reaches {:.3e}: {beyond} of its {finite} values are beyond ±{limit:.0e}, the largest magnitude the identifier takes (each such sample is rejected); give {name} in a larger unit (m rather than µm, say).",
                sorted[finite - 1]
            ));
        }
        let (smallest, largest, precision) = if options.f32 {
            (f64::from(f32::MIN_POSITIVE), f64::from(f32::MAX), "f32")
        } else {
            (f64::MIN_POSITIVE, f64::MAX, "f64")
        };
        let order = i32::from(options.poly_order.max(1));
        let power = order as f64 * max.log10();
        let or_f64 = if options.f32 { " or use --f64" } else { "" };
        if base && max > 0.0 && power < smallest.log10() {
            return Some(format!(
                "{name} is within {max:.3e} in 99 % of its samples, so the library's {name}^{order} is under {precision}'s smallest normal number ({smallest:.2e}) and the identifier cannot compute with it; give {name} in a smaller unit (µm rather than m, say){or_f64}."
            ));
        }
        if base && power > largest.log10() {
            return Some(format!(
                "1 % of {name}'s samples reach {max:.3e}, so the library's {name}^{order} is over {precision}'s largest number ({largest:.2e}) and the identifier cannot compute with it; give {name} in a larger unit (m rather than µm, say){or_f64}."
            ));
        }
    }
    None
}

/// A time column that is not a regular grid, named: rounded to too few decimals (steps of 0),
/// samples dropped (steps of two or more periods) or jittered (steps off the median by more
/// than half of it), when such steps are at least 1 % of them; `None` otherwise. Said (after
/// the file's name) when the recording cannot be identified for it (its clean stretches too
/// short).
pub fn time_axis(recording: &Recording) -> Option<String> {
    let t: Vec<(usize, f64)> = recording
        .t
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, t)| t.is_finite())
        .collect();
    if t.len() < 3 {
        return None;
    }
    let steps: Vec<(usize, f64)> = t.windows(2).map(|w| (w[1].0, w[1].1 - w[0].1)).collect();
    let mut positive: Vec<f64> = steps.iter().map(|s| s.1).filter(|d| *d > 0.0).collect();
    if positive.is_empty() {
        return None;
    }
    positive.sort_by(f64::total_cmp);
    let dt = positive[positive.len() / 2];
    let span = t[t.len() - 1].1 - t[0].1;
    let mean = span / steps.len() as f64;
    let early: Vec<usize> = steps
        .iter()
        .filter(|s| s.1 < 0.5 * dt)
        .map(|s| s.0 + 1)
        .collect();
    let gaps: Vec<(usize, f64)> = steps
        .iter()
        .filter(|s| s.1 > 1.5 * dt)
        .map(|s| (s.0 + 1, s.1 / dt))
        .collect();
    if early.len() + gaps.len() < (steps.len() / 100).max(1) {
        return None;
    }
    use crate::identify::blemish::where_text;
    let end = "so the samples are not evenly spaced in time; the identifier needs a regular time axis (one sample period between rows)";
    // Rounded: every time a multiple of 10⁻ᵈ no finer than half the mean step, steps of 0
    // (under half the median) at least as many as the gaps.
    let rounded = (0..=9).find(|&d| {
        let q = 10f64.powi(-d);
        t.iter()
            .all(|(_, t)| ((t / q) - (t / q).round()).abs() < 1e-6 * (t / q).abs().max(1.0))
    });
    if let Some(d) =
        rounded.filter(|&d| 10f64.powi(-d) >= 0.5 * mean && early.len() >= gaps.len().max(1))
    {
        return Some(format!(
            "the time column is rounded to {d} decimal{} (steps of {:e} s), coarser than the sample period (about {mean:.4e} s): {} steps are 0 or under half the median step ({}), {end}: write t with more digits.",
            if d == 1 { "" } else { "s" },
            10f64.powi(-d),
            early.len(),
            where_text(&early)
        ));
    }
    let multiples = gaps
        .iter()
        .filter(|(_, k)| (k - k.round()).abs() < 0.1)
        .count();
    if early.len() * 10 <= gaps.len() && multiples * 10 >= gaps.len() * 9 {
        let rows: Vec<usize> = gaps.iter().map(|g| g.0).collect();
        let largest = gaps.iter().map(|g| g.1).fold(0.0, f64::max);
        return Some(format!(
            "the time column has gaps: {} steps are {} the median step ({dt:.4e} s), at {} (samples dropped), {end}.",
            gaps.len(),
            if largest.round() > 2.0 {
                format!("2× to {largest:.0}×")
            } else {
                "2×".to_owned()
            },
            where_text(&rows)
        ));
    }
    let mut deviations: Vec<f64> = steps.iter().map(|s| (s.1 / dt - 1.0).abs()).collect();
    deviations.sort_by(f64::total_cmp);
    let spread = 100.0 * deviations[deviations.len() / 2];
    let mut rows: Vec<usize> = early.clone();
    rows.extend(gaps.iter().map(|g| g.0));
    rows.sort_unstable();
    Some(format!(
        "the time column is jittered: {} steps are off the median step ({dt:.4e} s) by more than half of it, at {} (the median step is off by {spread:.0} %), {end}: resample onto an even grid.",
        rows.len(),
        where_text(&rows)
    ))
}

/// Why a run with a forgetting time gave no model although samples enough came: `--memory`
/// of a few dozen samples keeps too few regression rows however many come (0.05 s at 2 kHz
/// gives none on `lssi gen eveh`'s record; 0.1 s a model). Empty without a memory.
pub fn memory_hint(config: &Config, accepted: u64) -> String {
    match config.memory {
        Some(m) if accepted >= 64 => format!(
            "; --memory {m} s keeps about {:.0} samples' rows at a time: give a longer memory",
            m / config.sample_period
        ),
        _ => String::new(),
    }
}

/// Configures and runs the identifier on a recording, in f32 or f64 as `options` say: what
/// `lssi identify` reports.
pub fn identify_recording(
    recording: &Recording,
    options: &Options,
) -> Result<Report, IdentifyError> {
    let reference = Reference::of(recording);
    let shifted = reference.shifted(recording);
    let recording = shifted.as_ref().unwrap_or(recording);
    let (config, estimated) = configure(recording, options)?;
    let mut report = if options.f32 {
        run::<f32>(recording, config, estimated)
    } else {
        run::<f64>(recording, config, estimated)
    }?;
    reference.restore(&mut report);
    Ok(report)
}

/// Runs a recording through the identifier in precision `T`.
pub fn run<T: Real>(
    recording: &Recording,
    config: Config,
    omega_estimated: bool,
) -> Result<Report, IdentifyError> {
    let file = recording.path.display();
    let mut identifier: Identifier<T, WINDOW_CAPACITY, TERM_CAPACITY> =
        Identifier::new(config).map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    let mut rejections = Vec::new();
    // Blemished samples are left out (the window restarts after them), each named.
    let scan = crate::identify::blemish::Scan::of(recording);
    rejections.extend(
        scan.blemishes
            .iter()
            .map(|b| format!("{file}: {}", b.sentence())),
    );
    for (i, s) in recording.samples().enumerate() {
        // A repaired spike is given as the cubic through its neighbours (the window goes on).
        let (x, v, u) = match scan.feed(i) {
            crate::identify::blemish::Feed::Skip => continue,
            crate::identify::blemish::Feed::AsIs => (s.x, s.v, s.u),
            crate::identify::blemish::Feed::Repaired(r) => (r.x, r.v, r.u),
        };
        let sample = Sample {
            t: s.t,
            x: T::from_f64(x),
            v: v.map(T::from_f64),
            u: u.map(T::from_f64),
        };
        // A rejected sample is counted and reported; it never stops the run.
        if let Err(why) = identifier.push(sample) {
            rejections.push(format!(
                "{file}: data row {} (t = {}): {why}; it was left out",
                i + 1,
                s.t
            ));
        }
    }
    identifier.screen();
    let counters = *identifier.counters();
    let model = identifier.model().ok_or_else(|| {
        IdentifyError(format!(
            "{file}: no model: {} samples were accepted and {} rejected, too few regression rows for the {}-term library{}{}.",
            counters.accepted,
            counters.rejected() + scan.skipped() as u64,
            identifier.library().len(),
            crate::identify::blemish::because(&scan),
            memory_hint(&config, counters.accepted)
        ))
    })?;
    let mut report = report(
        model,
        &config,
        omega_estimated,
        counters.rejected() + scan.skipped() as u64,
        std::any::type_name::<T>(),
    );
    report.rejections = rejections;
    Ok(report)
}

/// Rows whose mean is the reference of a channel ([`Reference`]).
pub const REFERENCE_ROWS: usize = 1024;

/// How many ranges of the first rows away from 0 their mean must lie to be a reference
/// ([`Reference::channel`]).
pub const REFERENCE_RANGES: f64 = 3.0;

/// The references subtracted from x and v (in f64, before anything is estimated from them or
/// they are converted to the identifier's precision), and added back to the model's offsets
/// ([`Reference::restore`]): the mean of a channel's
/// first [`REFERENCE_ROWS`] finite values when it lies more than [`REFERENCE_RANGES`] times
/// their range from 0, else 0. Raw ADC counts, or a displacement 10⁴ times its amplitude away from zero,
/// leave an f32 only a few significant bits of the motion; less the reference they keep all
/// 24 (a device can do the same with its first rows). A recording about zero is fed as it is.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reference {
    /// Subtracted from x.
    pub x: f64,
    /// Subtracted from v.
    pub v: f64,
}

impl Reference {
    /// The references of a recording's x and v: none for an x that is constant, or nearly
    /// (the gate names it as it is: [`quality::constant`]).
    pub fn of(recording: &Recording) -> Self {
        if quality::constant(recording).is_some() {
            return Self::default();
        }
        Self {
            x: Self::channel(&recording.x),
            v: recording.v.as_deref().map_or(0.0, Self::channel),
        }
    }

    /// The reference of one channel: the mean of its first [`REFERENCE_ROWS`] finite values
    /// when it is further from 0 than [`REFERENCE_RANGES`] times their range, else 0.
    pub fn channel(values: &[f64]) -> f64 {
        let head: Vec<f64> = values
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .take(REFERENCE_ROWS)
            .collect();
        if head.is_empty() {
            return 0.0;
        }
        let n = head.len() as f64;
        let mean = head.iter().sum::<f64>() / n;
        let (lo, hi) = head
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            });
        // Far from 0 against the motion's own range: an offset that costs f32 its bits. A
        // record that starts away from its equilibrium (released from x₀, eq. 17's x = 2 at
        // t = 0) is not: shifted, the identifier would have to find its origin again, and
        // it finds it only to 10⁻⁵ of x₀ (eq. 17 clean: 0.0009 % -> 0.009 %).
        if mean.abs() > REFERENCE_RANGES * (hi - lo) {
            mean
        } else {
            0.0
        }
    }

    /// Whether nothing is subtracted.
    pub fn is_zero(&self) -> bool {
        self.x == 0.0 && self.v == 0.0
    }

    /// The recording less the references (`None` when they are zero).
    pub fn shifted(&self, recording: &Recording) -> Option<Recording> {
        if self.is_zero() {
            return None;
        }
        let mut out = recording.clone();
        out.x.iter_mut().for_each(|x| *x -= self.x);
        if let Some(v) = out.v.as_mut() {
            v.iter_mut().for_each(|v| *v -= self.v);
        }
        Some(out)
    }

    /// The report's offsets back in the recording's coordinates.
    pub fn restore(&self, report: &mut Report) {
        report.offsets[0] += self.x;
        report.offsets[1] += self.v;
    }
}

fn names(terms: &[Term], support: u32, omega: f64) -> Vec<String> {
    terms
        .iter()
        .enumerate()
        .filter(|(j, _)| support & (1 << j) != 0)
        .map(|(_, t)| t.name(omega).to_string())
        .collect()
}

/// The report of a model: what [`run`] reports, and `lssi replay` for a device's model.
pub fn report<T: Real, const P: usize>(
    model: &lssi_core::Model<T, P>,
    config: &Config,
    omega_estimated: bool,
    rejected: u64,
    precision: &str,
) -> Report {
    let mut report = report_of(model, config, omega_estimated, rejected, precision);
    report.device_rate_hz = report.device_rate().map(|r| r.hz);
    report
}

/// [`report`]'s fields from the model, but the device rate.
fn report_of<T: Real, const P: usize>(
    model: &lssi_core::Model<T, P>,
    config: &Config,
    omega_estimated: bool,
    rejected: u64,
    precision: &str,
) -> Report {
    let omega = model.omega;
    let terms: Vec<TermReport> = model
        .terms
        .iter()
        .zip(model.coefficients.iter())
        .filter(|(_, c)| **c != T::ZERO)
        .map(|(t, c)| TermReport {
            term: t.name(omega).to_string(),
            coef: c.to_f64(),
            se: None,
        })
        .collect();
    let solutions = model
        .solutions
        .iter()
        .map(|s| SolutionReport {
            threshold: s.threshold.to_f64(),
            mean_error: s.mean_error.to_f64(),
            terms: names(&model.terms, s.support, omega),
        })
        .collect();
    Report {
        target: "x''".into(),
        streaming_terms: terms.clone(),
        terms,
        reported: crate::identify::refine::Chosen::Streaming,
        solutions,
        selected: model.selected,
        k: KReport {
            x: model.k.0,
            v: model.k.1,
        },
        omega,
        omega_estimated,
        resonance_hz: model.resonance_hz(),
        wells: model.wells(),
        well_resonance_hz: model.well_resonance_hz(),
        device_rate_hz: None,
        offsets: [model.offset_x.to_f64(), model.offset_v.to_f64()],
        samples: model.samples,
        rejected,
        window: config.window,
        degree: config.derivative_degree,
        test_rows: config.test_rows,
        sample_period: config.sample_period,
        precision: precision.to_string(),
        model: model
            .terms
            .iter()
            .zip(model.coefficients.iter())
            .filter(|(_, c)| **c != T::ZERO)
            .map(|(t, c)| (*t, c.to_f64()))
            .collect(),
        rejections: Vec::new(),
    }
}

/// The `lssi identify --json` object: the report's fields (`terms` the reported model,
/// `streaming_terms` the device's, `model` which one `terms` is), then `"refined"` (the
/// refinement's summary) when refinement ran, then `"warnings"` (an empty list when there
/// are none).
pub fn json_text(
    report: &Report,
    refined: Option<&refine::Summary>,
    warnings: &[String],
) -> String {
    let mut text = serde_json::to_string(report).unwrap_or_default();
    text.pop();
    if let Some(refined) = refined {
        text.push_str(",\"refined\":");
        text.push_str(&serde_json::to_string(refined).unwrap_or_default());
    }
    text.push_str(",\"warnings\":");
    text.push_str(&serde_json::Value::from(warnings.to_vec()).to_string());
    text.push('}');
    text
}

/// An equation `x'' = …` of named terms, with `(c ± se)` where a term has a standard error.
fn equation(terms: &[TermReport]) -> String {
    let mut equation = String::from("x'' =");
    for (i, t) in terms.iter().enumerate() {
        let term = if t.term == "1" {
            String::new()
        } else {
            format!(" {}", t.term)
        };
        if let Some(se) = t.se {
            let sep = if i == 0 { " " } else { " + " };
            equation.push_str(&format!("{sep}({:.6e} ± {se:.2e}){term}", t.coef));
            continue;
        }
        let sign = if t.coef < 0.0 { "-" } else { "+" };
        let value = number(t.coef.abs());
        if i == 0 {
            equation.push_str(&format!(
                " {}{value}{term}",
                if t.coef < 0.0 { "-" } else { "" }
            ));
        } else {
            equation.push_str(&format!(" {sign} {value}{term}"));
        }
    }
    if terms.is_empty() {
        equation.push_str(" 0");
    }
    equation
}

/// Where the reported model's x is measured from, in words: the streaming model's origin is
/// the equilibrium the identifier found (nearest the recording's zero); a refined model whose
/// restoring force is odd about its origin (an x³, no x², no constant) is about its centre of
/// symmetry, the midpoint between the wells of a double well; any other refined model's
/// origin is the identifier's, fitted by the refinement.
fn origin_text(report: &Report) -> &'static str {
    let has = |name: &str| report.terms.iter().any(|t| t.term == name && t.coef != 0.0);
    match report.reported {
        crate::identify::refine::Chosen::Streaming => {
            "x measured from the equilibrium the identifier found"
        }
        _ if has("x^3") && !has("x^2") && !has("1") => {
            if report.wells.is_some() {
                "x measured from the midpoint between the wells, the centre of symmetry of the restoring force"
            } else {
                "x measured from the centre of symmetry of the restoring force, its equilibrium"
            }
        }
        _ => "x measured from the equilibrium the identifier found, moved by the refinement's fit",
    }
}

/// The text report of `lssi identify`: the reported model's equation, which model it is and
/// why (`refined`: the refinement's summary when it ran; `note`: why it did not), the
/// streaming model when it is not the one shown, then the rest of [`render`].
pub fn render_reported(
    report: &Report,
    refined: Option<&refine::Summary>,
    note: Option<&str>,
    unit: &str,
) -> String {
    let plain = render(report);
    let mut out = format!("{}\n", equation(&report.terms));
    match report.reported {
        refine::Chosen::Refined => {
            out.push_str("model: refined on simulation error (host only)\n");
        }
        refine::Chosen::Streaming => {
            out.push_str("model: the streaming identifier's (as a device computes it)\n")
        }
    }
    if let Some(summary) = refined {
        out.push_str(&summary.render(unit));
    }
    if let Some(note) = note {
        out.push_str(&format!("  {note}\n"));
    }
    if report.reported == refine::Chosen::Refined {
        out.push_str(&format!(
            "streaming model (as a device computes it): {}\n",
            equation(&report.streaming_terms)
        ));
    }
    for line in plain.lines().skip(1) {
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// Formats a coefficient with 5 significant digits.
fn number(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let magnitude = v.abs().log10().floor();
    if (-3.0..6.0).contains(&magnitude) {
        let decimals = (4.0 - magnitude).max(0.0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.4e}")
    }
}

/// K of one channel: 0 means its k-neighbour smoothing is not applied (off by flag, or
/// decided off because it would bend the signal more than it removes noise).
fn k_text(k: u8) -> String {
    if k == 0 { "off".into() } else { k.to_string() }
}

/// Ω as the text report says it: its value where the library had harmonics of it, else
/// that there were none (a model driven by `u` has no Ω; the JSON keeps its placeholder).
pub fn omega_text(omega: f64, estimated: bool, harmonics: bool) -> String {
    if harmonics {
        format!(
            "Ω = {} rad/s{}",
            number(omega),
            if estimated { " (estimated)" } else { "" }
        )
    } else {
        "Ω: none (no harmonics in the library)".to_owned()
    }
}

/// The human-readable report.
pub fn render(report: &Report) -> String {
    let mut out = String::new();
    out.push_str(&equation(&report.terms));
    out.push('\n');
    out.push_str(&format!(
        "K: x = {}, v = {}   window: {} samples, degree {}{}   {}   samples: {} ({} rejected)   {}\n",
        k_text(report.k.x),
        k_text(report.k.v),
        report.window,
        report.degree,
        if report.test_rows > 0 {
            format!(", test function {} samples", report.test_rows)
        } else {
            String::new()
        },
        omega_text(
            report.omega,
            report.omega_estimated,
            report
                .solutions
                .iter()
                .flat_map(|s| s.terms.iter().map(String::as_str))
                .chain(report.terms.iter().map(|t| t.term.as_str()))
                .any(|t| t.contains("t)"))
        ),
        report.samples,
        report.rejected,
        report.precision
    ));
    if report.offsets != [0.0, 0.0] {
        out.push_str(&format!(
            "sensor offsets: x {}, v {} (the model is in x − {0} and v − {1}: {})\n",
            number(report.offsets[0]),
            number(report.offsets[1]),
            origin_text(report)
        ));
    }
    out.push_str("\n  #  threshold   mean error  terms\n");
    for (i, s) in report.solutions.iter().enumerate() {
        let mark = if i == report.selected { "*" } else { " " };
        out.push_str(&format!(
            "{mark}{i:>2}  {:>9.3e}  {:>11.4e}  {}\n",
            s.threshold,
            s.mean_error,
            s.terms.join(", ")
        ));
    }
    out.push_str(
        "  (* = selected by MES: the sparsest solution within 5 % of the least held-out error)\n\n",
    );
    match report.resonance_hz {
        Some(f) => out.push_str(&format!("linear resonance: {} Hz\n", number(f))),
        None => {
            out.push_str("linear resonance: none (the linear stiffness term is not restoring)\n")
        }
    }
    if let (Some(w), Some(f)) = (report.wells, report.well_resonance_hz) {
        out.push_str(&format!(
            "double well: wells at ±{} (resonance in a well {} Hz)\n",
            number(w),
            number(f)
        ));
    }
    if let Some(rate) = report.device_rate() {
        out.push_str(&device_rate::sentence(&rate, report.sample_period));
        out.push('\n');
    }
    out
}

/// The minimum of `f` on [lo, hi] by golden section.
pub(crate) fn golden(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64, steps: usize) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut fa, mut fb) = (f(a), f(b));
    for _ in 0..steps {
        if fa < fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - g * (hi - lo);
            fa = f(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + g * (hi - lo);
            fb = f(b);
        }
    }
    0.5 * (lo + hi)
}
