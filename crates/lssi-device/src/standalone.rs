//! The standalone instrument: the device samples its own sensor by a timer, identifies
//! without a host and reports by itself. Board-independent and safe: a board (the QEMU
//! stand-in, a real part with its HAL) wires these three parts to its interrupts.
//!
//! ```text
//! timer interrupt (highest)   Sampler::tick   reading + timer stamp → Event queue (spsc, 64) ; full → overruns += 1
//! identify (middle priority)  Engine::run     queue → Identifier::push_with; at a screening, a Snapshot → Shared
//! thread mode (lowest)        Reporter        Snapshot → select() → Model ; Model + Health every period ; RX commands
//! ```
//!
//! - **Time comes from the timer**: a sample's `t` is its index over the sampling rate, its
//!   stamp the clock at the interrupt; when the identify task runs does not move either.
//! - **No stall**: the screening (≈ 18 M instructions on the M4F) runs in thread mode on a
//!   [`Snapshot`] while rows go on at a higher priority; the model is, bit for bit, the one
//!   the identifier would have made in place (`Identifier::push_with`), so the host's
//!   `lssi identify` gives the device's model.
//! - **Ownership moves, nothing is shared mutably**: the one snapshot travels between the
//!   identify task and thread mode as a `&'static mut` through two one-place mailboxes
//!   (critical sections of a few instructions); counters are atomics.
//!
//! The board provides a [`Clock`] (a free-running tick counter), a [`Transport`] for
//! frames, and calls [`Engine::run`] whenever the timer has queued a sample (e.g. by pending
//! a software interrupt).

use crate::{Transport, wire};
use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicU32, Ordering};
use critical_section::Mutex;
use heapless::spsc::{Consumer, Producer, Queue};
use lssi_core::{Config, Identifier, IdentifierSlot, Sample, Snapshot};
use lssi_proto::{
    CONTROL_SEQ, CostUnit, DeviceMsg, HostFrameDecoder, HostMsg, MAX_BATCH, MAX_DEVICE_FRAME_LEN,
    ModelSnapshot, NakReason, PROTOCOL_VERSION, SnapshotCause, WireConfig, encode,
};

/// Slots of the sample queue: it holds `QUEUE_SLOTS − 1` = 64 events.
pub const QUEUE_SLOTS: usize = 65;

/// The queue between the sampling interrupt and the identify task.
pub type EventQueue = Queue<Event, QUEUE_SLOTS>;

/// One reading of the sensor's channels (v and u only when the configuration has them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// Displacement.
    pub x: f32,
    /// Measured velocity.
    pub v: Option<f32>,
    /// Measured excitation.
    pub u: Option<f32>,
}

/// What the sampling interrupt queues.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// A sample: its index since sampling started, the clock at its interrupt, the reading.
    Sample {
        /// Samples taken before this one (overruns included: time stays the timer's).
        index: u64,
        /// [`Clock::now`] in the interrupt.
        stamp: u32,
        /// The reading.
        reading: Reading,
    },
    /// The sensor has no more samples (the QEMU stand-in's recording ended).
    End,
}

/// A free-running tick counter (wrapping), for latencies.
pub trait Clock {
    /// Ticks per second.
    const HZ: u32;
    /// The count now.
    fn now(&self) -> u32;
}

/// Counters the three contexts share: atomics, written by one context each.
#[derive(Debug)]
pub struct Counters {
    /// Samples the timer could not queue (queue full).
    pub overruns: AtomicU32,
    /// The most events the queue held.
    pub queue_high_water: AtomicU32,
    /// Worst clock ticks from a sample's interrupt to its row done.
    pub latency_max: AtomicU32,
    /// Samples the identify task took from the queue.
    pub consumed: AtomicU32,
    /// Scheduled screenings left out (the snapshot was still being screened).
    pub screenings_skipped: AtomicU32,
    /// Readings passed on as NaN because the sensor was stuck ([`STUCK_RUN`]); the
    /// identifier counts them among its rejected samples too.
    pub stuck: AtomicU32,
}

