//! Thread mode's part: the screening, the reports and the host's commands.

use super::{Clock, FromHost, Schedule, Screening, Shared};
use crate::Transport;
use crate::decimate::{Decimator, factor_for};
use core::num::NonZeroU16;
use core::sync::atomic::Ordering;
use heapless::spsc::Consumer;
use lssi_core::Snapshot;
use lssi_proto::{
    CONTROL_SEQ, CostUnit, DeviceMsg, HostFrameDecoder, HostMsg, MAX_BATCH, MAX_DEVICE_FRAME_LEN,
    MAX_TERMS, ModelSnapshot, NakReason, PROTOCOL_VERSION, SnapshotCause, WireConfig, WireDuty,
    encode,
};

/// How the model moved from one duty-cycle window's model to the next (a model every
/// `model_every` windows: see [`lssi_proto::WireDuty`]): what a harvester that changes
/// over weeks shows first.
///
/// Per term, the relative change `|c − p| / |p|` of its coefficient from the previous
/// model `p` to this one's `c` (1 for a term that entered or left the model).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Drift {
    /// Windows reported since configured (this one, the window of the model, included).
    pub windows: u32,
    /// Root mean square of the terms' relative changes, over the terms in either model
    /// (0 for the first window, which has nothing to compare with).
    pub relative: f32,
    /// The largest relative change and the term (index in the library) that made it.
    pub largest: f32,
    /// That term's index in the model's terms.
    pub largest_term: u8,
    /// Terms that entered or left the model.
    pub support_changes: u8,
}

impl Drift {
    /// The drift from `previous` to `current` (the same library: the same terms in the
    /// same order; otherwise every term counts as changed).
    pub fn between(previous: &ModelSnapshot, current: &ModelSnapshot, windows: u32) -> Self {
        let mut drift = Drift {
            windows,
            ..Drift::default()
        };
        let same = previous.terms == current.terms;
        let (mut sum, mut n) = (0.0f32, 0u32);
        for (i, &c) in current.coefficients.iter().enumerate() {
            let p = if same {
                previous.coefficients.get(i).copied().unwrap_or(0.0)
            } else {
                0.0
            };
            let change = match (p != 0.0, c != 0.0) {
                (false, false) => continue,
                (true, true) => libm::fabsf(c - p) / libm::fabsf(p),
                _ => {
                    drift.support_changes = drift.support_changes.saturating_add(1);
                    1.0
                }
            };
            sum += change * change;
            n += 1;
            if change > drift.largest {
                drift.largest = change;
                drift.largest_term = u8::try_from(i).unwrap_or(u8::MAX);
            }
        }
        if n > 0 {
            drift.relative = libm::sqrtf(sum / n as f32);
        }
        drift
    }
}

/// Thread mode's part: screens the snapshot, keeps the latest model, sends Model and
/// Health frames every period and answers the host's commands.
///
/// `S` is what it screens: one equation's [`Snapshot`] (the default; `Model` frames, a
/// host's `Configure`) or a system's (`SystemShot`: `SystemModel` frames, a host's
/// `ConfigureSystem`).
pub struct Reporter<const W: usize, const P: usize, const C: usize, S: Screening = Snapshot<f32, P>>
{
    decoder: HostFrameDecoder,
    buffer: [u8; MAX_DEVICE_FRAME_LEN],
    /// The latest model's frame (`Model` or `SystemModel`).
    latest: Option<DeviceMsg>,
    /// The latest model's rows were taken less the references ([`Shared::reference`]).
    latest_shifted: bool,
    config: Option<S::Config>,
    rate_hz: f32,
    /// The ADC's conversion rate, Hz, and the CIC order rows are decimated with (0.0: no
    /// decimation, every conversion a row).
    adc_hz: f64,
    order: u8,
    /// The time of row 0 under the current decimation, s.
    offset: f64,
    /// Clock ticks between reports (0: only on request).
    period_ticks: u32,
    last_report: u32,
    frames_ok: u32,
    crc_errors: u32,
    decode_errors: u32,
    watchdog: u32,
    screen_cost: u32,
    screen_cost_max: u32,
    /// Frames sent.
    pub frames_sent: u32,
    /// Screenings run before the final one (scheduled, or a window's).
    pub screenings_run: u32,
    finished: bool,
    /// A host's configuration, accepted and not yet taken by the board to keep.
    to_keep: Option<WireConfig>,
    /// With a duty cycle (reports only at the end of a window, then), a model every how
    /// many windows; `None` without one. (Its window and interval are the sampling
    /// interrupt's schedule's: not kept here, where they would take room in a board's main
    /// frame for good.)
    duty: Option<NonZeroU16>,
    /// The model of the last window that made one, and how it moved from the one before.
    previous: Option<(
        heapless::Vec<lssi_proto::TermCode, MAX_TERMS>,
        heapless::Vec<f32, MAX_TERMS>,
    )>,
    /// That model's rows were taken less the references.
    previous_shifted: bool,
    drift: Option<Drift>,
    windows: u32,
}

