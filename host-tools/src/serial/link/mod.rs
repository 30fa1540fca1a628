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

mod framing;
mod retries;
mod session;

use std::io;
use std::path::PathBuf;
use std::time::Duration;

use lssi_proto::{ModelSnapshot, NakReason, PROTOCOL_VERSION};

pub use framing::{BatchSource, F32Samples, SystemSamples, batch_frame};
pub use session::Link;

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
    /// The byte error rate those losses imply, recently (what the batch length follows): an
    /// overestimate under go-back-N, which also resends the intact frames behind a lost one.
    pub byte_error_rate: f64,
    /// The byte error rate of the line to the device, from the frames the device received
    /// damaged (its CRC/COBS counter against those it decoded, from its last health report):
    /// b = 1 − (1 − damaged / received)^(1 / mean frame length). What firmware-sim's
    /// `--flip-rate` plus `--drop-rate` (plus a burst per 4096 bytes with `--burst`) inject per
    /// byte. 0 before the device has reported its health.
    pub line_error_rate: f64,
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
    /// How the device's coefficients moved between its last two duty-cycle windows, from its
    /// last health report (protocol 7; `null` from a device the host feeds, which runs no
    /// duty cycle).
    pub drift: Option<lssi_proto::WireDrift>,
}

impl LinkStats {
    /// The byte error rate of the line to the device that `health` implies (see
    /// [`LinkStats::line_error_rate`]), with the frames and bytes sent so far.
    pub fn line_error_rate_of(&self, health: &Health) -> f64 {
        let damaged = f64::from(health.crc_errors);
        let received = damaged + f64::from(health.frames_ok);
        if received <= 0.0 || self.frames_sent == 0 || damaged <= 0.0 {
            return 0.0;
        }
        let mean_len = (self.bytes_sent as f64 / self.frames_sent as f64).max(1.0);
        let crossed = (1.0 - damaged / received).max(1e-12);
        1.0 - crossed.powf(1.0 / mean_len)
    }

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
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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
    /// Its duty cycle's drift (since protocol 7).
    pub drift: Option<lssi_proto::WireDrift>,
}

impl Health {
    /// The counters of a `Health` message (`None` for any other message).
    pub fn of(message: &lssi_proto::DeviceMsg) -> Option<Self> {
        match *message {
            lssi_proto::DeviceMsg::Health {
                samples,
                rejected,
                crc_errors,
                duplicates,
                frames_ok,
                screenings,
                drift,
                ..
            } => Some(Self {
                samples,
                rejected,
                crc_errors,
                duplicates,
                frames_ok,
                screenings,
                drift,
            }),
            _ => None,
        }
    }
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
    /// Before any sample was sent (waiting for the answer to `Hello`, `Configure` or a
    /// `Query`), it says so instead of a frame loss and a position nothing was measured for.
    #[error("{}", deadline_text(.port, .waiting_for, *.waited, *.frame_loss, *.byte_error_rate, *.acked, *.samples, *.sent))]
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
        /// Samples sent to the device by then (0: the stream had not begun).
        sent: u64,
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

/// The sentence of [`LinkError::Deadline`].
#[allow(clippy::too_many_arguments, reason = "the error's fields, one each")]
fn deadline_text(
    port: &str,
    waiting_for: &str,
    waited: Duration,
    frame_loss: f64,
    byte_error_rate: f64,
    acked: u64,
    samples: u64,
    sent: u64,
) -> String {
    let waited = waited.as_secs_f64();
    if sent == 0 {
        return format!(
            "{port}: the host waited {waited:.1} s for {waiting_for} and none came, so it gives up before sending a single sample (nothing was streamed); check that the device runs the lssi replay firmware at this baud rate, or give a slow one a longer --deadline, and run the same command again"
        );
    }
    format!(
        "{port}: no progress for {waited:.1} s while the host waited for {waiting_for}, so it gives up: {:.1} % of the frames it sent were lost (a byte error rate of about {:.2} %); the device had acknowledged {acked} of {samples} samples, and `lssi replay --resume --port {port}` continues from there",
        100.0 * frame_loss,
        100.0 * byte_error_rate
    )
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
