//! Device → host messages.

#[cfg(feature = "system")]
use crate::SystemSnapshot;
use crate::size::{max_of, vec_max_size};
use crate::{MAX_LOG, MAX_SOLUTIONS, MAX_TERMS, ModelPart};
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

/// A message from the device to the host.
///
/// The variant order is the wire discriminant (0..=7); see the README before changing it.
///
/// What the device sends when is `lssi-device`'s contract (see its crate docs): every
/// host command gets exactly one reply, except [`HostMsg::Query`](crate::HostMsg::Query),
/// answered by a [`DeviceMsg::Model`] (when a model exists) and then always a
/// [`DeviceMsg::Health`]; `Model` (scheduled) and `Log` also come unsolicited.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[allow(
    clippy::large_enum_variant,
    reason = "no allocator to box into: a message is one fixed-size value"
)]
pub enum DeviceMsg {
    /// Answers [`HostMsg::Hello`](crate::HostMsg::Hello) with the device's version and sizes.
    ///
    /// Frozen: this stays variant 0 with the version first in every protocol version.
    HelloReply {
        /// The device's [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).
        protocol_version: u16,
        /// Library capacity the firmware was built with.
        max_terms: u8,
        /// Ring-buffer capacity in samples (the largest derivative window it accepts).
        window_capacity: u16,
        /// Most samples per batch the device takes.
        max_batch: u16,
    },
    /// Batch `seq` was applied (or was a duplicate of one already applied); or, with
    /// `seq` = [`CONTROL_SEQ`](crate::CONTROL_SEQ), a `Configure` or `Reset` was carried out.
    Ack {
        /// Sequence number of the batch, or [`CONTROL_SEQ`](crate::CONTROL_SEQ).
        seq: u32,
    },
    /// A frame or command was refused; nothing it carried was applied.
    Nak {
        /// Depends on the reason: [`NakReason::OutOfOrder`] and [`NakReason::Decode`]: the
        /// sequence number the device expects next (resend from there);
        /// [`NakReason::NotConfigured`] for a batch: the batch's; a refused command
        /// (`Configure`, `Query`): [`CONTROL_SEQ`](crate::CONTROL_SEQ).
        seq: u32,
        /// Why.
        reason: NakReason,
    },
    /// The current model.
    Model(ModelSnapshot),
    /// Counters that tell whether the device keeps up.
    Health {
        /// Samples the identifier accepted since it was (re)built.
        samples: u64,
        /// Samples it rejected (non-finite, out of range, out of order in time, wrong channels).
        rejected: u64,
        /// Samples in the derivative window (the ring buffer's fill).
        buffer_fill: u16,
        /// Mean per-sample cost, in `cost_unit` (pushes that ran a screening excluded).
        cost_mean: u32,
        /// Largest per-sample cost, in `cost_unit` (pushes that ran a screening excluded).
        cost_max: u32,
        /// Unit of every cost field.
        cost_unit: CostUnit,
        /// A counter the device's main loop bumps every pass; stuck means hung.
        watchdog: u32,
        /// Received frames dropped for a bad CRC or COBS, or for overrunning the buffer.
        crc_errors: u32,
        /// Received frames that decoded.
        frames_ok: u32,
        /// Cost of the latest screening (threshold sweep + MES), in `cost_unit`.
        screen_cost: u32,
        /// Largest cost of a screening, in `cost_unit`.
        screen_cost_max: u32,
        /// Screenings run (scheduled and queried).
        screenings: u32,
        /// Sample batches received again after they were applied (acked, not re-applied).
        duplicates: u32,
        /// Frames that passed the CRC but did not decode (e.g. another protocol version).
        decode_errors: u32,
        /// Standalone device: samples the timer took that found the sample queue full (lost,
        /// counted). 0 when the host sends the samples.
        overruns: u32,
        /// Standalone device: the most samples the queue has held at once.
        queue_high_water: u16,
        /// Standalone device: the longest time from a sample's timer interrupt to its row
        /// done, in nanoseconds (saturating).
        latency_max_ns: u32,
        /// Standalone device: scheduled screenings left out because the previous one was
        /// still running on the snapshot (the model then skips one update).
        screenings_skipped: u32,
        /// Standalone device: the sampling rate in Hz (0 when the host sends the samples).
        sample_rate_hz: f32,
        /// Standalone device on a duty cycle: how the model's coefficients moved between its
        /// last two windows (`None` without a duty cycle, and before the first window's
        /// report). Since version 7.
        drift: Option<WireDrift>,
        /// Standalone device: the references it subtracts from its channels (each learnt
        /// from the channel's first rows, as `lssi identify` does; see [`WireReference`]):
        /// the latest `Model` or `SystemModel` is about the channels less these. `None`:
        /// nothing is subtracted (channels about zero, the first rows still to come, or a
        /// device the host feeds). Since version 9.
        reference: Option<WireReference>,
    },
    /// Raw defmt frames, decoded on the host with the firmware's ELF.
    Log {
        /// The bytes, in the order the firmware's defmt logger produced them.
        bytes: heapless::Vec<u8, MAX_LOG>,
    },
    /// Answers [`HostMsg::ModelPart`](crate::HostMsg::ModelPart). Since version 5.
    ModelPart(ModelPart),
    /// A system's current model (every equation), sent where a single equation's
    /// [`DeviceMsg::Model`] would be once a `ConfigureSystem` is in force. Since version 6.
    #[cfg(feature = "system")]
    SystemModel(SystemSnapshot),
}

