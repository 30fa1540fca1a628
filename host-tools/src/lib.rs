//! The host side of lssi: the `lssi` command's building blocks, usable from tests and tools.
//!
//! - [`recording`]: CSV recordings in and out, with one-sentence errors.
//! - [`identify`]: a recording through the streaming identifier, and around it the model over
//!   time ([`identify::track`]), free simulation ([`identify::simulate`]), output-error
//!   refinement ([`identify::refine`]) and the names of library terms ([`identify::terms`]).
//! - [`synth`]: synthetic recordings with a known equation (`lssi gen`; [`synth::paper`] is the
//!   paper's eq. 17), built on [`synth::ode`] (fixed-step RK4) and [`synth::noise`] (eq. 16),
//!   with their answer key ([`synth::truth`]).
//! - [`serial`]: `lssi replay` and `lssi monitor` over a serial link ([`serial::link`]) to
//!   `firmware-sim`, QEMU or a board ([`serial::device`]).
//! - [`telemetry`]: the telemetry log the device's traffic goes to and `lssi log` reads, and the
//!   device's defmt log lines ([`telemetry::defmt`]).
//! - [`plot`]: the figures of `lssi plot` (PNG and SVG).
//! - [`error`]: the command's failures, each a sentence and an exit code.
//! - [`output`]: the command's buffered standard output.
//! - [`commands`]: the subcommands' clap arguments and the glue that `main` dispatches to.
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

pub mod commands;
pub mod error;
pub mod identify;
pub mod output;
pub mod plot;
pub mod recording;
pub mod serial;
pub mod synth;
pub mod system;
pub mod telemetry;
