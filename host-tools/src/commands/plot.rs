//! `lssi plot FILE.csv --out DIR`: pictures of a recording and its identified model.
//!
//! The recording is identified exactly as `lssi identify` does it (same flags), then every
//! figure of [`crate::plot`] is written to `DIR` as PNG and SVG, and the paths are printed.
//! A figure the data cannot support (e.g. no model came out of a screening) is skipped with
//! a note on stderr; the others are still written.

use std::path::PathBuf;

use clap::Args;

use crate::commands::identify::IdentifyArgs;
use crate::error::CliError;
use crate::identify::identify_recording;
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
    let report = identify_recording(&recording, &options)?;
    let units = Units {
        x: args.x_unit.clone(),
    };
    let (written, skipped) = plot_all(&recording, &options, &report, &args.out, &units)?;
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
