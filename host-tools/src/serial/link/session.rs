//! The session: the [`Link`] itself, its sending, receiving and round-trip timing, and
//! the requests that open and close a session (`Hello`, `Configure`, the model query,
//! the log summary). Streaming with retransmission is in `retries`.

use std::fmt;
use std::io::{self, Read, Write};
use std::sync::mpsc::RecvTimeoutError;
use std::time::{Duration, Instant};

use lssi_proto::{
    CONTROL_SEQ, DeviceMsg, HostMsg, MAX_FRAME_LEN, ModelSnapshot, NakReason, PROTOCOL_VERSION,
    SnapshotCause, SystemSnapshot, WireConfig, WireSystemConfig, decode_frame, encode,
    snapshot_from_parts,
};

use super::framing::{Incoming, Reader};
use super::{DeviceInfo, Health, LinkError, LinkOptions, LinkStats, Observer};
use crate::serial::adapt::Adapt;
use crate::telemetry::{RecordKind, TelemetryLog, now_us};

/// The shortest wait before resending a batch, however fast the round trip measures.
pub(super) const MIN_TIMEOUT: Duration = Duration::from_millis(4);

/// What a received frame means for the caller.
#[allow(
    clippy::large_enum_variant,
    reason = "one short-lived value per received frame; boxing buys nothing"
)]
pub(super) enum Event {
    Message(DeviceMsg),
    Nothing,
}

/// An open link to a device.
pub struct Link<'a> {
    pub(super) port: String,
    pub(super) writer: Box<dyn Write + Send>,
    pub(super) reader: Reader,
    pub(super) log: &'a mut TelemetryLog,
    pub(super) observer: &'a mut dyn Observer,
    pub(super) options: LinkOptions,
    pub(super) stats: LinkStats,
    pub(super) last_heard: Instant,
    pub(super) health: Option<Health>,
    pub(super) started: Option<Instant>,
    /// Smoothed round trip of a batch (sent to acknowledged), once measured.
    pub(super) srtt: Option<Duration>,
    /// Its mean deviation.
    pub(super) rttvar: Duration,
    /// The error-rate estimate of the last stream.
    pub(super) adapt: Option<Adapt>,
    /// When the link last made progress (a sample acknowledged, a request answered).
    pub(super) progress: Instant,
}

