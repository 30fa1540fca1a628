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

pub mod standalone;
pub mod wire;

use core::cmp::Ordering;
use lssi_core::{Config, Identifier, IdentifierSlot, Sample};
pub use lssi_proto::CostUnit;
use lssi_proto::{
    CONTROL_SEQ, DeviceMsg, Error, HostCommand, MAX_BATCH, MAX_FRAME_LEN, MAX_HOST_FRAME_LEN,
    MAX_LOG, MAX_TERMS, NakReason, PROTOCOL_VERSION, SampleEncoding, SnapshotCause, WireConfig,
    WireSample, decode_host_frame, encode,
};

/// Logs with defmt when the `defmt` feature is on; compiles to nothing otherwise.
macro_rules! log {
    ($level:ident, $($arg:tt)*) => {{
        #[cfg(feature = "defmt")]
        defmt::$level!($($arg)*);
    }};
}

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

/// The byte link to the host, as the platform provides it.
///
/// `read` must not block: it returns the bytes that have arrived (0 when none). `write`
/// sends a whole frame (at most [`MAX_DEVICE_FRAME_LEN`] bytes) and may block until the
/// bytes are on their way. An error from either ends [`Device::poll`] with that error; the
/// device's state stays consistent (a reply that could not be written is simply lost, as
/// on a noisy line, and the host's timeout recovers it).
pub trait Transport {
    /// What can go wrong: `core::convert::Infallible` for a UART, `std::io::Error` on a host.
    type Error;

    /// Copies received bytes into `buf` without blocking; returns how many (0: none yet).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error>;

    /// Sends all of `bytes`.
    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error>;
}

impl<T: Transport + ?Sized> Transport for &mut T {
    type Error = T::Error;

    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        (**self).read(buf)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        (**self).write(bytes)
    }
}

/// Measures what a piece of code costs, in the platform's unit.
///
/// The firmware's meter reads SysTick (instructions under QEMU `-icount shift=0`) or the DWT
/// cycle counter and subtracts its own overhead; a host uses wall-clock nanoseconds.
pub trait CostMeter {
    /// The unit of every figure [`CostMeter::measure`] returns.
    fn unit(&self) -> CostUnit;

    /// Runs `f` once and returns its result and its cost (saturating at `u32::MAX`).
    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32);
}

impl<M: CostMeter + ?Sized> CostMeter for &mut M {
    fn unit(&self) -> CostUnit {
        (**self).unit()
    }

    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        (**self).measure(f)
    }
}

/// A meter that measures nothing: every cost is 0 [`CostUnit::Ticks`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoCost;

impl CostMeter for NoCost {
    fn unit(&self) -> CostUnit {
        CostUnit::Ticks
    }

    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        (f(), 0)
    }
}

/// The device's own counters (what [`DeviceMsg::Health`] reports besides the identifier's).
///
/// Link counters count since power-up; cost figures since the identifier was last
/// (re)built by `Configure` or `Reset`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// [`Device::poll`] calls (the watchdog: stuck means the main loop hangs).
    pub watchdog: u32,
    /// Frames that decoded.
    pub frames_ok: u32,
    /// Frames dropped for COBS, CRC or overrunning the receive buffer.
    pub crc_errors: u32,
    /// Frames that passed the CRC but did not decode.
    pub decode_errors: u32,
    /// Sample batches received again after they had been applied.
    pub duplicates: u32,
    /// Samples pushed without a screening, whose cost is in `cost_sum`.
    pub cost_count: u64,
    /// Sum of their costs.
    pub cost_sum: u64,
    /// The largest of them.
    pub cost_max: u32,
    /// Cost of the latest screening (scheduled, within a push, or queried).
    pub screen_cost: u32,
    /// Largest cost of a screening.
    pub screen_cost_max: u32,
}

impl Stats {
    /// Mean per-sample cost (0 before any sample), saturating at `u32::MAX`.
    pub fn cost_mean(&self) -> u32 {
        match self.cost_sum.checked_div(self.cost_count) {
            Some(mean) => u32::try_from(mean).unwrap_or(u32::MAX),
            None => 0,
        }
    }

