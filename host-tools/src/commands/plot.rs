//! `lssi plot FILE.csv --out DIR`: pictures of a recording and its identified model.
//!
//! The recording is identified exactly as `lssi identify` does it (same flags, the same
//! pipeline: the model drawn is the one it prints, refined unless `--no-refine`), then every
//! figure of [`crate::plot`] is written to `DIR` as PNG and SVG, and the paths are printed.
//! A figure the data cannot support (e.g. no model came out of a screening) is skipped with
//! a note on stderr; the others are still written.

use std::path::PathBuf;

use clap::Args;

use crate::commands::identify::IdentifyArgs;
use crate::error::CliError;
use crate::identify;
use crate::identify::pipeline::{Failure, Refine};
use crate::plot::{Units, plot_all};
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
    if args.out.exists() && !args.out.is_dir() {
        return Err(CliError::BadOutput {
            path: args.out.clone(),
            reason: "exists and is not a directory, so the figures cannot go there".into(),
        });
    }
    let recording = Recording::read(&args.identify.file, &args.identify.columns)?;
    // The model `lssi identify` prints, through the same pipeline (refined unless
    // --no-refine; a model the quality gate withholds is not drawn).
    let refine = if args.identify.no_refine {
        Refine::No("not refined (--no-refine)")
    } else {
        Refine::Yes
    };
    let done = match identify::pipeline::identify(&recording, &options, refine) {
        Ok(done) => done,
        Err(Failure::Withheld(sentence, ..)) => return Err(CliError::NoDynamics(sentence)),
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
    let (written, skipped) = plot_all(
        &recording,
        &options,
        &report,
        prediction.as_deref(),
        &args.out,
        &units,
    )?;
    for note in &skipped {
        eprintln!("lssi: figure skipped: {note}");
    }
    if args.identify.json {
        let object =
            serde_json::json!({ "figures": written, "skipped": skipped, "report": report });
        crate::outln!("{object}");
    } else {
        for w in &written {
            crate::outln!("{}", w.png.display());
            crate::outln!("{}", w.svg.display());
        }
    }
    Ok(())
}
