//! `lssi monitor`'s work: listen to a standalone device's unsolicited frames (Model and Health
//! every period), show them live, and append them to the telemetry log that `lssi log` reads.
//!
//! - [`monitor_port`]: a board on a serial port, until a time limit.
//! - [`monitor_qemu`]: the standalone firmware under QEMU (`-icount shift=4,sleep=off`: a
//!   64 MHz Cortex-M4F's pace in guest time, its UART on a Unix socket) with the recording
//!   preloaded into its PSRAM as its sensor ([`recording_image`]), sampled by its timer at the
//!   recording's own rate or another, and configured as `lssi identify` would configure it for
//!   the file (the stored-configuration frame), or with the image's own configuration. It stops
//!   when the recording ends and returns a summary with the final model's terms, in
//!   `lssi identify --json`'s shape.

use std::io::{IsTerminal, Read, Write};
use std::path::PathBuf;
use std::process::Stdio;
use std::time::{Duration, Instant};

use lssi_core::Config;
use lssi_device::wire::config_to_wire;
use lssi_proto::{DeviceFrameDecoder, DeviceMsg, HostMsg, ModelSnapshot, SnapshotCause, encode};
use serde_json::{Value, json};

use crate::error::CliError;
use crate::identify::{self, Options};
use crate::recording::{ColumnNames, Recording};
use crate::serial::qemu;
use crate::serial::replay::report_from_snapshot;
use crate::telemetry::decode::message_json;
use crate::telemetry::defmt::{DefmtLines, Tables};
use crate::telemetry::{RecordKind, TelemetryLog};

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

/// A recording played through the standalone firmware under QEMU as its sensor.
#[derive(Debug, Clone)]
pub struct QemuPlay {
    /// The recording (CSV).
    pub file: PathBuf,
    /// Which header names hold which quantity.
    pub columns: ColumnNames,
    /// The sampling rate in Hz (`None`: the recording's own).
    pub rate: Option<f64>,
    /// Keep the image's default configuration instead of the one `lssi identify` chooses.
    pub image_config: bool,
    /// The standalone firmware image.
    pub firmware: PathBuf,
    /// The duty cycle stored with the configuration (`--duty-window`, `--duty-interval`).
    pub duty: Option<lssi_proto::WireDuty>,
}

/// How the frames are shown and how long to listen.
#[derive(Debug, Clone, Copy)]
pub struct Listen {
    /// One JSON object per frame instead of the live view.
    pub json: bool,
    /// Stop after this many seconds of wall time (`None`: the source's default).
    pub seconds: Option<f64>,
}

/// Plays `play` through the firmware under QEMU, logging to `log` and showing the frames on
/// `out`; returns the summary line's object.
pub fn monitor_qemu(
    play: &QemuPlay,
    listen_to: Listen,
    log: &mut TelemetryLog,
    out: &mut dyn Write,
) -> Result<Value, CliError> {
    let file = play.file.as_path();
    let recording = Recording::read(file, &play.columns)?;
    let (mut config, omega_estimated) = identify::configure(&recording, &Options::default())?;
    let own_rate = 1.0 / config.sample_period;
    let rate = match play.rate {
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
    let firmware = &play.firmware;
    if !firmware.is_file() {
        return Err(CliError::Input(format!(
            "{}: the standalone firmware image does not exist; build it (cargo build --release in crates/lssi-firmware, as scripts/setup.sh does) or give --firmware.",
            firmware.display()
        )));
    }
    let qemu = qemu::find().ok_or_else(|| {
        CliError::Input(
            "qemu-system-arm is not installed (apt-get install qemu-system-arm), so --qemu cannot run the firmware.".into(),
        )
    })?;
    let dir = tempfile::tempdir()
        .map_err(|e| CliError::Input(format!("no temporary directory: {e}.")))?;
    let image = dir.path().join("recording.bin");
    let stored = (!play.image_config).then_some(&config);
    let bytes = recording_image_with(&recording, rate, stored, play.duty)?;
    std::fs::write(&image, &bytes).map_err(|e| CliError::Write {
        path: image.clone(),
        source: e,
    })?;
    let session_config = if play.image_config {
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
    log_session(
        log,
        &session,
        &format!("qemu:{}", file.display()),
        rate,
        play.duty,
    )?;
    let socket = dir.path().join("uart.sock");
    let mut child = qemu::command(&qemu)
        .args(["-icount", "shift=4,sleep=off", "-kernel"])
        .arg(firmware)
        .arg("-device")
        .arg(format!("loader,file={},addr={PSRAM}", image.display()))
        .arg("-serial")
        .arg(format!("unix:{},server=on,wait=on", socket.display()))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| CliError::Device(format!("{}: cannot start QEMU: {e}.", qemu.display())))?;
    let stream = qemu::connect(&socket, &mut child)?;
    let defmt = child.stdout.take().map(|mut stdout| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            let _ = stdout.read_to_end(&mut bytes);
            bytes
        })
    });
    let limit = Duration::from_secs_f64(listen_to.seconds.unwrap_or(600.0));
    let mut view = View::new(listen_to.json, out);
    let seen = listen(stream, &session, log, &mut view, limit)?;
    let status = qemu::wait(&mut child, Duration::from_secs(10));
    let defmt_bytes = defmt.and_then(|h| h.join().ok()).unwrap_or_default();
    if !defmt_bytes.is_empty() {
        let _ = log.append(RecordKind::Defmt, &defmt_bytes);
    }
    let tables = Tables::load(firmware).ok();
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
    recording_image_with(recording, rate, config, None)
}

