//! The `lssi` subcommands, one module each: a clap `Args` type and a
//! `run(&Args) -> Result<(), CliError>` that glues the library's modules together; `main` only
//! parses and dispatches. [`identifier`] holds the identifier's flags, which `lssi identify`,
//! `lssi plot` and `lssi replay` flatten into their own.

pub mod bench;
pub mod defmt;
pub mod generate;
pub mod identifier;
pub mod identify;
pub mod info;
pub mod log;
pub mod monitor;
pub mod plot;
pub mod replay;
pub mod simulate;
