//! `lssi replay FILE.csv`: a recording through the device code over a serial link, to
//! `firmware-sim` (started here on a pty), to the firmware under QEMU (`--qemu`) or to a board
//! (`--port`), with the same result as `lssi identify --f32`.
//!
//! Everything the device sends is appended to the telemetry log (`--log`, default
//! `FILE.tlm` next to the recording) as it arrives; `lssi log` prints it.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, ValueEnum};

use crate::commands::identifier::IdentifierArgs;
use crate::error::CliError;
use crate::identify::{self, Options};
use crate::recording::ColumnNames;
use crate::serial::device::{DEFAULT_FIRMWARE, SimOptions};
use crate::serial::link::LinkOptions;
use crate::serial::replay::{ReplayReport, render_link};
use crate::serial::session::{self, Device, Setup};

/// How the samples cross the link (`--encoding`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Encoding {
    /// t as f64 and the channels as f32: the recording as `lssi identify --f32` reads it
    /// (12 bytes an x-only sample).
    F32,
    /// i16 fixed point with a scale per channel, times on a uniform grid (2 bytes an x-only
    /// sample): the model is that of the quantised recording (`lssi identify --quantise i16`).
    I16,
}

impl Encoding {
    /// Most samples a batch of this encoding holds.
    pub fn max_batch(self) -> usize {
        match self {
            Encoding::F32 => lssi_proto::MAX_BATCH,
            Encoding::I16 => lssi_proto::MAX_COMPACT_BATCH,
        }
    }

    /// The flag's value.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::F32 => "f32",
            Encoding::I16 => "i16",
        }
    }
}

/// Arguments of `lssi replay`.
#[derive(Debug, Clone, Args)]
pub struct ReplayArgs {
    /// The recording: CSV with a header row naming at least t and x.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// A serial port with a device on it (default: start firmware-sim on a pty).
    #[arg(long, value_name = "PATH", conflicts_with = "qemu")]
    pub port: Option<String>,
    /// Baud rate of the port (firmware-sim paces its pty at it).
    #[arg(long, default_value_t = 921_600, value_name = "N")]
    pub baud: u32,
    /// firmware-sim: probability of flipping each bit on the line.
    #[arg(long, default_value_t = 0.0, value_name = "R")]
    pub flip_rate: f64,
    /// firmware-sim: probability of dropping each frame.
    #[arg(long, default_value_t = 0.0, value_name = "R")]
    pub drop_rate: f64,
    /// firmware-sim: one burst of this many corrupted bytes.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub burst: u32,
    /// firmware-sim: seed of the faults.
    #[arg(long, default_value_t = 1, value_name = "S")]
    pub seed: u64,
    /// Run the firmware image under QEMU (mps2-an386) and replay through its UART.
    #[arg(long)]
    pub qemu: bool,
    /// The firmware image QEMU runs.
    #[arg(long, value_name = "ELF", requires = "qemu")]
    pub firmware: Option<PathBuf>,
    /// The firmware's ELF, to decode its defmt log lines (with --qemu: the image run).
    #[arg(long, value_name = "ELF")]
    pub elf: Option<PathBuf>,
    /// The telemetry log to append to (default: FILE.tlm next to the recording).
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Most sample batches unacknowledged at once.
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub window: usize,
    /// Most samples per batch (at most 24 with f32, 64 with i16; default: the most). The
    /// link shortens its batches while it measures losses and lengthens them again.
    #[arg(long, value_name = "N")]
    pub batch: Option<usize>,
    /// How the samples cross the link.
    #[arg(long, value_enum, default_value_t = Encoding::F32)]
    pub encoding: Encoding,
    /// Continue a replay the device (on --port) has begun, from the last sample it applied,
    /// without configuring it again (after a replay that gave up at its deadline).
    #[arg(long, requires = "port")]
    pub resume: bool,
    /// Seconds the link goes on without progress before it gives up.
    #[arg(long, default_value_t = 60.0, value_name = "SECONDS")]
    pub deadline: f64,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
    /// The identifier's flags (shared with `lssi identify`).
    #[command(flatten)]
    pub identifier: IdentifierArgs,
    /// Print one JSON object instead of text.
    #[arg(long, help_heading = "Output")]
    pub json: bool,
}

