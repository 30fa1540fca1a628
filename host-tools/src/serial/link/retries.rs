//! Retries: streaming samples in numbered batches, every one applied exactly once
//! (acknowledgements, retransmission, resynchronisation and the stream position).

use std::collections::VecDeque;
use std::time::Instant;

use lssi_proto::{
    CONTROL_SEQ, Channels, DeviceMsg, HostMsg, MAX_FRAME_LEN, NakReason, SampleBatch, WireSample,
};

use super::framing::InFlight;
use super::session::{Event, MIN_TIMEOUT};
use super::{BatchSource, F32Samples, Link, LinkError};
use crate::serial::adapt::Adapt;

impl Link<'_> {
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
        self.position_of(false)
    }

    /// [`Link::position`] of a device running a system (`system`: the probe is an empty
    /// `SystemSamples` batch, which such a device takes; it naks a `Samples` one).
    pub fn position_of(&mut self, system: bool) -> Result<(u64, u32), LinkError> {
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
        let probe = if system {
            HostMsg::SystemSamples(lssi_proto::SystemBatch::new(CONTROL_SEQ - 1))
        } else {
            HostMsg::Samples(SampleBatch::new(CONTROL_SEQ - 1, Channels::X))
        };
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
}
