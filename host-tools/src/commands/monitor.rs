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

use std::io::{IsTerminal, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use clap::Args;
use lssi_core::Config;
use lssi_device::wire::config_to_wire;
use lssi_proto::{DeviceFrameDecoder, DeviceMsg, HostMsg, ModelSnapshot, SnapshotCause, encode};
use serde_json::{Value, json};

use crate::commands::log::message_json;
use crate::defmt::{DefmtLines, Tables};
use crate::device::find_on_path;
use crate::error::CliError;
use crate::identify::{self, Options};
use crate::recording::{ColumnNames, Recording};
use crate::replay::report_from_snapshot;
use crate::telemetry::{RecordKind, TelemetryLog, now_us};

/// The standalone image `--qemu` runs without `--firmware`, relative to the workspace.
pub const DEFAULT_STANDALONE: &str =
    "crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-standalone";
/// Where the mps2 boards map their PSRAM (the recording goes there).
const PSRAM: &str = "0x21000000";
/// The recording's header (see crates/lssi-firmware/src/mps2.rs).
const HEADER: usize = 256;
/// Largest stored configuration frame.
const MAX_CONFIG: usize = HEADER - 28;
/// Most samples the 16 MiB PSRAM holds after the header, x only.
const MAX_SAMPLES: usize = ((16 << 20) - HEADER) / 4;

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
    /// Which header names hold which quantity (--qemu).
    #[command(flatten)]
    pub columns: ColumnNames,
}

/// What a monitoring session saw.
#[derive(Debug, Clone, Default)]
pub struct Seen {
    /// Frames decoded.
    pub frames: u64,
    /// Frames that failed their CRC or did not decode.
    pub corrupt: u64,
    /// The latest model and the latest health report.
    pub model: Option<ModelSnapshot>,
    /// The latest health report.
    pub health: Option<DeviceMsg>,
    /// The final model arrived (the recording ended).
    pub finished: bool,
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
        return Err(bad_flag("--seconds", s, "a positive number of seconds"));
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
    match (&args.qemu, &args.port) {
        (Some(file), _) => monitor_qemu(args, file, &mut log, out).map(Some),
        (None, Some(port)) => {
            monitor_port(args, port, &mut log, out)?;
            Ok(None)
        }
        (None, None) => Err(CliError::Input(
            "lssi monitor needs --port PATH or --qemu FILE.csv.".into(),
        )),
    }
}

fn bad_flag(flag: &'static str, value: impl ToString, requirement: &str) -> CliError {
    CliError::BadFlag {
        flag,
        value: value.to_string(),
        requirement: requirement.into(),
    }
}

/// The configuration sent (stored) and whether Ω was estimated.
struct Session {
    config: Config,
    omega_estimated: bool,
}