impl ReplayArgs {
    /// The arguments of `lssi replay FILE` with every flag at its command-line default
    /// (firmware-sim on a pty), for benchmarks and tests to adjust.
    pub fn for_file(file: &std::path::Path) -> Result<Self, CliError> {
        #[derive(clap::Parser)]
        struct Replay {
            #[command(flatten)]
            args: ReplayArgs,
        }
        <Replay as clap::Parser>::try_parse_from([std::ffi::OsStr::new("replay"), file.as_os_str()])
            .map(|r| r.args)
            .map_err(|e| CliError::Input(format!("{}: {e}", file.display())))
    }

    /// The identifier options: those `lssi identify --f32` takes from the same flags (the
    /// same struct, flattened into both commands).
    pub fn options(&self) -> Result<Options, CliError> {
        self.identifier.options()
    }

    /// The link's pacing from the flags.
    pub fn link_options(&self) -> Result<LinkOptions, CliError> {
        let bad = |flag, value: String, requirement: &str| CliError::BadFlag {
            flag,
            value,
            requirement: requirement.into(),
        };
        if self.baud == 0 {
            return Err(bad("--baud", "0".into(), "a positive baud rate"));
        }
        let max_batch = self.encoding.max_batch();
        let batch = self.batch.unwrap_or(max_batch);
        if !(1..=max_batch).contains(&batch) {
            return Err(bad(
                "--batch",
                batch.to_string(),
                &format!(
                    "between 1 and {max_batch} with --encoding {}",
                    self.encoding.name()
                ),
            ));
        }
        if !(self.deadline > 0.0 && self.deadline <= 86_400.0) {
            return Err(bad(
                "--deadline",
                self.deadline.to_string(),
                "a positive number of seconds, at most a day",
            ));
        }
        if !(1..=1024).contains(&self.window) {
            return Err(bad(
                "--window",
                self.window.to_string(),
                "between 1 and 1024",
            ));
        }
        let mut options = LinkOptions::for_baud(self.baud);
        options.window = self.window;
        options.batch = batch;
        options.deadline = Duration::from_secs_f64(self.deadline);
        if self.qemu {
            // An emulated Cortex-M4 screens far slower than a host.
            options.timeout = Duration::from_secs(1);
            options.silence = Duration::from_secs(120);
        }
        Ok(options)
    }

    /// firmware-sim's faults from the flags.
    pub fn sim_options(&self) -> Result<SimOptions, CliError> {
        for (flag, value) in [
            ("--flip-rate", self.flip_rate),
            ("--drop-rate", self.drop_rate),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(CliError::BadFlag {
                    flag,
                    value: value.to_string(),
                    requirement: "a probability between 0 and 1".into(),
                });
            }
        }
        let faults = self.flip_rate > 0.0 || self.drop_rate > 0.0 || self.burst > 0;
        if faults && (self.port.is_some() || self.qemu) {
            return Err(CliError::BadFlag {
                flag: "--flip-rate",
                value: format!("{} (or --drop-rate, --burst)", self.flip_rate),
                requirement: "left out with --port and --qemu: only firmware-sim injects faults"
                    .into(),
            });
        }
        Ok(SimOptions {
            baud: self.baud,
            flip_rate: self.flip_rate,
            drop_rate: self.drop_rate,
            burst: self.burst,
            seed: self.seed,
        })
    }

    /// The telemetry log's path.
    pub fn log_path(&self) -> PathBuf {
        self.log
            .clone()
            .unwrap_or_else(|| self.file.with_extension("tlm"))
    }
}

/// Runs `lssi replay`.
pub fn run(args: &ReplayArgs) -> Result<(), CliError> {
    let report = replay(args)?;
    print_report(&report, args.json);
    Ok(())
}

