//! `lssi plot FILE.csv --out DIR: pictures of a recording and its identified model` (being written).

use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;

/// Arguments of `lssi plot`.
#[derive(Debug, Clone, Args)]
pub struct PlotArgs {
    /// The input file.
    pub file: PathBuf,
}

/// Runs `lssi plot`.
pub fn run(args: &PlotArgs) -> Result<(), CliError> {
    Err(CliError::Identify(format!(
        "{}: `lssi plot` is not written yet.",
        args.file.display()
    )))
}
