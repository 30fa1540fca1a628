//! `lssi info FILE.csv`: reads a recording as `lssi identify` would and says what is in it, or
//! why it cannot be used.
//!
//! Besides the columns, the length and the time span, it runs the checks `lssi identify` runs
//! before it identifies, with its default flags: the blemishes of the time axis and the values
//! (time gaps, samples too early, NaNs, spikes: [`crate::identify::blemish`]) as warnings; a
//! constant x ([`crate::identify::quality::constant`]: exit 3, as `identify` withholds its
//! model); and the configuration (too few samples, too broken to identify, no frequency to
//! estimate: [`crate::identify::configure`]: exit 2 with `identify`'s sentence).

use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;
use crate::identify::blemish::Scan;
use crate::identify::{Options, configure, quality};
use crate::recording::{ColumnNames, Recording};

/// Arguments of `lssi info`.
#[derive(Debug, Clone, Args)]
pub struct InfoArgs {
    /// The recording: CSV with a header row naming at least t and x.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
}

/// Runs `lssi info`.
pub fn run(args: &InfoArgs) -> Result<(), CliError> {
    // Large files: one pass, nothing held (see crate::identify::stream).
    if crate::identify::stream::is_large(&args.file) {
        crate::out!(
            "{}",
            crate::identify::stream::describe_file(&args.file, &args.columns)?
        );
        return Ok(());
    }
    let recording = Recording::read(&args.file, &args.columns)?;
    crate::out!("{}", recording.describe());
    check(&recording)
}

/// What `lssi identify` would say of the recording before identifying it: the blemishes it
/// names printed as warnings, then its refusal (a constant x, a recording too short or too
/// broken), or the configuration it would use.
fn check(recording: &Recording) -> Result<(), CliError> {
    let scan = Scan::of(recording);
    for blemish in scan.summary() {
        crate::outln!("warning: {blemish}");
    }
    if let Some(why) = quality::constant(recording) {
        return Err(CliError::NoDynamics(format!(
            "no deterministic dynamics found in {}: {why}.",
            recording.path.display()
        )));
    }
    let (config, estimated) = configure(recording, &Options::default())?;
    crate::outln!(
        "identifier (default flags): sample period {:.6e} s, derivative window {} samples, test function {} rows, Ω {:.4} rad/s{}",
        config.sample_period,
        config.window,
        config.test_rows,
        config.omega,
        if estimated { " (estimated)" } else { "" }
    );
    Ok(())
}
