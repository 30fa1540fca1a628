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
use crate::serial::device::{BURST_RATE, DEFAULT_FIRMWARE, MAX_BURST, SimOptions};
use crate::serial::link::LinkOptions;
use crate::serial::replay::{ReplayReport, SystemReplayReport, render_link};
use crate::serial::session::{self, Device, RowRate, Setup};

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
    #[arg(long, default_value_t = 921_600, value_name = "N", value_parser = count::<u32>, allow_hyphen_values = true)]
    pub baud: u32,
    /// firmware-sim: probability per byte, in each direction, of flipping one random bit of
    /// it (0.001: about one byte in a thousand damaged).
    #[arg(long, default_value_t = 0.0, value_name = "R", value_parser = number, allow_hyphen_values = true)]
    pub flip_rate: f64,
    /// firmware-sim: probability per byte, in each direction, of dropping it (a frame that
    /// loses a byte fails its check and is sent again).
    #[arg(long, default_value_t = 0.0, value_name = "R", value_parser = number, allow_hyphen_values = true)]
    pub drop_rate: f64,
    /// firmware-sim: insert bursts of 1 to N random bytes in each direction, one burst per
    /// 4096 bytes on average (0: none; at most 65535).
    #[arg(long, default_value_t = 0, value_name = "N", value_parser = count::<u32>, allow_hyphen_values = true)]
    pub burst: u32,
    /// firmware-sim: seed of the faults.
    #[arg(long, default_value_t = 1, value_name = "S", value_parser = count::<u64>, allow_hyphen_values = true)]
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
    #[arg(long, default_value_t = 8, value_name = "N", value_parser = count::<usize>, allow_hyphen_values = true)]
    pub window: usize,
    /// Most samples per batch (at most 24 with f32, 64 with i16; default: the most). The
    /// link shortens its batches while it measures losses and lengthens them again.
    #[arg(long, value_name = "N", value_parser = count::<usize>, allow_hyphen_values = true)]
    pub batch: Option<usize>,
    /// How the samples cross the link.
    #[arg(long, value_enum, default_value_t = Encoding::F32)]
    pub encoding: Encoding,
    /// Continue a replay the device (on --port) has begun, from the last sample it applied,
    /// without configuring it again (after a replay that gave up at its deadline).
    #[arg(long, requires = "port")]
    pub resume: bool,
    /// Seconds the link goes on without progress before it gives up.
    #[arg(long, default_value_t = 60.0, value_name = "SECONDS", value_parser = number, allow_hyphen_values = true)]
    pub deadline: f64,
    /// Rows a second sent in the configuration: the recording's rows are averaged down to it
    /// (the recording's rate divided by a whole number; a first-order CIC, as a device's
    /// ADC oversampler, then the device's 3-tap droop compensator, which drops the first and
    /// last rows), and the model is that of the averaged recording [default: the
    /// recording's own rate, so that the model is `lssi identify --f32`'s]. `proposed`: the
    /// rate `lssi identify FILE` proposes ("a device needs N Hz for this harvester"), the
    /// recording's rows averaged by the largest whole number that keeps them at or above N
    /// (10 kHz and N = 210: 10000/47 = 212.766 rows a second). Not the default: the model is
    /// then the averaged rows' (`lssi identify --f32 --no-refine` of the averaged file), not
    /// the recording's own.
    #[arg(long, value_name = "HZ|proposed", value_parser = row_rate_value, allow_hyphen_values = true)]
    pub row_rate: Option<RowRate>,
    /// The duty cycle's window sent in the configuration: seconds of identification before
    /// the device reports and sleeps (with --duty-interval; a device the host feeds, such
    /// as firmware-sim, ignores it).
    #[arg(long, value_name = "SECONDS", value_parser = number, allow_hyphen_values = true)]
    pub duty_window: Option<f64>,
    /// The duty cycle's interval sent in the configuration: seconds asleep between windows
    /// (with --duty-window).
    #[arg(long, value_name = "SECONDS", value_parser = number, allow_hyphen_values = true)]
    pub duty_interval: Option<f64>,
    /// The duty cycle's windows a model: a model (and the drift) every this many windows,
    /// the windows between ending with a Health alone (with --duty-window) [default: the
    /// windows of about 40 minutes, at least 1: 4 for 10 s every 10 minutes].
    #[arg(long, value_name = "WINDOWS", allow_hyphen_values = true)]
    pub duty_model_every: Option<i64>,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
    /// The identifier's flags (shared with `lssi identify`).
    #[command(flatten)]
    pub identifier: IdentifierArgs,
    /// A system's flags (a recording with an electrical column, V or i): shared with
    /// `lssi identify`.
    #[command(flatten)]
    pub system: crate::system::SystemArgs,
    /// Print one JSON object instead of text.
    #[arg(long, help_heading = "Output")]
    pub json: bool,
}

