//! Framing: `COBS(postcard(message) ++ crc32c_le) ++ 0x00`, and a streaming decoder for it.
//!
//! ```
//! use lssi_proto::{encode, DeviceFrameDecoder, DeviceMsg, Error, MAX_DEVICE_FRAME_LEN};
//!
//! let mut wire = [0u8; 2 * MAX_DEVICE_FRAME_LEN];
//! let first = encode(&DeviceMsg::Ack { seq: 1 }, &mut wire).unwrap();
//! let second = encode(&DeviceMsg::Ack { seq: 2 }, &mut wire[first..]).unwrap();
//! wire[1] ^= 0x04; // a bit flip on the line
//!
//! let mut decoder = DeviceFrameDecoder::new();
//! let mut frames = decoder.feed::<DeviceMsg>(&wire[..first + second]);
//! assert_eq!(frames.next(), Some(Err(Error::Crc)));
//! assert_eq!(frames.next(), Some(Ok(DeviceMsg::Ack { seq: 2 })));
//! assert_eq!(frames.next(), None);
//! ```

use crate::batch::BatchHeader;
use crate::compact::CompactRef;
use crate::{
    BatchRef, CRC_LEN, DeviceMsg, Error, HostCommand, HostMsg, Message, PROTOCOL_VERSION,
    WireConfig,
};
#[cfg(feature = "system")]
use crate::{SystemBatch, WireSystemConfig};
use core::marker::PhantomData;
use crc::{CRC_32_ISCSI, Crc};
use postcard::ser_flavors::crc::CrcModifier;
use postcard::ser_flavors::{Cobs, Slice};
use serde::Deserialize;

/// CRC-32C (Castagnoli; the iSCSI parameters), table-driven: 1 KiB of flash.
pub(crate) static CRC32C: Crc<u32> = Crc::<u32>::new(&CRC_32_ISCSI);

/// Frames `message` into `out`; returns the frame's length, trailing `0x00` included.
///
/// An `out` of `T::MAX_FRAME_LEN` bytes ([`Message::MAX_FRAME_LEN`]) always suffices.
/// One pass, no scratch buffer: postcard's CRC flavour feeds its COBS flavour.
pub fn encode<T: Message>(message: &T, out: &mut [u8]) -> Result<usize, Error> {
    let cobs = Cobs::try_new(Slice::new(out)).map_err(encode_error)?;
    let flavor = CrcModifier::new(cobs, CRC32C.digest());
    postcard::serialize_with_flavor(message, flavor)
        .map(|frame: &mut [u8]| frame.len())
        .map_err(encode_error)
}

/// [`encode`] for a [`HostMsg`].
pub fn encode_host(message: &HostMsg, out: &mut [u8]) -> Result<usize, Error> {
    encode(message, out)
}

/// [`encode`] for a [`DeviceMsg`].
pub fn encode_device(message: &DeviceMsg, out: &mut [u8]) -> Result<usize, Error> {
    encode(message, out)
}

fn encode_error(error: postcard::Error) -> Error {
    match error {
        postcard::Error::SerializeBufferFull => Error::BufferTooSmall,
        _ => Error::Encode,
    }
}

/// Frames `message` and writes it to `writer` (host side).
#[cfg(feature = "std")]
pub fn write_frame<T: Message, W: std::io::Write>(
    writer: &mut W,
    message: &T,
) -> std::io::Result<usize> {
    let mut frame = [0u8; crate::MAX_FRAME_LEN];
    let len = encode(message, &mut frame)?;
    let bytes = frame.get(..len).ok_or(Error::BufferTooSmall)?;
    writer.write_all(bytes)?;
    Ok(len)
}