/// What the contexts hand each other: the counters, the snapshot's two mailboxes and a
/// configuration for the identify task to apply. In a `static`.
pub struct Shared<const P: usize> {
    /// The counters.
    pub counters: Counters,
    /// The snapshot while nobody screens it (the identify task fills it from here).
    free: Mutex<Cell<Option<&'static mut Snapshot<f32, P>>>>,
    /// The snapshot waiting for (or under) its screening, with why it was taken.
    full: Mutex<Cell<Option<Taken<P>>>>,
    /// A configuration for the identify task to apply before its next sample.
    pending: Mutex<Cell<Option<Config>>>,
    /// The identify task's figures: accepted, rejected, rows, screenings, buffer fill.
    status: Mutex<Cell<Status>>,
}

/// A snapshot taken for a screening, with why it was taken.
type Taken<const P: usize> = (&'static mut Snapshot<f32, P>, SnapshotCause);

/// The identifier's figures as the identify task last published them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Status {
    /// Samples accepted.
    pub samples: u64,
    /// Samples rejected (non-finite, saturated, out of order).
    pub rejected: u64,
    /// Regression rows.
    pub rows: u64,
    /// Screenings scheduled (run on the snapshot or skipped).
    pub screenings: u64,
    /// Ring buffer fill.
    pub buffer_fill: u16,
    /// Mean clock ticks a sample's push took (its row, and at a screening point the
    /// snapshot copy), over every sample since configured.
    pub cost_mean: u32,
    /// The most clock ticks one push took.
    pub cost_max: u32,
    /// The recording ended and its final snapshot was taken.
    pub ended: bool,
}

impl<const P: usize> Shared<P> {
    /// Empty: no snapshot yet (see [`Shared::give_snapshot`]).
    pub const fn new() -> Self {
        Self {
            counters: Counters {
                overruns: AtomicU32::new(0),
                queue_high_water: AtomicU32::new(0),
                latency_max: AtomicU32::new(0),
                consumed: AtomicU32::new(0),
                screenings_skipped: AtomicU32::new(0),
                stuck: AtomicU32::new(0),
            },
            free: Mutex::new(Cell::new(None)),
            full: Mutex::new(Cell::new(None)),
            pending: Mutex::new(Cell::new(None)),
            status: Mutex::new(Cell::new(Status {
                samples: 0,
                rejected: 0,
                rows: 0,
                screenings: 0,
                buffer_fill: 0,
                cost_mean: 0,
                cost_max: 0,
                ended: false,
            })),
        }
    }

    /// Hands over the one snapshot (at start-up, from a `static` the board owns).
    pub fn give_snapshot(&self, snapshot: &'static mut Snapshot<f32, P>) {
        critical_section::with(|cs| self.free.borrow(cs).set(Some(snapshot)));
    }

    /// Asks the identify task to configure the identifier anew before its next sample.
    pub fn request_config(&self, config: Config) {
        critical_section::with(|cs| self.pending.borrow(cs).set(Some(config)));
    }

    /// Whether a snapshot waits for its screening (thread mode has work: do not sleep).
    pub fn screening_waiting(&self) -> bool {
        critical_section::with(|cs| {
            let full = self.full.borrow(cs);
            let taken = full.take();
            let waiting = taken.is_some();
            full.set(taken);
            waiting
        })
    }

    /// The identify task's figures.
    pub fn status(&self) -> Status {
        critical_section::with(|cs| self.status.borrow(cs).get())
    }

    fn take_free(&self) -> Option<&'static mut Snapshot<f32, P>> {
        critical_section::with(|cs| self.free.borrow(cs).take())
    }

    fn take_full(&self) -> Option<Taken<P>> {
        critical_section::with(|cs| self.full.borrow(cs).take())
    }
}

impl<const P: usize> Default for Shared<P> {
    fn default() -> Self {
        Self::new()
    }
}