impl fmt::Debug for Link<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Link")
            .field("port", &self.port)
            .field("options", &self.options)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl<'a> Link<'a> {
    /// A link over a byte stream: `reader` and `writer` are two handles on the same port
    /// (`serialport`'s `try_clone`, or the two ends of a test's pipe). `port` names it in
    /// errors. The reader should time out now and then (a serial port's timeout) so that its
    /// thread notices the link is done.
    pub fn new(
        port: impl Into<String>,
        reader: Box<dyn Read + Send>,
        writer: Box<dyn Write + Send>,
        log: &'a mut TelemetryLog,
        observer: &'a mut dyn Observer,
        options: LinkOptions,
    ) -> Self {
        Self {
            port: port.into(),
            writer,
            reader: Reader::spawn(reader),
            log,
            observer,
            options,
            stats: LinkStats::default(),
            last_heard: Instant::now(),
            health: None,
            started: None,
            srtt: None,
            rttvar: Duration::ZERO,
            adapt: None,
            progress: Instant::now(),
        }
    }

    /// Also reads raw defmt bytes from `stream` (QEMU's semihosting output) until it ends:
    /// logged as they arrive and shown through [`Observer::device_log`].
    pub fn attach_defmt(&mut self, mut stream: Box<dyn Read + Send>) {
        let tx = self.reader.tx.clone();
        std::thread::spawn(move || {
            let mut buffer = [0u8; 1024];
            while let Ok(n) = stream.read(&mut buffer) {
                if n == 0
                    || tx
                        .send(Incoming::Defmt(buffer[..n].to_vec(), now_us()))
                        .is_err()
                {
                    return;
                }
            }
        });
    }

    /// Appends a note to the telemetry log.
    pub fn note(&mut self, text: &str) -> Result<(), LinkError> {
        self.log_record(RecordKind::Note, now_us(), text.as_bytes())
    }

    /// The counters so far.
    pub fn stats(&self) -> &LinkStats {
        &self.stats
    }

    /// The port's name.
    pub fn port(&self) -> &str {
        &self.port
    }

    /// The device's last health report.
    pub fn health(&self) -> Option<Health> {
        self.health
    }

    pub(super) fn closed(&self, detail: impl Into<String>) -> LinkError {
        LinkError::Closed {
            port: self.port.clone(),
            detail: detail.into(),
            acked: self.stats.samples_acked,
        }
    }

    pub(super) fn write_bytes(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let mut rest = bytes;
        let started = Instant::now();
        while !rest.is_empty() {
            match self.writer.write(rest) {
                Ok(0) => return Err(self.closed("the port accepts no more bytes")),
                Ok(n) => rest = &rest[n..],
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                // A full line: the device reads at the baud rate. Wait, within reason.
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                    ) && started.elapsed() < self.options.silence => {}
                Err(e) => return Err(self.closed(e.to_string())),
            }
        }
        self.stats.bytes_sent += bytes.len() as u64;
        Ok(())
    }

    pub(super) fn send(&mut self, message: &HostMsg) -> Result<(), LinkError> {
        let mut frame = [0u8; MAX_FRAME_LEN];
        let len = encode(message, &mut frame).unwrap_or(0);
        self.write_bytes(&frame[..len])?;
        self.stats.frames_sent += 1;
        Ok(())
    }

    pub(super) fn log_record(
        &mut self,
        kind: RecordKind,
        time_us: u64,
        data: &[u8],
    ) -> Result<(), LinkError> {
        self.log
            .append_at(kind, time_us, data)
            .map_err(|source| LinkError::Log {
                path: self.log.path().to_path_buf(),
                source,
            })
    }

    /// Waits up to `wait` for the next frame; logs it and returns what it means.
    pub(super) fn receive(&mut self, wait: Duration) -> Result<Option<Event>, LinkError> {
        let incoming = match self.reader.rx.recv_timeout(wait) {
            Ok(incoming) => incoming,
            Err(RecvTimeoutError::Timeout) => return Ok(None),
            Err(RecvTimeoutError::Disconnected) => return Err(self.closed("")),
        };
        self.last_heard = Instant::now();
        match incoming {
            Incoming::Closed(detail) => Err(self.closed(detail)),
            Incoming::Defmt(bytes, time) => {
                self.log_record(RecordKind::Defmt, time, &bytes)?;
                self.observer.device_log(&bytes);
                Ok(Some(Event::Nothing))
            }
            Incoming::Overlong(bytes, time) => {
                self.log_record(RecordKind::Frame, time, &bytes)?;
                self.stats.rx_crc_errors += 1;
                Ok(Some(Event::Nothing))
            }
            Incoming::Frame(bytes, time) => {
                self.log_record(RecordKind::Frame, time, &bytes)?;
                let mut copy = bytes;
                match decode_frame::<DeviceMsg>(&mut copy) {
                    Ok(message) => {
                        match &message {
                            DeviceMsg::Log { bytes } => self.observer.device_log(bytes),
                            DeviceMsg::Model(snapshot) => self.observer.model(snapshot),
                            DeviceMsg::Health { .. } => self.health = Health::of(&message),
                            _ => {}
                        }
                        Ok(Some(Event::Message(message)))
                    }
                    Err(lssi_proto::Error::VersionMismatch { theirs, .. }) => {
                        Err(LinkError::Version {
                            port: self.port.clone(),
                            theirs,
                        })
                    }
                    Err(_) => {
                        self.stats.rx_crc_errors += 1;
                        Ok(Some(Event::Nothing))
                    }
                }
            }
        }
    }

    /// Sends `message` until `answer` accepts a reply, resending after each timeout (a
    /// request or its reply lost or damaged on the line), until the deadline passes without
    /// progress or the device falls silent.
    pub(super) fn command<R>(
        &mut self,
        message: &HostMsg,
        waiting_for: &'static str,
        mut answer: impl FnMut(&DeviceMsg) -> Option<Result<R, LinkError>>,
    ) -> Result<R, LinkError> {
        // The first wait follows the measured round trip; it doubles while nothing answers
        // (a device that screens before answering takes longer than a batch's ack).
        let longest = self.options.timeout.max(MIN_TIMEOUT) * 4;
        let mut timeout = self.rto().min(longest);
        let asked = Instant::now();
        self.last_heard = asked;
        loop {
            self.send(message)?;
            let sent = Instant::now();
            while let Some(left) = timeout.checked_sub(sent.elapsed()) {
                match self.receive(left)? {
                    Some(Event::Message(reply)) => {
                        if let Some(result) = answer(&reply) {
                            self.progress = Instant::now();
                            return result;
                        }
                    }
                    Some(Event::Nothing) | None => {}
                }
            }
            if self.last_heard.elapsed() >= self.options.silence {
                return Err(LinkError::Silent {
                    port: self.port.clone(),
                    waiting_for,
                    waited: self.last_heard.elapsed(),
                });
            }
            if asked.elapsed() >= self.options.deadline {
                return Err(self.deadline(waiting_for, asked.elapsed()));
            }
            self.stats.timeouts += 1;
            self.stats.requests_resent += 1;
            timeout = (timeout * 2).min(longest);
        }
    }

    /// The wait for an answer the round trip measured so far calls for (the configured
    /// timeout until one is measured).
    pub(super) fn rto(&self) -> Duration {
        match self.srtt {
            // Jacobson's: the mean round trip and four times its mean deviation.
            Some(srtt) => {
                (srtt + 4 * self.rttvar).clamp(MIN_TIMEOUT, self.options.timeout.max(MIN_TIMEOUT))
            }
            None => self.options.timeout,
        }
    }

    /// Takes a round trip measured on a batch sent once (RFC 6298's smoothing).
    pub(super) fn measured(&mut self, rtt: Duration) {
        match self.srtt {
            None => {
                self.srtt = Some(rtt);
                self.rttvar = rtt / 2;
            }
            Some(srtt) => {
                let deviation = srtt.abs_diff(rtt);
                self.rttvar = (self.rttvar * 3 + deviation) / 4;
                self.srtt = Some((srtt * 7 + rtt) / 8);
            }
        }
        self.stats.round_trip_ms = self.srtt.map_or(0.0, |d| d.as_secs_f64() * 1e3);
    }

    /// The error that ends a link without progress, with what it measured.
    pub(super) fn deadline(&self, waiting_for: &'static str, waited: Duration) -> LinkError {
        let (frame_loss, adapted) = match &self.adapt {
            Some(adapt) => (adapt.frame_loss(), adapt.byte_error_rate()),
            None => (0.0, 0.0),
        };
        // The device's own count of damaged frames when it has reported one (the adaptive
        // estimate overstates the rate: go-back-N resends intact frames too).
        let byte_error_rate = match &self.health {
            Some(health) if health.frames_ok > 0 => self.stats.line_error_rate_of(health),
            _ => adapted,
        };
        LinkError::Deadline {
            port: self.port.clone(),
            waiting_for,
            waited,
            frame_loss,
            byte_error_rate,
            acked: self.stats.samples_acked,
            samples: self.stats.samples,
            sent: self.stats.samples_sent,
        }
    }

    /// Opens the session: `Hello` until the device answers; returns its capacities.
    pub fn hello(&mut self) -> Result<DeviceInfo, LinkError> {
        // A lone 0x00 ends whatever half frame the device may hold from before.
        self.write_bytes(&[0])?;
        let port = self.port.clone();
        self.command(
            &HostMsg::Hello {
                protocol_version: PROTOCOL_VERSION,
            },
            "the answer to Hello",
            |reply| match *reply {
                DeviceMsg::HelloReply {
                    protocol_version,
                    max_terms,
                    window_capacity,
                    max_batch,
                } => Some(if protocol_version == PROTOCOL_VERSION {
                    Ok(DeviceInfo {
                        max_terms,
                        window_capacity,
                        max_batch,
                    })
                } else {
                    Err(LinkError::Version {
                        port: port.clone(),
                        theirs: protocol_version,
                    })
                }),
                DeviceMsg::Nak {
                    reason: NakReason::VersionMismatch,
                    ..
                } => Some(Err(LinkError::Version {
                    port: port.clone(),
                    theirs: 0,
                })),
                _ => None,
            },
        )
    }

    /// Configures the identifier; the device acks or refuses (`BadConfig`).
    pub fn configure(&mut self, config: &WireConfig) -> Result<(), LinkError> {
        let port = self.port.clone();
        self.command(
            &HostMsg::Configure(*config),
            "the answer to Configure",
            |reply| match *reply {
                DeviceMsg::Ack { seq: CONTROL_SEQ } => Some(Ok(())),
                DeviceMsg::Nak {
                    seq: CONTROL_SEQ,
                    reason,
                } => Some(Err(LinkError::Refused {
                    port: port.clone(),
                    command: "the configuration",
                    reason,
                })),
                _ => None,
            },
        )
    }

    /// Configures a system's identifier (`ConfigureSystem`); the device acks or refuses.
    pub fn configure_system(&mut self, config: &WireSystemConfig) -> Result<(), LinkError> {
        let port = self.port.clone();
        self.command(
            &HostMsg::ConfigureSystem(*config),
            "the answer to ConfigureSystem",
            |reply| match *reply {
                DeviceMsg::Ack { seq: CONTROL_SEQ } => Some(Ok(())),
                DeviceMsg::Nak {
                    seq: CONTROL_SEQ,
                    reason,
                } => Some(Err(LinkError::Refused {
                    port: port.clone(),
                    command: "the system's configuration",
                    reason,
                })),
                // A device built without systems cannot decode the frame.
                DeviceMsg::Nak {
                    reason: NakReason::Decode,
                    ..
                } => Some(Err(LinkError::Refused {
                    port: port.clone(),
                    command: "the system's configuration",
                    reason: NakReason::Decode,
                })),
                _ => None,
            },
        )
    }

    /// Asks for a system's model: the device screens and answers `SystemModel` (if it has
    /// one) and `Health`. A system's model does not come in parts: when the Health reports
    /// screenings but its SystemModel frame was damaged on the line, the query is sent again
    /// (the device does not screen again without new samples, so the model is the same).
    pub fn query_system(&mut self) -> Result<(Option<SystemSnapshot>, Health), LinkError> {
        let mut last = None;
        for _ in 0..8 {
            let (model, health) = self.query_with(
                "the system's model (the answer to Query)",
                |reply| match reply {
                    DeviceMsg::SystemModel(snapshot) if snapshot.cause == SnapshotCause::Query => {
                        Some(snapshot.clone())
                    }
                    _ => None,
                },
            )?;
            if model.is_some() || health.screenings == 0 {
                return Ok((model, health));
            }
            last = Some(health);
        }
        Ok((None, last.unwrap_or_default()))
    }

    /// Asks for the model: the device screens and answers `Model` (if it has one) and
    /// `Health`. Returns the snapshot (`None`: no model yet) and the health counters, and
    /// settles `samples_lost` and `crc_errors` from them.
    ///
    /// The query is resent until its `Health` comes back. A `Health` that reports screenings
    /// without a `Model` before it means the Model frame (a few hundred bytes) was damaged on
    /// the line: the model is then fetched in short parts ([`HostMsg::ModelPart`]), each
    /// resent until it crosses, and checked as a whole against its CRC.
    pub fn query(&mut self) -> Result<(Option<ModelSnapshot>, Health), LinkError> {
        let (model, health) = self.query_once()?;
        if model.is_some() || health.screenings == 0 {
            return Ok((model, health));
        }
        let model = self.model_in_parts()?;
        if let Some(snapshot) = &model {
            self.observer.model(snapshot);
        }
        Ok((model, health))
    }

    /// The current model, part by part (`None`: the device has none).
    pub(super) fn model_in_parts(&mut self) -> Result<Option<ModelSnapshot>, LinkError> {
        for _ in 0..4 {
            let mut bytes: Vec<u8> = Vec::new();
            let mut whole: Option<(u16, u32)> = None;
            loop {
                let offset = u16::try_from(bytes.len()).unwrap_or(u16::MAX);
                let part = self.command(
                    &HostMsg::ModelPart { offset },
                    "a part of the model (ModelPart)",
                    |reply| match reply {
                        DeviceMsg::ModelPart(part) if part.offset == offset => {
                            Some(Ok(Some(part.clone())))
                        }
                        DeviceMsg::Nak {
                            seq: CONTROL_SEQ,
                            reason: NakReason::NotConfigured,
                        } => Some(Ok(None)),
                        _ => None,
                    },
                )?;
                self.stats.model_parts += 1;
                let Some(part) = part else {
                    return Ok(None);
                };
                match whole {
                    // A part of another model (it changed): start again.
                    Some(w) if w != (part.total, part.crc) => break,
                    _ => whole = Some((part.total, part.crc)),
                }
                if part.bytes.is_empty() && bytes.len() < usize::from(part.total) {
                    break;
                }
                bytes.extend_from_slice(&part.bytes);
                if bytes.len() >= usize::from(part.total) {
                    if let Some(snapshot) = snapshot_from_parts(&bytes, part.crc) {
                        return Ok(Some(snapshot));
                    }
                    break;
                }
            }
        }
        Ok(None)
    }

    pub(super) fn query_once(&mut self) -> Result<(Option<ModelSnapshot>, Health), LinkError> {
        self.query_with("the model (the answer to Query)", |reply| match reply {
            DeviceMsg::Model(snapshot) if snapshot.cause == SnapshotCause::Query => {
                Some(snapshot.clone())
            }
            _ => None,
        })
    }

    /// One `Query`: the model frame `pick` takes from the replies (before the `Health`), and
    /// the health counters, settled; a `Nak` is the device's refusal.
    fn query_with<M>(
        &mut self,
        what: &'static str,
        pick: impl Fn(&DeviceMsg) -> Option<M>,
    ) -> Result<(Option<M>, Health), LinkError> {
        let mut model = None;
        let port = self.port.clone();
        let health = self.command(&HostMsg::Query, what, |reply| match reply {
            DeviceMsg::Health { .. } => Health::of(reply).map(Ok),
            DeviceMsg::Nak {
                seq: CONTROL_SEQ,
                reason,
            } => Some(Err(LinkError::Refused {
                port: port.clone(),
                command: "the query",
                reason: *reason,
            })),
            other => {
                if let Some(m) = pick(other) {
                    model = Some(m);
                }
                None
            }
        })?;
        self.settle(&health)?;
        Ok((model, health))
    }

    /// Settles the counters the device's health report at the end of a stream gives.
    fn settle(&mut self, health: &Health) -> Result<(), LinkError> {
        let counted = health.samples + health.rejected;
        if counted > self.stats.samples {
            return Err(LinkError::Overcount {
                port: self.port.clone(),
                sent: self.stats.samples,
                counted,
            });
        }
        self.stats.samples_lost = self.stats.samples - counted;
        self.stats.crc_errors = u64::from(health.crc_errors) + self.stats.rx_crc_errors;
        self.stats.line_error_rate = self.stats.line_error_rate_of(health);
        self.stats.duplicates = u64::from(health.duplicates);
        self.stats.drift = health.drift;
        Ok(())
    }

    /// Writes the link counters to the telemetry log as the session's summary.
    pub fn log_summary(&mut self) -> Result<(), LinkError> {
        let summary = serde_json::to_vec(&self.stats).unwrap_or_default();
        self.log_record(RecordKind::Summary, now_us(), &summary)
    }
}
