//! The `lssi` command: parses the command line and dispatches to a subcommand in
//! [`lssi_host::commands`]. Failures print as `lssi: <sentence>` on stderr and set the exit
//! code (see [`lssi_host::error`]).

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use lssi_host::commands::{bench, generate, identify, info, log, monitor, plot, replay, simulate};
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
    /// Identify the equation of motion x'' = f(x, v, t) of a recording (CSV).
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
    /// Draw a recording and its identified model (PNG and SVG).
    Plot(plot::PlotArgs),
    /// Simulate a model from `lssi identify --json` over a recording's time grid and input.
    Simulate(simulate::SimulateArgs),
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
