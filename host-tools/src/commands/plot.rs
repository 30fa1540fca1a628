//! `lssi plot FILE.csv [MORE.csv | DIR]... --out DIR`: pictures of recordings and their
//! identified models.
//!
//! Each recording is identified exactly as `lssi identify` does it (same flags, the same
//! pipeline: the model drawn is the one it prints, refined unless `--no-refine`), then every
//! figure of [`crate::plot`] is written to `DIR` as PNG and SVG, and the paths are printed.
//! Several recordings (a folder meaning its `*.csv` files) are plotted one after the other,
//! each named `<stem>-<figure>`; one that fails says why on stderr and the others are still
//! plotted, and the exit code says the worst (2 for a recording that cannot be used, 3 for a
//! withheld model, 1 for figures that cannot be written).
//!
//! A model the quality gate withholds (`lssi identify` exits 3) is not drawn at all: no
//! figure of that recording is written, and the reason is printed. A figure the data cannot
//! support (e.g. too few rows for the neighbour curve) is skipped with a note on stderr; the
//! others are still written. A figure whose file cannot be written is an error naming it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::commands::identify::IdentifyArgs;
use crate::error::CliError;
use crate::identify::pipeline::{Failure, Refine};
use crate::identify::{self, Options, batch};
use crate::plot::{PlotError, Units, plot_all};
use crate::recording::Recording;

/// Arguments of `lssi plot`.
#[derive(Debug, Clone, Args)]
pub struct PlotArgs {
    /// The recording and the identification flags, as for `lssi identify` (`--json` prints
    /// the files written and the model as one JSON object).
    #[command(flatten)]
    pub identify: IdentifyArgs,
    /// Directory the figures go to (created if missing).
    #[arg(long, value_name = "DIR", help_heading = "Output")]
    pub out: PathBuf,
    /// Unit of the displacement x, for the axis labels (e.g. m, mm); v is in UNIT/s.
    #[arg(long, value_name = "UNIT", help_heading = "Output")]
    pub x_unit: Option<String>,
}

/// Runs `lssi plot`.
pub fn run(args: &PlotArgs) -> Result<(), CliError> {
    let options = args.identify.options()?;
    if let Some(unit) = &args.x_unit
        && (unit.trim().is_empty() || unit.chars().any(char::is_control) || unit.len() > 16)
    {
        return Err(CliError::BadFlag {
            flag: "--x-unit",
            value: format!("{unit:?}"),
            requirement: "a short unit name such as m or mm".into(),
        });
    }
    let id = &args.identify;
    for (flag, given) in [
        ("--csv", id.csv),
        ("--track", id.track),
        ("--quantise", id.quantise.is_some()),
    ] {
        if given {
            return Err(CliError::BadFlag {
                flag,
                value: "with lssi plot".into(),
                requirement: "left out: it is a flag of lssi identify, and lssi plot draws figures"
                    .into(),
            });
        }
    }
    if args.out.exists() && !args.out.is_dir() {
        return Err(CliError::BadOutput {
            path: args.out.clone(),
            reason: "exists and is not a directory, so the figures cannot go there".into(),
        });
    }
    let mut paths = vec![id.file.clone()];
    paths.extend(id.more.iter().cloned());
    let files = batch::expand(&paths)?;
    same_stems(&files, &args.out)?;
    if files.len() == 1 {
        return plot_one(args, &options, &files[0]);
    }
    // Several: each plotted or failed in turn, each failure on stderr as it comes.
    let mut failed: Vec<(String, CliError)> = Vec::new();
    for file in &files {
        if let Err(error) = plot_one(args, &options, file) {
            eprintln!("lssi: {error}");
            failed.push((file.display().to_string(), error));
        }
    }
    if failed.is_empty() {
        return Ok(());
    }
    let mut names: Vec<&str> = failed.iter().take(5).map(|(f, _)| f.as_str()).collect();
    let more = failed.len().saturating_sub(names.len());
    let and_more = if more > 0 {
        format!(" and {more} more")
    } else {
        String::new()
    };
    names.dedup();
    let summary = |what: &str| {
        format!(
            "{} of {} recordings {what}: {}{and_more} (each said why above).",
            failed.len(),
            files.len(),
            names.join(", ")
        )
    };
    let worst = failed
        .iter()
        .map(|(_, e)| e.exit_code())
        .max_by_key(|&code| match code {
            crate::error::EXIT_BAD_INPUT => 3,
            crate::error::EXIT_NO_DYNAMICS => 2,
            _ => 1,
        });
    Err(match worst {
        Some(crate::error::EXIT_BAD_INPUT) => CliError::Input(summary("could not be plotted")),
        Some(crate::error::EXIT_NO_DYNAMICS) => CliError::NoDynamics(summary(
            "were not plotted because their models are withheld",
        )),
        _ => CliError::Write {
            path: args.out.clone(),
            source: std::io::Error::other(summary("have figures that could not be written")),
        },
    })
}

