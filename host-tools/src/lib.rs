//! The host side of lssi: the `lssi` command's building blocks, usable from tests and tools.
//!
//! - [`recording`]: CSV recordings in and out, with one-sentence errors.
//! - [`generators`]: synthetic recordings with a known equation ([`generators::paper`] is the
//!   paper's eq. 17), built on [`ode`] (fixed-step RK4) and [`noise`] (eq. 16).
//! - [`simulate`]: free simulation of an identified model, and its NRMSE against a record.
//! - [`plot`]: the figures of `lssi plot` (PNG and SVG).
//! - [`track`]: the identified coefficients over time, and the settle time after a change.
//! - [`truth`]: the answer key a generator writes and a benchmark reads.
//! - [`terms`]: how library terms are named across the project.
//! - [`error`]: the command's failures, each a sentence and an exit code.
//! - [`link`], [`replay`], [`device`], [`telemetry`], [`defmt`]: `lssi replay` over a serial
//!   link (to `firmware-sim`, QEMU or a board) and the telemetry log `lssi log` reads.
//! - [`commands`]: the subcommands that `main` dispatches to.
//!
//! A subcommand reads its input like this, and `main` prints the error as `lssi: <sentence>`:
//!
//! ```no_run
//! use lssi_host::error::CliError;
//! use lssi_host::recording::{ColumnNames, Recording};
//!
//! let recording = Recording::read("data.csv", &ColumnNames::default())?;
//! for sample in recording.samples() {
//!     // feed sample.t, sample.x, sample.v (if observed) to the identifier
//! }
//! # Ok::<(), CliError>(())
//! ```

// Tests may panic on the unexpected: that is how they fail.
#![cfg_attr(test, allow(clippy::unwrap_used))]

pub mod adapt;
pub mod commands;
pub mod defmt;
pub mod device;
pub mod error;
pub mod generators;
pub mod identify;
pub mod link;
pub mod noise;
pub mod ode;
pub mod output;
pub mod plot;
pub mod quantise;
pub mod recording;
pub mod refine;
pub mod replay;
pub mod simulate;
pub mod telemetry;
pub mod terms;
pub mod track;
pub mod truth;