/// Replays as the flags say and returns the report (what `lssi replay` prints).
pub fn replay(args: &ReplayArgs) -> Result<ReplayReport, CliError> {
    let options = args.options()?;
    let link = args.link_options()?;
    let sim = args.sim_options()?;
    let device = match (&args.port, args.qemu) {
        (Some(port), _) => Device::Port(port.clone()),
        (None, true) => Device::Qemu(
            args.firmware
                .clone()
                .unwrap_or_else(|| PathBuf::from(DEFAULT_FIRMWARE)),
        ),
        (None, false) => Device::FirmwareSim,
    };
    let setup = Setup {
        file: args.file.clone(),
        columns: args.columns.clone(),
        options,
        link,
        sim,
        device,
        elf: args.elf.clone(),
        log: args.log_path(),
        progress: std::io::stderr().is_terminal() && !args.json,
        quantise: args.encoding == Encoding::I16,
        resume: args.resume,
    };
    session::replay(&setup)
}

fn print_report(report: &ReplayReport, json: bool) {
    if json {
        crate::outln!("{}", serde_json::to_string(report).unwrap_or_default());
    } else {
        crate::out!("{}", identify::render(&report.report));
        if let Some(quantisation) = &report.quantisation {
            crate::out!("{}", quantisation.render());
        }
        crate::out!("{}", render_link(&report.link));
    }
}

/// Arguments of `lssi bench replay`.
#[derive(Debug, Clone, Args)]
pub struct ReplayBenchArgs {
    /// The recording to replay.
    #[arg(value_name = "FILE.csv", default_value = "data/paper-eq17.csv")]
    pub file: PathBuf,
    /// Baud rates to measure at.
    #[arg(long, value_delimiter = ',', default_values_t = [115_200u32, 921_600])]
    pub baud: Vec<u32>,
    /// Samples per batch (default: the most the encoding allows).
    #[arg(long, value_name = "N")]
    pub batch: Option<usize>,
    /// Encodings to measure.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Encoding::F32, Encoding::I16])]
    pub encoding: Vec<Encoding>,
    /// Batches unacknowledged at once.
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub window: usize,
}

/// Runs `lssi bench replay`: the whole recording through firmware-sim at each baud rate,
/// with the throughput against the line's bound (8N1: baud / 10 bytes per second over the
/// wire bytes each sample costs).
pub fn bench(args: &ReplayBenchArgs) -> Result<(), CliError> {
    let dir = std::env::temp_dir().join(format!("lssi-bench-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| CliError::Write {
        path: dir.clone(),
        source: e,
    })?;
    crate::outln!(
        "lssi replay of {} through firmware-sim (pty paced at the baud rate, no faults), {} samples per batch, window {}\n",
        args.file.display(),
        args.batch
            .map_or_else(|| "the most".to_string(), |b| b.to_string()),
        args.window
    );
    crate::outln!(
        "| encoding | baud | bytes/sample | samples/s | bound (samples/s) | % of bound | retransmits |"
    );
    crate::outln!("|---|---:|---:|---:|---:|---:|---:|");
    let mut result = Ok(());
    let runs = args
        .encoding
        .iter()
        .flat_map(|&e| args.baud.iter().map(move |&b| (e, b)));
    for (encoding, baud) in runs {
        let replay_args = ReplayArgs {
            baud,
            log: Some(dir.join(format!("bench-{}-{baud}.tlm", encoding.name()))),
            encoding,
            window: args.window,
            batch: args.batch,
            json: true,
            ..ReplayArgs::for_file(&args.file)?
        };
        match replay(&replay_args) {
            Ok(report) => {
                let link = &report.link;
                let rate = link.samples_per_second();
                let bound = link.bound(baud);
                crate::outln!(
                    "| {} | {baud} | {:.2} | {rate:.0} | {bound:.0} | {:.1} | {} |",
                    encoding.name(),
                    link.bytes_per_sample(),
                    if bound > 0.0 {
                        100.0 * rate / bound
                    } else {
                        0.0
                    },
                    link.retransmits
                );
            }
            Err(error) => {
                result = Err(error);
                break;
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    result
}