/// Decodes one frame in place: its COBS bytes, with or without the trailing `0x00`.
///
/// Checks, in order: the COBS stuffing, the CRC-32C, the handshake's protocol version (a
/// variant-0 message whose version is not [`PROTOCOL_VERSION`] is
/// [`Error::VersionMismatch`], whatever follows it), then postcard, which must consume the
/// payload exactly. `frame` is left holding the decoded bytes.
pub fn decode_frame<T: Message>(frame: &mut [u8]) -> Result<T, Error> {
    let payload = checked_payload(frame)?;
    match postcard::take_from_bytes::<T>(payload) {
        Ok((message, [])) => Ok(message),
        _ => Err(Error::Decode),
    }
}

/// [`decode_frame`] for a [`HostMsg`], in place: the same checks, the same errors, but a
/// sample batch's samples are not copied out of `frame` ([`HostCommand::Samples`] reads them
/// from its bytes), so the result is a few dozen bytes instead of a whole [`HostMsg`].
///
/// For every input, `decode_host_frame` succeeds exactly when `decode_frame::<HostMsg>`
/// does, with the same message.
pub fn decode_host_frame(frame: &mut [u8]) -> Result<HostCommand<'_>, Error> {
    let payload = checked_payload(frame)?;
    let Ok((shape, [])) = postcard::take_from_bytes::<HostShape>(payload) else {
        return Err(Error::Decode);
    };
    Ok(match shape {
        HostShape::Hello { protocol_version } => HostCommand::Hello { protocol_version },
        HostShape::Configure(config) => HostCommand::Configure(config),
        HostShape::Samples(header) => {
            // The samples end the payload (postcard consumed it exactly) and have a fixed
            // width, so they are its last `len · bytes_per_sample` bytes.
            let samples = header
                .len
                .checked_mul(header.channels.bytes_per_sample())
                .and_then(|n| payload.len().checked_sub(n))
                .and_then(|start| payload.get(start..))
                .ok_or(Error::Decode)?;
            HostCommand::Samples(BatchRef::new(header.seq, header.channels, samples))
        }
        HostShape::Query => HostCommand::Query,
        HostShape::Reset => HostCommand::Reset,
        HostShape::Compact(batch) if batch.is_well_formed() => HostCommand::Compact(batch),
        HostShape::Compact(_) => return Err(Error::Decode),
        HostShape::ModelPart { offset } => HostCommand::ModelPart { offset },
        #[cfg(feature = "system")]
        HostShape::ConfigureSystem(config) => HostCommand::ConfigureSystem(config),
        #[cfg(feature = "system")]
        HostShape::SystemSamples(batch) => HostCommand::SystemSamples(batch),
    })
}

/// The checks both decoders share; returns the postcard payload (CRC stripped).
fn checked_payload(frame: &mut [u8]) -> Result<&[u8], Error> {
    let len = cobs::decode_in_place(frame).map_err(|_| Error::Cobs)?;
    let decoded = frame.get(..len).ok_or(Error::Cobs)?;
    let split = decoded.len().checked_sub(CRC_LEN).ok_or(Error::Crc)?;
    let (payload, crc) = decoded.split_at_checked(split).ok_or(Error::Crc)?;
    let crc: [u8; CRC_LEN] = crc.try_into().map_err(|_| Error::Crc)?;
    if CRC32C.checksum(payload) != u32::from_le_bytes(crc) {
        return Err(Error::Crc);
    }
    if let Some((&0, rest)) = payload.split_first()
        && let Ok((theirs, _)) = postcard::take_from_bytes::<u16>(rest)
        && theirs != PROTOCOL_VERSION
    {
        return Err(Error::VersionMismatch {
            ours: PROTOCOL_VERSION,
            theirs,
        });
    }
    Ok(payload)
}

/// [`HostMsg`]'s wire shape with a batch's samples checked and counted, not stored: the
/// same variants in the same order, so postcard accepts exactly what it accepts for
/// [`HostMsg`].
#[derive(Deserialize)]
#[allow(
    clippy::large_enum_variant,
    reason = "a system batch is copied out of the frame (12 samples, 0.6 KiB), once a frame"
)]
enum HostShape<'a> {
    Hello {
        protocol_version: u16,
    },
    Configure(WireConfig),
    Samples(BatchHeader),
    Query,
    Reset,
    #[serde(borrow)]
    Compact(CompactRef<'a>),
    ModelPart {
        offset: u16,
    },
    #[cfg(feature = "system")]
    ConfigureSystem(WireSystemConfig),
    #[cfg(feature = "system")]
    SystemSamples(SystemBatch),
}