impl<const W: usize, const P: usize, const C: usize, S: Screening> Reporter<W, P, C, S> {
    /// Reports every `period_ticks` clock ticks, about the identifier configured with
    /// `config` (the board's default or stored one), sampled at `rate_hz`.
    pub const fn new(config: S::Config, rate_hz: f32, period_ticks: u32) -> Self {
        Self {
            decoder: HostFrameDecoder::new(),
            buffer: [0; MAX_DEVICE_FRAME_LEN],
            latest: None,
            latest_shifted: false,
            config: Some(config),
            rate_hz,
            adc_hz: 0.0,
            order: 1,
            offset: 0.0,
            period_ticks,
            last_report: 0,
            frames_ok: 0,
            crc_errors: 0,
            decode_errors: 0,
            watchdog: 0,
            screen_cost: 0,
            screen_cost_max: 0,
            frames_sent: 0,
            screenings_run: 0,
            finished: false,
            to_keep: None,
            duty: None,
            previous: None,
            previous_shifted: false,
            drift: None,
            windows: 0,
        }
    }

    /// Samples in windows of `duty` (the board's start-up configuration; a host's
    /// `Configure` sets it too): the sampling interrupt's schedule in conversions of the
    /// ADC set by [`Reporter::set_adc`] (call that first) or, without one, of rows at the
    /// configuration's rate. Reports go out at the end of each window only: Model then
    /// Health every `model_every`-th window, Health alone at the others (no screening).
    pub fn set_duty(&mut self, duty: Option<WireDuty>, shared: &Shared<P, S>) {
        self.duty = duty.map(|d| NonZeroU16::new(d.model_every).unwrap_or(NonZeroU16::MIN));
        let schedule = match (duty, self.config) {
            (Some(d), Some(config)) => {
                let config = S::base(&config);
                let (adc_hz, factor) = if self.adc_hz > 0.0 {
                    (
                        self.adc_hz,
                        factor_for(self.adc_hz, config.sample_period).unwrap_or(1),
                    )
                } else {
                    (1.0 / config.sample_period, 1)
                };
                Schedule::duty(d.window, d.interval, adc_hz, factor)
            }
            _ => Schedule::ALWAYS,
        };
        if !schedule.is_duty() {
            self.duty = None;
        }
        self.previous = None;
        self.previous_shifted = false;
        self.drift = None;
        self.windows = 0;
        shared.request_schedule(schedule);
    }

    /// Whether a periodic report is due at clock `now` (thread mode that sleeps through
    /// the rows' interrupts wakes for it).
    pub fn due(&self, now: u32) -> bool {
        self.duty.is_none()
            && self.period_ticks > 0
            && now.wrapping_sub(self.last_report) >= self.period_ticks
    }