/// A duty-cycled device makes a model about this often by default, seconds (40 minutes):
/// the windows between end with a Health alone. A model costs one screening, about as much
/// energy as the rows of a 10 s window (7.5 M instructions against 8 M on the eveh
/// harvester at 210 rows a second: `bash scripts/firmware-power.sh`); a harvester drifts
/// over days and weeks (wear, its mounting, the seasons' temperatures), which 36 models a
/// day follow with the daily temperature swing resolved, and every window's rows still go
/// into each model.
pub const DUTY_MODEL_SECONDS: f64 = 2400.0;

/// The windows a model by default: those of about [`DUTY_MODEL_SECONDS`] (rounded down, so
/// a model at least that often; at least 1).
pub fn default_model_every(window: f64, interval: f64) -> u16 {
    let n = (DUTY_MODEL_SECONDS / (window + interval)).floor();
    if n.is_finite() && n >= 1.0 {
        n.min(f64::from(u16::MAX)) as u16
    } else {
        1
    }
}

/// The duty cycle the flags ask for (`None` without them), or the sentence saying what is
/// wrong: both flags or neither, a window of a positive number of seconds up to a day, an
/// interval of a positive number of seconds up to 30 days, a model every 1 to 65,535
/// windows (only with a duty cycle; by default [`default_model_every`]).
pub fn duty_from_flags(
    window: Option<f64>,
    interval: Option<f64>,
    model_every: Option<i64>,
) -> Result<Option<lssi_proto::WireDuty>, CliError> {
    let bad = |flag, value: f64, requirement: &str| CliError::BadFlag {
        flag,
        value: value.to_string(),
        requirement: requirement.into(),
    };
    let model_every = match model_every {
        None => None,
        Some(n) if window.is_none() && interval.is_none() => {
            return Err(CliError::BadFlag {
                flag: "--duty-model-every",
                value: n.to_string(),
                requirement:
                    "given with --duty-window and --duty-interval (windows a model of a duty cycle)"
                        .into(),
            });
        }
        Some(n) => match u16::try_from(n) {
            Ok(n) if n >= 1 => Some(n),
            _ => {
                return Err(CliError::BadFlag {
                    flag: "--duty-model-every",
                    value: n.to_string(),
                    requirement: "a whole number of windows from 1 to 65535".into(),
                });
            }
        },
    };
    match (window, interval) {
        (None, None) => Ok(None),
        (Some(w), None) => Err(bad(
            "--duty-window",
            w,
            "given with --duty-interval (a duty cycle is a window of identification and the sleep after it)",
        )),
        (None, Some(i)) => Err(bad(
            "--duty-interval",
            i,
            "given with --duty-window (a duty cycle is a window of identification and the sleep after it)",
        )),
        (Some(w), Some(i)) => {
            if !(w.is_finite() && w > 0.0 && w <= 86_400.0) {
                return Err(bad(
                    "--duty-window",
                    w,
                    "a positive number of seconds, at most a day",
                ));
            }
            if !(i.is_finite() && i > 0.0 && i <= 2_592_000.0) {
                return Err(bad(
                    "--duty-interval",
                    i,
                    "a positive number of seconds, at most 30 days",
                ));
            }
            Ok(Some(lssi_proto::WireDuty {
                window: w as f32,
                interval: i as f32,
                model_every: model_every.unwrap_or_else(|| default_model_every(w, i)),
            }))
        }
    }
}