impl MaxSize for DeviceMsg {
    // The discriminant (one byte below 128 variants), then the largest variant.
    const POSTCARD_MAX_SIZE: usize = 1 + max_of(&[
        u16::POSTCARD_MAX_SIZE + u8::POSTCARD_MAX_SIZE + 2 * u16::POSTCARD_MAX_SIZE,
        u32::POSTCARD_MAX_SIZE,
        u32::POSTCARD_MAX_SIZE + NakReason::POSTCARD_MAX_SIZE,
        ModelSnapshot::POSTCARD_MAX_SIZE,
        2 * u64::POSTCARD_MAX_SIZE
            + u16::POSTCARD_MAX_SIZE
            + 2 * u32::POSTCARD_MAX_SIZE
            + CostUnit::POSTCARD_MAX_SIZE
            + 8 * u32::POSTCARD_MAX_SIZE
            + 3 * u32::POSTCARD_MAX_SIZE
            + u16::POSTCARD_MAX_SIZE
            + f32::POSTCARD_MAX_SIZE
            + <Option<WireDrift>>::POSTCARD_MAX_SIZE
            + <Option<WireReference>>::POSTCARD_MAX_SIZE,
        vec_max_size::<u8>(MAX_LOG),
        ModelPart::POSTCARD_MAX_SIZE,
        #[cfg(feature = "system")]
        SystemSnapshot::POSTCARD_MAX_SIZE,
    ]);
}

/// How a duty-cycled device's model moved from one window to the next (in
/// [`DeviceMsg::Health`]): what a harvester that changes over weeks shows first. Since
/// version 7.
///
/// Per term, the relative change `|c − p| / |p|` of its coefficient from the previous
/// window's model `p` to this one's `c` (1 for a term that entered or left the model).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireDrift {
    /// Windows reported since the device was configured (the latest included).
    pub windows: u32,
    /// Root mean square of the terms' relative changes, over the terms in either model
    /// (0 after the first window, which has nothing to compare with).
    pub relative: f32,
    /// The largest relative change.
    pub largest: f32,
    /// The term that made it: its index in the model's library.
    pub largest_term: u8,
    /// Terms that entered or left the model.
    pub support_changes: u8,
}

/// The references a standalone device subtracts from its channels before they meet its f32
/// identifier (in [`DeviceMsg::Health`]): the mean of a channel's first 1,024 finite rows
/// when it lies far from zero (raw ADC counts, a sensor biased at mid-rail), else 0. The
/// device's model is about the channels less these; the readings are `model's channel +
/// reference`. In f64: a reference 10⁴ amplitudes from zero keeps every bit of the motion
/// (an f32 offset would not). Since version 9.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireReference {
    /// Subtracted from the displacement x.
    pub x: f64,
    /// Subtracted from the measured velocity v (0 without one).
    pub v: f64,
    /// Subtracted from the electrical channel (a system's V or I; 0 for one equation).
    pub e: f64,
}

/// Why the device refused a frame or a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NakReason {
    /// The frame failed its CRC or COBS check.
    Crc,
    /// The frame passed its CRC but did not decode.
    Decode,
    /// The frame was longer than the device's receive buffer.
    Overflow,
    /// The batch's `seq` is ahead of the one expected (one was lost); resend from the nak's `seq`.
    OutOfOrder,
    /// Samples or a query arrived before any valid configuration.
    NotConfigured,
    /// The configuration was refused (out of range, or beyond the firmware's capacities).
    BadConfig,
    /// The device cannot take the batch now; resend it later.
    Busy,
    /// The host's protocol version is not the device's.
    VersionMismatch,
    /// The configuration's library has more terms than the device holds (a `Configure`
    /// refused for its size; other refusals are [`NakReason::BadConfig`]).
    TooManyTerms {
        /// Terms the configuration asks for (saturating at 255).
        terms: u8,
        /// The most terms the device holds.
        capacity: u8,
    },
}

