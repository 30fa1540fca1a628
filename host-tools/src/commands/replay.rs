//! `lssi replay FILE.csv: replay a recording through the device code over a serial link` (being written).

use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;

/// Arguments of `lssi replay`.
#[derive(Debug, Clone, Args)]
pub struct ReplayArgs {
    /// The input file.
    pub file: PathBuf,
}

/// Runs `lssi replay`.
pub fn run(args: &ReplayArgs) -> Result<(), CliError> {
    Err(CliError::Identify(format!(
        "{}: `lssi replay` is not written yet.",
        args.file.display()
    )))
}