/// Two recordings of the same name (in different folders) would write the same figure files.
fn same_stems(files: &[PathBuf], out: &Path) -> Result<(), CliError> {
    let mut seen: HashMap<std::ffi::OsString, &Path> = HashMap::new();
    for file in files {
        let stem = file.file_stem().unwrap_or_default().to_owned();
        if let Some(first) = seen.insert(stem, file) {
            return Err(CliError::Input(format!(
                "{} and {} have the same name, so their figures would overwrite each other in {}; plot them into different --out folders.",
                first.display(),
                file.display(),
                out.display()
            )));
        }
    }
    Ok(())
}

/// Plots one recording: its figures written and their paths printed, or why not.
fn plot_one(args: &PlotArgs, options: &Options, file: &Path) -> Result<(), CliError> {
    if let Some(problem) = batch::folder_problem(file) {
        return Err(CliError::Input(problem));
    }
    // A harvester's recording (an electrical channel): its own figures.
    if let Some(data) =
        crate::system::read_if_system(file, &args.identify.columns, &args.identify.system.columns)?
    {
        return plot_system(args, options, &data);
    }
    crate::system::refuse_stray_flags(file, &args.identify.system)?;
    let recording = Recording::read(file, &args.identify.columns)?;
    // The model `lssi identify` prints, through the same pipeline (refined unless
    // --no-refine); a model the quality gate withholds is not drawn.
    let refine = if args.identify.no_refine {
        Refine::No("not refined (--no-refine)")
    } else {
        Refine::Yes
    };
    let done = match identify::pipeline::identify(&recording, options, refine) {
        Ok(done) => done,
        Err(Failure::Withheld(sentence, ..)) => {
            return Err(CliError::NoDynamics(format!(
                "{sentence} No figure of it was drawn."
            )));
        }
        Err(Failure::Error(e)) => return Err(CliError::Identify(e)),
    };
    let report = done.report;
    let prediction = done.refined.as_ref().and_then(|r| {
        r.prediction.map(|f| {
            format!(
                "predictions over {:.3} s windows of the held-out half, as lssi identify reports them: NRMSE {:.2} %",
                r.horizon.seconds, f.nrmse_percent
            )
        })
    });
    let units = Units {
        x: args.x_unit.clone(),
    };
    let figures = plot_all(
        &recording,
        options,
        &report,
        prediction.as_deref(),
        &args.out,
        &units,
    )?;
    for note in &figures.skipped {
        eprintln!("lssi: {}: figure skipped: {note}", file.display());
    }
    if args.identify.json {
        let failed: Vec<String> = figures.failed.iter().map(ToString::to_string).collect();
        let object = serde_json::json!({
            "file": file,
            "figures": figures.written,
            "skipped": figures.skipped,
            "failed": failed,
            "report": report,
        });
        crate::outln!("{object}");
    } else {
        for w in &figures.written {
            crate::outln!("{}", w.png.display());
            crate::outln!("{}", w.svg.display());
        }
    }
    match figures.failed.first() {
        None => Ok(()),
        Some(PlotError::Write { path, reason }) => {
            let others = figures.failed.len() - 1;
            let reason = if others > 0 {
                format!("{reason} (and {others} more of its figures could not be written)")
            } else {
                reason.clone()
            };
            Err(CliError::Write {
                path: path.clone(),
                source: std::io::Error::other(reason),
            })
        }
        Some(other) => Err(CliError::Input(other.to_string())),
    }
}

/// Plots a harvester's recording (issue 26): the model `lssi identify` prints for it, drawn by
/// [`crate::plot::plot_system`]; a withheld model is not drawn.
fn plot_system(
    args: &PlotArgs,
    options: &Options,
    data: &crate::system::SystemData,
) -> Result<(), CliError> {
    use crate::system::{Outcome, identify_system};
    let file = &data.recording.path;
    let report = match identify_system(
        data,
        options,
        &args.identify.system,
        args.identify.no_refine,
    )? {
        Outcome::Passed(report) => report,
        Outcome::Withheld(sentence, _) => {
            return Err(CliError::NoDynamics(format!(
                "{sentence} No figure of it was drawn."
            )));
        }
    };
    let figures = crate::plot::plot_system(data, &report, &args.out)?;
    for note in &figures.skipped {
        eprintln!("lssi: {}: figure skipped: {note}", file.display());
    }
    if args.identify.json {
        let failed: Vec<String> = figures.failed.iter().map(ToString::to_string).collect();
        let object = serde_json::json!({
            "file": file,
            "figures": figures.written,
            "skipped": figures.skipped,
            "failed": failed,
            "report": report,
        });
        crate::outln!("{object}");
    } else {
        for w in &figures.written {
            crate::outln!("{}", w.png.display());
            crate::outln!("{}", w.svg.display());
        }
    }
    match figures.failed.first() {
        None => Ok(()),
        Some(PlotError::Write { path, reason }) => Err(CliError::Write {
            path: path.clone(),
            source: std::io::Error::other(reason.clone()),
        }),
        Some(other) => Err(CliError::Input(other.to_string())),
    }
}
