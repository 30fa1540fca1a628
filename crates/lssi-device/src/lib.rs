//! The lssi device application: the command loop between a serial link and the streaming
//! identifier, transport-agnostic, so that `firmware-sim` (a host process on a pty) and the
//! Cortex-M4F firmware run exactly the same code.
//!
//! # How a platform drives it
//!
//! The platform owns the hardware and implements three small things:
//!
//! - a [`Transport`]: a **non-blocking** `read` of whatever bytes have arrived (0 when none)
//!   and a `write` of a whole frame (it may block until the UART has taken the bytes);
//! - a [`CostMeter`]: runs a closure and says what it cost, in the [`CostUnit`] it counts
//!   (instructions under QEMU `-icount`, DWT cycles on silicon, nanoseconds on a host);
//!   [`NoCost`] when there is nothing to measure with;
//! - optionally, defmt log bytes: whatever its defmt global logger buffered, handed to
//!   [`Device::send_log`], which sends them as [`DeviceMsg::Log`] frames.
//!
//! and then calls [`Device::poll`] from its main loop, forever. `poll` bumps the watchdog
//! counter, reads what the transport has, reassembles frames, runs the commands (applying
//! samples to the identifier), and writes the replies before it returns. There is no
//! interrupt, no allocation and no panic anywhere on received data.
//!
//! ```
//! use lssi_device::{Device, NoCost, Transport};
//! use lssi_proto::{encode, DeviceFrameDecoder, DeviceMsg, HostMsg, MAX_HOST_FRAME_LEN,
//!                  PROTOCOL_VERSION};
//! use std::collections::VecDeque;
//!
//! /// A loopback "UART": bytes from the host in `rx`, bytes to the host in `tx`.
//! #[derive(Default)]
//! struct Loopback { rx: VecDeque<u8>, tx: Vec<u8> }
//!
//! impl Transport for Loopback {
//!     type Error = core::convert::Infallible;
//!     fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
//!         let n = buf.len().min(self.rx.len());
//!         for (slot, byte) in buf.iter_mut().zip(self.rx.drain(..n)) { *slot = byte; }
//!         Ok(n)
//!     }
//!     fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
//!         self.tx.extend_from_slice(bytes);
//!         Ok(())
//!     }
//! }
//!
//! // The firmware puts the device in a static; 16 KiB is too much for a doctest's stack.
//! let mut device: Box<Device> = Box::new(Device::new());
//! let mut link = Loopback::default();
//! let mut meter = NoCost;
//!
//! // The host says hello.
//! let mut frame = [0u8; MAX_HOST_FRAME_LEN];
//! let len = encode(&HostMsg::Hello { protocol_version: PROTOCOL_VERSION }, &mut frame).unwrap();
//! link.rx.extend(&frame[..len]);
//!
//! // The platform's main loop: poll (a firmware would add `wfi` when nothing came).
//! while device.poll(&mut link, &mut meter).unwrap() > 0 {}
//!
//! let mut decoder = DeviceFrameDecoder::new();
//! let replies: Vec<_> = decoder.feed::<DeviceMsg>(&link.tx).collect();
//! assert!(matches!(replies[..], [Ok(DeviceMsg::HelloReply { protocol_version: PROTOCOL_VERSION, .. })]));
//! ```
//!
//! # The protocol, as the device implements it
//!
//! Every host command gets exactly one reply, in order, except `Query` (two):
//!
//! | host sends | device replies |
//! |---|---|
//! | `Hello` (any version) | `HelloReply` with [`PROTOCOL_VERSION`], `max_terms` = P, `window_capacity` = W, `max_batch` = [`MAX_BATCH`] |
//! | `Configure(c)` | builds the identifier from exactly `c` ([`wire::config_from_wire`]); `Ack { seq: CONTROL_SEQ }`, or (a field out of range, or more window or channels than W, C) `Nak { seq: CONTROL_SEQ, BadConfig }`, (more terms than P) `Nak { seq: CONTROL_SEQ, TooManyTerms { terms, capacity } }` and the previous configuration and state stay |
//! | `Samples(b)`, `b.seq` = next expected | every sample pushed once into the identifier (rejections are counted, not refused); `Ack { seq }`; then, if a scheduled screening ran during the batch, one `Model` (cause `Scheduled`, the latest) |
//! | `Samples(b)`, `b.seq` < next expected | a duplicate: `Ack { seq }` again, nothing applied |
//! | `Samples(b)`, `b.seq` > next expected | `Nak { seq: next expected, OutOfOrder }`: a batch was lost, resend from `seq` |
//! | `Samples` before any `Configure` | `Nak { seq: b.seq, NotConfigured }` |
//! | `Query` | screens if samples came since the last screening, then `Model` (cause `Query`) if a model exists, then always `Health` |
//! | `Reset` | the identifier rebuilt from the kept configuration, next expected seq 0: `Ack { seq: CONTROL_SEQ }` (`Nak { CONTROL_SEQ, NotConfigured }` without one) |
//! | `ConfigureSystem`, `SystemSamples` (the `system` feature, default) | a system of equations (x'' and V' from x and V): see the `system` module; `Query`, `Reset` and scheduled screenings then send `SystemModel`; without the feature they do not decode (`Nak Decode`) |
//! | a frame failing COBS, CRC or overrunning the receive buffer | nothing; `crc_errors` + 1 (the host's timeout resends) |
//! | a frame passing the CRC that does not decode | `Nak { seq: next expected, Decode }`; `decode_errors` + 1 |
//!
//! Sequence numbers start at 0 after every `Configure` and `Reset`, so a host can pipeline
//! batches (go-back-N: on `Nak OutOfOrder` resend from its `seq`; on a timeout resend the
//! oldest unacknowledged batch). Every sample is applied exactly once whatever the link
//! does; `Configure` and `Reset` are idempotent, so resending them is safe too.
//!
//! **`Query` does not perturb the identifier.** [`Identifier::screen`] on request leaves the
//! identifier's state as it was (only the scheduled screenings re-choose the smoothing's K),
//! so a `Query` in mid-stream changes nothing that follows. A `Query` after the last batch
//! gives bit for bit the model of `lssi identify --f32` (which pushes every sample, then
//! screens once). A `Query` with no samples since the last screening (a resent query, or one
//! right after a scheduled screening) does not screen again.
#![cfg_attr(not(test), no_std)]
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

