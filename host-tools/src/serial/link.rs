//! The host end of the serial link: handshake, configuration, sliding-window sample delivery
//! with retransmission, and the final query.
//!
//! The device's side of the contract is `lssi-device`'s (its crate docs have the table): one
//! reply per command, batches numbered from 0 after `Configure`, applied exactly once in `seq`
//! order, a duplicate acked again without being applied, a gap answered with
//! `Nak { seq: next expected, OutOfOrder }`, a corrupt frame answered with nothing.
//!
//! The host keeps up to [`LinkOptions::window`] batches unacknowledged (go-back-N):
//!
//! - an `Ack { seq }` acknowledges every batch up to `seq` (the device applies in order);
//! - a `Nak { seq: s, OutOfOrder | Decode }` says everything before `s` was applied and `s`
//!   was not: the host resends every unacknowledged batch from `s`. The batches already on
//!   the wire behind the lost one will each be naked with the same `s` before the resent
//!   ones arrive (the link is FIFO); that many naks of `s` are expected and ignored, so one
//!   loss costs one resend of the window, not one per batch in flight;
//! - no reply for [`LinkOptions::timeout`] resends every unacknowledged batch (the line
//!   dropped the last frames or their acks); the timeout doubles while nothing comes back
//!   and the link gives up after [`LinkOptions::silence`] without a single frame.
//!
//! Every frame the device sends is appended to the telemetry log as it arrives, before it is
//! acted on. A reader thread splits the incoming bytes into frames; the calling thread writes
//! and decides.

use std::collections::VecDeque;
use std::fmt;
use std::io::{self, Read, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use lssi_proto::{
    CONTROL_SEQ, Channels, DeviceMsg, HostMsg, MAX_DEVICE_FRAME_LEN, MAX_FRAME_LEN, ModelSnapshot,
    NakReason, PROTOCOL_VERSION, SampleBatch, SnapshotCause, WireConfig, WireSample, decode_frame,
    encode, snapshot_from_parts,
};

use crate::serial::adapt::Adapt;
use crate::telemetry::{RecordKind, TelemetryLog, now_us};

/// How the link paces itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkOptions {
    /// The line's baud rate (8N1: 10 bit times a byte), used to size the timeouts.
    pub baud: u32,
    /// Most batches unacknowledged at once.
    pub window: usize,
    /// Most samples per batch (the device's `max_batch` lowers it further).
    pub batch: usize,
    /// The shortest wait for a reply before resending (it grows with the window's line time).
    pub timeout: Duration,
    /// How long the device may send nothing at all before the link gives up.
    pub silence: Duration,
    /// How long the link goes on without progress (no sample acknowledged, no request
    /// answered) before it gives up, saying what it measured.
    pub deadline: Duration,
}

impl LinkOptions {
    /// Defaults for a line at `baud`: a window of 8 full batches.
    pub fn for_baud(baud: u32) -> Self {
        Self {
            baud,
            window: 8,
            batch: lssi_proto::MAX_BATCH,
            timeout: Duration::from_millis(200),
            silence: Duration::from_secs(10),
            deadline: Duration::from_secs(60),
        }
    }

    /// Time the line takes to carry `bytes`.
    pub fn line_time(&self, bytes: usize) -> Duration {
        Duration::from_secs_f64(bytes as f64 * 10.0 / f64::from(self.baud.max(1)))
    }
}