/// Reassembles frames from a byte stream cut into any chunks, with an `N`-byte buffer.
///
/// Bytes accumulate up to each `0x00`; the frame is then decoded with [`decode_frame`].
/// Empty frames (`0x00 0x00`) are skipped, so a sender may lead with `0x00` to flush a
/// half-received frame. A frame longer than `N` is reported once as [`Error::Overflow`] and
/// its remaining bytes are skipped up to the next `0x00`. No input can make it panic.
///
/// `N` = [`Message::MAX_FRAME_LEN`] accepts every message of that type; see
/// [`HostFrameDecoder`](crate::HostFrameDecoder) and
/// [`DeviceFrameDecoder`](crate::DeviceFrameDecoder).
#[derive(Clone, Debug)]
pub struct FrameDecoder<const N: usize> {
    buffer: [u8; N],
    len: usize,
    skipping: bool,
}

impl<const N: usize> Default for FrameDecoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameDecoder<N> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buffer: [0; N],
            len: 0,
            skipping: false,
        }
    }

    /// Takes one byte; at a frame's end returns the message or why the frame was dropped.
    pub fn push<T: Message>(&mut self, byte: u8) -> Option<Result<T, Error>> {
        if byte == 0 {
            let len = core::mem::replace(&mut self.len, 0);
            if core::mem::replace(&mut self.skipping, false) || len == 0 {
                return None;
            }
            let frame = self.buffer.get_mut(..len)?;
            return Some(decode_frame(frame));
        }
        if self.skipping {
            return None;
        }
        if let Some(slot) = self.buffer.get_mut(self.len) {
            *slot = byte;
            self.len += 1;
            None
        } else {
            self.len = 0;
            self.skipping = true;
            Some(Err(Error::Overflow))
        }
    }

    /// Takes a chunk of bytes; the iterator yields one result per frame that ends in it.
    ///
    /// Bytes are consumed as the iterator advances: run it to the end (or hand
    /// [`Frames::remaining`] back to `feed` later) or they are not seen.
    pub fn feed<'d, 'b, T: Message>(&'d mut self, bytes: &'b [u8]) -> Frames<'d, 'b, T, N> {
        Frames {
            decoder: self,
            bytes,
            message: PhantomData,
        }
    }

    /// Drops a partly received frame.
    pub fn reset(&mut self) {
        self.len = 0;
        self.skipping = false;
    }

    /// Bytes of the current, unfinished frame held (0 while skipping an overlong one).
    pub fn buffered(&self) -> usize {
        self.len
    }
}

/// The results of [`FrameDecoder::feed`], one per frame that ends in the chunk.
#[derive(Debug)]
pub struct Frames<'d, 'b, T, const N: usize> {
    decoder: &'d mut FrameDecoder<N>,
    bytes: &'b [u8],
    message: PhantomData<fn() -> T>,
}

impl<'b, T, const N: usize> Frames<'_, 'b, T, N> {
    /// The bytes of the chunk not consumed yet.
    pub fn remaining(&self) -> &'b [u8] {
        self.bytes
    }
}

impl<T: Message, const N: usize> Iterator for Frames<'_, '_, T, N> {
    type Item = Result<T, Error>;

    fn next(&mut self) -> Option<Result<T, Error>> {
        while let Some((&byte, rest)) = self.bytes.split_first() {
            self.bytes = rest;
            if let Some(result) = self.decoder.push(byte) {
                return Some(result);
            }
        }
        None
    }
}

impl<T: Message, const N: usize> core::iter::FusedIterator for Frames<'_, '_, T, N> {}
