//! Failures the `lssi` command shows to a person: one sentence each, and an exit code.
//!
//! `main` prints a [`CliError`] as `lssi: <sentence>` on stderr and exits with
//! [`CliError::exit_code`]: 2 when the input was unusable (a bad recording, a bad flag value;
//! clap itself exits 2 for flags it cannot parse), 1 when the work itself failed (an output that
//! cannot be written).
//!
//! ```
//! use lssi_host::error::CliError;
//! use lssi_host::recording::{ColumnNames, parse_csv};
//!
//! let error: CliError = parse_csv("a.csv", "".as_bytes(), &ColumnNames::default())
//!     .unwrap_err()
//!     .into();
//! assert_eq!(error.exit_code(), 2);
//! assert!(error.to_string().starts_with("a.csv: the file is empty"));
//! ```

use std::io;
use std::path::PathBuf;

use crate::identify::IdentifyError;
use crate::recording::RecordingError;
use crate::serial::replay::ReplayError;
use crate::synth::OptionError;

/// Exit code for unusable input: a bad recording or a bad flag value.
pub const EXIT_BAD_INPUT: u8 = 2;
/// Exit code when the work failed for another reason, such as an unwritable output.
pub const EXIT_FAILURE: u8 = 1;
/// Exit status: the recording was read, but no model explains it (the quality gate).
pub const EXIT_NO_DYNAMICS: u8 = 3;

/// A failure of an `lssi` subcommand.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CliError {
    /// An input recording cannot be used.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A flag's value cannot be used.
    #[error("{flag} {value} cannot be used: it must be {requirement}.")]
    BadFlag {
        /// The flag, e.g. `--dt`.
        flag: &'static str,
        /// The value given, as text.
        value: String,
        /// What it must be, as the end of a sentence.
        requirement: String,
    },
    /// An output path cannot be used as given.
    #[error("{}: {reason}.", .path.display())]
    BadOutput {
        /// The path given.
        path: PathBuf,
        /// Why, as the end of a sentence.
        reason: String,
    },
    /// A simulation left the finite numbers: the options have no bounded solution that long.
    #[error(
        "the {model} simulation diverged at t = {t} s, so these options have no bounded \
         solution that long; try a smaller --t-end or other coefficients."
    )]
    Diverged {
        /// The generator's model name.
        model: String,
        /// The first sample time whose state is not finite, in seconds.
        t: f64,
    },
    /// The identifier cannot use a recording (a sentence naming the file).
    #[error("{0}")]
    Identify(String),
    /// An input other than a recording cannot be used (a telemetry log, a firmware image, a
    /// configuration the device refuses): a sentence naming it.
    #[error("{0}")]
    Input(String),
    /// The device or the link to it failed while working: a sentence naming the port.
    #[error("{0}")]
    Device(String),
    /// The identifier found no model that explains the recording (the quality gate,
    /// [`crate::identify::quality`]): a sentence naming the file and the reason. Exit status 3.
    #[error("{0}")]
    NoDynamics(String),
    /// An output file could not be written.
    #[error("{}: cannot write the file: {source}.", .path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
    /// An output folder could not be created.
    #[error("{}: cannot create the folder: {source}.", .path.display())]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
}

impl CliError {
    /// The process exit code for this failure.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Recording(_)
            | CliError::BadFlag { .. }
            | CliError::BadOutput { .. }
            | CliError::Diverged { .. }
            | CliError::Identify(_)
            | CliError::Input(_) => EXIT_BAD_INPUT,
            CliError::Write { .. } | CliError::CreateDir { .. } | CliError::Device(_) => {
                EXIT_FAILURE
            }
            CliError::NoDynamics(_) => EXIT_NO_DYNAMICS,
        }
    }

    /// Turns a generator [`OptionError`] into a flag error, naming the flag that sets `field`.
    pub fn from_option(error: OptionError, flag: &'static str) -> Self {
        CliError::BadFlag {
            flag,
            value: error.value.to_string(),
            requirement: error.requirement.to_owned(),
        }
    }
}

impl From<IdentifyError> for CliError {
    fn from(error: IdentifyError) -> Self {
        CliError::Identify(error.0)
    }
}

impl From<ReplayError> for CliError {
    fn from(error: ReplayError) -> Self {
        match error {
            ReplayError::Link(error) => CliError::Device(format!("{error}.")),
            ReplayError::Input(sentence) => CliError::Input(sentence),
        }
    }
}