/// The link's counters (the `"link"` object of `lssi replay --json`, with extras).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct LinkStats {
    /// Frames written to the device, retransmissions and commands included.
    pub frames_sent: u64,
    /// Sample-batch frames written again (after a nak or a timeout).
    pub retransmits: u64,
    /// Frames dropped for a bad CRC or COBS: by the device (its health counter) plus those the
    /// host received.
    pub crc_errors: u64,
    /// Samples sent but not applied by the device (its count against the recording's); 0 on a
    /// sound link.
    pub samples_lost: u64,
    /// Frames received from the device that failed their check.
    pub rx_crc_errors: u64,
    /// Waits that ended without a reply and caused a resend.
    pub timeouts: u64,
    /// Times the batches in flight were cut shorter after losses (the device asked where it
    /// was first).
    pub rechunks: u64,
    /// Batches the device received again after applying them (its health counter).
    pub duplicates: u64,
    /// Bytes written to the device.
    pub bytes_sent: u64,
    /// Bytes of the sample-batch frames, first transmissions only: the wire cost of the
    /// samples themselves.
    pub sample_bytes: u64,
    /// Samples in the recording.
    pub samples: u64,
    /// Samples sent so far (first transmissions).
    pub samples_sent: u64,
    /// Samples the device acknowledged.
    pub samples_acked: u64,
    /// Seconds from the first batch to the last acknowledgement.
    pub stream_seconds: f64,
    /// Times the link went back and resent the batches in flight (after a nak or a timeout).
    pub go_backs: u64,
    /// The byte error rate those losses imply, recently (what the batch length follows).
    pub byte_error_rate: f64,
    /// The batch length and window in use at the end.
    pub batch_len: usize,
    /// The window in use at the end.
    pub window: usize,
    /// Requests (commands, queries, model parts) sent again after a timeout.
    pub requests_resent: u64,
    /// Parts of the model fetched because a whole Model frame did not cross.
    pub model_parts: u64,
    /// The smoothed round trip of a batch, in milliseconds (what the waits follow).
    pub round_trip_ms: f64,
}

impl LinkStats {
    /// Wire bytes per sample (the sample frames' bytes over the samples).
    pub fn bytes_per_sample(&self) -> f64 {
        if self.samples_sent > 0 {
            self.sample_bytes as f64 / self.samples_sent as f64
        } else {
            0.0
        }
    }

    /// The most samples per second a line at `baud` (8N1) can carry at these bytes per sample.
    pub fn bound(&self, baud: u32) -> f64 {
        let per_sample = self.bytes_per_sample();
        if per_sample > 0.0 {
            f64::from(baud) / 10.0 / per_sample
        } else {
            0.0
        }
    }

    /// Samples per second delivered while streaming.
    pub fn samples_per_second(&self) -> f64 {
        if self.stream_seconds > 0.0 {
            self.samples_acked as f64 / self.stream_seconds
        } else {
            0.0
        }
    }
}

/// What the device said it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Library capacity.
    pub max_terms: u8,
    /// Largest derivative window.
    pub window_capacity: u16,
    /// Most samples per batch.
    pub max_batch: u16,
}

/// The device's health counters, as its last `Health` frame reported them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Health {
    /// Samples the identifier accepted.
    pub samples: u64,
    /// Samples it rejected.
    pub rejected: u64,
    /// Frames the device dropped for CRC, COBS or overrun.
    pub crc_errors: u32,
    /// Batches it received again after applying them.
    pub duplicates: u32,
    /// Frames it received that decoded.
    pub frames_ok: u32,
    /// Screenings it has run.
    pub screenings: u32,
}

/// Why the link failed; each displays as one sentence naming the port.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// The port closed or failed under us (the device or its simulator went away).
    #[error(
        "{port}: the link closed{} after the device had acknowledged {acked} samples; \
         the device (or its simulator) went away",
        parenthesized(.detail)
    )]
    Closed {
        /// The port.
        port: String,
        /// What the operating system said, if anything.
        detail: String,
        /// Samples the device had acknowledged by then.
        acked: u64,
    },
    /// The device sent nothing for too long.
    #[error(
        "{port}: the device sent nothing for {:.1} s while the host waited for {waiting_for}; \
         is it running the lssi firmware at this baud rate?",
        .waited.as_secs_f64()
    )]
    Silent {
        /// The port.
        port: String,
        /// What the host was waiting for.
        waiting_for: &'static str,
        /// How long it waited.
        waited: Duration,
    },
    /// The device refused a command.
    #[error("{port}: the device refused {command} ({})", nak_text(*.reason))]
    Refused {
        /// The port.
        port: String,
        /// The command.
        command: &'static str,
        /// The device's reason.
        reason: NakReason,
    },
    /// The device speaks another protocol version.
    #[error(
        "{port}: the device speaks lssi protocol version {theirs}, but this build speaks \
         version {}; flash a matching firmware",
        PROTOCOL_VERSION
    )]
    Version {
        /// The port.
        port: String,
        /// The device's version.
        theirs: u16,
    },
    /// The device applied more samples than were sent: it broke the exactly-once contract.
    #[error(
        "{port}: the device counted {counted} samples but {sent} were sent, so it applied \
         some twice"
    )]
    Overcount {
        /// The port.
        port: String,
        /// Samples sent.
        sent: u64,
        /// Samples the device counted.
        counted: u64,
    },
    /// No progress for the whole deadline: the line is too poor (or the device too slow).
    #[error(
        "{port}: no progress for {:.1} s while the host waited for {waiting_for}, so it gives up: {:.1} % of the frames it sent were lost (a byte error rate of about {:.2} %); the device had acknowledged {acked} of {samples} samples, and `lssi replay --resume --port {port}` continues from there",
        .waited.as_secs_f64(),
        100.0 * .frame_loss,
        100.0 * .byte_error_rate
    )]
    Deadline {
        /// The port.
        port: String,
        /// What the host was waiting for.
        waiting_for: &'static str,
        /// How long it went on without progress.
        waited: Duration,
        /// Fraction of the frames sent that were lost.
        frame_loss: f64,
        /// The byte error rate that implies.
        byte_error_rate: f64,
        /// Samples the device had acknowledged: the next replay with `--resume` starts there.
        acked: u64,
        /// Samples in the recording.
        samples: u64,
    },
    /// The telemetry log could not be written.
    #[error("{}: cannot append to the telemetry log: {source}", .path.display())]
    Log {
        /// The log file.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
}