/// Identical readings in a row after which the sensor counts as stuck: the readings that
/// follow, while they stay identical, are passed on as NaN (rejected and skipped like a
/// gap, so a stuck sensor cannot teach the identifier a flat line). 256 samples: 25.6 ms at
/// 10 kHz; a 12-bit ADC on a 1 Hz harvester at full scale holds one code for about 5 ms at
/// a turning point, and sensor noise moves the last bit far more often.
pub const STUCK_RUN: u32 = 256;

/// The sampling interrupt's part: queues each reading with its index and stamp.
pub struct Sampler<'q> {
    producer: Producer<'q, Event>,
    next: u64,
    ended: bool,
    /// The last displacement reading's bits and how many times in a row it came.
    last_x: u32,
    run: u32,
}

impl<'q> Sampler<'q> {
    /// The producer end of the queue (split once at start-up).
    pub fn new(producer: Producer<'q, Event>) -> Self {
        Self {
            producer,
            next: 0,
            ended: false,
            last_x: 0,
            run: 0,
        }
    }

    /// One timer interrupt's sample. A full queue loses it, counted in `overruns`: its
    /// index is used all the same, so the next sample's time stays the timer's. A reading
    /// that repeats the last one more than [`STUCK_RUN`] times goes on as NaN (counted in
    /// `stuck`).
    pub fn tick(&mut self, stamp: u32, mut reading: Reading, counters: &Counters) {
        let index = self.next;
        self.next += 1;
        let bits = reading.x.to_bits();
        if bits == self.last_x {
            self.run = self.run.saturating_add(1);
        } else {
            self.last_x = bits;
            self.run = 1;
        }
        if self.run > STUCK_RUN {
            reading.x = f32::NAN;
            counters.stuck.fetch_add(1, Ordering::Relaxed);
        }
        let event = Event::Sample {
            index,
            stamp,
            reading,
        };
        if self.producer.enqueue(event).is_err() {
            counters.overruns.fetch_add(1, Ordering::Relaxed);
        } else {
            let len = u32::try_from(self.producer.len()).unwrap_or(u32::MAX);
            counters.queue_high_water.fetch_max(len, Ordering::Relaxed);
        }
    }

    /// The sensor has no more samples: queues the end once (false while the queue is full;
    /// call again on the next tick).
    pub fn end(&mut self) -> bool {
        if !self.ended && self.producer.enqueue(Event::End).is_ok() {
            self.ended = true;
        }
        self.ended
    }

    /// Samples taken so far (queued or lost).
    pub fn taken(&self) -> u64 {
        self.next
    }
}

/// The identify task's part: the identifier, fed from the queue, with its screenings
/// handed to thread mode on the snapshot. In a `static` (it is all zero bytes until
/// configured: `.bss`).
pub struct Engine<const W: usize, const P: usize, const C: usize> {
    slot: IdentifierSlot<f32, W, P, C>,
    /// The sampling period, s (a sample's time is its index times this).
    period: f64,
    /// Configured since the snapshot was last filled: the snapshot's model is stale.
    fresh: bool,
    /// The recording ended; its final snapshot is still to be taken.
    final_pending: bool,
    ended: bool,
    /// Clock ticks of the pushes since configured: sum, count, largest.
    cost_sum: u64,
    cost_count: u64,
    cost_max: u32,
}

impl<const W: usize, const P: usize, const C: usize> Default for Engine<W, P, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const P: usize, const C: usize> Engine<W, P, C> {
    /// Not configured. `const`, all zero bytes.
    pub const fn new() -> Self {
        Self {
            slot: IdentifierSlot::new(),
            period: 0.0,
            fresh: false,
            final_pending: false,
            ended: false,
            cost_sum: 0,
            cost_count: 0,
            cost_max: 0,
        }
    }

    /// The identifier, once configured.
    pub fn identifier(&self) -> Option<&Identifier<f32, W, P, C>> {
        self.slot.get()
    }

    /// Configures the identifier in place (a refused configuration changes nothing).
    pub fn configure(&mut self, config: Config) -> Result<(), lssi_core::ConfigError> {
        self.slot.configure(config)?;
        self.period = config.sample_period;
        self.fresh = true;
        self.final_pending = false;
        self.ended = false;
        self.cost_sum = 0;
        self.cost_count = 0;
        self.cost_max = 0;
        Ok(())
    }

