//! One `lssi replay` session: the device started (a port as given, `firmware-sim` or QEMU on a
//! pty), the telemetry log opened, the recording streamed over the [`Link`] with
//! [`replay_over_with`], and the device process stopped, its last words noted in the log.

use std::path::{Path, PathBuf};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lssi_proto::ModelSnapshot;

use crate::error::CliError;
use crate::identify::{self, Options};
use crate::recording::{ColumnNames, Recording};
use crate::serial::device::{DeviceProcess, SimOptions};
use crate::serial::link::{Link, LinkError, LinkOptions, LinkStats, Observer};
use crate::serial::quantise::{Quantised, quantise};
use crate::serial::replay::{
    ReplayError, ReplayMode, ReplayReport, SystemReplayReport, decimate_recording, decimate_system,
    replay_over_with, replay_system_over, rows_per_row, wire_config,
};
use crate::system::SystemData;
use crate::telemetry::defmt::{DefmtLines, Tables};
use crate::telemetry::{RecordKind, TelemetryLog};

/// Which device the recording goes to.
#[derive(Debug, Clone, PartialEq)]
pub enum Device {
    /// A serial port with a device on it.
    Port(String),
    /// This firmware image, run under QEMU (mps2-an386) on a pty.
    Qemu(PathBuf),
    /// `firmware-sim`, started on a pty with the session's [`SimOptions`].
    FirmwareSim,
}

/// Everything a replay session needs, checked.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The recording (CSV).
    pub file: PathBuf,
    /// Which header names hold which quantity.
    pub columns: ColumnNames,
    /// The identifier options (`lssi identify --f32`'s).
    pub options: Options,
    /// The link's pacing.
    pub link: LinkOptions,
    /// The baud rate, and firmware-sim's faults (recorded in the log whatever the device).
    pub sim: SimOptions,
    /// The device.
    pub device: Device,
    /// The firmware's ELF, to decode its defmt log lines (with QEMU: default, the image run).
    pub elf: Option<PathBuf>,
    /// The telemetry log to append to.
    pub log: PathBuf,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// Send i16 samples (`--encoding i16`): the recording is quantised first, and the
    /// quantised recording is what is configured, streamed and reported.
    pub quantise: bool,
    /// Continue a replay the device has begun (`--resume`): no Configure, the samples from
    /// the device's count on.
    pub resume: bool,
    /// The row rate (`--row-rate`): the recording's rows averaged down to it (`None`: its
    /// own rate).
    pub row_rate: Option<RowRate>,
    /// The duty cycle sent in the configuration (`--duty-window`, `--duty-interval`).
    pub duty: Option<lssi_proto::WireDuty>,
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

/// The rows a second a replay sends (`--row-rate`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RowRate {
    /// This many rows a second: the recording's rate divided by a whole number.
    Hz(f64),
    /// The rate `lssi identify` proposes for the recording ("a device needs N Hz for this
    /// harvester"): the recording's rows averaged by the largest whole number that keeps the
    /// rows at or above it.
    Proposed,
}

/// How many of the recording's rows a row averages at `rate` (`sample_period` the
/// recording's own); for [`RowRate::Proposed`], from the streaming model `lssi identify
/// --no-refine` finds in `recording` (a note on stderr says which rate and why).
fn rows_a_row(
    file: &str,
    rate: RowRate,
    recording: &Recording,
    options: &Options,
    sample_period: f64,
) -> Result<usize, CliError> {
    use crate::identify::pipeline::{self, Failure, Refine};
    let hz = match rate {
        RowRate::Hz(hz) => hz,
        RowRate::Proposed => {
            let report = match pipeline::identify(recording, options, Refine::No("")) {
                Ok(done) => done.report,
                Err(Failure::Withheld(sentence, ..)) => {
                    return Err(CliError::Input(format!(
                        "{file}: --row-rate proposed needs lssi identify's model of the recording to propose a rate, and it is withheld ({sentence}); give --row-rate HZ."
                    )));
                }
                Err(Failure::Error(sentence)) => return Err(CliError::Input(sentence)),
            };
            let Some(proposal) = report.device_rate() else {
                return Err(CliError::Input(format!(
                    "{file}: --row-rate proposed: lssi identify proposes no rate for this recording (its model has no line to sample); give --row-rate HZ."
                )));
            };
            let own = 1.0 / sample_period;
            let k = (own / proposal.hz)
                .floor()
                .clamp(1.0, f64::from(lssi_device::decimate::MAX_FACTOR));
            let sentence = identify::device_rate::sentence(&proposal, sample_period);
            if own < proposal.hz {
                eprintln!(
                    "lssi: warning: {file}: replaying every row ({own:.6} a second): the recording is slower than the rate lssi identify proposes ({sentence})."
                );
            } else {
                eprintln!(
                    "lssi: replaying at {:.6} rows a second, the recording's rows averaged {k} at a time: {sentence}.",
                    own / k
                );
            }
            return Ok(k as usize);
        }
    };
    rows_per_row(file, sample_period, hz).map_err(CliError::Input)
}