    /// The most clock ticks one screening took.
    pub fn screen_cost_max(&self) -> u32 {
        self.screen_cost_max
    }

    /// How the model moved between the last two models of the duty cycle (after the report
    /// of each window that made one; `None` before the first or without a duty cycle).
    pub fn drift(&self) -> Option<Drift> {
        self.drift
    }

    /// Rows are decimated from an ADC converting at `adc_hz` by a CIC of `order`
    /// ([`crate::decimate`]): a `Configure` then sets the row rate by its sample period,
    /// which must be a whole number of conversions (1 to 255; otherwise `BadConfig`). The
    /// board sets the decimation of its start-up configuration itself
    /// ([`Decimator::time_offset`] is row 0's time).
    pub fn set_adc(&mut self, adc_hz: f64, order: u8, offset: f64) {
        self.adc_hz = adc_hz;
        self.order = order;
        self.offset = offset;
    }

    /// The configuration a host sent and this device accepted since the last call, for a
    /// board that keeps it across resets (in flash) and starts from it at power-up.
    pub fn take_accepted(&mut self) -> Option<WireConfig> {
        self.to_keep.take()
    }

    /// The latest model, once a screening made one.
    pub fn latest(&self) -> Option<&ModelSnapshot> {
        match self.latest.as_ref() {
            Some(DeviceMsg::Model(model)) => Some(model),
            _ => None,
        }
    }

    /// The latest model's frame (`Model`, or `SystemModel` for a system), once a
    /// screening made one.
    pub fn latest_message(&self) -> Option<&DeviceMsg> {
        self.latest.as_ref()
    }

    /// Whether the final model (the recording ended) has been sent.
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// One pass of thread mode on a board: the bytes the UART's receive ring holds (up to
    /// 64) go to [`Reporter::receive`], then [`Reporter::poll`]. Returns whether thread mode
    /// may sleep (nothing was received); the board then checks, with interrupts off, that
    /// no snapshot waits ([`Shared::screening_waiting`]) and the ring is still empty
    /// before its `wfi`.
    pub fn pass<L: Transport, K: Clock>(
        &mut self,
        rx: &mut Consumer<'_, u8>,
        shared: &Shared<P, S>,
        link: &mut L,
        clock: &K,
        screened: impl FnOnce(),
    ) -> Result<bool, L::Error> {
        let mut chunk = [0u8; 64];
        let mut n = 0;
        while n < chunk.len()
            && let Some(b) = rx.dequeue()
        {
            if let Some(slot) = chunk.get_mut(n) {
                *slot = b;
            }
            n += 1;
        }
        self.receive::<L, K>(chunk.get(..n).unwrap_or(&[]), shared, link)?;
        self.poll(shared, link, clock, screened)?;
        Ok(n == 0)
    }

    /// Screens a waiting snapshot (sending its model at once; its cost in `clock` ticks),
    /// then sends Model and Health if a period has passed. `screened` is called after a
    /// screening gave its snapshot back (the board pends the identify task, which may
    /// be waiting to take the final one).
    pub fn poll<L: Transport, K: Clock>(
        &mut self,
        shared: &Shared<P, S>,
        link: &mut L,
        clock: &K,
        screened: impl FnOnce(),
    ) -> Result<(), L::Error> {
        self.watchdog = self.watchdog.wrapping_add(1);
        if let Some((snapshot, cause, window, shifted)) = shared.take_full() {
            // A duty cycle's window makes a model every `model_every`-th time only: the
            // others end with Health alone, unscreened (their rows are in the identifier,
            // and the next model's snapshot is taken from it anew).
            let model = !window || self.models_this_window();
            if model {
                self.screen(snapshot, cause, shifted, clock);
            }
            critical_section::with(|cs| shared.free.borrow(cs).set(Some(snapshot)));
            screened();
            if cause == SnapshotCause::Final {
                self.send_model(link)?;
                self.send_health::<L, K>(shared, link)?;
                self.finished = true;
                return Ok(());
            }
            if window {
                self.windows = self.windows.saturating_add(1);
                self.last_report = clock.now();
                if model {
                    self.end_window();
                    self.send_model(link)?;
                }
                self.send_health::<L, K>(shared, link)?;
                return Ok(());
            }
        }
        let now = clock.now();
        if self.duty.is_none()
            && self.period_ticks > 0
            && now.wrapping_sub(self.last_report) >= self.period_ticks
        {
            // On a grid of whole periods: a report held up by a screening does not push
            // every later one back (the reports kept the screening's delay for good, about
            // 5 % of the period on the netduinoplus2 image); more than a period late, the
            // grid starts again from now (no burst of reports).
            let late = now.wrapping_sub(self.last_report) - self.period_ticks;
            self.last_report = if late < self.period_ticks {
                self.last_report.wrapping_add(self.period_ticks)
            } else {
                now
            };
            self.send_model(link)?;
            self.send_health::<L, K>(shared, link)?;
        }
        Ok(())
    }

