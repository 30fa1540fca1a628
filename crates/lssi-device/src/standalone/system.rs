//! The identify task of a standalone instrument with two ADC channels: a harvester's
//! displacement x and the voltage V across its load (or its current), identified as the
//! system x'' = …, V' = … by `lssi_core::SystemIdentifier` in f32 (the `system` feature).
//!
//! The same design as [`Engine`](super::Engine): rows at a higher priority, the screening
//! in thread mode on a [`SystemSnapshot`], bit for bit the model the identifier would have
//! made in place, so that the host's f32 `SystemIdentifier` on the same rows gives the
//! device's equations.

use super::reference::{References, Rule};
use super::{Clock, Event, Reading, Shared, Status, Task};
use core::sync::atomic::Ordering;
use heapless::spsc::Consumer;
use lssi_core::{SystemConfig, SystemIdentifier, SystemSample, SystemSlot, SystemSnapshot};
use lssi_proto::SnapshotCause;

/// The snapshot a system's screening runs on (P terms, two equations).
pub type SystemShot<const P: usize> = SystemSnapshot<f32, P, 2>;

/// The identify task's part for a system (x'' and one electrical equation): the
/// identifier, fed from the queue, its screenings handed to thread mode on the snapshot.
/// In a `static` (all zero bytes until configured: `.bss`).
pub struct SystemEngine<const W: usize, const P: usize, const C: usize> {
    slot: SystemSlot<f32, W, P, 2, C>,
    period: f64,
    offset: f64,
    fresh: bool,
    final_pending: bool,
    window_pending: bool,
    ended: bool,
    cost_sum: u64,
    cost_count: u64,
    cost_max: u32,
    /// The references taken off the channels, learnt from the first rows.
    reference: References,
}

impl<const W: usize, const P: usize, const C: usize> Default for SystemEngine<W, P, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const P: usize, const C: usize> SystemEngine<W, P, C> {
    /// Not configured. `const`, all zero bytes.
    pub const fn new() -> Self {
        Self {
            slot: SystemSlot::new(),
            period: 0.0,
            offset: 0.0,
            fresh: false,
            final_pending: false,
            window_pending: false,
            ended: false,
            cost_sum: 0,
            cost_count: 0,
            cost_max: 0,
            reference: References::new(),
        }
    }

    /// The identifier, once configured.
    pub fn identifier(&self) -> Option<&SystemIdentifier<f32, W, P, 2, C>> {
        self.slot.get()
    }

    /// Configures the identifier in place, row `i` at `i · sample_period + offset` seconds
    /// (a refused configuration changes nothing).
    pub fn configure_at(
        &mut self,
        config: SystemConfig,
        offset: f64,
    ) -> Result<(), lssi_core::SystemConfigError> {
        self.slot.configure(config)?;
        self.period = config.base.sample_period;
        self.offset = offset;
        self.fresh = true;
        self.final_pending = false;
        self.window_pending = false;
        self.ended = false;
        self.cost_sum = 0;
        self.cost_count = 0;
        self.cost_max = 0;
        self.reference = References::new();
        Ok(())
    }

    /// The references subtracted from every row now (`None`: nothing is, or not yet: see
    /// [`References`](super::References)).
    pub fn reference(&self) -> Option<lssi_proto::WireReference> {
        self.reference.subtracted()
    }

    /// The identifier started anew with its own configuration, in place
    /// (`SystemIdentifier::forget`, as [`Engine`](super::Engine)'s). Not inlined (once a
    /// configuration).
    #[inline(never)]
    fn restart(&mut self) {
        if let Some(id) = self.slot.get_mut() {
            id.forget();
            self.fresh = true;
        }
    }

    fn push(&mut self, index: u64, mut reading: Reading, shared: &Shared<P, SystemShot<P>>) {
        if self.reference.take(&mut reading, Rule::System) {
            self.restart();
            shared.set_reference(self.reference.subtracted());
        }
        let period = self.period;
        let offset = self.offset;
        let fresh = &mut self.fresh;
        let shifted = self.reference.subtracted().is_some();
        let Some(id) = self.slot.get_mut() else {
            return;
        };
        let electrical = [reading.e.unwrap_or(f32::NAN)];
        let sample = SystemSample {
            x2: None,
            v2: None,
            t: index as f64 * period + offset,
            x: reading.x,
            v: reading.v,
            u: reading.u,
            electrical: if reading.e.is_some() {
                &electrical
            } else {
                &[]
            },
        };
        let windowed = shared.windowed.load(Ordering::Relaxed);
        let _ = id.push_with(&sample, |id| {
            if windowed {
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

    fn hand_over(
        &mut self,
        shared: &Shared<P, SystemShot<P>>,
        cause: SnapshotCause,
        window: bool,
    ) -> bool {
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

    fn publish(&self, shared: &Shared<P, SystemShot<P>>) {
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

impl<const W: usize, const P: usize, const C: usize> Task<P> for SystemEngine<W, P, C> {
    type Snapshot = SystemShot<P>;

    /// As [`Engine::run`](super::Engine::run), for a system.
    fn run<K: Clock>(
        &mut self,
        events: &mut Consumer<'_, Event>,
        shared: &Shared<P, SystemShot<P>>,
        clock: &K,
    ) {
        if let Some((config, offset)) =
            critical_section::with(|cs| shared.pending.borrow(cs).take())
        {
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
                    shared
                        .counters
                        .latency_max
                        .fetch_max(done.wrapping_sub(stamp), Ordering::Relaxed);
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
}
