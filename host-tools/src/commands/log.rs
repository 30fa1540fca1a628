//! `lssi log FILE: print a telemetry log` (being written).

use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;

/// Arguments of `lssi log`.
#[derive(Debug, Clone, Args)]
pub struct LogArgs {
    /// The input file.
    pub file: PathBuf,
}

/// Runs `lssi log`.
pub fn run(args: &LogArgs) -> Result<(), CliError> {
    Err(CliError::Identify(format!(
        "{}: `lssi log` is not written yet.",
        args.file.display()
    )))
}
