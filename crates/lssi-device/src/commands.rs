//! What the device does with each decoded frame: configure, apply a sample batch exactly
//! once in `seq` order, query, reset.

#[cfg(feature = "system")]
use crate::device::Mode;
use crate::{CostMeter, Device, Stats, Transport, wire};
use core::cmp::Ordering;
use lssi_core::{IdentifierSlot, Sample};
#[cfg(feature = "system")]
use lssi_proto::WireSystemConfig;
use lssi_proto::{
    CONTROL_SEQ, Error, HostCommand, NakReason, SampleEncoding, SnapshotCause, WireConfig,
    WireSample, decode_host_frame,
};

impl<const W: usize, const P: usize, const C: usize> Device<W, P, C> {
    /// Handles the frame of `len` bytes in the buffer: decodes it in place, runs the
    /// command and sends the replies (into the same buffer, the frame being done with).
    pub(crate) fn handle<L: Transport, M: CostMeter>(
        &mut self,
        len: usize,
        link: &mut L,
        meter: &mut M,
    ) -> Result<(), L::Error> {
        let system = self.in_system();
        let frame = self.buffer.get_mut(..len).unwrap_or(&mut []);
        let command = match decode_host_frame(frame) {
            Ok(HostCommand::Samples(batch)) if !system => {
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
            #[cfg(feature = "system")]
            Ok(HostCommand::SystemSamples(batch)) => {
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                return self.system_batch(&batch, link, meter);
            }
            Ok(HostCommand::Samples(batch)) => {
                // One equation's samples while a system is configured.
                let seq = batch.seq;
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                return self.nak(link, seq, NakReason::NotConfigured);
            }
            Ok(HostCommand::Compact(batch)) if system => {
                let seq = batch.seq;
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                return self.nak(link, seq, NakReason::NotConfigured);
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
                Command::from_host(command)
            }
            Err(error) => {
                if !self.frame_error(error, link)? {
                    return Ok(());
                }
                Command::Hello
            }
        };
        match (command, system) {
            (Command::Hello, _) => self.send_hello(link),
            (Command::Configure(config), _) => self.configure(&config, link),
            #[cfg(feature = "system")]
            (Command::ConfigureSystem(config), _) => self.configure_system(&config, link),
            (Command::Query, false) => self.query(link, meter),
            (Command::Query, true) => self.query_system(link, meter),
            (Command::Reset, false) => self.reset(link),
            (Command::Reset, true) => self.reset_system(link),
            (Command::ModelPart(offset), false) => self.send_model_part(link, offset),
            // The model in parts is one equation's.
            (Command::ModelPart(_), true) => self.nak(link, CONTROL_SEQ, NakReason::NotConfigured),
        }
    }

    /// Counts a frame that did not decode and answers it: true when the answer is our
    /// `HelloReply` (another protocol version), false when it was sent here (`Nak Decode`
    /// to a frame that passed the CRC but does not decode) or there is none (COBS, CRC).
    fn frame_error<L: Transport>(&mut self, error: Error, link: &mut L) -> Result<bool, L::Error> {
        match error {
            Error::VersionMismatch { theirs, .. } => {
                // The README's advice: answer with our version; the host reports the mismatch.
                log!(warn, "host speaks protocol version {=u16}", theirs);
                let _ = theirs;
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                Ok(true)
            }
            Error::Decode => {
                self.stats.decode_errors = self.stats.decode_errors.wrapping_add(1);
                self.nak(link, self.next_seq, NakReason::Decode)?;
                Ok(false)
            }
            _ => {
                // COBS, CRC, overflow: the frame cannot be attributed; the host resends.
                self.stats.crc_errors = self.stats.crc_errors.wrapping_add(1);
                Ok(false)
            }
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
                #[cfg(feature = "system")]
                {
                    self.mode = Mode::Single;
                }
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

    pub(crate) fn reset<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
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

    pub(crate) fn query<L: Transport, M: CostMeter>(
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
}

/// A decoded command other than a sample batch: a copy, so the frame's bytes are free for
/// the replies.
enum Command {
    Hello,
    Configure(WireConfig),
    #[cfg(feature = "system")]
    ConfigureSystem(WireSystemConfig),
    Query,
    Reset,
    ModelPart(u16),
}

impl Command {
    /// The copy of a decoded command; `Samples` and `Compact` are applied in place before
    /// this, and only `Hello` is left among the rest.
    fn from_host(command: HostCommand<'_>) -> Self {
        match command {
            HostCommand::Configure(config) => Command::Configure(config),
            #[cfg(feature = "system")]
            HostCommand::ConfigureSystem(config) => Command::ConfigureSystem(config),
            HostCommand::Query => Command::Query,
            HostCommand::Reset => Command::Reset,
            HostCommand::ModelPart { offset } => Command::ModelPart(offset),
            HostCommand::Hello { .. } | HostCommand::Samples(_) | HostCommand::Compact(_) => {
                Command::Hello
            }
            // lssi-proto's system messages when this crate's `system` feature is off (another
            // crate asked lssi-proto for them): not applied here, `SystemSamples` above.
            #[allow(unreachable_patterns, reason = "reachable only without the feature")]
            _ => Command::Hello,
        }
    }
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
