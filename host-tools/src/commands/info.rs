//! `lssi info FILE.csv`: reads a recording as `lssi identify` would and says what is in it, or
//! why it cannot be used.

use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;
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
    Ok(())
}
