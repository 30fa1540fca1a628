//! The identify task's part: the identifier fed from the queue, its screenings handed over
//! on the snapshot.

use super::reference::{References, Rule};
use super::{Clock, Event, Reading, Screening, Shared, Status};
use core::cell::{Cell, RefCell};
use core::sync::atomic::Ordering;
use critical_section::Mutex;
use heapless::spsc::Consumer;
use lssi_core::{Config, Identifier, IdentifierSlot, Sample, Snapshot};
use lssi_proto::SnapshotCause;

/// The identify task's part: the identifier, fed from the queue, with its screenings
/// handed to thread mode on the snapshot. In a `static` (it is all zero bytes until
/// configured: `.bss`).
pub struct Engine<const W: usize, const P: usize, const C: usize> {
    slot: IdentifierSlot<f32, W, P, C>,
    /// The sampling period, s (a sample's time is its index times this, plus `offset`).
    period: f64,
    /// The time of row 0, s (a decimator's delay: see `decimate`).
    offset: f64,
    /// Configured since the snapshot was last filled: the snapshot's model is stale.
    fresh: bool,
    /// The recording ended; its final snapshot is still to be taken.
    final_pending: bool,
    /// A duty cycle's window ended; its snapshot is still to be taken.
    window_pending: bool,
    ended: bool,
    /// Clock ticks of the pushes since configured: sum, count, largest.
    cost_sum: u64,
    cost_count: u64,
    cost_max: u32,
    /// The mean of the pushes' cost as last published.
    cost_mean: u32,
    /// Scheduled screenings since configured (the stride's count).
    scheduled: u32,
    /// The references taken off the channels, learnt from the first rows.
    reference: References,
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
            offset: 0.0,
            fresh: false,
            final_pending: false,
            window_pending: false,
            ended: false,
            cost_sum: 0,
            cost_count: 0,
            cost_max: 0,
            cost_mean: 0,
            scheduled: 0,
            reference: References::new(),
        }
    }

    /// The identifier, once configured.
    pub fn identifier(&self) -> Option<&Identifier<f32, W, P, C>> {
        self.slot.get()
    }

    /// Configures the identifier in place (a refused configuration changes nothing).
    pub fn configure(&mut self, config: Config) -> Result<(), lssi_core::ConfigError> {
        self.configure_at(config, 0.0)
    }

    /// Configures the identifier in place, row `i` at `i · sample_period + offset` seconds
    /// (a decimator's rows: `Decimator::time_offset`).
    pub fn configure_at(
        &mut self,
        config: Config,
        offset: f64,
    ) -> Result<(), lssi_core::ConfigError> {
        self.slot.configure(config)?;
        self.period = config.sample_period;
        self.offset = offset;
        self.fresh = true;
        self.final_pending = false;
        self.window_pending = false;
        self.ended = false;
        self.cost_sum = 0;
        self.cost_count = 0;
        self.cost_max = 0;
        self.cost_mean = 0;
        self.scheduled = 0;
        self.reference = References::new();
        Ok(())
    }

    /// The references subtracted from every row now (`None`: nothing is, or not yet: see
    /// [`References`](super::References)).
    pub fn reference(&self) -> Option<lssi_proto::WireReference> {
        self.reference.subtracted()
    }

    /// The identifier started anew with its own configuration, in place
    /// (`Identifier::forget`: bit for bit a reconfiguration, without designing its taps
    /// again, which took 27 ms of the M4F at 10 kHz rows and lost 210 rows): its rows from
    /// here on are the channels less their references. Not inlined (once a configuration).
    #[inline(never)]
    fn restart(&mut self) {
        if let Some(id) = self.slot.get_mut() {
            id.forget();
            self.fresh = true;
            self.scheduled = 0;
        }
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
        if let Some((config, offset)) =
            critical_section::with(|cs| shared.pending.borrow(cs).take())
        {
            // A refused configuration was checked by thread mode before it was requested.
            let _ = self.configure_at(config, offset);
            shared.set_reference(None);
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
                Event::Pause => {
                    self.window_pending = self.slot.get().is_some();
                }
            }
        }
        if self.window_pending && self.hand_over(shared, SnapshotCause::Scheduled, true) {
            self.window_pending = false;
        }
        if self.final_pending && self.hand_over(shared, SnapshotCause::Final, false) {
            self.final_pending = false;
        }
        self.publish(shared);
    }

    fn push(&mut self, index: u64, mut reading: Reading, shared: &Shared<P>) {
        if self.reference.take(&mut reading, Rule::Equation) {
            self.restart();
            shared.set_reference(self.reference.subtracted());
        }
        let period = self.period;
        let offset = self.offset;
        let fresh = &mut self.fresh;
        let scheduled = &mut self.scheduled;
        let shifted = self.reference.subtracted().is_some();
        let Some(id) = self.slot.get_mut() else {
            return;
        };
        let sample = Sample {
            t: index as f64 * period + offset,
            x: reading.x,
            v: reading.v,
            u: reading.u,
        };
        // A rejected sample (NaN, saturated, wrong channels) is counted by the identifier.
        // Sampling in windows, the model is screened once a window (at its end) instead.
        let windowed = shared.windowed.load(Ordering::Relaxed);
        let _ = id.push_with(sample, |id| {
            if windowed {
                return false;
            }
            // Every `model_stride`-th one only: the others are left out whole.
            *scheduled = scheduled.wrapping_add(1);
            if !(*scheduled).is_multiple_of(shared.model_stride()) {
                return false;
            }
            match shared.take_free() {
                Some(snapshot) => {
                    if core::mem::replace(fresh, false) {
                        snapshot.clear_model();
                    }
                    id.snapshot_into(snapshot);
                    critical_section::with(|cs| {
                        shared.full.borrow(cs).set(Some((
                            snapshot,
                            SnapshotCause::Scheduled,
                            false,
                            shifted,
                        )))
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

    /// Takes the final (or a window's) snapshot if the snapshot is free.
    fn hand_over(&mut self, shared: &Shared<P>, cause: SnapshotCause, window: bool) -> bool {
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
        let shifted = self.reference.subtracted().is_some();
        critical_section::with(|cs| {
            shared
                .full
                .borrow(cs)
                .set(Some((snapshot, cause, window, shifted)))
        });
        true
    }

    fn publish(&mut self, shared: &Shared<P>) {
        // The mean push cost anew every 64 pushes (and at the end): a u64 division is a
        // software routine on the M4F, ≈ 1 % of a row's instructions when done every row.
        if self.cost_count.is_multiple_of(64) || self.ended {
            self.cost_mean = self
                .cost_sum
                .checked_div(self.cost_count)
                .map_or(0, |m| u32::try_from(m).unwrap_or(u32::MAX));
        }
        let status = match self.slot.get() {
            Some(id) => {
                let c = id.counters();
                Status {
                    samples: c.accepted,
                    rejected: c.rejected(),
                    rows: c.rows,
                    screenings: c.screenings,
                    buffer_fill: u16::try_from(id.buffered()).unwrap_or(u16::MAX),
                    cost_mean: self.cost_mean,
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

/// An identify task's engine: [`Engine`] (one equation) or `SystemEngine` (a system).
pub trait Task<const P: usize>: 'static {
    /// What its screenings run on.
    type Snapshot: Screening;

    /// Takes every event the queue holds (see [`Engine::run`]).
    fn run<K: Clock>(
        &mut self,
        events: &mut Consumer<'_, Event>,
        shared: &Shared<P, Self::Snapshot>,
        clock: &K,
    );
}

impl<const W: usize, const P: usize, const C: usize> Task<P> for Engine<W, P, C> {
    type Snapshot = Snapshot<f32, P>;

    fn run<K: Clock>(
        &mut self,
        events: &mut Consumer<'_, Event>,
        shared: &Shared<P, Self::Snapshot>,
        clock: &K,
    ) {
        Engine::run(self, events, shared, clock);
    }
}

/// Where a board keeps the identify task's two resources between its runs: the engine and
/// the queue's consumer, each moved out for the run and back after it (critical sections of
/// a few instructions; the run itself is not in one).
pub struct IdentifyTask<
    const W: usize,
    const P: usize,
    const C: usize,
    E: Task<P> = Engine<W, P, C>,
> {
    engine: Mutex<Cell<Option<&'static mut E>>>,
    events: Mutex<RefCell<Option<Consumer<'static, Event>>>>,
}

impl<const W: usize, const P: usize, const C: usize, E: Task<P>> Default
    for IdentifyTask<W, P, C, E>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const P: usize, const C: usize, E: Task<P>> IdentifyTask<W, P, C, E> {
    /// Empty (in a `static`).
    pub const fn new() -> Self {
        Self {
            engine: Mutex::new(Cell::new(None)),
            events: Mutex::new(RefCell::new(None)),
        }
    }

    /// Hands over the engine and the consumer end of the sample queue (at start-up).
    pub fn give(&self, engine: &'static mut E, events: Consumer<'static, Event>) {
        critical_section::with(|cs| {
            self.engine.borrow(cs).set(Some(engine));
            self.events.borrow(cs).replace(Some(events));
        });
    }

    /// The identify interrupt's body: [`Engine::run`] on what the queue holds.
    pub fn run<K: Clock>(&self, shared: &Shared<P, E::Snapshot>, clock: &K) {
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