/// `--row-rate`'s value: `proposed`, or a number (checked by [`row_rate_from_flag`]).
fn row_rate_value(text: &str) -> Result<RowRate, String> {
    if text.trim().eq_ignore_ascii_case("proposed") {
        return Ok(RowRate::Proposed);
    }
    text.trim()
        .parse::<f64>()
        .map(RowRate::Hz)
        .map_err(|_| format!("{text:?} is neither a number of rows a second nor `proposed`"))
}

/// The replay's `--row-rate` checked on its own (against the recording later).
fn replay_row_rate(rate: Option<RowRate>) -> Result<Option<RowRate>, CliError> {
    match rate {
        Some(RowRate::Hz(hz)) => Ok(row_rate_from_flag(Some(hz))?.map(RowRate::Hz)),
        other => Ok(other),
    }
}

/// The `--row-rate` flag checked on its own (against the recording later): a positive,
/// finite number of rows a second.
pub fn row_rate_from_flag(rate: Option<f64>) -> Result<Option<f64>, CliError> {
    match rate {
        Some(r) if !(r.is_finite() && r > 0.0) => Err(CliError::BadFlag {
            flag: "--row-rate",
            value: r.to_string(),
            requirement: "a positive number of rows a second".into(),
        }),
        other => Ok(other),
    }
}

/// A flag's number: any decimal number (a negative or out-of-range one is refused later by
/// lssi with a sentence naming the range), or clap's error with one naming what is wanted.
fn number(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .map_err(|_| format!("{text:?} is not a number"))
}

/// A flag's whole number: a negative one and one too large are named as such.
fn count<T: std::str::FromStr>(text: &str) -> Result<T, String> {
    let text = text.trim();
    text.parse::<T>().map_err(|_| match text.parse::<f64>() {
        Ok(v) if v < 0.0 => format!("{text} is negative; it must be a whole number"),
        Ok(v) if v.fract() == 0.0 => format!("{text} is too large"),
        _ => format!("{text:?} is not a whole number"),
    })
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
            // `contains` is false for NaN as well. At 1 every byte is lost (or corrupted):
            // no frame would ever get through, and the replay would wait for its deadline.
            if !(0.0..1.0).contains(&value) {
                return Err(CliError::BadFlag {
                    flag,
                    value: value.to_string(),
                    requirement: "a probability per byte between 0 and 1, less than 1 (at 1 \
                                  no frame gets through)"
                        .into(),
                });
            }
        }
        if self.burst > MAX_BURST {
            return Err(CliError::BadFlag {
                flag: "--burst",
                value: self.burst.to_string(),
                requirement: format!("at most {MAX_BURST} bytes (firmware-sim's longest burst)"),
            });
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
    // A recording with an electrical channel is a system (issue 26; crate::system).
    match crate::system::read_if_system(&args.file, &args.columns, &args.system.columns)? {
        Some(data) => {
            let report = replay_system(args, &data)?;
            if args.json {
                crate::outln!("{}", serde_json::to_string(&report).unwrap_or_default());
            } else {
                for w in &report.report.warnings {
                    eprintln!("lssi: warning: {w}.");
                }
                if let Some(q) = report.report.quality.as_ref().filter(|q| !q.passed()) {
                    eprintln!(
                        "lssi: warning: lssi identify would withhold this model (exit status 3): {}.",
                        q.failures.join("; ")
                    );
                }
                crate::out!("{}", report.report.render());
                crate::outln!(
                    "  (the device sends each equation's selected solution, not its whole sweep: `lssi identify --f32 --no-refine` lists every candidate)"
                );
                crate::out!("{}", render_link(&report.link));
            }
            return Ok(());
        }
        None => crate::system::refuse_stray_flags(&args.file, &args.system)?,
    }
    let report = replay(args)?;
    print_report(&report, args.json);
    if !args.json
        && let Some(injected) = injected(args)
    {
        crate::outln!(
            "faults: firmware-sim damaged about {:.3} % of the bytes each way ({}); measured on the line to the device: {:.3} %",
            100.0 * injected,
            fault_list(args),
            100.0 * report.link.line_error_rate
        );
    }
    Ok(())
}