/// ` (detail)`, or nothing for no detail.
fn parenthesized(detail: &str) -> String {
    if detail.is_empty() {
        String::new()
    } else {
        format!(" ({detail})")
    }
}

/// A nak reason as words.
pub fn nak_text(reason: NakReason) -> String {
    if let NakReason::TooManyTerms { terms, capacity } = reason {
        return format!(
            "its library holds at most {capacity} terms, and the configuration asks for {terms}"
        );
    }
    match reason {
        NakReason::Crc => "a frame failed its CRC",
        NakReason::Decode => "a frame did not decode",
        NakReason::Overflow => "a frame overran the receive buffer",
        NakReason::OutOfOrder => "a batch arrived out of order",
        NakReason::NotConfigured => "it has no configuration",
        NakReason::BadConfig => {
            "it cannot run this configuration: it does not fit its capacities or is out of range"
        }
        NakReason::Busy => "it is busy",
        NakReason::VersionMismatch => "it speaks another protocol version",
        NakReason::TooManyTerms { .. } => "its library is too small for the configuration",
    }
    .to_owned()
}

/// What the link tells the person watching, as it happens.
pub trait Observer {
    /// Samples were acknowledged (or resent): the counters so far.
    fn progress(&mut self, _stats: &LinkStats) {}
    /// The device sent defmt log bytes.
    fn device_log(&mut self, _bytes: &[u8]) {}
    /// The device sent a model snapshot.
    fn model(&mut self, _snapshot: &ModelSnapshot) {}
}

/// An observer that shows nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quiet;

impl Observer for Quiet {}

/// What the reader thread hands over.
#[derive(Debug)]
enum Incoming {
    /// One frame's bytes (COBS, no delimiter) and when it ended.
    Frame(Vec<u8>, u64),
    /// A frame longer than any device frame (its start), dropped.
    Overlong(Vec<u8>, u64),
    /// The port closed (end of file or an error).
    Closed(String),
    /// Raw defmt bytes from outside the link (QEMU's semihosting output).
    Defmt(Vec<u8>, u64),
}