fn monitor_qemu(
    args: &MonitorArgs,
    file: &Path,
    log: &mut TelemetryLog,
    out: &mut dyn Write,
) -> Result<Value, CliError> {
    let recording = Recording::read(file, &args.columns)?;
    let (mut config, omega_estimated) = identify::configure(&recording, &Options::default())
        .map_err(|e| CliError::Identify(e.0))?;
    let own_rate = 1.0 / config.sample_period;
    let rate = match args.rate {
        Some(r) if !(r.is_finite() && (1.0..=1.0e6).contains(&r)) => {
            return Err(bad_flag(
                "--rate",
                r,
                "a sampling rate between 1 Hz and 1 MHz",
            ));
        }
        Some(r) => r,
        None => own_rate,
    };
    config.sample_period = 1.0 / rate;
    let firmware = args
        .firmware
        .clone()
        .unwrap_or_else(|| PathBuf::from(DEFAULT_STANDALONE));
    if !firmware.is_file() {
        return Err(CliError::Input(format!(
            "{}: the standalone firmware image does not exist; build it (cargo build --release in crates/lssi-firmware, as scripts/setup.sh does) or give --firmware.",
            firmware.display()
        )));
    }
    let qemu = find_on_path("qemu-system-arm").ok_or_else(|| {
        CliError::Input(
            "qemu-system-arm is not installed (apt-get install qemu-system-arm), so --qemu cannot run the firmware.".into(),
        )
    })?;
    let dir = tempfile::tempdir()
        .map_err(|e| CliError::Input(format!("no temporary directory: {e}.")))?;
    let image = dir.path().join("recording.bin");
    let stored = (!args.image_config).then_some(&config);
    let bytes = recording_image(&recording, rate, stored)?;
    std::fs::write(&image, &bytes).map_err(|e| CliError::Write {
        path: image.clone(),
        source: e,
    })?;
    let session_config = if args.image_config {
        // What the image configures itself with (src/bin/lssi-standalone.rs).
        Config {
            sample_period: 1.0 / rate,
            screening_period: (rate as u32).max(1000),
            channels: config.channels,
            ..Config::default()
        }
    } else {
        config
    };
    let session = Session {
        config: session_config,
        omega_estimated,
    };
    log_session(log, &session, &format!("qemu:{}", file.display()), rate)?;
    let socket = dir.path().join("uart.sock");
    let mut child = Command::new(&qemu)
        .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-nographic"])
        .args(["-monitor", "none"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=4,sleep=off", "-kernel"])
        .arg(&firmware)
        .arg("-device")
        .arg(format!("loader,file={},addr={PSRAM}", image.display()))
        .arg("-serial")
        .arg(format!("unix:{},server=on,wait=on", socket.display()))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| CliError::Device(format!("{}: cannot start QEMU: {e}.", qemu.display())))?;
    let stream = connect(&socket, &mut child)?;
    let defmt = child.stdout.take().map(|mut stdout| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            let _ = stdout.read_to_end(&mut bytes);
            bytes
        })
    });
    let limit = Duration::from_secs_f64(args.seconds.unwrap_or(600.0));
    let mut view = View::new(args.json, out);
    let seen = listen(stream, &session, log, &mut view, limit)?;
    let status = wait(&mut child, Duration::from_secs(10));
    let defmt_bytes = defmt.and_then(|h| h.join().ok()).unwrap_or_default();
    if !defmt_bytes.is_empty() {
        let _ = log.append(RecordKind::Defmt, &defmt_bytes);
    }
    let tables = Tables::load(&firmware).ok();
    let lines = DefmtLines::new(tables.as_ref()).push(&defmt_bytes);
    let _ = log.sync();
    // The firmware exits 0 once it has sent its last frames: with or without a final model
    // (a recording whose samples were lost or rejected may leave too few rows for one).
    if !seen.finished && status != Some(0) {
        let said = lines
            .last()
            .map(|l| format!("; its last log line: {l}"))
            .unwrap_or_default();
        return Err(CliError::Device(format!(
            "the firmware under QEMU stopped before the recording's final model ({}){said}.",
            match status {
                Some(code) => format!("exit status {code}"),
                None => "still running after the time limit; stopped".into(),
            }
        )));
    }
    summary(&seen, &session, rate)
}

/// The recording as the firmware's PSRAM image: header, stored configuration, samples.
pub fn recording_image(
    recording: &Recording,
    rate: f64,
    config: Option<&Config>,
) -> Result<Vec<u8>, CliError> {
    let file = recording.path.display();
    let samples: Vec<_> = recording.samples().collect();
    let velocity = samples.first().is_some_and(|s| s.v.is_some());
    let input = samples.first().is_some_and(|s| s.u.is_some());
    let per = 1 + usize::from(velocity) + usize::from(input);
    if samples.len() * per > MAX_SAMPLES {
        return Err(CliError::Input(format!(
            "{file}: {} samples of {per} channels do not fit the board's 16 MiB PSRAM (at most {}).",
            samples.len(),
            MAX_SAMPLES / per
        )));
    }
    let mut frame = Vec::new();
    if let Some(config) = config {
        let wire = config_to_wire(config).map_err(|e| CliError::Input(format!("{file}: {e}.")))?;
        let mut buffer = [0u8; lssi_proto::MAX_HOST_FRAME_LEN];
        let len = encode(&HostMsg::Configure(wire), &mut buffer).map_err(|e| {
            CliError::Input(format!("{file}: the configuration does not encode: {e}."))
        })?;
        frame.extend_from_slice(&buffer[..len]);
        if frame.len() > MAX_CONFIG {
            return Err(CliError::Input(format!(
                "{file}: the configuration frame is {} bytes, more than the {MAX_CONFIG} the image keeps.",
                frame.len()
            )));
        }
    }
    let mut out = Vec::with_capacity(HEADER + 4 * per * samples.len());
    out.extend_from_slice(b"LSSIREC1");
    let channels = u32::from(velocity) | (u32::from(input) << 1);
    out.extend_from_slice(&channels.to_le_bytes());
    out.extend_from_slice(&(samples.len() as u32).to_le_bytes());
    out.extend_from_slice(&rate.to_le_bytes());
    out.extend_from_slice(&(frame.len() as u32).to_le_bytes());
    out.extend_from_slice(&frame);
    out.resize(HEADER, 0);
    for s in &samples {
        out.extend_from_slice(&(s.x as f32).to_le_bytes());
        if let Some(v) = s.v {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        }
        if let Some(u) = s.u {
            out.extend_from_slice(&(u as f32).to_le_bytes());
        }
    }
    Ok(out)
}

