//! `lssi identify FILE.csv`: the equation of motion of a recording.
//!
//! With `--track` it prints instead the model selected at every screening (every `--every`
//! seconds) as CSV on stdout, or JSON lines with `--json`, and the settle time after a change
//! (see [`crate::identify::track`]): on stderr after the CSV, or as a last JSON line
//! `{"settle": {...}}`. The change time is `--change-at`, or the drift time of `--truth`;
//! the reference is the truth's coefficients after the change, or else the last snapshot.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::commands::identifier::IdentifierArgs;
use crate::error::CliError;
use crate::identify::pipeline::{Failure, Refine};
use crate::identify::track::{self, TrackOptions};
use crate::identify::{self, Options, batch};
use crate::recording::{ColumnNames, Recording};
use crate::synth::truth::Truth;

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
    /// The recording: CSV with a header row naming t and x (or v alone, integrated), and optionally u, V or i.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// More recordings (or folders, each meaning its *.csv files): identified in parallel on
    /// every core, one JSON line (--json) or one CSV row (--csv) per file; a file that fails
    /// gets its error in its row, and the exit code is 2 if any did.
    #[arg(value_name = "MORE.csv", num_args = 0..)]
    pub more: Vec<PathBuf>,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
    /// A system's electrical channels, load and coupling order (issue 26; see crate::system).
    #[command(flatten)]
    pub system: crate::system::SystemArgs,
    /// Identify the recording as `lssi replay --encoding i16` sends it: times on a uniform
    /// grid, values rounded to i16 quanta (one scale per channel), so the model is the one
    /// a compact replay must give.
    #[arg(
        long,
        value_enum,
        value_name = "ENCODING",
        conflicts_with_all = ["more", "csv"],
        help_heading = "Input"
    )]
    pub quantise: Option<Quantise>,
    /// The identifier's flags (shared with `lssi replay` and `lssi plot`): the library,
    /// then the smoothing and the memory.
    #[command(flatten)]
    pub identifier: IdentifierArgs,
    /// Compute in f32, as a device does (the default).
    #[arg(long, conflicts_with = "f64", help_heading = "Identifier")]
    pub f32: bool,
    /// Compute in f64 (the reference).
    #[arg(long, help_heading = "Identifier")]
    pub f64: bool,
    /// Experimental: take the noise of the derivative estimates out of the normal equations
    /// (errors in variables; rows as they are, without the test-function sums; host only,
    /// the device protocol does not carry it)
    #[arg(long, help_heading = "Identifier")]
    pub noise_correction: bool,
    /// Skip the refinement on simulation error: report the streaming identifier's model (the
    /// one a device computes for the same samples), in a fraction of the time.
    #[arg(long, conflicts_with = "refine", help_heading = "Identifier")]
    pub no_refine: bool,
    /// Refine even where the default does not: a file over 8 MiB is then read whole instead
    /// of streamed, and several recordings are each refined. (Refinement is on by default for
    /// one recording; this flag was needed before, and is accepted.)
    #[arg(long, help_heading = "Identifier")]
    pub refine: bool,
    /// Print one JSON object instead of text (with --track: JSON lines instead of CSV).
    #[arg(long, help_heading = "Output")]
    pub json: bool,
    /// With several recordings: a CSV table (file, equation, terms, coefficients, samples,
    /// rejected, error) instead of text.
    #[arg(long, conflicts_with = "json", help_heading = "Output")]
    pub csv: bool,
    /// The unit of x, for the text report (e.g. m, mm, V).
    #[arg(
        long,
        value_name = "UNIT",
        default_value = "[x]",
        help_heading = "Output"
    )]
    pub unit: String,
    /// Print the coefficients over time (one row per screening) and the settle time after a
    /// change, instead of the final model (the streaming identifier's models: not refined).
    #[arg(long, help_heading = "Output")]
    pub track: bool,
    /// With --track: seconds between two screenings.
    #[arg(
        long,
        value_name = "SECONDS",
        default_value_t = 0.25,
        help_heading = "Output"
    )]
    pub every: f64,
    /// With --track: the truth file (from `lssi gen`) whose coefficients after its drift are
    /// the reference of the settle time, and whose drift time is the change time.
    #[arg(long, value_name = "FILE.json", help_heading = "Output")]
    pub truth: Option<PathBuf>,
    /// With --track: the time of the change, seconds [default: the truth's drift time].
    #[arg(
        long = "change-at",
        value_name = "SECONDS",
        allow_negative_numbers = true,
        help_heading = "Output"
    )]
    pub change_at: Option<f64>,
    /// With --track: the relative tolerance of the settle time.
    #[arg(
        long = "settle-tol",
        value_name = "FRACTION",
        default_value_t = 0.05,
        help_heading = "Output"
    )]
    pub settle_tol: f64,
}