    /// Takes every event the queue holds: applies a requested configuration first, pushes
    /// each sample (its time from its index), hands each scheduled screening's snapshot to
    /// thread mode, and records each sample's latency by `clock`. Call it whenever the
    /// timer has queued something (and when thread mode returns the snapshot, so that a
    /// pending final snapshot is taken).
    pub fn run<K: Clock>(
        &mut self,
        events: &mut Consumer<'_, Event>,
        shared: &Shared<P>,
        clock: &K,
    ) {
        if let Some(config) = critical_section::with(|cs| shared.pending.borrow(cs).take()) {
            // A refused configuration was checked by thread mode before it was requested.
            let _ = self.configure(config);
        }
        while let Some(event) = events.dequeue() {
            shared.counters.consumed.fetch_add(1, Ordering::Relaxed);
            match event {
                Event::Sample {
                    index,
                    stamp,
                    reading,
                } => {
                    let start = clock.now();
                    self.push(index, reading, shared);
                    let done = clock.now();
                    let cost = done.wrapping_sub(start);
                    self.cost_sum = self.cost_sum.saturating_add(u64::from(cost));
                    self.cost_count += 1;
                    self.cost_max = self.cost_max.max(cost);
                    let latency = done.wrapping_sub(stamp);
                    shared
                        .counters
                        .latency_max
                        .fetch_max(latency, Ordering::Relaxed);
                }
                Event::End => {
                    self.ended = true;
                    self.final_pending = self.slot.get().is_some();
                }
            }
        }
        if self.final_pending && self.hand_over(shared, SnapshotCause::Final) {
            self.final_pending = false;
        }
        self.publish(shared);
    }

    fn push(&mut self, index: u64, reading: Reading, shared: &Shared<P>) {
        let period = self.period;
        let fresh = &mut self.fresh;
        let Some(id) = self.slot.get_mut() else {
            return;
        };
        let sample = Sample {
            t: index as f64 * period,
            x: reading.x,
            v: reading.v,
            u: reading.u,
        };
        // A rejected sample (NaN, saturated, wrong channels) is counted by the identifier.
        let _ = id.push_with(sample, |id| {
            match shared.take_free() {
                Some(snapshot) => {
                    if core::mem::replace(fresh, false) {
                        snapshot.clear_model();
                    }
                    id.snapshot_into(snapshot);
                    critical_section::with(|cs| {
                        shared
                            .full
                            .borrow(cs)
                            .set(Some((snapshot, SnapshotCause::Scheduled)))
                    });
                }
                None => {
                    shared
                        .counters
                        .screenings_skipped
                        .fetch_add(1, Ordering::Relaxed);
                }
            }
            false
        });
    }

    /// Takes the final snapshot if the snapshot is free.
    fn hand_over(&mut self, shared: &Shared<P>, cause: SnapshotCause) -> bool {
        let Some(id) = self.slot.get() else {
            return true;
        };
        let Some(snapshot) = shared.take_free() else {
            return false;
        };
        if core::mem::replace(&mut self.fresh, false) {
            snapshot.clear_model();
        }
        id.snapshot_into(snapshot);
        critical_section::with(|cs| shared.full.borrow(cs).set(Some((snapshot, cause))));
        true
    }

    fn publish(&self, shared: &Shared<P>) {
        let status = match self.slot.get() {
            Some(id) => {
                let c = id.counters();
                Status {
                    samples: c.accepted,
                    rejected: c.rejected(),
                    rows: c.rows,
                    screenings: c.screenings,
                    buffer_fill: u16::try_from(id.buffered()).unwrap_or(u16::MAX),
                    cost_mean: self
                        .cost_sum
                        .checked_div(self.cost_count)
                        .map_or(0, |m| u32::try_from(m).unwrap_or(u32::MAX)),
                    cost_max: self.cost_max,
                    ended: self.ended && !self.final_pending,
                }
            }
            None => Status {
                ended: self.ended,
                ..Status::default()
            },
        };
        critical_section::with(|cs| shared.status.borrow(cs).set(status));
    }
}