/// Replays as `setup` says and returns the report (what `lssi replay` prints).
pub fn replay(setup: &Setup) -> Result<ReplayReport, CliError> {
    let recording = Recording::read(&setup.file, &setup.columns)?;
    // The row rate: the recording's rows averaged down to it (none by default).
    let recording = match setup.row_rate {
        Some(rate) => {
            let (own, _) = identify::configure(&recording, &setup.options)?;
            let file = setup.file.display().to_string();
            let k = rows_a_row(&file, rate, &recording, &setup.options, own.sample_period)?;
            decimate_recording(&recording, k)
        }
        None => recording,
    };
    // The compact encoding's quantisation is part of the recording: configured, streamed
    // and reported as the quantised recording (what `lssi identify --quantise i16` reads).
    let quantised: Option<Quantised> = if setup.quantise {
        Some(quantise(&recording).map_err(CliError::Input)?)
    } else {
        None
    };
    // f32 samples travel less the reference `lssi identify` takes off them (the mean of the
    // first rows of a channel far from zero: raw ADC counts, an offset 10⁴ amplitudes away),
    // as a device can take it off its own first rows; the device's model is in those
    // coordinates and is reported back in the recording's, as `identify --f32` reports it.
    // The compact encoding's quantisation takes its own offset out.
    let (recording, reference) = match &quantised {
        Some(q) => (q.recording.clone(), identify::Reference::default()),
        None => {
            let reference = identify::Reference::of(&recording);
            (
                reference.shifted(&recording).unwrap_or(recording),
                reference,
            )
        }
    };
    let (config, estimated) = identify::configure(&recording, &setup.options)?;
    let mut wire = wire_config(&recording, &config)?;
    wire.duty = setup.duty;
    let session = serde_json::json!({
        "tool": "lssi replay",
        "version": env!("CARGO_PKG_VERSION"),
        "input": setup.file.display().to_string(),
        "encoding": if setup.quantise { "i16" } else { "f32" },
        "resume": setup.resume,
        "omega_estimated": estimated,
        "samples": recording.len(),
        "row_rate_hz": 1.0 / config.sample_period,
        "config": wire,
    });
    with_link(setup, recording.len(), session, |link| {
        let mode = ReplayMode {
            quantised: quantised.as_ref(),
            resume: setup.resume,
            duty: setup.duty,
        };
        replay_over_with(link, &recording, &config, estimated, mode)
    })
    .map(|mut replayed| {
        reference.restore(&mut replayed.report);
        replayed
    })
}

