//! The `lssi` command: parses the command line and dispatches to a subcommand in
//! [`lssi_host::commands`]. Failures print as `lssi: <sentence>` on stderr and set the exit
//! code (see [`lssi_host::error`]).

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use lssi_host::commands::{
    bench, defmt, generate, identify, info, log, monitor, plot, replay, simulate,
};
use lssi_host::error::CliError;

/// Streaming sparse identification (LSSI) of vibration energy harvesters: host tools.
#[derive(Debug, Parser)]
#[command(name = "lssi", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Write a synthetic recording (CSV) and its truth (JSON beside it).
    Gen(generate::GenArgs),
    /// Benchmarks that print tables (accuracy on the paper's eq. 17, throughput).
    Bench(bench::BenchArgs),
    /// Identify the equation of motion x'' = f(x, v, t, u) of a recording (CSV), or a
    /// harvester's system (x'' and V' or i') when it has a voltage or current column.
    Identify(identify::IdentifyArgs),
    /// Read a recording (CSV) and summarise it, or say why it cannot be used.
    Info(info::InfoArgs),
    /// Replay a recording through the device code over a serial link (simulated, QEMU or real).
    Replay(replay::ReplayArgs),
    /// Print a telemetry log written by `lssi replay` or `lssi monitor` (text, JSON or CSV).
    Log(log::LogArgs),
    /// Listen to a standalone device (a serial port, or the firmware under QEMU sampling a
    /// recording): live model and health, telemetry log, JSON lines.
    Monitor(monitor::MonitorArgs),
    /// Draw recordings and their identified models (PNG and SVG).
    ///
    /// Each recording named (a folder: its *.csv files) is identified as `lssi identify`
    /// does it and its figures are written to --out as <stem>-<figure>.png and .svg. A model
    /// the quality gate withholds (`lssi identify` exits 3) is not drawn at all: no figure of
    /// that recording is written, and the reason is printed. A recording that fails does not
    /// stop the others; the exit code is 2 if one could not be used, else 3 if a model was
    /// withheld, else 1 if a figure could not be written.
    #[command(mut_arg("more", |a| a.help(
        "More recordings (or folders, each meaning its *.csv files), plotted one after the \
         other; one that fails is named on stderr and the others are still plotted"
    )))]
    Plot(plot::PlotArgs),
    /// Simulate a model from `lssi identify --json` over a recording's time grid and input.
    Simulate(simulate::SimulateArgs),
    /// Decode a device's defmt log (bytes on standard input) with its firmware's ELF, as
    /// `defmt-print -e ELF` does.
    Defmt(defmt::DefmtArgs),
}

fn run(cli: &Cli) -> Result<(), CliError> {
    match &cli.command {
        Command::Gen(args) => generate::run(args),
        Command::Info(args) => info::run(args),
        Command::Identify(args) => identify::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Replay(args) => replay::run(args),
        Command::Log(args) => log::run(args),
        Command::Monitor(args) => monitor::run(args),
        Command::Plot(args) => plot::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Defmt(args) => defmt::run(args),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => {
            lssi_host::output::flush();
            ExitCode::SUCCESS
        }
        Err(error) => {
            lssi_host::output::flush();
            eprintln!("lssi: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        super::Cli::command().debug_assert();
    }
}
