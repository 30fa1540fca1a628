//! `lssi replay FILE.csv`: a recording through the device code over a serial link, to
//! `firmware-sim` (started here on a pty), to the firmware under QEMU (`--qemu`) or to a board
//! (`--port`), with the same result as `lssi identify --f32`.
//!
//! Everything the device sends is appended to the telemetry log (`--log`, default
//! `FILE.tlm` next to the recording) as it arrives; `lssi log` prints it.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lssi_proto::ModelSnapshot;

use crate::commands::identify::{Family, IdentifyArgs};
use crate::defmt::{DefmtLines, Tables};
use crate::device::{DEFAULT_FIRMWARE, DeviceProcess, SimOptions};
use crate::error::CliError;
use crate::identify::{self, Options};
use crate::link::{Link, LinkOptions, LinkStats, Observer};
use crate::quantise::{Quantised, quantise};
use crate::recording::{ColumnNames, Recording};
use crate::replay::{
    ReplayError, ReplayMode, ReplayReport, render_link, replay_over_with, wire_config,
};
use crate::telemetry::{RecordKind, TelemetryLog};

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
    /// Base excitation frequency Ω in rad/s (default: estimated from the data).
    #[arg(long, value_name = "RAD_PER_S")]
    pub omega: Option<f64>,
    /// sin/cos(kΩt) terms for k = 1..H (0: none, for a measured excitation u).
    #[arg(long, default_value_t = 1, value_name = "H")]
    pub harmonics: u8,
    /// Highest order of the monomials of (x, v).
    #[arg(long, default_value_t = 3, value_name = "P")]
    pub poly_order: u8,
    /// Which monomials.
    #[arg(long, value_enum, default_value_t = Family::All)]
    pub family: Family,
    /// Turn the k-neighbour smoothing off (the ablation).
    #[arg(long)]
    pub no_smoothing: bool,
    /// Forgetting time constant in seconds (default: remember everything).
    #[arg(long, value_name = "SECONDS")]
    pub memory: Option<f64>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
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

    /// The identifier options: those `lssi identify --f32` takes from the same flags.
    ///
    /// The flags go through `lssi identify`'s own parser and checks, so both commands accept
    /// and refuse the same values and agree on every default.
    pub fn options(&self) -> Result<Options, CliError> {
        #[derive(clap::Parser)]
        struct Identify {
            #[command(flatten)]
            args: IdentifyArgs,
        }
        let mut argv: Vec<std::ffi::OsString> =
            vec!["lssi identify".into(), self.file.clone().into()];
        // `--flag=value`, so that a negative value is not taken for a flag.
        let mut flag = |name: &str, value: String| argv.push(format!("{name}={value}").into());
        if let Some(omega) = self.omega {
            flag("--omega", omega.to_string());
        }
        flag("--harmonics", self.harmonics.to_string());
        flag("--poly-order", self.poly_order.to_string());
        let family = match self.family {
            Family::All => "all",
            Family::Families => "families",
            Family::Odd => "odd",
        };
        flag("--family", family.into());
        if let Some(memory) = self.memory {
            flag("--memory", memory.to_string());
        }
        if self.no_smoothing {
            argv.push("--no-smoothing".into());
        }
        argv.push("--f32".into());
        let parsed = <Identify as clap::Parser>::try_parse_from(argv).map_err(|e| {
            CliError::Input(format!(
                "the identification flags cannot be used: {}.",
                e.kind()
            ))
        })?;
        parsed.args.options()
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

/// Shows progress on a terminal and prints the device's log lines.
struct Watcher {
    bar: ProgressBar,
    lines: DefmtLines,
    baud: u32,
}

impl Observer for Watcher {
    fn progress(&mut self, stats: &LinkStats) {
        self.bar.set_position(stats.samples_acked);
        let rate = stats.samples_per_second();
        let bound = stats.bound(self.baud);
        self.bar.set_message(format!(
            "{} frames sent, {} retransmitted, {:.0} samples/s ({:.0} % of the {} baud bound)",
            stats.frames_sent,
            stats.retransmits,
            rate,
            if bound > 0.0 {
                100.0 * rate / bound
            } else {
                0.0
            },
            self.baud
        ));
    }

    fn device_log(&mut self, bytes: &[u8]) {
        for line in self.lines.push(bytes) {
            self.bar.suspend(|| eprintln!("device: {line}"));
        }
    }

    fn model(&mut self, snapshot: &ModelSnapshot) {
        self.bar.set_message(format!(
            "model at {} samples ({} terms active)",
            snapshot.samples,
            snapshot.coefficients.iter().filter(|c| **c != 0.0).count()
        ));
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
    let link_options = args.link_options()?;
    let sim_options = args.sim_options()?;
    let firmware = args
        .firmware
        .clone()
        .unwrap_or_else(|| PathBuf::from(DEFAULT_FIRMWARE));
    let elf = args
        .elf
        .clone()
        .or_else(|| args.qemu.then(|| firmware.clone()));
    let tables = match &elf {
        Some(path) if !args.qemu || path.is_file() => {
            Some(Tables::load(path).map_err(|e| CliError::Input(format!("{e}."))))
        }
        _ => None,
    }
    .transpose()?;

    let recording = Recording::read(&args.file, &args.columns)?;
    // The compact encoding's quantisation is part of the recording: configured, streamed
    // and reported as the quantised recording (what `lssi identify --quantise i16` reads).
    let quantised: Option<Quantised> = match args.encoding {
        Encoding::F32 => None,
        Encoding::I16 => Some(quantise(&recording).map_err(CliError::Input)?),
    };
    let recording = match &quantised {
        Some(q) => q.recording.clone(),
        None => recording,
    };
    let (config, estimated) =
        identify::configure(&recording, &options).map_err(|e| CliError::Identify(e.0))?;
    let wire = wire_config(&recording, &config).map_err(replay_error)?;

    let log_path = args.log_path();
    let mut log = TelemetryLog::open(&log_path).map_err(|e| {
        CliError::Input(format!(
            "{}: cannot open the telemetry log: {e}.",
            log_path.display()
        ))
    })?;

    // The device: a port as given, or a child process on a pty.
    let mut process = if args.port.is_some() {
        None
    } else if args.qemu {
        Some(DeviceProcess::qemu(&firmware).map_err(|e| CliError::Input(format!("{e}."))))
    } else {
        Some(
            DeviceProcess::firmware_sim(&sim_options)
                .map_err(|e| CliError::Device(format!("{e}."))),
        )
    }
    .transpose()?;
    let port_name = match (&args.port, &process) {
        (Some(port), _) => port.clone(),
        (None, Some(process)) => process.pty().to_string(),
        (None, None) => return Err(CliError::Device("no device to replay to.".into())),
    };
    let kind = match (&args.port, args.qemu) {
        (Some(_), _) => "port",
        (None, true) => "qemu",
        (None, false) => "firmware-sim",
    };
    let session = serde_json::json!({
        "tool": "lssi replay",
        "version": env!("CARGO_PKG_VERSION"),
        "input": args.file.display().to_string(),
        "device": kind,
        "port": port_name,
        "baud": args.baud,
        "faults": {"flip_rate": args.flip_rate, "drop_rate": args.drop_rate, "burst": args.burst, "seed": args.seed},
        "encoding": args.encoding.name(),
        "resume": args.resume,
        "omega_estimated": estimated,
        "samples": recording.len(),
        "config": wire,
    });
    log.append(RecordKind::Session, session.to_string().as_bytes())
        .map_err(|e| log_write_error(&log_path, e))?;

    let port = serialport::new(&port_name, args.baud)
        .timeout(Duration::from_millis(50))
        .open()
        .map_err(|e| CliError::Device(format!("{port_name}: cannot open the serial port: {e}.")))?;
    let reader = port.try_clone().map_err(|e| {
        CliError::Device(format!(
            "{port_name}: cannot open the serial port twice: {e}."
        ))
    })?;

    let bar = if std::io::stderr().is_terminal() && !args.json {
        ProgressBar::with_draw_target(Some(recording.len() as u64), ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} samples acked  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut watcher = Watcher {
        bar,
        lines: DefmtLines::new(tables.as_ref()),
        baud: args.baud,
    };
    let qemu_stdout = process.as_mut().and_then(DeviceProcess::take_stdout);
    let result = {
        let mut link = Link::new(
            port_name.clone(),
            Box::new(reader),
            Box::new(port),
            &mut log,
            &mut watcher,
            link_options,
        );
        if let Some(stdout) = qemu_stdout {
            link.attach_defmt(Box::new(stdout));
        }
        let mode = ReplayMode {
            quantised: quantised.as_ref(),
            resume: args.resume,
        };
        let result = replay_over_with(&mut link, &recording, &config, estimated, mode);
        if let Err(error) = &result {
            let _ = link.note(&format!("replay stopped: {error}"));
        }
        result
    };
    watcher.bar.finish_and_clear();
    if let Some(process) = process {
        // firmware-sim exits once the port is closed; QEMU never does.
        let grace = Duration::from_millis(if args.qemu { 0 } else { 2000 });
        for line in process.finish(grace) {
            let _ = log.note(&format!("{kind}: {line}"));
        }
    }
    let _ = log.sync();
    result.map_err(replay_error)
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

fn log_write_error(path: &Path, error: std::io::Error) -> CliError {
    CliError::Write {
        path: path.to_path_buf(),
        source: error,
    }
}

/// A replay failure as the command's error.
pub fn replay_error(error: ReplayError) -> CliError {
    match error {
        ReplayError::Link(error) => CliError::Device(format!("{error}.")),
        ReplayError::Input(sentence) => CliError::Input(sentence),
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
    /// Batches unacknowledged at once.
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub window: usize,
    /// Encodings to measure.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Encoding::F32, Encoding::I16])]
    pub encoding: Vec<Encoding>,
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
            window: args.window,
            batch: args.batch,
            encoding,
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