/// [`recording_image`] with a duty cycle in the stored configuration.
pub fn recording_image_with(
    recording: &Recording,
    rate: f64,
    config: Option<&Config>,
    duty: Option<lssi_proto::WireDuty>,
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
        let mut wire =
            config_to_wire(config).map_err(|e| CliError::Input(format!("{file}: {e}.")))?;
        wire.duty = duty;
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
    duty: Option<lssi_proto::WireDuty>,
) -> Result<(), CliError> {
    let wire = config_to_wire(&session.config).ok().map(|mut w| {
        w.duty = duty;
        w
    });
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

/// The configuration `lssi monitor --port` sends a standalone board for a row rate: the
/// image's own for that rate (crates/lssi-firmware's `default_config`: a derivative window
/// of a tenth of a second, a row every sample, a screening a second; lssi-core's defaults
/// otherwise).
pub fn port_config(row_hz: f64) -> Config {
    Config {
        sample_period: 1.0 / row_hz,
        window: ((row_hz / 10.0) as usize | 1).clamp(7, lssi_device::DEFAULT_WINDOW - 1),
        row_stride: 1,
        screening_period: (row_hz as u32).max(100),
        ..Config::default()
    }
}

/// The row rate of a standalone image's own configuration, Hz (crates/lssi-firmware's
/// `DEFAULT_ROW_HZ`): what `lssi monitor --port` sends with a duty cycle and no
/// `--row-rate`.
pub const IMAGE_ROW_HZ: f64 = 200.0;

/// What `lssi monitor --port` sends the board before it listens (`--row-rate`,
/// `--duty-window`, `--duty-interval`): its configuration (rows at `row_hz`, the duty
/// cycle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PortSetup {
    /// Rows a second.
    pub row_hz: f64,
    /// The duty cycle, if any.
    pub duty: Option<lssi_proto::WireDuty>,
}

/// Listens to a standalone board on serial port `port` until `listen_to.seconds` (default:
/// for ever), logging to `log` and showing the frames on `out`. With `setup`, first sends it
/// the configuration (`Configure`, resent until acknowledged, at most three times) and
/// decodes its models with it.
pub fn monitor_port(
    port: &str,
    baud: u32,
    listen_to: Listen,
    setup: Option<PortSetup>,
    log: &mut TelemetryLog,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let mut serial = serialport::new(port, baud)
        .timeout(Duration::from_millis(200))
        .open()
        .map_err(|e| CliError::Device(format!("{port}: cannot open the serial port: {e}.")))?;
    let session = Session {
        config: setup.map_or_else(Config::default, |s| port_config(s.row_hz)),
        omega_estimated: false,
    };
    log_session(
        log,
        &session,
        port,
        setup.map_or(0.0, |s| s.row_hz),
        setup.and_then(|s| s.duty),
    )?;
    // What the board sent after its Ack, in the same read: the listening starts with it.
    let leftover = match setup {
        Some(setup) => configure_port(&mut serial, port, &session.config, setup, log)?,
        None => Vec::new(),
    };
    let serial = std::io::Cursor::new(leftover).chain(serial);
    let limit = Duration::from_secs_f64(listen_to.seconds.unwrap_or(f64::MAX / 4.0).min(1.0e9));
    let mut view = View::new(listen_to.json, out);
    listen(serial, &session, log, &mut view, limit)?;
    let _ = log.sync();
    Ok(())
}