    fn record_sample(&mut self, cost: u32) {
        self.cost_count = self.cost_count.saturating_add(1);
        self.cost_sum = self.cost_sum.saturating_add(u64::from(cost));
        self.cost_max = self.cost_max.max(cost);
    }

    fn record_screening(&mut self, cost: u32) {
        self.screen_cost = cost;
        self.screen_cost_max = self.screen_cost_max.max(cost);
    }

    fn reset_costs(&mut self) {
        self.cost_count = 0;
        self.cost_sum = 0;
        self.cost_max = 0;
        self.screen_cost = 0;
        self.screen_cost_max = 0;
    }
}

/// The device application: a frame decoder, the identifier (f32, window capacity `W`
/// samples, `P` library terms, ring buffers for `C` sample channels) and the link state.
///
/// 11 KiB with the defaults, 10 KiB with `C = 2` (see the crate README for `size_of` and
/// the screening's stack); the firmware keeps it in a static. `P` may not exceed
/// [`lssi_proto::MAX_TERMS`] and `W` not `u16::MAX` (checked at compile time).
pub struct Device<
    const W: usize = DEFAULT_WINDOW,
    const P: usize = DEFAULT_TERMS,
    const C: usize = DEFAULT_CHANNELS,
> {
    /// The link's one frame buffer, for both directions: a received frame accumulates in
    /// its first [`MAX_HOST_FRAME_LEN`] bytes and is decoded in place there (a batch's
    /// samples are read from it as they are pushed); once it is handled, the replies are
    /// encoded into the whole buffer. Log frames, sent between polls while a frame may be
    /// half received, are encoded into the bytes past [`MAX_HOST_FRAME_LEN`].
    buffer: [u8; MAX_FRAME_LEN],
    /// Bytes of the frame being received.
    received: usize,
    /// Skipping the rest of an overlong frame, up to the next `0x00`.
    skipping: bool,
    /// Configured in place: the identifier never exists on the stack.
    identifier: IdentifierSlot<f32, W, P, C>,
    next_seq: u32,
    /// How sample batches travel, as the configuration in force says.
    encoding: SampleEncoding,
    /// Samples were pushed since the last screening ran (or was attempted).
    dirty: bool,
    stats: Stats,
}

impl<const W: usize, const P: usize, const C: usize> Default for Device<W, P, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const P: usize, const C: usize> Device<W, P, C> {
    /// The capacities fit the wire format.
    const CAPACITIES_FIT: () = {
        assert!(
            P <= MAX_TERMS,
            "P exceeds the terms a ModelSnapshot carries"
        );
        assert!(W <= u16::MAX as usize, "W exceeds what HelloReply carries");
    };