/// Replays a system's recording as the flags say and returns the report.
pub fn replay_system(
    args: &ReplayArgs,
    data: &crate::system::SystemData,
) -> Result<SystemReplayReport, CliError> {
    args.system.check_load()?;
    let setup = setup(args)?;
    session::replay_system(
        &setup,
        data,
        args.system.coupling_order,
        args.system.load_ohms,
        args.system.coil_ohms,
    )
}

/// Replays as the flags say and returns the report (what `lssi replay` prints).
pub fn replay(args: &ReplayArgs) -> Result<ReplayReport, CliError> {
    session::replay(&setup(args)?)
}

/// The session's setup from the flags, checked.
fn setup(args: &ReplayArgs) -> Result<Setup, CliError> {
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
        row_rate: replay_row_rate(args.row_rate)?,
        duty: duty_from_flags(args.duty_window, args.duty_interval, args.duty_model_every)?,
    };
    Ok(setup)
}

/// The probability that firmware-sim damages a byte, as the flags ask: dropped, else flipped,
/// or a burst inserted before it (`--burst`: one per 4096 bytes); `None` without faults.
fn injected(args: &ReplayArgs) -> Option<f64> {
    let burst = if args.burst > 0 { BURST_RATE } else { 0.0 };
    let clean = (1.0 - args.drop_rate) * (1.0 - args.flip_rate) * (1.0 - burst);
    (clean < 1.0 && args.port.is_none() && !args.qemu).then_some(1.0 - clean)
}

fn fault_list(args: &ReplayArgs) -> String {
    let mut parts = Vec::new();
    if args.flip_rate > 0.0 {
        parts.push(format!("--flip-rate {} per byte", args.flip_rate));
    }
    if args.drop_rate > 0.0 {
        parts.push(format!("--drop-rate {} per byte", args.drop_rate));
    }
    if args.burst > 0 {
        parts.push(format!(
            "--burst {}: a burst per {} bytes",
            args.burst,
            (1.0 / BURST_RATE).round()
        ));
    }
    parts.join(", ")
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
    std::fs::create_dir_all(&dir).map_err(|e| CliError::CreateDir {
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

#[cfg(test)]
mod tests {
    use super::{default_model_every, duty_from_flags};

    #[test]
    fn a_duty_cycle_makes_a_model_about_every_40_minutes_by_default() {
        // 10 s every 10 minutes: every 4th window; 10 s windows every 600 s asleep (610 s):
        // every 3rd (a model at least every 40 minutes).
        assert_eq!(default_model_every(10.0, 590.0), 4);
        assert_eq!(default_model_every(10.0, 600.0), 3);
        // Windows 40 minutes or more apart: every one; short ones: many (capped).
        assert_eq!(default_model_every(60.0, 3600.0), 1);
        assert_eq!(default_model_every(0.01, 0.01), u16::MAX);
        let duty = duty_from_flags(Some(10.0), Some(590.0), None)
            .unwrap()
            .unwrap();
        assert_eq!(duty.model_every, 4);
        let duty = duty_from_flags(Some(10.0), Some(590.0), Some(1))
            .unwrap()
            .unwrap();
        assert_eq!(duty.model_every, 1);
        for bad in [0, -1, 65_536] {
            assert!(
                duty_from_flags(Some(10.0), Some(590.0), Some(bad)).is_err(),
                "{bad}"
            );
        }
        assert!(duty_from_flags(None, None, Some(2)).is_err());
    }
}
