//! The lssi wire format: postcard messages in COBS frames with a CRC-32C.
//!
//! ```
//! use lssi_proto::{
//!     encode, Channels, DeviceMsg, HostFrameDecoder, HostMsg, SampleBatch, WireSample,
//!     MAX_HOST_FRAME_LEN,
//! };
//!
//! // Host: batch samples, frame them, write the bytes to the serial port.
//! let mut batch = SampleBatch::new(7, Channels::X);
//! batch.push(WireSample { t: 0.001, x: 1.5e-3, v: None, u: None }).unwrap();
//! let mut frame = [0u8; MAX_HOST_FRAME_LEN];
//! let len = encode(&HostMsg::Samples(batch.clone()), &mut frame).unwrap();
//!
//! // Device: feed whatever the UART delivered, in any chunks; get messages (or errors) back.
//! let mut decoder = HostFrameDecoder::new();
//! let mut received = None;
//! for chunk in frame[..len].chunks(5) {
//!     for result in decoder.feed::<HostMsg>(chunk) {
//!         received = Some(result);
//!     }
//! }
//! assert_eq!(received, Some(Ok(HostMsg::Samples(batch))));
//! # let _ = DeviceMsg::Ack { seq: 7 };
//! ```
//!
//! A frame is `COBS(postcard(message) ++ crc32c_le(postcard(message))) ++ 0x00`
//! (see the crate README for every message byte by byte). Nothing here allocates or panics
//! on received data: a bad frame is an [`Error`] value and the decoder carries on at the next
//! `0x00`.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(missing_docs)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo
    )
)]

mod batch;
mod compact;
mod device;
mod error;
mod frame;
mod host;
pub mod size;
#[cfg(feature = "system")]
mod system;

pub use batch::{BatchRef, BatchSamples, Channels, SampleBatch, Samples, WireSample};
pub use compact::{
    CompactBatch, CompactRef, I16Encoding, MAX_COMPACT_BATCH, MAX_COMPACT_BYTES, MODEL_PART_LEN,
    ModelPart, NOT_A_NUMBER, SampleEncoding, crc32c, model_part, snapshot_from_parts,
};
pub use device::{
    CostUnit, DeviceMsg, ModelSnapshot, NakReason, SnapshotCause, SolutionSummary, TermCode,
    TermKind, WireDrift, WireReference,
};
pub use error::Error;
#[cfg(feature = "std")]
pub use frame::write_frame;
pub use frame::{
    FrameDecoder, Frames, decode_frame, decode_host_frame, encode, encode_device, encode_host,
};
pub use host::{HostCommand, HostMsg, PolyFamily, WireChannels, WireConfig, WireDuty, WireLibrary};
/// postcard's worst-case size trait, implemented by every wire type.
pub use postcard::experimental::max_size::MaxSize;
#[cfg(feature = "system")]
pub use system::{
    MAX_ELECTRICAL, MAX_EQUATIONS, MAX_SYSTEM_BATCH, StateTermCode, SystemBatch, SystemEquation,
    SystemSnapshot, SystemWireSample, WireElectrical, WireSystemConfig, WireTarget,
};

/// The protocol version, sent in [`HostMsg::Hello`] and [`DeviceMsg::HelloReply`].
///
/// Bump it for any change that alters the bytes of any message or the meaning of a field:
/// a new variant, a new or reordered field, a changed capacity (`MAX_*`), a changed CRC.
/// The one thing that never changes is how the version itself travels: variant 0 of both
/// message enums starts with `protocol_version`, so peers of any two versions can read each
/// other's version and [`decode_frame`] reports [`Error::VersionMismatch`] instead of garbage.
pub const PROTOCOL_VERSION: u16 = 9;

/// The `seq` of a [`DeviceMsg::Ack`] or [`DeviceMsg::Nak`] that answers a command
/// (`Configure`, `Reset`, `Query`) rather than a sample batch. Batches are numbered from 0
/// after every `Configure` and `Reset` and never reach it.
pub const CONTROL_SEQ: u32 = u32::MAX;

/// Most samples in one [`SampleBatch`].
///
/// 24 keeps the largest host frame (24 samples with x, v and u) at 495 bytes, under 512,
/// so a device can receive into a 512-byte buffer; see [`MAX_HOST_FRAME_LEN`].
pub const MAX_BATCH: usize = 24;
/// Most library terms in a [`ModelSnapshot`] (also the width limit of
/// [`SolutionSummary::support`], 32).
pub const MAX_TERMS: usize = 24;
/// Most candidate solutions S_1..S_n in a [`ModelSnapshot`].
pub const MAX_SOLUTIONS: usize = 32;
/// Most raw defmt bytes in one [`DeviceMsg::Log`].
pub const MAX_LOG: usize = 96;

/// Bytes of CRC-32C appended to every payload before COBS, little-endian.
pub const CRC_LEN: usize = 4;

/// Longest host → device frame, trailing `0x00` included: the buffer size
/// [`encode`] needs for any [`HostMsg`] and a [`FrameDecoder`] needs to accept it.
pub const MAX_HOST_FRAME_LEN: usize = size::frame_len(HostMsg::POSTCARD_MAX_SIZE);
/// Longest device → host frame, trailing `0x00` included (a full [`ModelSnapshot`]).
pub const MAX_DEVICE_FRAME_LEN: usize = size::frame_len(DeviceMsg::POSTCARD_MAX_SIZE);
/// Longest frame in either direction.
pub const MAX_FRAME_LEN: usize = size::max(MAX_HOST_FRAME_LEN, MAX_DEVICE_FRAME_LEN);

/// The decoder a device runs on its receive line: accepts every [`HostMsg`].
pub type HostFrameDecoder = FrameDecoder<MAX_HOST_FRAME_LEN>;
/// The decoder a host runs on its receive line: accepts every [`DeviceMsg`].
pub type DeviceFrameDecoder = FrameDecoder<MAX_DEVICE_FRAME_LEN>;

// The promises the constants' docs make, checked at compile time.
const _: () = assert!(MAX_HOST_FRAME_LEN <= 512);
const _: () = assert!(MAX_TERMS <= 32);
const _: () = assert!(MAX_BATCH <= u16::MAX as usize);

/// A message that travels in a frame: [`HostMsg`] or [`DeviceMsg`].
///
/// Sealed: the framing relies on both enums keeping the handshake as variant 0 with the
/// protocol version as its first field.
pub trait Message:
    serde::Serialize + serde::de::DeserializeOwned + MaxSize + sealed::Sealed
{
    /// Longest frame of this message type, trailing `0x00` included.
    const MAX_FRAME_LEN: usize;
}

impl Message for HostMsg {
    const MAX_FRAME_LEN: usize = MAX_HOST_FRAME_LEN;
}

impl Message for DeviceMsg {
    const MAX_FRAME_LEN: usize = MAX_DEVICE_FRAME_LEN;
}

// The README's examples compile and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::HostMsg {}
    impl Sealed for super::DeviceMsg {}
}