    /// The screening of `snapshot` and its model as the latest (its cost in `clock` ticks).
    /// Not inlined: its locals (the screening's factors and sweep, the model's frame) are
    /// on the stack only while it runs, not in the board's main loop's frame for good.
    #[inline(never)]
    fn screen<K: Clock>(
        &mut self,
        snapshot: &mut S,
        cause: SnapshotCause,
        shifted: bool,
        clock: &K,
    ) {
        let start = clock.now();
        let made = snapshot.select();
        let spent = clock.now().wrapping_sub(start);
        self.screen_cost = spent;
        self.screen_cost_max = self.screen_cost_max.max(spent);
        if cause != SnapshotCause::Final {
            self.screenings_run = self.screenings_run.wrapping_add(1);
        }
        if made {
            self.take_model(snapshot, cause, shifted);
        }
    }

    /// The snapshot's model as the latest message. Not inlined: the frame's message is
    /// built here, apart from the screening's locals.
    #[inline(never)]
    fn take_model(&mut self, snapshot: &S, cause: SnapshotCause, shifted: bool) {
        if let Some(message) = snapshot.message(cause) {
            self.latest = Some(message);
            self.latest_shifted = shifted;
        }
    }

    /// Whether the duty cycle's window ending now makes a model (every `model_every`-th
    /// window; 0 or 1: every one).
    fn models_this_window(&self) -> bool {
        let every = self.duty.map_or(1, |every| u32::from(every.get()));
        (self.windows.saturating_add(1)).is_multiple_of(every)
    }

    /// A window's model is in: how it moved from the previous model's (the windows between
    /// made none). Not inlined (its copy of the previous model is on the stack only while
    /// it runs).
    #[inline(never)]
    fn end_window(&mut self) {
        // Drift is reported for one equation's model (a system's is in its frames).
        let Some(DeviceMsg::Model(latest)) = self.latest.as_ref() else {
            return;
        };
        // A model about other coordinates (the references were learnt since: the identifier
        // restarted) has nothing to compare with: the drift starts again from this one.
        if self.previous_shifted != self.latest_shifted {
            self.previous = None;
        }
        self.previous_shifted = self.latest_shifted;
        let drift = match &self.previous {
            Some((terms, coefficients)) => {
                let previous = ModelSnapshot {
                    terms: terms.clone(),
                    coefficients: coefficients.clone(),
                    ..ModelSnapshot::default()
                };
                Drift::between(&previous, latest, self.windows)
            }
            None => Drift {
                windows: self.windows,
                ..Drift::default()
            },
        };
        log!(
            info,
            "window {=u32}: coefficients moved {=f32} (RMS relative), at most {=f32} (term {=u8}), {=u8} terms in or out",
            drift.windows,
            drift.relative,
            drift.largest,
            drift.largest_term,
            drift.support_changes
        );
        self.drift = Some(drift);
        self.previous = Some((latest.terms.clone(), latest.coefficients.clone()));
    }