/// Sends the board its configuration and waits for the answer (other frames are logged and
/// passed over): `Ack` configures it (returned: the bytes read after it), a `Nak` is one
/// sentence naming the reason.
fn configure_port<P: Read + Write + ?Sized>(
    serial: &mut P,
    port: &str,
    config: &Config,
    setup: PortSetup,
    log: &mut TelemetryLog,
) -> Result<Vec<u8>, CliError> {
    let mut wire = config_to_wire(config).map_err(|e| CliError::Input(format!("{e}.")))?;
    wire.duty = setup.duty;
    let mut frame = [0u8; lssi_proto::MAX_HOST_FRAME_LEN];
    let len = encode(&HostMsg::Configure(wire), &mut frame)
        .map_err(|e| CliError::Input(format!("the configuration does not encode: {e}.")))?;
    let what = match setup.duty {
        Some(d) => format!(
            "rows at {} Hz, windows of {} s every {} s, a model every {} window{}",
            setup.row_hz,
            d.window,
            d.interval,
            d.model_every.max(1),
            if d.model_every > 1 { "s" } else { "" }
        ),
        None => format!("rows at {} Hz", setup.row_hz),
    };
    let mut decoder = DeviceFrameDecoder::new();
    let mut raw: Vec<u8> = Vec::new();
    let mut buffer = [0u8; 1024];
    for _ in 0..3 {
        // A lone 0x00 ends whatever half frame the board holds.
        serial
            .write_all(&[0])
            .and_then(|()| serial.write_all(&frame[..len]))
            .map_err(|e| {
                CliError::Device(format!("{port}: cannot write the configuration: {e}."))
            })?;
        let sent = Instant::now();
        while sent.elapsed() < Duration::from_secs(2) {
            let n = match serial.read(&mut buffer) {
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    continue;
                }
                Err(e) => {
                    return Err(CliError::Device(format!(
                        "{port}: the device's link failed: {e}."
                    )));
                }
            };
            if n == 0 {
                return Err(CliError::Device(format!(
                    "{port}: the link closed before the device answered the configuration ({what})."
                )));
            }
            for (i, &byte) in buffer[..n].iter().enumerate() {
                if byte != 0 {
                    raw.push(byte);
                } else if !raw.is_empty() {
                    let _ = log.append(RecordKind::Frame, &raw);
                    raw.clear();
                }
                match decoder.push::<DeviceMsg>(byte) {
                    Some(Ok(DeviceMsg::Ack {
                        seq: lssi_proto::CONTROL_SEQ,
                    })) => return Ok(buffer[i + 1..n].to_vec()),
                    Some(Ok(DeviceMsg::Nak {
                        seq: lssi_proto::CONTROL_SEQ,
                        reason,
                    })) => {
                        return Err(CliError::Device(format!(
                            "{port}: the device refused the configuration ({what}): {}.",
                            crate::serial::link::nak_text(reason)
                        )));
                    }
                    Some(Err(lssi_proto::Error::VersionMismatch { theirs, ours })) => {
                        return Err(CliError::Device(format!(
                            "{port}: the device speaks lssi protocol version {theirs}, but this build speaks version {ours}; flash a matching firmware."
                        )));
                    }
                    _ => {}
                }
            }
        }
    }
    Err(CliError::Device(format!(
        "{port}: the device did not answer the configuration ({what}) in three tries of 2 s; is it a standalone lssi device at this baud rate?"
    )))
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
    let (overruns, high_water, latency, drift, reference) = match &seen.health {
        Some(DeviceMsg::Health {
            overruns,
            queue_high_water,
            latency_max_ns,
            drift,
            reference,
            ..
        }) => (
            *overruns,
            *queue_high_water,
            *latency_max_ns,
            *drift,
            *reference,
        ),
        _ => (0, 0, 0, None, None),
    };
    Ok(json!({
        "samples": samples,
        "rate_hz": rate,
        "overruns": overruns,
        "queue_high_water": high_water,
        "latency_max_us": f64::from(latency) / 1000.0,
        "frames": seen.frames,
        "drift": drift.map(|d| crate::telemetry::decode::drift_json(&d)),
        // The references the device took off its channels (its model's terms are about
        // the channels less them), null when none.
        "reference": reference.map(|r| crate::telemetry::decode::reference_json(&r)),
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
            drift,
            reference,
            ..
        } => format!(
            "samples {samples} at {sample_rate_hz} Hz ({rejected} rejected)   overruns {overruns}   queue high-water {queue_high_water}   worst latency {:.1} µs   screenings {screenings} ({screenings_skipped} skipped)   bad frames in {crc_errors}{}{}",
            f64::from(*latency_max_ns) / 1000.0,
            drift
                .map(|d| format!("   {}", crate::telemetry::decode::drift_text(&d)))
                .unwrap_or_default(),
            reference
                .map(|r| format!("   {}", crate::telemetry::decode::reference_text(&r)))
                .unwrap_or_default()
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