/// Unit of the per-sample cost in [`DeviceMsg::Health`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CostUnit {
    /// Instructions retired (QEMU's instruction counter).
    Instructions,
    /// CPU cycles (the Cortex-M DWT cycle counter).
    Cycles,
    /// Ticks of a device timer.
    Ticks,
    /// Nanoseconds of wall time (a host-side simulation).
    Nanoseconds,
}

/// What a library term is; see [`TermCode`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TermKind {
    /// The constant 1.
    Constant,
    /// x^a · v^b.
    Monomial,
    /// sin(a Ω t).
    Sin,
    /// cos(a Ω t).
    Cos,
    /// The measured excitation u.
    Input,
}

/// One library term, flat: a monomial's powers or a harmonic's number in `a` and `b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TermCode {
    /// What the term is.
    pub kind: TermKind,
    /// [`TermKind::Monomial`]: power of x. [`TermKind::Sin`]/[`TermKind::Cos`]: harmonic k.
    /// Otherwise 0.
    pub a: u8,
    /// [`TermKind::Monomial`]: power of v. Otherwise 0.
    pub b: u8,
}

/// One of the candidate solutions S_1..S_n of a threshold sweep.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SolutionSummary {
    /// Threshold on the scaled coefficients that produced it.
    pub threshold: f32,
    /// Its mean error on held-out samples (the paper's eq. 15).
    pub mean_error: f32,
    /// Bit i set: term i of [`ModelSnapshot::terms`] is in the solution.
    pub support: u32,
}

/// The identifier's current model: the library, the selected solution's coefficients and
/// every candidate with its mean error.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModelSnapshot {
    /// The library, in column order.
    pub terms: heapless::Vec<TermCode, MAX_TERMS>,
    /// Coefficients of the selected solution in physical units, one per term (0 if inactive).
    pub coefficients: heapless::Vec<f32, MAX_TERMS>,
    /// The candidate solutions of the last sweep.
    pub solutions: heapless::Vec<SolutionSummary, MAX_SOLUTIONS>,
    /// Index into `solutions` of the one MES selected.
    pub selected: u8,
    /// Neighbours K of the smoothing of x.
    pub k_x: u8,
    /// Neighbours K of the smoothing of v.
    pub k_v: u8,
    /// Base angular frequency Ω in rad/s, as configured.
    pub omega: f64,
    /// Linearised resonance in Hz, when the stiffness makes one (`Model::resonance_hz`).
    pub resonance_hz: Option<f64>,
    /// Position ± of the wells, when the model is bistable (`Model::wells`).
    pub wells: Option<f64>,
    /// Estimated sensor offset of x, removed before fitting.
    pub offset_x: f32,
    /// Estimated offset of v, removed before fitting.
    pub offset_v: f32,
    /// Samples the model has seen.
    pub samples: u64,
    /// Samples rejected.
    pub rejected: u64,
    /// Regression rows folded into the fit.
    pub rows: u64,
    /// Why the snapshot was sent.
    pub cause: SnapshotCause,
}

/// Why a [`ModelSnapshot`] was sent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SnapshotCause {
    /// The identifier's own screening, every `screening_period` samples (telemetry).
    #[default]
    Scheduled,
    /// The answer to a [`HostMsg::Query`](crate::HostMsg::Query).
    Query,
    /// A standalone device's last model: its sensor's recording ended (the QEMU stand-in)
    /// and every sample was screened, as `lssi identify` screens at the end of a file.
    Final,
}

impl MaxSize for ModelSnapshot {
    const POSTCARD_MAX_SIZE: usize = vec_max_size::<TermCode>(MAX_TERMS)
        + vec_max_size::<f32>(MAX_TERMS)
        + vec_max_size::<SolutionSummary>(MAX_SOLUTIONS)
        + u8::POSTCARD_MAX_SIZE // selected
        + u8::POSTCARD_MAX_SIZE // k_x
        + u8::POSTCARD_MAX_SIZE // k_v
        + f64::POSTCARD_MAX_SIZE // omega
        + 2 * <Option<f64>>::POSTCARD_MAX_SIZE // resonance_hz, wells
        + 2 * f32::POSTCARD_MAX_SIZE // offsets
        + 3 * u64::POSTCARD_MAX_SIZE // samples, rejected, rows
        + SnapshotCause::POSTCARD_MAX_SIZE;
}
