//! The `lssi` subcommands, one module each. Each exposes a clap `Args` type and a
//! `run(&Args) -> Result<(), CliError>`; `main` only parses and dispatches.

pub mod batch;
pub mod bench;
pub mod generate;
pub mod identify;
pub mod info;
pub mod log;
pub mod monitor;
pub mod plot;
pub mod replay;