impl IdentifyArgs {
    /// The identifier options these flags ask for.
    pub fn options(&self) -> Result<Options, CliError> {
        Ok(Options {
            f32: !self.f64,
            noise_correction: self.noise_correction,
            ..self.identifier.options()?
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
    // Standard input (`-`) or a pipe (`/dev/stdin`): spooled to a temporary file in chunks,
    // then read as a file is (streamed when large), named as given.
    let input = if args.more.is_empty() && !args.csv {
        identify::stream::Input::open(&args.file)?
    } else {
        identify::stream::Input::plain(&args.file)
    };
    // A recording with an electrical channel is a system (issue 26; crate::system).
    if args.more.is_empty() && !args.track && !args.csv && args.quantise.is_none() {
        let read = crate::system::read_if_system(input.file(), &args.columns, &args.system.columns)
            .map_err(|e| match e {
                // A spooled pipe's messages name it as the user did (`-`), not the temporary file.
                e if e.exit_code() == crate::error::EXIT_BAD_INPUT
                    && input.file() != input.name() =>
                {
                    CliError::Input(e.to_string().replace(
                        &input.file().display().to_string(),
                        &input.name().display().to_string(),
                    ))
                }
                e => e,
            })?;
        match read {
            Some(mut data) => {
                data.recording.path = input.name().to_owned();
                return crate::system::identify_command(
                    &data,
                    &options,
                    &args.system,
                    args.json,
                    args.no_refine,
                );
            }
            None => crate::system::refuse_stray_flags(&args.file, &args.system)?,
        }
    }
    if !args.more.is_empty() || args.file.is_dir() || args.csv {
        return run_batch(args, &options);
    }
    // Large files: read in chunks, configured from an excerpt (see identify::stream); not
    // refined unless --refine asks for it (refinement needs the whole signal in memory).
    if !args.track
        && !args.refine
        && args.quantise.is_none()
        && identify::stream::is_large(input.file())
    {
        let note = (!args.no_refine).then(|| {
            format!(
                "{}: not refined: the file is over {} MiB and {} rows and was read in chunks; this is the streaming identifier's model (--refine reads it whole and refines)",
                args.file.display(),
                identify::stream::STREAM_BYTES >> 20,
                identify::stream::STREAM_ROWS
            )
        });
        return identify::stream::identify_command(
            input.file(),
            input.name(),
            &args.columns,
            &options,
            args.json,
            note.as_deref(),
        );
    }
    let mut recording = input.read(&args.columns)?;
    if args.quantise == Some(Quantise::I16) {
        let quantised = crate::serial::quantise::quantise(&recording).map_err(CliError::Input)?;
        eprint!("lssi: {}", quantised.summary.render());
        recording = quantised.recording;
    }
    if args.track {
        return run_track(args, &recording, &options);
    }
    let refine = if args.no_refine {
        Refine::No("not refined (--no-refine)")
    } else {
        Refine::Yes
    };
    let outcome = identify::pipeline::identify(&recording, &options, refine);
    // Each rejected sample, on stderr: the first few named, then how many more.
    let report = match &outcome {
        Ok(done) => &done.report,
        Err(Failure::Withheld(_, _, report)) => report.as_ref(),
        Err(Failure::Error(e)) => return Err(CliError::Identify(e.clone())),
    };
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
    let done = match outcome {
        Ok(done) => done,
        Err(Failure::Withheld(sentence, reasons, report)) => {
            if args.json {
                // No "terms" at the top: a withheld model is not the answer. It is shown
                // under "withheld_model", beside why.
                let mut warnings = identify::pipeline::warnings(&report);
                warnings.extend(reasons);
                // "warnings" last, as in every other `--json` object.
                crate::outln!(
                    "{{\"withheld\":true,\"reason\":{},\"withheld_model\":{},\"warnings\":{}}}",
                    serde_json::Value::from(sentence.as_str()),
                    identify::json_text(&report, None, &[]),
                    serde_json::Value::from(warnings)
                );
            }
            return Err(CliError::NoDynamics(sentence));
        }
        Err(Failure::Error(e)) => return Err(CliError::Identify(e)),
    };
    if args.json {
        crate::outln!(
            "{}",
            identify::json_text(&done.report, done.refined.as_ref(), &done.warnings)
        );
    } else {
        let note = args.no_refine.then_some("not refined (--no-refine)");
        crate::out!(
            "{}",
            identify::render_reported(&done.report, done.refined.as_ref(), note, &args.unit)
        );
    }
    Ok(())
}

/// `lssi identify FILE...`: every file identified in parallel; printed in the order given, and
/// the exit code is 2 if any failed.
fn run_batch(args: &IdentifyArgs, options: &Options) -> Result<(), CliError> {
    if args.track {
        return Err(CliError::BadFlag {
            flag: "--track",
            value: "with several recordings".into(),
            requirement: "used with one recording only".into(),
        });
    }
    let mut paths = vec![args.file.clone()];
    paths.extend(args.more.iter().cloned());
    let files = batch::expand(&paths)?;
    let bar = if std::io::stderr().is_terminal() {
        let bar =
            ProgressBar::with_draw_target(Some(files.len() as u64), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template("{bar:30} {pos}/{len} recordings {elapsed}")
        {
            bar.set_style(style);
        }
        bar
    } else {
        ProgressBar::hidden()
    };
    let results = batch::identify_all(&files, &args.columns, options, args.refine, || bar.inc(1));
    bar.finish_and_clear();
    let mut out = String::new();
    if args.csv {
        out.push_str(batch::CSV_HEADER);
    }
    for (path, result) in files.iter().zip(&results) {
        let file = path.display().to_string();
        out.push_str(&if args.json {
            batch::json_line(&file, result)
        } else if args.csv {
            batch::csv_row(&file, result)
        } else {
            batch::text_block(&file, result, &args.unit)
        });
    }
    if let Err(e) = std::io::stdout().write_all(out.as_bytes()) {
        crate::output::fail(&e)
    }
    // Files that failed and folders that gave no recording, named: exit status 2.
    if let Some(sentence) = batch::failure_sentence(&files, &results) {
        return Err(CliError::Input(sentence));
    }
    // Models withheld by the quality gate: exit status 3, each file named.
    let withheld: Vec<String> = files
        .iter()
        .zip(&results)
        .filter(|(_, r)| matches!(r, Err(batch::Failure::Withheld(..))))
        .map(|(p, _)| p.display().to_string())
        .collect();
    if !withheld.is_empty() {
        const NAMED: usize = 5;
        let mut names = withheld
            .iter()
            .take(NAMED)
            .cloned()
            .collect::<Vec<_>>()
            .join(", ");
        if withheld.len() > NAMED {
            names.push_str(&format!(" and {} more", withheld.len() - NAMED));
        }
        return Err(CliError::NoDynamics(format!(
            "no deterministic dynamics found in {} of {} recordings, so their models are withheld: {names} (their rows say why).",
            withheld.len(),
            files.len(),
        )));
    }
    Ok(())
}

/// `lssi identify --track`: the snapshots, then the settle time.
fn run_track(
    args: &IdentifyArgs,
    recording: &Recording,
    options: &Options,
) -> Result<(), CliError> {
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
    let (config, _) = identify::configure(recording, options)?;
    let track_options = TrackOptions { every: args.every };
    let track = if options.f32 {
        track::track::<f32>(recording, config, &track_options)
    } else {
        track::track::<f64>(recording, config, &track_options)
    }?;
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
            eprintln!("{}", s.sentence(reference_name));
        }
    }
    Ok(())
}