/// Replays a system's recording (one with an electrical column) as `setup` says:
/// `ConfigureSystem`, `SystemSamples`, the device's equations reported as `lssi identify
/// --f32` reports the system.
pub fn replay_system(
    setup: &Setup,
    data: &SystemData,
    coupling_order: u8,
    load_ohms: Option<f64>,
    coil_ohms: Option<f64>,
) -> Result<SystemReplayReport, CliError> {
    let file = setup.file.display().to_string();
    if setup.quantise {
        return Err(CliError::Input(format!(
            "{file}: --encoding i16 is for one equation's samples; a system's (with its electrical channel) travel as f32, so leave --encoding out."
        )));
    }
    let data = match setup.row_rate {
        Some(rate) => {
            let (own, _) = crate::system::configure(data, &setup.options, coupling_order)?;
            // Proposed from the motion's equation (x and u), as `lssi identify` proposes it
            // for the same columns without the electrical one.
            let k = rows_a_row(
                &file,
                rate,
                &data.recording,
                &setup.options,
                own.base.sample_period,
            )?;
            decimate_system(data, k)
        }
        None => data.clone(),
    };
    // Channels far from zero travel less their references, as `lssi identify` identifies
    // them ([`crate::system::references`]); the report names them as its report does.
    let (data, reference) = match crate::system::references(&data) {
        Some((shifted, reference)) => (shifted, Some(reference)),
        None => (data, None),
    };
    let (config, estimated) = crate::system::configure(&data, &setup.options, coupling_order)?;
    let mut wire = lssi_device::system::system_config_to_wire(&config)
        .map_err(|e| CliError::Input(format!("{file}: {e}.")))?;
    wire.base.duty = setup.duty;
    let session = serde_json::json!({
        "tool": "lssi replay",
        "version": env!("CARGO_PKG_VERSION"),
        "input": file,
        "encoding": "f32",
        "resume": setup.resume,
        "omega_estimated": estimated,
        "samples": data.recording.len(),
        "row_rate_hz": 1.0 / config.base.sample_period,
        "config": wire.base,
        "system": {
            "electrical": data.electrical.iter().map(|e| e.kind.symbol()).collect::<Vec<_>>(),
            "coupling_order": config.coupling_order,
        },
    });
    with_link(setup, data.recording.len(), session, |link| {
        let mode = ReplayMode {
            quantised: None,
            resume: setup.resume,
            duty: setup.duty,
        };
        replay_system_over(link, &data, &config, estimated, mode)
    })
    .map(|mut replayed| {
        // The host's gate on the device's model, as `lssi identify` judges its own: its
        // measures and warnings in the report; a model it would withhold is said so.
        let quality = crate::system::quality::assess(&replayed.report, &data);
        let report = &mut replayed.report;
        report.warnings.extend(quality.warnings.iter().cloned());
        if !quality.passed() {
            report.warnings.extend(quality.failures.iter().cloned());
        }
        report.quality = Some(quality);
        if let Some(ohms) = load_ohms {
            replayed.report.harvester = Some(crate::system::power::harvester(
                &replayed.report,
                &data,
                ohms,
                coil_ohms,
            ));
        }
        replayed.report.reference = reference;
        replayed
    })
}