    /// Handles bytes received from the host: `Hello`, `Configure` (checked here, applied
    /// by the identify task before its next sample), `Query` (the latest model and
    /// health), `Reset` (the configuration anew). A host's sample batch is refused with
    /// `Busy`: this device samples its own sensor. Garbage is counted and skipped.
    /// Not inlined (a decoded command and its reply are on the stack only while it runs).
    #[inline(never)]
    pub fn receive<L: Transport, K: Clock>(
        &mut self,
        bytes: &[u8],
        shared: &Shared<P, S>,
        link: &mut L,
    ) -> Result<(), L::Error> {
        for &byte in bytes {
            match self.decoder.push::<HostMsg>(byte) {
                None => {}
                Some(Ok(message)) => {
                    self.frames_ok = self.frames_ok.wrapping_add(1);
                    self.command::<L, K>(message, shared, link)?;
                }
                Some(Err(lssi_proto::Error::Decode)) => {
                    self.decode_errors = self.decode_errors.wrapping_add(1);
                }
                Some(Err(lssi_proto::Error::VersionMismatch { .. })) => {
                    self.frames_ok = self.frames_ok.wrapping_add(1);
                    self.send(link, &hello::<W, P>())?;
                }
                Some(Err(_)) => self.crc_errors = self.crc_errors.wrapping_add(1),
            }
        }
        Ok(())
    }

    /// Runs one decoded command and sends its reply.
    fn command<L: Transport, K: Clock>(
        &mut self,
        message: HostMsg,
        shared: &Shared<P, S>,
        link: &mut L,
    ) -> Result<(), L::Error> {
        if let Some(parsed) = S::from_host(&message) {
            return self.configure(parsed, shared, link);
        }
        match message {
            HostMsg::Hello { .. } => self.send(link, &hello::<W, P>()),
            HostMsg::Reset => match self.config {
                Some(config) => {
                    shared.request_config_at(config, self.offset);
                    self.latest = None;
                    self.send(link, &DeviceMsg::Ack { seq: CONTROL_SEQ })
                }
                None => self.nak(link, CONTROL_SEQ, NakReason::NotConfigured),
            },
            HostMsg::Query => {
                self.send_model(link)?;
                self.send_health::<L, K>(shared, link)
            }
            // The instrument samples its own sensor: no host samples, no model in parts.
            HostMsg::Samples(batch) => self.nak(link, batch.seq, NakReason::Busy),
            HostMsg::Compact(batch) => self.nak(link, batch.seq, NakReason::Busy),
            HostMsg::ModelPart { .. } => self.nak(link, CONTROL_SEQ, NakReason::Busy),
            // A configuration for the other kind of identifier (one equation on a system's
            // instrument, or a system on one equation's), or system samples.
            _ => self.nak(link, CONTROL_SEQ, NakReason::BadConfig),
        }
    }

    /// `Configure`: checked here, applied by the identify task before its next sample; kept
    /// for the board to store once acked.
    fn configure<L: Transport>(
        &mut self,
        (config, duty, keep): FromHost<S::Config>,
        shared: &Shared<P, S>,
        link: &mut L,
    ) -> Result<(), L::Error> {
        let base = S::base(&config);
        let decimator = if self.adc_hz > 0.0 {
            match factor_for(self.adc_hz, base.sample_period)
                .and_then(|d| Decimator::new(d, self.order).ok())
            {
                Some(d) => Some(d),
                None => {
                    log!(
                        warn,
                        "Configure: a row period of {=f64} s is no whole number of ADC conversions",
                        base.sample_period
                    );
                    return self.nak(link, CONTROL_SEQ, NakReason::BadConfig);
                }
            }
        } else {
            None
        };
        let rate_hz = (1.0 / base.sample_period) as f32;
        match S::validate::<W, C>(&config) {
            Ok(()) => {
                if let Some(d) = decimator {
                    self.offset = d.time_offset(self.adc_hz);
                    shared.request_decimator(d);
                }
                shared.request_config_at(config, self.offset);
                self.config = Some(config);
                self.set_duty(duty, shared);
                self.to_keep = keep;
                self.rate_hz = rate_hz;
                self.latest = None;
                self.send(link, &DeviceMsg::Ack { seq: CONTROL_SEQ })
            }
            Err(reason) => self.nak(link, CONTROL_SEQ, reason),
        }
    }