// The macro is declared before the modules that use it (textual scope).
/// Logs with defmt when the `defmt` feature is on; compiles to nothing otherwise.
macro_rules! log {
    ($level:ident, $($arg:tt)*) => {{
        #[cfg(feature = "defmt")]
        defmt::$level!($($arg)*);
    }};
}

mod commands;
pub mod decimate;
mod device;
mod platform;
mod replies;
pub mod standalone;
mod stats;
#[cfg(feature = "system")]
pub mod system;
pub mod wire;

pub use device::Device;
#[cfg(doc)]
use lssi_core::Identifier;
pub use lssi_proto::CostUnit;
#[cfg(doc)]
use lssi_proto::{DeviceMsg, MAX_BATCH, PROTOCOL_VERSION};
pub use platform::{CostMeter, NoCost, Transport};
pub use stats::Stats;

/// Window capacity of the firmware's identifier, in samples: the largest derivative window
/// a `Configure` may ask for.
pub const DEFAULT_WINDOW: usize = 256;
/// Library capacity of the firmware's identifier, in terms (the paper's harvester library,
/// odd families to order 9 with a constant and one harmonic, has 13).
pub const DEFAULT_TERMS: usize = 16;
/// Sample channels the identifier keeps ring buffers for by default: x, v and u. A device
/// built with fewer (the firmware's default is 2: x and one of v, u) naks a `Configure`
/// that asks for more with `BadConfig`.
pub const DEFAULT_CHANNELS: usize = 3;

/// Bytes [`Device::poll`] reads from the transport per call (on its stack).
pub const READ_CHUNK: usize = 64;