/// Reads the port on its own thread and splits the bytes into frames.
#[derive(Debug)]
struct Reader {
    rx: Receiver<Incoming>,
    tx: mpsc::Sender<Incoming>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Reader {
    fn spawn(mut port: Box<dyn Read + Send>) -> Self {
        let (tx, rx) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = Arc::clone(&stop);
        let sender = tx.clone();
        let thread = std::thread::spawn(move || {
            let tx = sender;
            let mut buffer = [0u8; 4096];
            let mut frame = Vec::with_capacity(MAX_DEVICE_FRAME_LEN);
            let mut overlong = false;
            while !stopped.load(Ordering::Relaxed) {
                let n = match port.read(&mut buffer) {
                    Ok(0) => {
                        let _ = tx.send(Incoming::Closed("end of file".into()));
                        return;
                    }
                    Ok(n) => n,
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::TimedOut
                                | io::ErrorKind::WouldBlock
                                | io::ErrorKind::Interrupted
                        ) =>
                    {
                        continue;
                    }
                    Err(e) => {
                        let _ = tx.send(Incoming::Closed(e.to_string()));
                        return;
                    }
                };
                for &byte in &buffer[..n] {
                    if byte == 0 {
                        let bytes = std::mem::take(&mut frame);
                        let message = if std::mem::take(&mut overlong) {
                            Incoming::Overlong(bytes, now_us())
                        } else if bytes.is_empty() {
                            continue;
                        } else {
                            Incoming::Frame(bytes, now_us())
                        };
                        if tx.send(message).is_err() {
                            return;
                        }
                    } else if frame.len() < MAX_DEVICE_FRAME_LEN {
                        frame.push(byte);
                    } else {
                        overlong = true;
                    }
                }
            }
        });
        Self {
            rx,
            tx,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for Reader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // The thread wakes at the port's read timeout; a port without one (a test's pipe)
        // ends with its writer, so do not wait for it here.
        if let Some(thread) = self.thread.take()
            && thread.is_finished()
        {
            let _ = thread.join();
        }
    }
}

/// One batch on the wire, kept until acknowledged.
#[derive(Debug)]
struct InFlight {
    seq: u32,
    frame: Vec<u8>,
    samples: usize,
    /// Index of its first sample in the stream.
    start: usize,
    /// When it was sent, and whether only once (Karn: only those time the round trip).
    sent: Instant,
    once: bool,
}

/// Where the samples of a stream come from: batches framed on demand.
pub trait BatchSource {
    /// Samples in the stream.
    fn len(&self) -> usize;
    /// Whether there are none.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Most samples in one batch.
    fn max_batch(&self) -> usize;
    /// Wire bytes a sample costs in a batch.
    fn bytes_per_sample(&self) -> usize;
    /// The frame of batch `seq` holding at most `max` samples from sample `from`, and how
    /// many it holds (at least one while `from` is a sample).
    fn frame(&self, seq: u32, from: usize, max: usize) -> (Vec<u8>, usize);
}

/// Samples sent as they are: t as f64, the channels as f32 ([`HostMsg::Samples`]).
#[derive(Clone, Copy, Debug)]
pub struct F32Samples<'a>(pub &'a [WireSample]);

impl BatchSource for F32Samples<'_> {
    fn len(&self) -> usize {
        self.0.len()
    }

    fn max_batch(&self) -> usize {
        lssi_proto::MAX_BATCH
    }

    fn bytes_per_sample(&self) -> usize {
        self.0
            .first()
            .map_or(Channels::X, Channels::of)
            .bytes_per_sample()
    }

    fn frame(&self, seq: u32, from: usize, max: usize) -> (Vec<u8>, usize) {
        let max = max.clamp(1, lssi_proto::MAX_BATCH);
        let chunk = self
            .0
            .get(from..(from + max).min(self.0.len()))
            .unwrap_or(&[]);
        (batch_frame(seq, chunk), chunk.len())
    }
}

/// The shortest wait before resending a batch, however fast the round trip measures.
const MIN_TIMEOUT: Duration = Duration::from_millis(4);

/// What a received frame means for the caller.
#[allow(
    clippy::large_enum_variant,
    reason = "one short-lived value per received frame; boxing buys nothing"
)]
enum Event {
    Message(DeviceMsg),
    Nothing,
}