    /// Sends `Nak { seq, reason }`.
    fn nak<L: Transport>(
        &mut self,
        link: &mut L,
        seq: u32,
        reason: NakReason,
    ) -> Result<(), L::Error> {
        self.send(link, &DeviceMsg::Nak { seq, reason })
    }

    /// The health report now.
    pub fn health<K: Clock>(&self, shared: &Shared<P, S>) -> DeviceMsg {
        let s = shared.status();
        let c = &shared.counters;
        let ticks_to_ns = |ticks: u32| -> u32 {
            let ns = u64::from(ticks) * 1_000_000_000 / u64::from(K::HZ.max(1));
            u32::try_from(ns).unwrap_or(u32::MAX)
        };
        DeviceMsg::Health {
            samples: s.samples,
            rejected: s.rejected,
            buffer_fill: s.buffer_fill,
            cost_mean: s.cost_mean,
            cost_max: s.cost_max,
            cost_unit: CostUnit::Ticks,
            watchdog: self.watchdog,
            crc_errors: self.crc_errors,
            frames_ok: self.frames_ok,
            screen_cost: self.screen_cost,
            screen_cost_max: self.screen_cost_max,
            screenings: u32::try_from(s.screenings).unwrap_or(u32::MAX),
            duplicates: 0,
            decode_errors: self.decode_errors,
            overruns: c.overruns.load(Ordering::Relaxed),
            queue_high_water: u16::try_from(c.queue_high_water.load(Ordering::Relaxed))
                .unwrap_or(u16::MAX),
            latency_max_ns: ticks_to_ns(c.latency_max.load(Ordering::Relaxed)),
            screenings_skipped: c.screenings_skipped.load(Ordering::Relaxed),
            sample_rate_hz: self.rate_hz,
            drift: self.drift.as_ref().map(crate::wire::drift_to_wire),
            // Those of the latest model (a model screened from rows before the restart is
            // about the raw channels); without a model, those subtracted now.
            reference: if self.latest.is_some() && !self.latest_shifted {
                None
            } else {
                shared.reference()
            },
        }
    }

    #[inline(never)]
    fn send_model<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
        match self.latest.take() {
            Some(message) => {
                let sent = self.send(link, &message);
                self.latest = Some(message);
                sent
            }
            None => Ok(()),
        }
    }

    #[inline(never)]
    fn send_health<L: Transport, K: Clock>(
        &mut self,
        shared: &Shared<P, S>,
        link: &mut L,
    ) -> Result<(), L::Error> {
        let health = self.health::<K>(shared);
        self.send(link, &health)
    }

    fn send<L: Transport>(&mut self, link: &mut L, message: &DeviceMsg) -> Result<(), L::Error> {
        let Ok(len) = encode(message, &mut self.buffer) else {
            return Ok(());
        };
        self.frames_sent = self.frames_sent.wrapping_add(1);
        link.write(self.buffer.get(..len).unwrap_or(&[]))
    }
}

fn hello<const W: usize, const P: usize>() -> DeviceMsg {
    DeviceMsg::HelloReply {
        protocol_version: PROTOCOL_VERSION,
        max_terms: u8::try_from(P).unwrap_or(u8::MAX),
        window_capacity: u16::try_from(W).unwrap_or(u16::MAX),
        max_batch: u16::try_from(MAX_BATCH).unwrap_or(u16::MAX),
    }
}
