//! What can go wrong framing or unframing a message.

use crate::NakReason;
use core::fmt;

/// Why a message could not be framed, or a frame could not be read.
///
/// Every receive-side variant is one dropped frame; the [`FrameDecoder`](crate::FrameDecoder)
/// has already resynchronised and the next frame decodes normally.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// The output buffer given to [`encode`](crate::encode) cannot hold the frame.
    BufferTooSmall,
    /// postcard refused to serialise the message (never seen with this crate's types).
    Encode,
    /// A frame ran past the decoder's buffer before its `0x00`; it is dropped up to the next one.
    Overflow,
    /// The frame's COBS byte stuffing is inconsistent.
    Cobs,
    /// The frame's CRC-32C does not match its contents, or the frame is shorter than a CRC.
    Crc,
    /// The frame passed its CRC but is not a message of this protocol version.
    Decode,
    /// The peer's handshake carries a different [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).
    VersionMismatch {
        /// This build's version.
        ours: u16,
        /// The version the peer announced.
        theirs: u16,
    },
}

impl Error {
    /// The reason a device reports in its [`DeviceMsg::Nak`](crate::DeviceMsg::Nak) when a
    /// received frame fails with this error; `None` for the send-side errors.
    pub const fn nak_reason(&self) -> Option<NakReason> {
        match self {
            Error::BufferTooSmall | Error::Encode => None,
            Error::Overflow => Some(NakReason::Overflow),
            Error::Cobs | Error::Crc => Some(NakReason::Crc),
            Error::Decode => Some(NakReason::Decode),
            Error::VersionMismatch { .. } => Some(NakReason::VersionMismatch),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::BufferTooSmall => f.write_str("the output buffer is too small for the frame"),
            Error::Encode => f.write_str("the message could not be serialised with postcard"),
            Error::Overflow => {
                f.write_str("a frame was longer than the receive buffer and was dropped")
            }
            Error::Cobs => {
                f.write_str("a frame was dropped because its COBS byte stuffing is invalid")
            }
            Error::Crc => f.write_str("a frame was dropped because its CRC-32C does not match"),
            Error::Decode => f.write_str(
                "a frame passed its CRC but does not decode as a message of this protocol version",
            ),
            Error::VersionMismatch { ours, theirs } => write!(
                f,
                "the peer speaks lssi protocol version {theirs}, but this build speaks version {ours}"
            ),
        }
    }
}

impl core::error::Error for Error {}

#[cfg(feature = "std")]
impl From<Error> for std::io::Error {
    fn from(error: Error) -> Self {
        let kind = match error {
            Error::BufferTooSmall | Error::Encode => std::io::ErrorKind::InvalidInput,
            _ => std::io::ErrorKind::InvalidData,
        };
        std::io::Error::new(kind, error)
    }
}