/// An open link to a device.
pub struct Link<'a> {
    port: String,
    writer: Box<dyn Write + Send>,
    reader: Reader,
    log: &'a mut TelemetryLog,
    observer: &'a mut dyn Observer,
    options: LinkOptions,
    stats: LinkStats,
    last_heard: Instant,
    health: Option<Health>,
    started: Option<Instant>,
    /// Smoothed round trip of a batch (sent to acknowledged), once measured.
    srtt: Option<Duration>,
    /// Its mean deviation.
    rttvar: Duration,
    /// The error-rate estimate of the last stream.
    adapt: Option<Adapt>,
    /// When the link last made progress (a sample acknowledged, a request answered).
    progress: Instant,
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

    fn closed(&self, detail: impl Into<String>) -> LinkError {
        LinkError::Closed {
            port: self.port.clone(),
            detail: detail.into(),
            acked: self.stats.samples_acked,
        }
    }

    fn write_bytes(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
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

    fn send(&mut self, message: &HostMsg) -> Result<(), LinkError> {
        let mut frame = [0u8; MAX_FRAME_LEN];
        let len = encode(message, &mut frame).unwrap_or(0);
        self.write_bytes(&frame[..len])?;
        self.stats.frames_sent += 1;
        Ok(())
    }

    fn log_record(&mut self, kind: RecordKind, time_us: u64, data: &[u8]) -> Result<(), LinkError> {
        self.log
            .append_at(kind, time_us, data)
            .map_err(|source| LinkError::Log {
                path: self.log.path().to_path_buf(),
                source,
            })
    }

    /// Waits up to `wait` for the next frame; logs it and returns what it means.
    fn receive(&mut self, wait: Duration) -> Result<Option<Event>, LinkError> {
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
                            DeviceMsg::Health {
                                samples,
                                rejected,
                                crc_errors,
                                duplicates,
                                frames_ok,
                                screenings,
                                ..
                            } => {
                                self.health = Some(Health {
                                    samples: *samples,
                                    rejected: *rejected,
                                    crc_errors: *crc_errors,
                                    duplicates: *duplicates,
                                    frames_ok: *frames_ok,
                                    screenings: *screenings,
                                });
                            }
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
    fn command<R>(
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
    fn rto(&self) -> Duration {
        match self.srtt {
            // Jacobson's: the mean round trip and four times its mean deviation.
            Some(srtt) => {
                (srtt + 4 * self.rttvar).clamp(MIN_TIMEOUT, self.options.timeout.max(MIN_TIMEOUT))
            }
            None => self.options.timeout,
        }
    }

    /// Takes a round trip measured on a batch sent once (RFC 6298's smoothing).
    fn measured(&mut self, rtt: Duration) {
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
    fn deadline(&self, waiting_for: &'static str, waited: Duration) -> LinkError {
        let (frame_loss, byte_error_rate) = match &self.adapt {
            Some(adapt) => (adapt.frame_loss(), adapt.byte_error_rate()),
            None => (0.0, 0.0),
        };
        LinkError::Deadline {
            port: self.port.clone(),
            waiting_for,
            waited,
            frame_loss,
            byte_error_rate,
            acked: self.stats.samples_acked,
            samples: self.stats.samples,
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

    /// Streams `samples` in batches numbered from 0, every one applied exactly once.
    pub fn stream(&mut self, samples: &[WireSample]) -> Result<(), LinkError> {
        self.stream_from(&F32Samples(samples), 0, 0)
    }

    /// Streams the samples of `source` from sample `from` on, in batches numbered from
    /// `first_seq` (0 and 0 after `Configure`; where the device is, for `--resume`), every
    /// one applied exactly once.
    ///
    /// The batch length and the window follow the error rate measured on the way
    /// ([`Adapt`]): shorter batches and a smaller window when frames are lost, the longest
    /// and the full window when the line is clean. Waits follow the measured round trip.
    pub fn stream_from(
        &mut self,
        source: &dyn BatchSource,
        from: usize,
        first_seq: u32,
    ) -> Result<(), LinkError> {
        let max_batch = self.options.batch.clamp(1, source.max_batch());
        let max_window = self.options.window.max(1);
        let mut adapt = Adapt::new(source.bytes_per_sample(), max_batch, max_window);
        let (mut batch_len, mut window) = adapt.choose();
        self.stats.samples = source.len() as u64;
        self.stats.samples_acked = from as u64;
        self.stats.samples_sent = self.stats.samples_sent.max(from as u64);
        let mut next = first_seq as usize;
        let mut offset = from;
        let mut in_flight: VecDeque<InFlight> = VecDeque::with_capacity(max_window);
        // After a go-back to `s`, the batches that were behind the lost one are naked with `s`
        // once each before the resent ones arrive: that many naks of `s` say nothing new.
        let mut stale: Option<(u32, usize)> = None;
        let mut resend = false;
        let base_timeout = self.options.timeout.max(
            4 * self
                .options
                .line_time(max_window * lssi_proto::MAX_HOST_FRAME_LEN),
        );
        let mut backoff = 1u32;
        let mut last_progress = Instant::now();
        let started = Instant::now();
        self.started = Some(started);
        self.last_heard = started;
        self.progress = started;
        loop {
            if resend {
                resend = false;
                (batch_len, window) = adapt.choose();
                self.stats.go_backs += 1;
                // Frames longer than the line now carries are resent in shorter batches, from
                // the first sample the device has not applied (asked for: its Health counts
                // them), numbered on from the sequence number it expects there. Only then is
                // it safe: a batch whose ack was lost may have been applied.
                if in_flight.iter().any(|b| b.samples > 2 * batch_len)
                    && let Some((seq, start)) = self.resync(&mut in_flight)?
                {
                    in_flight.clear();
                    next = seq as usize;
                    offset = start;
                    stale = None;
                    last_progress = Instant::now();
                    backoff = 1;
                    self.stats.rechunks += 1;
                    continue;
                }
                // Go-back-N: every batch in flight again (at most the window now allows;
                // the rest follow as acks come).
                let now = Instant::now();
                for i in 0..in_flight.len() {
                    let frame = std::mem::take(&mut in_flight[i].frame);
                    let result = self.write_bytes(&frame);
                    in_flight[i].frame = frame;
                    in_flight[i].sent = now;
                    in_flight[i].once = false;
                    result?;
                    adapt.sent(in_flight[i].frame.len());
                    self.stats.frames_sent += 1;
                    self.stats.retransmits += 1;
                }
                self.observer.progress(&self.stats);
            }
            while in_flight.len() < window && offset < source.len() {
                let seq = next as u32;
                let (frame, taken) = source.frame(seq, offset, batch_len);
                if taken == 0 {
                    break;
                }
                self.write_bytes(&frame)?;
                adapt.sent(frame.len());
                self.stats.frames_sent += 1;
                // First sendings only: after a resync, the part of a batch sent before is
                // not counted again (its bytes pro rata).
                let end = (offset + taken) as u64;
                if end > self.stats.samples_sent {
                    let new = end - self.stats.samples_sent.max(offset as u64);
                    self.stats.sample_bytes += frame.len() as u64 * new / taken as u64;
                    self.stats.samples_sent = end;
                }
                in_flight.push_back(InFlight {
                    seq,
                    frame,
                    samples: taken,
                    start: offset,
                    sent: Instant::now(),
                    once: true,
                });
                offset += taken;
                next += 1;
            }
            if in_flight.is_empty() {
                break;
            }
            // The measured round trip, but never less than twice the line time of what is in
            // flight (the acks come behind it): a loaded host must not resend intact frames.
            let in_line: usize = in_flight.iter().map(|b| b.frame.len()).sum();
            let floor = 2 * self.options.line_time(in_line) + MIN_TIMEOUT;
            let timeout = (self.rto().max(floor).min(base_timeout) * backoff).min(4 * base_timeout);
            let wait = timeout.saturating_sub(last_progress.elapsed());
            let event = self.receive(wait)?;
            match event {
                Some(Event::Message(DeviceMsg::Ack { seq })) if seq != CONTROL_SEQ => {
                    let timed = in_flight
                        .iter()
                        .find(|b| b.seq == seq && b.once)
                        .map(|b| b.sent.elapsed());
                    let acked = self.acknowledge(&mut in_flight, seq);
                    if acked > 0 {
                        adapt.acked(acked);
                        if let Some(rtt) = timed {
                            self.measured(rtt);
                        }
                        last_progress = Instant::now();
                        self.progress = last_progress;
                        backoff = 1;
                        stale = None;
                        (batch_len, window) = adapt.choose();
                    }
                }
                Some(Event::Message(DeviceMsg::Nak { seq, reason })) if seq != CONTROL_SEQ => {
                    match reason {
                        NakReason::OutOfOrder | NakReason::Decode | NakReason::Crc => {
                            // Everything before `seq` was applied.
                            let acked = match seq {
                                0 => 0,
                                _ => self.acknowledge(&mut in_flight, seq - 1),
                            };
                            adapt.acked(acked);
                            if acked > 0 {
                                last_progress = Instant::now();
                                self.progress = last_progress;
                                backoff = 1;
                                stale = None;
                            }
                            let unsent = in_flight.front().is_none_or(|b| b.seq != seq);
                            match &mut stale {
                                _ if unsent => {}
                                Some((s, left)) if *s == seq && *left > 0 => *left -= 1,
                                _ => {
                                    let behind = in_flight.len().saturating_sub(1);
                                    stale = Some((seq, behind));
                                    resend = true;
                                    last_progress = Instant::now();
                                }
                            }
                        }
                        NakReason::Busy | NakReason::Overflow => {
                            std::thread::sleep(self.options.line_time(MAX_FRAME_LEN));
                            resend = true;
                            stale = Some((in_flight.front().map_or(0, |b| b.seq), in_flight.len()));
                            last_progress = Instant::now();
                        }
                        NakReason::NotConfigured
                        | NakReason::BadConfig
                        | NakReason::TooManyTerms { .. }
                        | NakReason::VersionMismatch => {
                            return Err(LinkError::Refused {
                                port: self.port.clone(),
                                command: "a sample batch",
                                reason,
                            });
                        }
                    }
                }
                Some(_) => {}
                None => {
                    if self.last_heard.elapsed() >= self.options.silence {
                        return Err(LinkError::Silent {
                            port: self.port.clone(),
                            waiting_for: "acknowledgements of sample batches",
                            waited: self.last_heard.elapsed(),
                        });
                    }
                    if self.progress.elapsed() >= self.options.deadline {
                        self.adapt = Some(adapt);
                        return Err(self.deadline(
                            "acknowledgements of sample batches",
                            self.progress.elapsed(),
                        ));
                    }
                    if last_progress.elapsed() >= timeout {
                        self.stats.timeouts += 1;
                        resend = true;
                        stale = Some((in_flight.front().map_or(0, |b| b.seq), in_flight.len()));
                        backoff = (backoff * 2).min(4);
                        last_progress = Instant::now();
                    }
                }
            }
            self.adapt = Some(adapt);
            self.stats.byte_error_rate = adapt.byte_error_rate();
            self.stats.batch_len = batch_len;
            self.stats.window = window;
        }
        self.stats.stream_seconds = started.elapsed().as_secs_f64();
        self.observer.progress(&self.stats);
        Ok(())
    }

    /// Where the device is: the samples it has applied (accepted or rejected, from its
    /// Health) and the sequence number it expects next (an empty batch numbered far ahead
    /// is naked `OutOfOrder` with it). What `lssi replay --resume` continues from.
    pub fn position(&mut self) -> Result<(u64, u32), LinkError> {
        let port = self.port.clone();
        let refused = |reason: NakReason| LinkError::Refused {
            port: port.clone(),
            command: "the query",
            reason,
        };
        let applied = self.command(
            &HostMsg::Query,
            "the device's sample count (a Query)",
            |reply| match reply {
                DeviceMsg::Health {
                    samples, rejected, ..
                } => Some(Ok(samples + rejected)),
                DeviceMsg::Nak {
                    seq: CONTROL_SEQ,
                    reason,
                } => Some(Err(refused(*reason))),
                _ => None,
            },
        )?;
        let probe = HostMsg::Samples(SampleBatch::new(CONTROL_SEQ - 1, Channels::X));
        let next = self.command(
            &probe,
            "the device's next sequence number",
            |reply| match *reply {
                DeviceMsg::Nak {
                    seq,
                    reason: NakReason::OutOfOrder,
                } => Some(Ok(seq)),
                DeviceMsg::Nak {
                    reason: NakReason::NotConfigured,
                    ..
                } => Some(Err(LinkError::Refused {
                    port: port.clone(),
                    command: "resuming (a sample batch)",
                    reason: NakReason::NotConfigured,
                })),
                _ => None,
            },
        )?;
        self.stats.samples_acked = applied;
        Ok((applied, next))
    }

    /// Where the device is in the stream: asks for its Health (a `Query`, resent until
    /// answered), whose sample count says how many samples it applied; drops the in-flight
    /// batches it applied and returns the sequence number and first sample of the first one
    /// it did not (`None`: the count falls inside no in-flight batch's start, so the
    /// batches are resent as they are).
    fn resync(
        &mut self,
        in_flight: &mut VecDeque<InFlight>,
    ) -> Result<Option<(u32, usize)>, LinkError> {
        let port = self.port.clone();
        let health = self.command(
            &HostMsg::Query,
            "the device's sample count (a Query)",
            |reply| match reply {
                DeviceMsg::Health {
                    samples, rejected, ..
                } => Some(Ok(samples + rejected)),
                DeviceMsg::Nak {
                    seq: CONTROL_SEQ,
                    reason,
                } => Some(Err(LinkError::Refused {
                    port: port.clone(),
                    command: "the query",
                    reason: *reason,
                })),
                _ => None,
            },
        )?;
        let applied = usize::try_from(health).unwrap_or(usize::MAX);
        let Some(pos) = in_flight.iter().position(|b| b.start == applied) else {
            return Ok(None);
        };
        let seq = in_flight[pos].seq;
        if seq > 0 {
            self.acknowledge(in_flight, seq - 1);
        }
        Ok(Some((seq, applied)))
    }

    /// Drops the batches up to `seq`; how many were dropped.
    fn acknowledge(&mut self, in_flight: &mut VecDeque<InFlight>, seq: u32) -> usize {
        let mut any = 0;
        while let Some(front) = in_flight.front() {
            if front.seq > seq {
                break;
            }
            self.stats.samples_acked += front.samples as u64;
            in_flight.pop_front();
            any += 1;
        }
        if any > 0 {
            if let Some(started) = self.started {
                self.stats.stream_seconds = started.elapsed().as_secs_f64();
            }
            self.observer.progress(&self.stats);
        }
        any
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
    fn model_in_parts(&mut self) -> Result<Option<ModelSnapshot>, LinkError> {
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

    fn query_once(&mut self) -> Result<(Option<ModelSnapshot>, Health), LinkError> {
        let mut model = None;
        let port = self.port.clone();
        let health = self.command(
            &HostMsg::Query,
            "the model (the answer to Query)",
            |reply| match reply {
                DeviceMsg::Model(snapshot) if snapshot.cause == SnapshotCause::Query => {
                    model = Some(snapshot.clone());
                    None
                }
                DeviceMsg::Health {
                    samples,
                    rejected,
                    crc_errors,
                    duplicates,
                    frames_ok,
                    screenings,
                    ..
                } => Some(Ok(Health {
                    samples: *samples,
                    rejected: *rejected,
                    crc_errors: *crc_errors,
                    duplicates: *duplicates,
                    frames_ok: *frames_ok,
                    screenings: *screenings,
                })),
                DeviceMsg::Nak {
                    seq: CONTROL_SEQ,
                    reason,
                } => Some(Err(LinkError::Refused {
                    port: port.clone(),
                    command: "the query",
                    reason: *reason,
                })),
                _ => None,
            },
        )?;
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
        self.stats.duplicates = u64::from(health.duplicates);
        Ok((model, health))
    }

    /// Writes the link counters to the telemetry log as the session's summary.
    pub fn log_summary(&mut self) -> Result<(), LinkError> {
        let summary = serde_json::to_vec(&self.stats).unwrap_or_default();
        self.log_record(RecordKind::Summary, now_us(), &summary)
    }
}

/// The frame of one batch of samples, numbered `seq`.
///
/// The samples must share their channels (a recording's do); at most
/// [`lssi_proto::MAX_BATCH`] of them.
pub fn batch_frame(seq: u32, samples: &[WireSample]) -> Vec<u8> {
    let channels = samples.first().map_or(Channels::X, Channels::of);
    let mut batch = SampleBatch::new(seq, channels);
    for sample in samples {
        // A recording's samples all have the same channels and a chunk fits a batch.
        let _ = batch.push(*sample);
    }
    let mut frame = vec![0u8; lssi_proto::MAX_HOST_FRAME_LEN];
    let len = encode(&HostMsg::Samples(batch), &mut frame).unwrap_or(0);
    frame.truncate(len);
    frame
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_frame_decodes_to_its_samples() {
        let samples: Vec<WireSample> = (0..5)
            .map(|i| WireSample {
                t: f64::from(i) * 0.002,
                x: i as f32,
                v: Some(0.5),
                u: None,
            })
            .collect();
        let mut frame = batch_frame(9, &samples);
        assert_eq!(frame.last(), Some(&0));
        let len = frame.len() - 1;
        match decode_frame::<HostMsg>(&mut frame[..len]).unwrap() {
            HostMsg::Samples(batch) => {
                assert_eq!(batch.seq, 9);
                assert_eq!(batch.iter().collect::<Vec<_>>(), samples);
            }
            other => panic!("not a batch: {other:?}"),
        }
    }
}
