//! The device application's state and its main loop: bytes in, frames out.

use crate::{
    CostMeter, CostUnit, DEFAULT_CHANNELS, DEFAULT_TERMS, DEFAULT_WINDOW, READ_CHUNK, Stats,
    Transport,
};
#[cfg(feature = "system")]
use lssi_core::SystemSlot;
use lssi_core::{Config, Identifier, IdentifierSlot};
use lssi_proto::{
    DeviceMsg, MAX_FRAME_LEN, MAX_HOST_FRAME_LEN, MAX_LOG, MAX_TERMS, SampleEncoding, encode,
};
#[cfg(doc)]
use lssi_proto::{HostMsg, PROTOCOL_VERSION};

/// Which identifier the device runs.
#[cfg(feature = "system")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Mode {
    /// One equation (`Configure`), or nothing configured yet.
    #[default]
    Single,
    /// A system (`ConfigureSystem`; the `system` feature).
    System,
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
    pub(crate) buffer: [u8; MAX_FRAME_LEN],
    /// Bytes of the frame being received.
    pub(crate) received: usize,
    /// Skipping the rest of an overlong frame, up to the next `0x00`.
    pub(crate) skipping: bool,
    /// Configured in place: the identifier never exists on the stack.
    pub(crate) identifier: IdentifierSlot<f32, W, P, C>,
    /// A system's identifier (x'' and V', `ConfigureSystem`), configured in place too
    /// (the `system` feature: 9.8 KB of RAM, 20 KB of flash on the Cortex-M4F).
    #[cfg(feature = "system")]
    pub(crate) system: SystemSlot<f32, W, P, 2, C>,
    /// Which of the two the commands address.
    #[cfg(feature = "system")]
    pub(crate) mode: Mode,
    pub(crate) next_seq: u32,
    /// How sample batches travel, as the configuration in force says.
    pub(crate) encoding: SampleEncoding,
    /// Samples were pushed since the last screening ran (or was attempted).
    pub(crate) dirty: bool,
    pub(crate) stats: Stats,
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
            #[cfg(feature = "system")]
            system: SystemSlot::new(),
            #[cfg(feature = "system")]
            mode: Mode::Single,
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

    /// The identifier, once configured (`None` while a system is).
    pub fn identifier(&self) -> Option<&Identifier<f32, W, P, C>> {
        if self.in_system() {
            None
        } else {
            self.identifier.get()
        }
    }

    /// The configuration in force, once configured (a system's: its `base`).
    pub fn config(&self) -> Option<&Config> {
        if self.in_system() {
            self.system_base_config()
        } else {
            self.identifier.get().map(Identifier::config)
        }
    }

    /// The sequence number of the next sample batch to apply.
    pub fn next_seq(&self) -> u32 {
        self.next_seq
    }

    /// Whether a system is configured (`ConfigureSystem`; never without the `system`
    /// feature, whose branches then compile out).
    pub(crate) fn in_system(&self) -> bool {
        #[cfg(feature = "system")]
        {
            self.mode == Mode::System
        }
        #[cfg(not(feature = "system"))]
        {
            false
        }
    }

    /// The health report as it would be sent now, with costs in `unit`.
    pub fn health(&self, unit: CostUnit) -> DeviceMsg {
        let single = self.identifier.get().filter(|_| !self.in_system());
        let (samples, rejected, buffer_fill, screenings) = match (single, self.system_counts()) {
            (Some(id), _) => {
                let c = id.counters();
                let fill = u16::try_from(id.buffered()).unwrap_or(u16::MAX);
                (c.accepted, c.rejected(), fill, c.screenings)
            }
            (None, Some((accepted, rejected, screenings))) => {
                // The rings fill with every sample accepted, up to their capacity.
                let fill = accepted.min(W as u64);
                let fill = u16::try_from(fill).unwrap_or(u16::MAX);
                (accepted, rejected, fill, screenings)
            }
            (None, None) => (0, 0, 0, 0),
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
            // No duty cycle: the host sends the samples.
            drift: None,
            reference: None,
        }
    }
}

/// A log frame fits in the link buffer past the receive part.
const _: () =
    assert!(MAX_FRAME_LEN - MAX_HOST_FRAME_LEN >= lssi_proto::size::frame_len(1 + 1 + MAX_LOG));

/// Without the `system` feature (a device image that must stay small) the device never
/// leaves [`Mode::Single`]: `ConfigureSystem` does not decode (`Nak Decode`).
#[cfg(not(feature = "system"))]
impl<const W: usize, const P: usize, const C: usize> Device<W, P, C> {
    pub(crate) fn system_base_config(&self) -> Option<&Config> {
        None
    }

    pub(crate) fn system_counts(&self) -> Option<(u64, u64, u64)> {
        None
    }

    pub(crate) fn query_system<L: Transport, M: CostMeter>(
        &mut self,
        link: &mut L,
        meter: &mut M,
    ) -> Result<(), L::Error> {
        self.query(link, meter)
    }

    pub(crate) fn reset_system<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
        self.reset(link)
    }
}