fn log_session(
    log: &mut TelemetryLog,
    session: &Session,
    source: &str,
    rate: f64,
) -> Result<(), CliError> {
    let wire = config_to_wire(&session.config).ok();
    let info = json!({
        "tool": "lssi monitor",
        "source": source,
        "rate_hz": rate,
        "config": wire,
        "omega_estimated": session.omega_estimated,
    });
    log.append(RecordKind::Session, info.to_string().as_bytes())
        .map_err(|e| CliError::Write {
            path: log.path().to_path_buf(),
            source: e,
        })
}

/// Connects to QEMU's UART socket (QEMU waits for it before starting the guest).
fn connect(socket: &Path, child: &mut Child) -> Result<UnixStream, CliError> {
    let started = Instant::now();
    loop {
        if let Ok(stream) = UnixStream::connect(socket) {
            return Ok(stream);
        }
        if let Ok(Some(status)) = child.try_wait() {
            let mut said = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = e.read_to_string(&mut said);
            }
            return Err(CliError::Device(format!(
                "qemu-system-arm exited ({status}) before its UART could be connected: {}.",
                said.trim()
            )));
        }
        if started.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            return Err(CliError::Device(format!(
                "QEMU's UART socket {} did not appear within 20 s.",
                socket.display()
            )));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The exit code of `child`, waiting up to `grace` (then killed: `None`).
fn wait(child: &mut Child, grace: Duration) -> Option<i32> {
    let started = Instant::now();
    loop {
        if let Ok(Some(status)) = child.try_wait() {
            return status.code();
        }
        if started.elapsed() > grace {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn monitor_port(
    args: &MonitorArgs,
    port: &str,
    log: &mut TelemetryLog,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let serial = serialport::new(port, args.baud)
        .timeout(Duration::from_millis(200))
        .open()
        .map_err(|e| CliError::Device(format!("{port}: cannot open the serial port: {e}.")))?;
    let session = Session {
        config: Config::default(),
        omega_estimated: false,
    };
    log_session(log, &session, port, 0.0)?;
    let limit = Duration::from_secs_f64(args.seconds.unwrap_or(f64::MAX / 4.0).min(1.0e9));
    let mut view = View::new(args.json, out);
    listen(serial, &session, log, &mut view, limit)?;
    let _ = log.sync();
    Ok(())
}

/// Reads frames until the final model, the end of the stream, or `limit`.
fn listen<R: Read>(
    mut source: R,
    session: &Session,
    log: &mut TelemetryLog,
    view: &mut View<'_>,
    limit: Duration,
) -> Result<Seen, CliError> {
    let started = Instant::now();
    let mut decoder = DeviceFrameDecoder::new();
    let mut raw: Vec<u8> = Vec::new();
    let mut seen = Seen::default();
    let mut buffer = [0u8; 4096];
    let session_key = (session.config, session.omega_estimated);
    while started.elapsed() < limit && !seen.finished {
        let n = match source.read(&mut buffer) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e)
                if e.kind() == std::io::ErrorKind::TimedOut
                    || e.kind() == std::io::ErrorKind::Interrupted =>
            {
                continue;
            }
            Err(e) => return Err(CliError::Device(format!("the device's link failed: {e}."))),
        };
        for &byte in &buffer[..n] {
            if byte != 0 {
                raw.push(byte);
            } else if !raw.is_empty() {
                let _ = log.append(RecordKind::Frame, &raw);
                raw.clear();
            }
            match decoder.push::<DeviceMsg>(byte) {
                None => {}
                Some(Ok(message)) => {
                    seen.frames += 1;
                    match &message {
                        DeviceMsg::Model(m) => {
                            seen.finished |= m.cause == SnapshotCause::Final;
                            seen.model = Some(m.clone());
                        }
                        DeviceMsg::Health { .. } => seen.health = Some(message.clone()),
                        _ => {}
                    }
                    view.show(&message, &seen, &session_key)?;
                }
                Some(Err(_)) => seen.corrupt += 1,
            }
        }
        if seen.finished {
            // The final Health follows the final Model at once: read it too.
            let deadline = Instant::now() + Duration::from_secs(2);
            while Instant::now() < deadline {
                let n = match source.read(&mut buffer) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => n,
                };
                for &byte in &buffer[..n] {
                    if let Some(Ok(message)) = decoder.push::<DeviceMsg>(byte) {
                        seen.frames += 1;
                        if let DeviceMsg::Health { .. } = message {
                            seen.health = Some(message.clone());
                        }
                        view.show(&message, &seen, &session_key)?;
                    }
                }
            }
        }
    }
    Ok(seen)
}

/// The summary line: samples, rate, overruns, queue high-water, frames, and the final
/// model's terms as `lssi identify --json` gives them.
fn summary(seen: &Seen, session: &Session, rate: f64) -> Result<Value, CliError> {
    let terms = match seen.model.as_ref().filter(|_| seen.finished) {
        Some(model) => {
            let report = report_from_snapshot(model, &session.config, session.omega_estimated)
                .map_err(|e| {
                    CliError::Device(format!("the device's model cannot be read: {e}."))
                })?;
            serde_json::to_value(report)
                .ok()
                .and_then(|r| r.get("terms").cloned())
                .unwrap_or(Value::Null)
        }
        // No final model: too few regression rows (see the health counters).
        None => Value::Array(Vec::new()),
    };
    let samples = match &seen.health {
        Some(DeviceMsg::Health { samples, .. }) => *samples,
        _ => 0,
    };
    let (overruns, high_water, latency) = match &seen.health {
        Some(DeviceMsg::Health {
            overruns,
            queue_high_water,
            latency_max_ns,
            ..
        }) => (*overruns, *queue_high_water, *latency_max_ns),
        _ => (0, 0, 0),
    };
    Ok(json!({
        "samples": samples,
        "rate_hz": rate,
        "overruns": overruns,
        "queue_high_water": high_water,
        "latency_max_us": f64::from(latency) / 1000.0,
        "frames": seen.frames,
        "terms": terms,
    }))
}

/// The live view: one refreshing block on a terminal, plain lines otherwise, or JSON.
struct View<'a> {
    json: bool,
    tty: bool,
    drawn: usize,
    out: &'a mut dyn Write,
}