/// Opens the telemetry log, starts the device, opens the link and runs `body` over it; the
/// device process is stopped and its last words noted in the log whatever `body` did.
/// `session` is the log's session record (the device's kind, port, baud and faults are
/// added here).
fn with_link<T>(
    setup: &Setup,
    samples: usize,
    mut session: serde_json::Value,
    body: impl FnOnce(&mut Link<'_>) -> Result<T, ReplayError>,
) -> Result<T, CliError> {
    let qemu = matches!(setup.device, Device::Qemu(_));
    let elf = setup.elf.clone().or_else(|| match &setup.device {
        Device::Qemu(firmware) => Some(firmware.clone()),
        _ => None,
    });
    let tables = match &elf {
        Some(path) if !qemu || path.is_file() => {
            Some(Tables::load(path).map_err(|e| CliError::Input(format!("{e}."))))
        }
        _ => None,
    }
    .transpose()?;

    let log_path = &setup.log;
    let mut log = TelemetryLog::open(log_path).map_err(|e| {
        CliError::Input(format!(
            "{}: cannot open the telemetry log: {e}.",
            log_path.display()
        ))
    })?;

    // The device: a port as given, or a child process on a pty.
    let mut process = match &setup.device {
        Device::Port(_) => None,
        Device::Qemu(firmware) => {
            Some(DeviceProcess::qemu(firmware).map_err(|e| CliError::Input(format!("{e}."))))
        }
        Device::FirmwareSim => Some(
            DeviceProcess::firmware_sim(&setup.sim).map_err(|e| CliError::Device(format!("{e}."))),
        ),
    }
    .transpose()?;
    let port_name = match (&setup.device, &process) {
        (Device::Port(port), _) => port.clone(),
        (_, Some(process)) => process.pty().to_string(),
        (_, None) => return Err(CliError::Device("no device to replay to.".into())),
    };
    let kind = match &setup.device {
        Device::Port(_) => "port",
        Device::Qemu(_) => "qemu",
        Device::FirmwareSim => "firmware-sim",
    };
    if let Some(object) = session.as_object_mut() {
        object.insert("device".into(), kind.into());
        object.insert("port".into(), port_name.clone().into());
        object.insert("baud".into(), setup.sim.baud.into());
        object.insert(
            "faults".into(),
            serde_json::json!({"flip_rate": setup.sim.flip_rate, "drop_rate": setup.sim.drop_rate, "burst": setup.sim.burst, "seed": setup.sim.seed}),
        );
    }
    log.append(RecordKind::Session, session.to_string().as_bytes())
        .map_err(|e| log_write_error(log_path, e))?;

    let port = serialport::new(&port_name, setup.sim.baud)
        .timeout(Duration::from_millis(50))
        .open()
        .map_err(|e| CliError::Device(format!("{port_name}: cannot open the serial port: {e}.")))?;
    let reader = port.try_clone().map_err(|e| {
        CliError::Device(format!(
            "{port_name}: cannot open the serial port twice: {e}."
        ))
    })?;

    let bar = if setup.progress {
        ProgressBar::with_draw_target(Some(samples as u64), ProgressDrawTarget::stderr())
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
        baud: setup.sim.baud,
    };
    let qemu_stdout = process.as_mut().and_then(DeviceProcess::take_stdout);
    let result = {
        let mut link = Link::new(
            port_name.clone(),
            Box::new(reader),
            Box::new(port),
            &mut log,
            &mut watcher,
            setup.link,
        );
        if let Some(stdout) = qemu_stdout {
            link.attach_defmt(Box::new(stdout));
        }
        let result = body(&mut link);
        if let Err(error) = &result {
            let _ = link.note(&format!("replay stopped: {error}"));
        }
        result
    };
    watcher.bar.finish_and_clear();
    if let Some(process) = process {
        // firmware-sim exits once the port is closed; QEMU never does.
        let grace = Duration::from_millis(if matches!(setup.device, Device::Qemu(_)) {
            0
        } else {
            2000
        });
        for line in process.finish(grace) {
            let _ = log.note(&format!("{kind}: {line}"));
        }
    }
    let _ = log.sync();
    result.map_err(|error| replay_error(error, &setup.device))
}

/// A replay's failure as `lssi` says it. A link that gave up at its deadline can be resumed
/// on a port (the device keeps its state); firmware-sim and QEMU ran on a pty this replay
/// started, which ended with it, so there is nothing to resume: the sentence says to replay
/// again instead of `--resume --port` on a pty that no longer exists.
fn replay_error(error: ReplayError, device: &Device) -> CliError {
    let what = match device {
        Device::Port(_) => return CliError::from(error),
        Device::FirmwareSim => "firmware-sim",
        Device::Qemu(_) => "QEMU",
    };
    match error {
        ReplayError::Link(LinkError::Deadline {
            port,
            waiting_for,
            waited,
            frame_loss,
            byte_error_rate,
            acked,
            samples,
            ..
        }) => {
            let measured = if frame_loss > 0.0 || byte_error_rate > 0.0 {
                format!(
                    "{:.1} % of the sample frames it sent were not acknowledged (a byte error rate of about {:.3} %)",
                    100.0 * frame_loss,
                    100.0 * byte_error_rate
                )
            } else {
                "no sample frame had crossed yet".to_string()
            };
            let progress = if samples > 0 {
                format!("; the device had acknowledged {acked} of {samples} samples")
            } else {
                String::new()
            };
            CliError::Device(format!(
                "{port}: no progress for {:.1} s while the host waited for {waiting_for}, so it gives up: {measured}{progress}. {what} ran on that pty for this replay only and has ended, so it cannot be resumed: replay again (with lower fault rates or a longer --deadline).",
                waited.as_secs_f64(),
            ))
        }
        other => CliError::from(other),
    }
}

fn log_write_error(path: &Path, error: std::io::Error) -> CliError {
    CliError::Write {
        path: path.to_path_buf(),
        source: error,
    }
}