    /// A device waiting for `Hello` and `Configure`. `const`, and every byte of it is zero
    /// (its identifier is an empty [`IdentifierSlot`]): in a static it lies in `.bss`, with
    /// nothing to build at start-up.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value, reason = "forces the compile-time check")]
        let () = Self::CAPACITIES_FIT;
        Self {
            buffer: [0; MAX_FRAME_LEN],
            received: 0,
            skipping: false,
            identifier: IdentifierSlot::new(),
            next_seq: 0,
            encoding: SampleEncoding::F32,
            dirty: false,
            stats: Stats {
                watchdog: 0,
                frames_ok: 0,
                crc_errors: 0,
                decode_errors: 0,
                duplicates: 0,
                cost_count: 0,
                cost_sum: 0,
                cost_max: 0,
                screen_cost: 0,
                screen_cost_max: 0,
            },
        }
    }

    /// One pass of the main loop: bumps the watchdog, reads up to [`READ_CHUNK`] bytes from
    /// `link` without blocking, handles every frame they complete and writes the replies.
    /// Returns how many bytes were read (0: the platform may sleep until the next interrupt).
    pub fn poll<L: Transport, M: CostMeter>(
        &mut self,
        link: &mut L,
        meter: &mut M,
    ) -> Result<usize, L::Error> {
        self.stats.watchdog = self.stats.watchdog.wrapping_add(1);
        let mut chunk = [0u8; READ_CHUNK];
        let n = link.read(&mut chunk)?.min(READ_CHUNK);
        let received = chunk.get(..n).unwrap_or(&[]);
        self.receive(received, link, meter)?;
        Ok(n)
    }

    /// Handles received bytes the platform already has (e.g. from an interrupt-fed ring
    /// buffer), in any chunks; replies go to `link`. [`Device::poll`] calls it.
    pub fn receive<L: Transport, M: CostMeter>(
        &mut self,
        bytes: &[u8],
        link: &mut L,
        meter: &mut M,
    ) -> Result<(), L::Error> {
        for &byte in bytes {
            // `lssi_proto::HostFrameDecoder::push`, with the frame decoded in place.
            if byte == 0 {
                let len = core::mem::replace(&mut self.received, 0);
                if !core::mem::replace(&mut self.skipping, false) && len > 0 {
                    self.handle(len, link, meter)?;
                }
            } else if self.skipping {
            } else if self.received < MAX_HOST_FRAME_LEN
                && let Some(slot) = self.buffer.get_mut(self.received)
            {
                *slot = byte;
                self.received += 1;
            } else {
                // Longer than any host frame: dropped like a bad CRC.
                self.received = 0;
                self.skipping = true;
                self.stats.crc_errors = self.stats.crc_errors.wrapping_add(1);
            }
        }
        Ok(())
    }

    /// Sends raw defmt bytes (what the platform's defmt logger produced, in order) as
    /// [`DeviceMsg::Log`] frames of at most [`MAX_LOG`] bytes; the host concatenates their
    /// contents into one defmt stream.
    ///
    /// Safe to call between polls while a frame is half received: a log frame is encoded
    /// past the receive part of the link buffer.
    #[inline(never)]
    pub fn send_log<L: Transport>(&mut self, link: &mut L, bytes: &[u8]) -> Result<(), L::Error> {
        let out = self.buffer.get_mut(MAX_HOST_FRAME_LEN..).unwrap_or(&mut []);
        for chunk in bytes.chunks(MAX_LOG) {
            if let Ok(bytes) = heapless::Vec::from_slice(chunk)
                && let Ok(len) = encode(&DeviceMsg::Log { bytes }, out)
            {
                link.write(out.get(..len).unwrap_or(&[]))?;
            }
        }
        Ok(())
    }

    /// The device's counters.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The identifier, once configured.
    pub fn identifier(&self) -> Option<&Identifier<f32, W, P, C>> {
        self.identifier.get()
    }

    /// The configuration in force, once configured.
    pub fn config(&self) -> Option<&Config> {
        self.identifier.get().map(Identifier::config)
    }

    /// The sequence number of the next sample batch to apply.
    pub fn next_seq(&self) -> u32 {
        self.next_seq
    }

    /// The health report as it would be sent now, with costs in `unit`.
    pub fn health(&self, unit: CostUnit) -> DeviceMsg {
        let (samples, rejected, buffer_fill, screenings) = match self.identifier.get() {
            Some(id) => {
                let c = id.counters();
                let fill = u16::try_from(id.buffered()).unwrap_or(u16::MAX);
                (c.accepted, c.rejected(), fill, c.screenings)
            }
            None => (0, 0, 0, 0),
        };
        let s = &self.stats;
        DeviceMsg::Health {
            samples,
            rejected,
            buffer_fill,
            cost_mean: s.cost_mean(),
            cost_max: s.cost_max,
            cost_unit: unit,
            watchdog: s.watchdog,
            crc_errors: s.crc_errors,
            frames_ok: s.frames_ok,
            screen_cost: s.screen_cost,
            screen_cost_max: s.screen_cost_max,
            screenings: u32::try_from(screenings).unwrap_or(u32::MAX),
            duplicates: s.duplicates,
            decode_errors: s.decode_errors,
            // A host sends the samples: nothing is sampled here.
            overruns: 0,
            queue_high_water: 0,
            latency_max_ns: 0,
            screenings_skipped: 0,
            sample_rate_hz: 0.0,
        }
    }

    /// Handles the frame of `len` bytes in the buffer: decodes it in place, runs the
    /// command and sends the replies (into the same buffer, the frame being done with).
    fn handle<L: Transport, M: CostMeter>(
        &mut self,
        len: usize,
        link: &mut L,
        meter: &mut M,
    ) -> Result<(), L::Error> {
        let frame = self.buffer.get_mut(..len).unwrap_or(&mut []);
        let command = match decode_host_frame(frame) {
            Ok(HostCommand::Samples(batch)) => {
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                // The samples are pushed straight from the frame's bytes; the replies are
                // sent once they are done with.
                let outcome = Self::apply(
                    &mut self.identifier,
                    &mut self.next_seq,
                    &mut self.dirty,
                    &mut self.stats,
                    batch.seq,
                    batch.iter(),
                    meter,
                );
                return self.batch_replies(outcome, link);
            }
            Ok(HostCommand::Compact(batch)) => {
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                let SampleEncoding::I16(encoding) = self.encoding else {
                    // Compact samples without the compact encoding configured.
                    let seq = batch.seq;
                    return self.nak(link, seq, NakReason::NotConfigured);
                };
                let outcome = Self::apply(
                    &mut self.identifier,
                    &mut self.next_seq,
                    &mut self.dirty,
                    &mut self.stats,
                    batch.seq,
                    batch.samples(&encoding),
                    meter,
                );
                return self.batch_replies(outcome, link);
            }
            Ok(command) => {
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                match command {
                    HostCommand::Configure(config) => Command::Configure(config),
                    HostCommand::Query => Command::Query,
                    HostCommand::Reset => Command::Reset,
                    HostCommand::ModelPart { offset } => Command::ModelPart(offset),
                    // `Samples` and `Compact` are handled above.
                    HostCommand::Hello { .. }
                    | HostCommand::Samples(_)
                    | HostCommand::Compact(_) => Command::Hello,
                }
            }
            Err(Error::VersionMismatch { theirs, .. }) => {
                // The README's advice: answer with our version; the host reports the mismatch.
                log!(warn, "host speaks protocol version {=u16}", theirs);
                let _ = theirs;
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                Command::Hello
            }
            Err(Error::Decode) => {
                self.stats.decode_errors = self.stats.decode_errors.wrapping_add(1);
                return self.nak(link, self.next_seq, NakReason::Decode);
            }
            Err(_) => {
                // COBS, CRC, overflow: the frame cannot be attributed; the host resends.
                self.stats.crc_errors = self.stats.crc_errors.wrapping_add(1);
                return Ok(());
            }
        };
        match command {
            Command::Hello => self.send_hello(link),
            Command::Configure(config) => self.configure(&config, link),
            Command::Query => self.query(link, meter),
            Command::Reset => self.reset(link),
            Command::ModelPart(offset) => self.send_model_part(link, offset),
        }
    }

    fn hello_reply(&self) -> DeviceMsg {
        DeviceMsg::HelloReply {
            protocol_version: PROTOCOL_VERSION,
            // Both fit: CAPACITIES_FIT.
            max_terms: u8::try_from(P).unwrap_or(u8::MAX),
            window_capacity: u16::try_from(W).unwrap_or(u16::MAX),
            max_batch: u16::try_from(MAX_BATCH).unwrap_or(u16::MAX),
        }
    }

    /// Out of line: the configuration's conversion is not in the main loop's frame.
    #[inline(never)]
    fn configure<L: Transport>(
        &mut self,
        config: &WireConfig,
        link: &mut L,
    ) -> Result<(), L::Error> {
        let encoding = config.encoding;
        let config = wire::config_from_wire(config);
        // In place: the identifier is built (or rebuilt) where it lives, never on the
        // stack (its 9 KB and the derivative taps' 3 KB would come on top of the device's
        // peak RAM). A refused configuration leaves the identifier as it was.
        match self.identifier.configure(config) {
            Ok(_) => {
                log!(info, "configured: {}", config);
                self.encoding = encoding;
                self.restarted();
                self.ack(link, CONTROL_SEQ)
            }
            Err(error) => {
                #[cfg(feature = "defmt")]
                defmt::warn!("configuration refused: {}", defmt::Display2Format(&error));
                let reason = wire::config_nak(&error);
                self.nak(link, CONTROL_SEQ, reason)
            }
        }
    }

    /// The link state after the identifier was (re)built.
    fn restarted(&mut self) {
        self.next_seq = 0;
        self.dirty = false;
        self.stats.reset_costs();
    }

    fn reset<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
        // Rebuilt in place from the kept configuration, like `Configure`.
        let rebuilt = self
            .identifier
            .get_mut()
            .map(|id| id.reconfigure(*id.config()));
        match rebuilt {
            Some(Ok(())) => {
                log!(info, "reset");
                self.restarted();
                self.ack(link, CONTROL_SEQ)
            }
            // A configuration that built once builds again; refused like no configuration.
            Some(Err(_)) | None => self.nak(link, CONTROL_SEQ, NakReason::NotConfigured),
        }
    }

    /// Applies a sample batch read in place (exactly once, in `seq` order) and says what
    /// to reply. Holds no frame or message of its own: the scheduled screening runs under it.
    fn apply<M: CostMeter>(
        identifier: &mut IdentifierSlot<f32, W, P, C>,
        next_seq: &mut u32,
        dirty: &mut bool,
        stats: &mut Stats,
        seq: u32,
        samples: impl Iterator<Item = WireSample>,
        meter: &mut M,
    ) -> BatchOutcome {
        let Some(identifier) = identifier.get_mut() else {
            return BatchOutcome::NotConfigured(seq);
        };
        match seq.cmp(next_seq) {
            Ordering::Less => {
                stats.duplicates = stats.duplicates.wrapping_add(1);
                BatchOutcome::Duplicate(seq)
            }
            Ordering::Greater => BatchOutcome::OutOfOrder,
            Ordering::Equal => {
                let mut screened = false;
                for s in samples {
                    let sample = Sample {
                        t: s.t,
                        x: s.x,
                        v: s.v,
                        u: s.u,
                    };
                    let (result, cost) = meter.measure(|| identifier.push(sample));
                    *dirty = true;
                    if result == Ok(true) {
                        // The push ran the scheduled screening: its cost is a screening's.
                        stats.record_screening(cost);
                        *dirty = false;
                        screened = true;
                    } else {
                        stats.record_sample(cost);
                    }
                }
                // Saturates at CONTROL_SEQ, 4·10⁹ batches away: batches past it are naked.
                *next_seq = next_seq.saturating_add(1);
                BatchOutcome::Applied { seq, screened }
            }
        }
    }

    /// The replies to a sample batch, once applied.
    fn batch_replies<L: Transport>(
        &mut self,
        outcome: BatchOutcome,
        link: &mut L,
    ) -> Result<(), L::Error> {
        match outcome {
            BatchOutcome::NotConfigured(seq) => self.nak(link, seq, NakReason::NotConfigured),
            BatchOutcome::Duplicate(seq) => self.ack(link, seq),
            BatchOutcome::OutOfOrder => self.nak(link, self.next_seq, NakReason::OutOfOrder),
            BatchOutcome::Applied { seq, screened } => {
                self.ack(link, seq)?;
                if screened {
                    log!(debug, "scheduled screening");
                    self.send_model(link, SnapshotCause::Scheduled)?;
                }
                Ok(())
            }
        }
    }

    fn query<L: Transport, M: CostMeter>(
        &mut self,
        link: &mut L,
        meter: &mut M,
    ) -> Result<(), L::Error> {
        let Some(identifier) = self.identifier.get_mut() else {
            return self.nak(link, CONTROL_SEQ, NakReason::NotConfigured);
        };
        if self.dirty {
            let (ran, cost) = meter.measure(|| identifier.screen());
            if ran {
                self.stats.record_screening(cost);
            }
            self.dirty = false;
        }
        self.send_model(link, SnapshotCause::Query)?;
        self.send_health(link, meter.unit())
    }

    /// Sends `Ack { seq }`. Out of line, like every send: a [`DeviceMsg`] is as large as its
    /// largest variant (a snapshot, 0.6 KiB), and none may sit in the main loop's frame,
    /// under the screening.
    #[inline(never)]
    fn ack<L: Transport>(&mut self, link: &mut L, seq: u32) -> Result<(), L::Error> {
        self.send(link, &DeviceMsg::Ack { seq })
    }

    /// Sends `Nak { seq, reason }` (out of line, see [`Device::ack`]).
    #[inline(never)]
    fn nak<L: Transport>(
        &mut self,
        link: &mut L,
        seq: u32,
        reason: NakReason,
    ) -> Result<(), L::Error> {
        self.send(link, &DeviceMsg::Nak { seq, reason })
    }

    /// Sends `HelloReply` (out of line, see [`Device::ack`]).
    #[inline(never)]
    fn send_hello<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
        self.send(link, &self.hello_reply())
    }

    /// Sends [`Device::health`] (its own frame: not under a screening).
    #[inline(never)]
    fn send_health<L: Transport>(&mut self, link: &mut L, unit: CostUnit) -> Result<(), L::Error> {
        self.send(link, &self.health(unit))
    }

    /// Sends the identifier's current model, if it has one (its own frame: the snapshot is
    /// not under a screening).
    #[inline(never)]
    fn send_model<L: Transport>(
        &mut self,
        link: &mut L,
        cause: SnapshotCause,
    ) -> Result<(), L::Error> {
        let snapshot = self
            .identifier
            .get()
            .and_then(|id| id.model())
            .and_then(|model| wire::snapshot(model, cause).ok());
        match snapshot {
            Some(snapshot) => self.send(link, &DeviceMsg::Model(snapshot)),
            None => Ok(()),
        }
    }

    /// Sends part `offset..` of the current model's bytes (`Nak NotConfigured` without a
    /// model). The snapshot is encoded into the link buffer, the part copied out of it, and
    /// the reply framed into the buffer again.
    #[inline(never)]
    fn send_model_part<L: Transport>(&mut self, link: &mut L, offset: u16) -> Result<(), L::Error> {
        let snapshot = self
            .identifier
            .get()
            .and_then(|id| id.model())
            .and_then(|model| wire::snapshot(model, SnapshotCause::Query).ok());
        let part = snapshot.and_then(|s| lssi_proto::model_part(&s, offset, &mut self.buffer));
        match part {
            Some(part) => self.send(link, &DeviceMsg::ModelPart(part)),
            None => self.nak(link, CONTROL_SEQ, NakReason::NotConfigured),
        }
    }

    /// Frames `message` into the link buffer and writes it. Only between frames: the
    /// frame received last has been handled.
    fn send<L: Transport>(&mut self, link: &mut L, message: &DeviceMsg) -> Result<(), L::Error> {
        // Cannot fail: the buffer holds the longest device frame.
        let Ok(len) = encode(message, &mut self.buffer) else {
            return Ok(());
        };
        link.write(self.buffer.get(..len).unwrap_or(&[]))
    }
}

/// A decoded command other than a sample batch: a copy, so the frame's bytes are free for
/// the replies.
enum Command {
    Hello,
    Configure(WireConfig),
    Query,
    Reset,
    ModelPart(u16),
}

/// What became of a sample batch.
#[derive(Clone, Copy)]
enum BatchOutcome {
    /// No configuration yet: naked with its `seq`.
    NotConfigured(u32),
    /// Applied before: acked again.
    Duplicate(u32),
    /// A batch was lost before it: naked with the next expected `seq`.
    OutOfOrder,
    /// Applied now; `screened` when a scheduled screening ran during it.
    Applied { seq: u32, screened: bool },
}

/// A log frame fits in the link buffer past the receive part.
const _: () =
    assert!(MAX_FRAME_LEN - MAX_HOST_FRAME_LEN >= lssi_proto::size::frame_len(1 + 1 + MAX_LOG));