/// Where a board keeps the identify task's two resources between its runs: the engine and
/// the queue's consumer, each moved out for the run and back after it (critical sections of
/// a few instructions; the run itself is not in one).
pub struct IdentifyTask<const W: usize, const P: usize, const C: usize> {
    engine: Mutex<Cell<Option<&'static mut Engine<W, P, C>>>>,
    events: Mutex<RefCell<Option<Consumer<'static, Event>>>>,
}

impl<const W: usize, const P: usize, const C: usize> Default for IdentifyTask<W, P, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const P: usize, const C: usize> IdentifyTask<W, P, C> {
    /// Empty (in a `static`).
    pub const fn new() -> Self {
        Self {
            engine: Mutex::new(Cell::new(None)),
            events: Mutex::new(RefCell::new(None)),
        }
    }

    /// Hands over the engine and the consumer end of the sample queue (at start-up).
    pub fn give(&self, engine: &'static mut Engine<W, P, C>, events: Consumer<'static, Event>) {
        critical_section::with(|cs| {
            self.engine.borrow(cs).set(Some(engine));
            self.events.borrow(cs).replace(Some(events));
        });
    }

    /// The identify interrupt's body: [`Engine::run`] on what the queue holds.
    pub fn run<K: Clock>(&self, shared: &Shared<P>, clock: &K) {
        let engine = critical_section::with(|cs| self.engine.borrow(cs).take());
        let events = critical_section::with(|cs| self.events.borrow(cs).take());
        if let (Some(engine), Some(mut events)) = (engine, events) {
            engine.run(&mut events, shared, clock);
            critical_section::with(|cs| {
                self.engine.borrow(cs).set(Some(engine));
                self.events.borrow(cs).replace(Some(events));
            });
        }
    }
}

/// Thread mode's part: screens the snapshot, keeps the latest model, sends Model and
/// Health frames every period and answers the host's commands.
pub struct Reporter<const W: usize, const P: usize, const C: usize> {
    decoder: HostFrameDecoder,
    buffer: [u8; MAX_DEVICE_FRAME_LEN],
    latest: Option<ModelSnapshot>,
    config: Option<Config>,
    rate_hz: f32,
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
    finished: bool,
    /// A host's configuration, accepted and not yet taken by the board to keep.
    to_keep: Option<WireConfig>,
}

impl<const W: usize, const P: usize, const C: usize> Reporter<W, P, C> {
    /// Reports every `period_ticks` clock ticks, about the identifier configured with
    /// `config` (the board's default or stored one), sampled at `rate_hz`.
    pub const fn new(config: Config, rate_hz: f32, period_ticks: u32) -> Self {
        Self {
            decoder: HostFrameDecoder::new(),
            buffer: [0; MAX_DEVICE_FRAME_LEN],
            latest: None,
            config: Some(config),
            rate_hz,
            period_ticks,
            last_report: 0,
            frames_ok: 0,
            crc_errors: 0,
            decode_errors: 0,
            watchdog: 0,
            screen_cost: 0,
            screen_cost_max: 0,
            frames_sent: 0,
            finished: false,
            to_keep: None,
        }
    }

    /// The configuration a host sent and this device accepted since the last call, for a
    /// board that keeps it across resets (in flash) and starts from it at power-up.
    pub fn take_accepted(&mut self) -> Option<WireConfig> {
        self.to_keep.take()
    }

