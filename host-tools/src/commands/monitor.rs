//! `lssi monitor`: listens to a standalone device's unsolicited frames (Model and Health
//! every period), shows them live, and writes the telemetry log that `lssi log` reads.
//!
//! - `--port /dev/ttyUSB0`: a board on a serial port, until `--seconds` or Ctrl-C.
//! - `--qemu FILE.csv`: the standalone firmware under QEMU (`-icount shift=4,sleep=off`: a
//!   64 MHz Cortex-M4F's pace in guest time) with the recording preloaded into its PSRAM as
//!   its sensor, sampled by its timer at the recording's own rate (`--rate` overrides), and
//!   configured as `lssi identify` would configure it for the file (the stored-configuration
//!   frame; `--image-config` keeps the image's own). It stops when the recording ends; the
//!   last line is a summary with the final model's terms, in `lssi identify --json`'s shape.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;
use serde_json::Value;

use crate::error::CliError;
use crate::recording::ColumnNames;
use crate::serial::monitor::{
    DEFAULT_STANDALONE, IMAGE_ROW_HZ, Listen, PortSetup, QemuPlay, monitor_port, monitor_qemu,
};
use crate::telemetry::{TelemetryLog, now_us};

/// Arguments of `lssi monitor`.
#[derive(Debug, Clone, Args)]
pub struct MonitorArgs {
    /// The serial port of a standalone device (e.g. /dev/ttyUSB0).
    #[arg(
        long,
        value_name = "PATH",
        required_unless_present = "qemu",
        conflicts_with = "qemu"
    )]
    pub port: Option<String>,
    /// Play this recording (CSV) through the standalone firmware under QEMU as its sensor.
    #[arg(long, value_name = "FILE.csv")]
    pub qemu: Option<PathBuf>,
    /// The serial port's baud rate.
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// With --qemu: the sampling rate in Hz [default: the recording's own].
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// With --qemu: keep the image's default configuration instead of the one `lssi
    /// identify` chooses for the file.
    #[arg(long)]
    pub image_config: bool,
    /// With --qemu: the standalone firmware image [default: the workspace's release build].
    #[arg(long, value_name = "ELF")]
    pub firmware: Option<PathBuf>,
    /// One JSON object per frame (as `lssi log --json` prints them), then the summary.
    #[arg(long)]
    pub json: bool,
    /// The telemetry log to write [default: lssi-monitor-<unix time>.tlm].
    #[arg(long, value_name = "FILE.tlm")]
    pub log: Option<PathBuf>,
    /// Stop after this many seconds of wall time [default: --port never, --qemu 600].
    #[arg(long, value_name = "SECONDS")]
    pub seconds: Option<f64>,
    /// With --port: configure the board to this many rows a second before listening (its
    /// ADC's rate divided by a whole number; the board naks another) [default: the board's
    /// own configuration, untouched; with a duty cycle, 200, the image's default].
    #[arg(
        long,
        value_name = "HZ",
        conflicts_with = "qemu",
        allow_hyphen_values = true
    )]
    pub row_rate: Option<f64>,
    /// Configure a duty cycle: seconds of identification a window, after which the device
    /// reports (Model, then Health with the drift, every --duty-model-every windows; Health
    /// alone at the others) and sleeps (with --duty-interval).
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub duty_window: Option<f64>,
    /// The duty cycle's seconds asleep between windows (with --duty-window).
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub duty_interval: Option<f64>,
    /// The duty cycle's windows a model: a model (and the drift) every this many windows,
    /// the windows between ending with a Health alone (with --duty-window) [default: the
    /// windows of about 40 minutes, at least 1: 4 for 10 s every 10 minutes].
    #[arg(long, value_name = "WINDOWS", allow_hyphen_values = true)]
    pub duty_model_every: Option<i64>,
    /// Which header names hold which quantity (--qemu).
    #[command(flatten)]
    pub columns: ColumnNames,
}

/// Runs `lssi monitor`.
pub fn run(args: &MonitorArgs) -> Result<(), CliError> {
    let summary = monitor(args, &mut std::io::stdout())?;
    if let Some(summary) = summary {
        crate::outln!("{summary}");
    }
    Ok(())
}

/// Runs a session, writing the live view or JSON lines to `out`; with `--qemu`, returns the
/// summary line's object.
pub fn monitor(args: &MonitorArgs, out: &mut dyn Write) -> Result<Option<Value>, CliError> {
    if let Some(s) = args.seconds
        && !(s.is_finite() && s > 0.0)
    {
        return Err(CliError::BadFlag {
            flag: "--seconds",
            value: s.to_string(),
            requirement: "a positive number of seconds".into(),
        });
    }
    let duty = crate::commands::replay::duty_from_flags(
        args.duty_window,
        args.duty_interval,
        args.duty_model_every,
    )?;
    let row_rate = crate::commands::replay::row_rate_from_flag(args.row_rate)?;
    if let Some(r) = row_rate
        && r > 1.0e6
    {
        return Err(CliError::BadFlag {
            flag: "--row-rate",
            value: r.to_string(),
            requirement: "at most 1 MHz".into(),
        });
    }
    let log_path = args
        .log
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("lssi-monitor-{}.tlm", now_us() / 1_000_000)));
    let mut log = TelemetryLog::open(&log_path).map_err(|e| {
        CliError::Input(format!(
            "{}: cannot open the telemetry log: {e}.",
            log_path.display()
        ))
    })?;
    let listen = Listen {
        json: args.json,
        seconds: args.seconds,
    };
    match (&args.qemu, &args.port) {
        (Some(file), _) => {
            let play = QemuPlay {
                file: file.clone(),
                columns: args.columns.clone(),
                rate: args.rate,
                image_config: args.image_config,
                firmware: args
                    .firmware
                    .clone()
                    .unwrap_or_else(|| PathBuf::from(DEFAULT_STANDALONE)),
                duty,
            };
            monitor_qemu(&play, listen, &mut log, out).map(Some)
        }
        (None, Some(port)) => {
            let setup = (row_rate.is_some() || duty.is_some()).then(|| PortSetup {
                row_hz: row_rate.unwrap_or(IMAGE_ROW_HZ),
                duty,
            });
            monitor_port(port, args.baud, listen, setup, &mut log, out)?;
            Ok(None)
        }
        (None, None) => Err(CliError::Input(
            "lssi monitor needs --port PATH or --qemu FILE.csv.".into(),
        )),
    }
}
