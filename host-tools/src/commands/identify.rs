//! `lssi identify FILE.csv`: the equation of motion of a recording.
//!
//! With `--track` it prints instead the model selected at every screening (every `--every`
//! seconds) as CSV on stdout, or JSON lines with `--json`, and the settle time after a change
//! (see [`crate::track`]): on stderr after the CSV, or as a last JSON line
//! `{"settle": {...}}`. The change time is `--change-at`, or the drift time of `--truth`;
//! the reference is the truth's coefficients after the change, or else the last snapshot.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use crate::error::CliError;
use crate::identify::{self, Options};
use crate::recording::{ColumnNames, Recording};
use crate::track::{self, TrackOptions};
use crate::truth::Truth;

/// Monomial families (clap's view of [`lssi_core::PolyFamily`]).
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Family {
    /// Every monomial x^a v^b up to the order.
    All,
    /// x^k and x^(k-1)*v.
    Families,
    /// x^k and x^(k-1)*v for odd k (the paper's Table 7).
    Odd,
}

/// A quantisation of the recording (`--quantise`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Quantise {
    /// i16 fixed point with a scale per channel, times on a uniform grid (`lssi replay
    /// --encoding i16`).
    I16,
}

/// Arguments of `lssi identify`.
#[derive(Debug, Clone, Args)]
pub struct IdentifyArgs {
    /// The recording: CSV with a header row naming at least t and x.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// More recordings (or folders, each meaning its *.csv files): identified in parallel on
    /// every core, one JSON line (--json) or one CSV row (--csv) per file; a file that fails
    /// gets its error in its row, and the exit code is 2 if any did.
    #[arg(value_name = "MORE.csv", num_args = 0..)]
    pub more: Vec<PathBuf>,
    /// With several recordings: a CSV table (file, equation, terms, coefficients, samples,
    /// rejected, error) instead of text.
    #[arg(long, conflicts_with = "json")]
    pub csv: bool,
    /// Base excitation frequency Ω in rad/s (default: estimated from the data).
    #[arg(long, value_name = "RAD_PER_S")]
    pub omega: Option<f64>,
    /// sin/cos(kΩt) terms for k = 1..H (0: none, for a measured excitation u).
    #[arg(long, default_value_t = 1, value_name = "H")]
    pub harmonics: u8,
    /// Highest order of the monomials of (x, v).
    #[arg(long, default_value_t = 3, value_name = "P")]
    pub poly_order: u8,
    /// Which monomials.
    #[arg(long, value_enum, default_value_t = Family::All)]
    pub family: Family,
    /// Compute in f32, as a device does (the default).
    #[arg(long, conflicts_with = "f64")]
    pub f32: bool,
    /// Compute in f64 (the reference).
    #[arg(long)]
    pub f64: bool,
    /// Turn the k-neighbour smoothing off (the ablation).
    #[arg(long)]
    pub no_smoothing: bool,
    /// Also refine the selected terms' coefficients on simulation error (f64, host only):
    /// reports the refined model with standard errors, its held-out fit and the free run's
    /// NRMSE (`"refined"` in --json); the streaming model above stays the device's.
    #[arg(long)]
    pub refine: bool,
    /// The unit of x, for the text report (e.g. m, mm, V).
    #[arg(long, value_name = "UNIT", default_value = "[x]")]
    pub unit: String,
    /// Forgetting time constant in seconds (default: remember everything).
    #[arg(long, value_name = "SECONDS")]
    pub memory: Option<f64>,
    /// Experimental: take the noise of the derivative estimates out of the normal equations
    /// (errors in variables; rows as they are, without the test-function sums; host only,
    /// the device protocol does not carry it)
    #[arg(long)]
    pub noise_correction: bool,
    /// Identify the recording as `lssi replay --encoding i16` sends it: times on a uniform
    /// grid, values rounded to i16 quanta (one scale per channel), so the model is the one
    /// a compact replay must give.
    #[arg(long, value_enum, value_name = "ENCODING", conflicts_with_all = ["more", "csv"])]
    pub quantise: Option<Quantise>,
    /// Print one JSON object instead of text (with --track: JSON lines instead of CSV).
    #[arg(long)]
    pub json: bool,
    /// Print the coefficients over time (one row per screening) and the settle time after a
    /// change, instead of the final model.
    #[arg(long)]
    pub track: bool,
    /// With --track: seconds between two screenings.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.25)]
    pub every: f64,
    /// With --track: the truth file (from `lssi gen`) whose coefficients after its drift are
    /// the reference of the settle time, and whose drift time is the change time.
    #[arg(long, value_name = "FILE.json")]
    pub truth: Option<PathBuf>,
    /// With --track: the time of the change, seconds [default: the truth's drift time].
    #[arg(
        long = "change-at",
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub change_at: Option<f64>,
    /// With --track: the relative tolerance of the settle time.
    #[arg(long = "settle-tol", value_name = "FRACTION", default_value_t = 0.05)]
    pub settle_tol: f64,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
}