impl<'a> View<'a> {
    fn new(json: bool, out: &'a mut dyn Write) -> Self {
        Self {
            json,
            tty: !json && std::io::stdout().is_terminal(),
            drawn: 0,
            out,
        }
    }

    fn show(
        &mut self,
        message: &DeviceMsg,
        seen: &Seen,
        session: &(Config, bool),
    ) -> Result<(), CliError> {
        let write = |e: std::io::Error| -> CliError { crate::output::fail(&e) };
        if self.json {
            writeln!(self.out, "{}", message_json(message, session)).map_err(write)?;
            return Ok(());
        }
        let lines = describe(message, seen, session);
        if self.tty {
            if !matches!(message, DeviceMsg::Health { .. } | DeviceMsg::Model(_)) {
                return Ok(());
            }
            let block = block(seen, session);
            if self.drawn > 0 {
                write!(self.out, "\x1b[{}A\x1b[J", self.drawn).map_err(write)?;
            }
            for line in &block {
                writeln!(self.out, "{line}").map_err(write)?;
            }
            self.drawn = block.len();
        } else {
            for line in lines {
                writeln!(self.out, "{line}").map_err(write)?;
            }
        }
        self.out.flush().map_err(write)
    }
}

fn equation(model: &ModelSnapshot, session: &(Config, bool)) -> String {
    match report_from_snapshot(model, &session.0, session.1) {
        Ok(report) => identify::render(&report)
            .lines()
            .next()
            .unwrap_or("")
            .to_string(),
        Err(e) => format!("(unreadable model: {e})"),
    }
}

fn health_line(health: &DeviceMsg) -> String {
    match health {
        DeviceMsg::Health {
            samples,
            rejected,
            screenings,
            overruns,
            queue_high_water,
            latency_max_ns,
            screenings_skipped,
            sample_rate_hz,
            crc_errors,
            ..
        } => format!(
            "samples {samples} at {sample_rate_hz} Hz ({rejected} rejected)   overruns {overruns}   queue high-water {queue_high_water}   worst latency {:.1} µs   screenings {screenings} ({screenings_skipped} skipped)   bad frames in {crc_errors}",
            f64::from(*latency_max_ns) / 1000.0
        ),
        _ => String::new(),
    }
}

fn describe(message: &DeviceMsg, _seen: &Seen, session: &(Config, bool)) -> Vec<String> {
    match message {
        DeviceMsg::Model(m) => vec![format!(
            "model ({:?}, {} rows): {}",
            m.cause,
            m.rows,
            equation(m, session)
        )],
        DeviceMsg::Health { .. } => vec![format!("health: {}", health_line(message))],
        other => vec![format!("{other:?}")],
    }
}

fn block(seen: &Seen, session: &(Config, bool)) -> Vec<String> {
    let mut out = vec!["lssi monitor".to_string()];
    match &seen.model {
        Some(m) => {
            out.push(equation(m, session));
            out.push(format!(
                "rows {}   samples {}   cause {:?}",
                m.rows, m.samples, m.cause
            ));
        }
        None => out.push("no model yet".into()),
    }
    if let Some(h) = &seen.health {
        out.push(health_line(h));
    }
    out.push(format!("frames {}   corrupt {}", seen.frames, seen.corrupt));
    out
}