    /// The latest model, once a screening made one.
    pub fn latest(&self) -> Option<&ModelSnapshot> {
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
        shared: &Shared<P>,
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
        shared: &Shared<P>,
        link: &mut L,
        clock: &K,
        screened: impl FnOnce(),
    ) -> Result<(), L::Error> {
        self.watchdog = self.watchdog.wrapping_add(1);
        if let Some((snapshot, cause)) = shared.take_full() {
            let start = clock.now();
            let made = snapshot.select();
            let spent = clock.now().wrapping_sub(start);
            self.screen_cost = spent;
            self.screen_cost_max = self.screen_cost_max.max(spent);
            if made && let Some(model) = snapshot.model() {
                self.latest = wire::snapshot(model, cause).ok();
            }
            critical_section::with(|cs| shared.free.borrow(cs).set(Some(snapshot)));
            screened();
            if cause == SnapshotCause::Final {
                self.send_model(link)?;
                self.send_health::<L, K>(shared, link)?;
                self.finished = true;
                return Ok(());
            }
        }
        let now = clock.now();
        if self.period_ticks > 0 && now.wrapping_sub(self.last_report) >= self.period_ticks {
            self.last_report = now;
            self.send_model(link)?;
            self.send_health::<L, K>(shared, link)?;
        }
        Ok(())
    }

    /// Handles bytes received from the host: `Hello`, `Configure` (checked here, applied
    /// by the identify task before its next sample), `Query` (the latest model and
    /// health), `Reset` (the configuration anew). A host's sample batch is refused with
    /// `Busy`: this device samples its own sensor. Garbage is counted and skipped.
    pub fn receive<L: Transport, K: Clock>(
        &mut self,
        bytes: &[u8],
        shared: &Shared<P>,
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

    fn command<L: Transport, K: Clock>(
        &mut self,
        message: HostMsg,
        shared: &Shared<P>,
        link: &mut L,
    ) -> Result<(), L::Error> {
        match message {
            HostMsg::Hello { .. } => self.send(link, &hello::<W, P>()),
            HostMsg::Configure(wire_config) => {
                let config = wire::config_from_wire(&wire_config);
                match config.validate::<W, P, C>() {
                    Ok(()) => {
                        shared.request_config(config);
                        self.config = Some(config);
                        self.to_keep = Some(wire_config);
                        self.rate_hz = (1.0 / config.sample_period) as f32;
                        self.latest = None;
                        self.send(link, &DeviceMsg::Ack { seq: CONTROL_SEQ })
                    }
                    Err(error) => self.send(
                        link,
                        &DeviceMsg::Nak {
                            seq: CONTROL_SEQ,
                            reason: wire::config_nak(&error),
                        },
                    ),
                }
            }
            HostMsg::Reset => match self.config {
                Some(config) => {
                    shared.request_config(config);
                    self.latest = None;
                    self.send(link, &DeviceMsg::Ack { seq: CONTROL_SEQ })
                }
                None => self.send(
                    link,
                    &DeviceMsg::Nak {
                        seq: CONTROL_SEQ,
                        reason: NakReason::NotConfigured,
                    },
                ),
            },
            HostMsg::Query => {
                self.send_model(link)?;
                self.send_health::<L, K>(shared, link)
            }
            HostMsg::Samples(batch) => self.send(
                link,
                &DeviceMsg::Nak {
                    seq: batch.seq,
                    reason: NakReason::Busy,
                },
            ),
            // The instrument samples its own sensor: no host samples, no model in parts.
            HostMsg::Compact(batch) => self.send(
                link,
                &DeviceMsg::Nak {
                    seq: batch.seq,
                    reason: NakReason::Busy,
                },
            ),
            HostMsg::ModelPart { .. } => self.send(
                link,
                &DeviceMsg::Nak {
                    seq: CONTROL_SEQ,
                    reason: NakReason::Busy,
                },
            ),
        }
    }

    /// The health report now.
    pub fn health<K: Clock>(&self, shared: &Shared<P>) -> DeviceMsg {
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
        }
    }

    #[inline(never)]
    fn send_model<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
        match self.latest.take() {
            Some(model) => {
                let message = DeviceMsg::Model(model);
                let sent = self.send(link, &message);
                if let DeviceMsg::Model(model) = message {
                    self.latest = Some(model);
                }
                sent
            }
            None => Ok(()),
        }
    }

    #[inline(never)]
    fn send_health<L: Transport, K: Clock>(
        &mut self,
        shared: &Shared<P>,
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