impl IdentifyArgs {
    /// The identifier options these flags ask for.
    pub fn options(&self) -> Result<Options, CliError> {
        if let Some(w) = self.omega
            && !(w.is_finite() && w > 0.0)
        {
            return Err(CliError::BadFlag {
                flag: "--omega",
                value: w.to_string(),
                requirement: "a positive angular frequency in rad/s".into(),
            });
        }
        if let Some(m) = self.memory
            && !(m.is_finite() && m > 0.0)
        {
            return Err(CliError::BadFlag {
                flag: "--memory",
                value: m.to_string(),
                requirement: "a positive time in seconds".into(),
            });
        }
        if !(1..=9).contains(&self.poly_order) {
            return Err(CliError::BadFlag {
                flag: "--poly-order",
                value: self.poly_order.to_string(),
                requirement: "between 1 and 9".into(),
            });
        }
        if self.harmonics > 8 {
            return Err(CliError::BadFlag {
                flag: "--harmonics",
                value: self.harmonics.to_string(),
                requirement: "at most 8".into(),
            });
        }
        Ok(Options {
            omega: self.omega,
            harmonics: self.harmonics,
            poly_order: self.poly_order,
            family: match self.family {
                Family::All => lssi_core::PolyFamily::All,
                Family::Families => lssi_core::PolyFamily::Families,
                Family::Odd => lssi_core::PolyFamily::OddFamilies,
            },
            f32: !self.f64,
            smoothing: !self.no_smoothing,
            memory: self.memory,
            noise_correction: self.noise_correction,
        })
    }
}

impl IdentifyArgs {
    /// Checks the `--track` flags: positive `--every` and `--settle-tol`, and none of them
    /// without `--track`.
    fn check_track_flags(&self) -> Result<(), CliError> {
        let defaults = (0.25, 0.05);
        if !self.track {
            let stray = if self.every != defaults.0 {
                Some(("--every", self.every.to_string()))
            } else if self.settle_tol != defaults.1 {
                Some(("--settle-tol", self.settle_tol.to_string()))
            } else if let Some(c) = self.change_at {
                Some(("--change-at", c.to_string()))
            } else {
                self.truth
                    .as_ref()
                    .map(|p| ("--truth", p.display().to_string()))
            };
            if let Some((flag, value)) = stray {
                return Err(CliError::BadFlag {
                    flag,
                    value,
                    requirement: "used with --track only".into(),
                });
            }
        }
        if !(self.every.is_finite() && self.every > 0.0) {
            return Err(CliError::BadFlag {
                flag: "--every",
                value: self.every.to_string(),
                requirement: "a positive time in seconds".into(),
            });
        }
        if !(self.settle_tol.is_finite() && self.settle_tol > 0.0) {
            return Err(CliError::BadFlag {
                flag: "--settle-tol",
                value: self.settle_tol.to_string(),
                requirement: "a positive fraction, such as 0.05 for 5 %".into(),
            });
        }
        if let Some(c) = self.change_at
            && !c.is_finite()
        {
            return Err(CliError::BadFlag {
                flag: "--change-at",
                value: c.to_string(),
                requirement: "a time in seconds".into(),
            });
        }
        Ok(())
    }
}

/// Runs `lssi identify`.
pub fn run(args: &IdentifyArgs) -> Result<(), CliError> {
    let options = args.options()?;
    args.check_track_flags()?;
    if !args.more.is_empty() || args.file.is_dir() || args.csv {
        return super::batch::run(args, &options);
    }
    let mut recording = Recording::read(&args.file, &args.columns)?;
    if args.quantise == Some(Quantise::I16) {
        let quantised = crate::quantise::quantise(&recording).map_err(CliError::Input)?;
        eprint!("lssi: {}", quantised.summary.render());
        recording = quantised.recording;
    }
    if args.track {
        return run_track(args, &recording, &options);
    }
    let report = identify_recording(&recording, &options)?;
    // Each rejected sample, on stderr: the first few named, then how many more.
    const NAMED: usize = 5;
    for warning in report.rejections.iter().take(NAMED) {
        eprintln!("lssi: warning: {warning}.");
    }
    if report.rejections.len() > NAMED {
        eprintln!(
            "lssi: warning: {} more samples were left out ({} in all).",
            report.rejections.len() - NAMED,
            report.rejections.len()
        );
    }
    let refined = args.refine.then(|| {
        let model = crate::simulate::SimModel::from_report(&report);
        let data = crate::refine::Data {
            t: &recording.t,
            x: &recording.x,
            u: recording.u.as_deref(),
        };
        crate::refine::Summary::of(
            &crate::refine::refine_and_check(&model, &data),
            report.omega,
        )
    });
    if args.json {
        // The report's own fields in their order, then "refined" when asked for.
        let mut text = serde_json::to_string(&report).unwrap_or_default();
        if let Some(refined) = &refined {
            text.pop();
            text.push_str(",\"refined\":");
            text.push_str(&serde_json::to_string(refined).unwrap_or_default());
            text.push('}');
        }
        crate::outln!("{text}");
    } else {
        crate::out!("{}", identify::render(&report));
        if let Some(refined) = &refined {
            crate::out!("{}", refined.render(&args.unit));
        }
    }
    Ok(())
}

/// Configures and runs the identifier on a recording.
pub fn identify_recording(
    recording: &Recording,
    options: &Options,
) -> Result<identify::Report, CliError> {
    let bad = |e: identify::IdentifyError| CliError::Identify(e.0);
    let (config, estimated) = identify::configure(recording, options).map_err(bad)?;
    if options.f32 {
        identify::run::<f32>(recording, config, estimated).map_err(bad)
    } else {
        identify::run::<f64>(recording, config, estimated).map_err(bad)
    }
}

/// `lssi identify --track`: the snapshots, then the settle time.
fn run_track(
    args: &IdentifyArgs,
    recording: &Recording,
    options: &Options,
) -> Result<(), CliError> {
    let bad = |e: identify::IdentifyError| CliError::Identify(e.0);
    let truth: Option<Truth> = match &args.truth {
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|e| CliError::BadFlag {
                flag: "--truth",
                value: path.display().to_string(),
                requirement: format!("a readable truth file ({e})"),
            })?;
            Some(serde_json::from_str(&text).map_err(|e| CliError::BadFlag {
                flag: "--truth",
                value: path.display().to_string(),
                requirement: format!("a truth file written by `lssi gen` ({e})"),
            })?)
        }
        None => None,
    };
    let (config, _) = identify::configure(recording, options).map_err(bad)?;
    let track_options = TrackOptions { every: args.every };
    let track = if options.f32 {
        track::track::<f32>(recording, config, &track_options)
    } else {
        track::track::<f64>(recording, config, &track_options)
    }
    .map_err(bad)?;
    let (reference, truth_change) = match &truth {
        Some(truth) => {
            let (r, c) =
                track::reference_from_truth(truth, &track).map_err(|reason| CliError::BadFlag {
                    flag: "--truth",
                    value: args
                        .truth
                        .as_ref()
                        .map(|p| p.display().to_string())
                        .unwrap_or_default(),
                    requirement: format!("a truth for this library, but {reason}"),
                })?;
            (r, c)
        }
        None => (
            track
                .snapshots
                .last()
                .map(|s| s.coefficients.clone())
                .unwrap_or_default(),
            None,
        ),
    };
    let reference_name = if truth.is_some() {
        "the true coefficients after the change"
    } else {
        "the final estimate"
    };
    let settle = args
        .change_at
        .or(truth_change)
        .map(|at| track::settle(&track, &reference, at, args.settle_tol));
    if args.json {
        crate::out!("{}", track::to_json_lines(&track));
        if let Some(s) = &settle {
            let line = serde_json::json!({ "settle": s, "reference": reference_name });
            crate::outln!("{line}");
        }
    } else {
        crate::out!("{}", track::to_csv(&track));
        if let Some(s) = &settle {
            eprintln!("{}", settle_sentence(s, reference_name));
        }
    }
    Ok(())
}

/// The settle time as a sentence.
fn settle_sentence(s: &track::Settle, reference: &str) -> String {
    let tol = 100.0 * s.tolerance;
    match (s.settled_at, s.settle_time) {
        (Some(at), Some(time)) => format!(
            "settled {time:.3} s after the change at {} s (from t = {at} s every coefficient stays within {tol} % of {reference}).",
            s.change_at
        ),
        _ => format!(
            "not settled: after the change at {} s the coefficients never stay within {tol} % of {reference} to the end of the record.",
            s.change_at
        ),
    }
}
