//! What the three contexts hand each other: the sample queue's events, the counters, the
//! snapshot's two mailboxes and a configuration for the identify task.

#[cfg(doc)]
use super::STUCK_RUN;
use super::{Schedule, Screening};
use crate::decimate::Decimator;
use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use critical_section::Mutex;
use heapless::spsc::Queue;
use lssi_core::Snapshot;
use lssi_proto::{SnapshotCause, WireReference};

/// Slots of the sample queue: it holds `QUEUE_SLOTS − 1` = 64 events.
pub const QUEUE_SLOTS: usize = 65;

/// The queue between the sampling interrupt and the identify task.
pub type EventQueue = Queue<Event, QUEUE_SLOTS>;

/// One reading of the sensor's channels (v, u and the electrical channel only when the
/// configuration has them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// Displacement.
    pub x: f32,
    /// Measured velocity.
    pub v: Option<f32>,
    /// Measured excitation.
    pub u: Option<f32>,
    /// The electrical channel (a harvester's voltage across its load, or its current), for
    /// a system's identifier (`SystemEngine`); one equation leaves it out.
    pub e: Option<f32>,
}

impl Reading {
    /// A reading of the displacement alone.
    pub const fn x(x: f32) -> Self {
        Self {
            x,
            v: None,
            u: None,
            e: None,
        }
    }
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
    /// A duty cycle's window ended: the model of every row so far is screened and reported
    /// (at a window that makes no model, Health alone), then the sampler sleeps for the
    /// interval.
    Pause,
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
/// configuration for the identify task to apply. In a `static`. `S` is what is screened:
/// one equation's [`Snapshot`] (the default) or a system's (`SystemEngine`).
pub struct Shared<const P: usize, S: Screening = Snapshot<f32, P>> {
    /// The counters.
    pub counters: Counters,
    /// The snapshot while nobody screens it (the identify task fills it from here).
    pub(super) free: Mutex<Cell<Option<&'static mut S>>>,
    /// The snapshot waiting for (or under) its screening, with why it was taken.
    pub(super) full: Mutex<Cell<Option<Taken<S>>>>,
    /// A configuration for the identify task to apply before its next sample, with the
    /// time of row 0 (the decimator's delay).
    pub(super) pending: Mutex<Cell<Option<Pending<S>>>>,
    /// A decimator for the sampling interrupt to put in before its next conversion.
    pub(super) decimator: Mutex<Cell<Option<Decimator>>>,
    /// Whether `decimator` holds one: the sampling interrupt checks this flag, not the
    /// cell (taking the cell copies a whole decimator in and out on every conversion).
    decimator_waiting: AtomicBool,
    /// A duty cycle for the sampling interrupt to follow from its next conversion.
    pub(super) schedule: Mutex<Cell<Option<Schedule>>>,
    /// Sampling in windows: the identify task leaves the scheduled screenings out (the
    /// model is screened and reported once a window, at its end).
    pub(super) windowed: AtomicBool,
    /// Every how many scheduled screenings one is run and its model reported (0 or 1:
    /// every one). The others are left out whole (no snapshot, no screening): the
    /// identifier's rows and its K re-choice go on as before, so the models that are made,
    /// and the final one, are the same bit for bit; a device on a harvester's power saves
    /// the screenings' instructions (see [`Shared::set_model_stride`]).
    pub(super) model_stride: AtomicU32,
    /// The identify task's figures: accepted, rejected, rows, screenings, buffer fill.
    pub(super) status: Mutex<Cell<Status>>,
    /// The references the identify task subtracts from every row (set once, when it has
    /// learnt them and one is not zero; `None` again at a configuration).
    pub(super) reference: Mutex<Cell<Option<WireReference>>>,
}

/// A configuration for the identify task, with the time of row 0.
pub(super) type Pending<S> = (<S as Screening>::Config, f64);

/// A snapshot taken for a screening, with why it was taken, whether it ends a duty cycle's
/// window, and whether its rows were taken less the references ([`Shared::reference`]: its
/// model is about the channels less them).
pub(super) type Taken<S> = (&'static mut S, SnapshotCause, bool, bool);

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

impl<const P: usize, S: Screening> Shared<P, S> {
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
            decimator: Mutex::new(Cell::new(None)),
            decimator_waiting: AtomicBool::new(false),
            schedule: Mutex::new(Cell::new(None)),
            windowed: AtomicBool::new(false),
            model_stride: AtomicU32::new(1),
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
            reference: Mutex::new(Cell::new(None)),
        }
    }

    /// Hands over the one snapshot (at start-up, from a `static` the board owns).
    pub fn give_snapshot(&self, snapshot: &'static mut S) {
        critical_section::with(|cs| self.free.borrow(cs).set(Some(snapshot)));
    }

    /// Asks the identify task to configure the identifier anew before its next sample.
    pub fn request_config(&self, config: S::Config) {
        self.request_config_at(config, 0.0);
    }

    /// Asks the identify task to configure the identifier anew before its next sample,
    /// row `i` at time `i · sample_period + offset` seconds.
    pub fn request_config_at(&self, config: S::Config, offset: f64) {
        critical_section::with(|cs| self.pending.borrow(cs).set(Some((config, offset))));
    }

    /// Asks the sampling interrupt to decimate by `decimator` from its next conversion.
    pub fn request_decimator(&self, decimator: Decimator) {
        critical_section::with(|cs| {
            self.decimator.borrow(cs).set(Some(decimator));
            self.decimator_waiting.store(true, Ordering::Relaxed);
        });
    }

    /// Asks the sampling interrupt to follow `schedule` from its next conversion (and the
    /// identify task to screen once a window instead of on its own schedule).
    pub fn request_schedule(&self, schedule: Schedule) {
        self.windowed.store(schedule.is_duty(), Ordering::Relaxed);
        critical_section::with(|cs| self.schedule.borrow(cs).set(Some(schedule)));
    }

    /// Runs only every `stride`-th scheduled screening (0 or 1: every one). A board that
    /// reports a model every few minutes sets it from its configuration: the stride for a
    /// model every `s` seconds is [`model_stride_for`]`(s, &config)`.
    pub fn set_model_stride(&self, stride: u32) {
        self.model_stride.store(stride.max(1), Ordering::Relaxed);
    }

    /// The stride set by [`Shared::set_model_stride`].
    pub fn model_stride(&self) -> u32 {
        self.model_stride.load(Ordering::Relaxed)
    }

    pub(super) fn take_schedule(&self) -> Option<Schedule> {
        critical_section::with(|cs| self.schedule.borrow(cs).take())
    }

    pub(super) fn take_decimator(&self) -> Option<Decimator> {
        if !self.decimator_waiting.load(Ordering::Relaxed) {
            return None;
        }
        critical_section::with(|cs| {
            self.decimator_waiting.store(false, Ordering::Relaxed);
            self.decimator.borrow(cs).take()
        })
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

    /// The references the identify task subtracts from every row (`None`: nothing is, or
    /// not yet: see [`References`](super::References)).
    pub fn reference(&self) -> Option<WireReference> {
        critical_section::with(|cs| self.reference.borrow(cs).get())
    }

    pub(super) fn set_reference(&self, reference: Option<WireReference>) {
        critical_section::with(|cs| self.reference.borrow(cs).set(reference));
    }

    pub(super) fn take_free(&self) -> Option<&'static mut S> {
        critical_section::with(|cs| self.free.borrow(cs).take())
    }

    pub(super) fn take_full(&self) -> Option<Taken<S>> {
        critical_section::with(|cs| self.full.borrow(cs).take())
    }
}

impl<const P: usize, S: Screening> Default for Shared<P, S> {
    fn default() -> Self {
        Self::new()
    }
}

/// The stride of scheduled screenings (see [`Shared::set_model_stride`]) for a model about
/// every `seconds` (at least one a `seconds`, never fewer than every screening): the
/// scheduled screenings come every `screening_period` rows of `sample_period` s.
pub fn model_stride_for(seconds: f64, config: &lssi_core::Config) -> u32 {
    let every = f64::from(config.screening_period) * config.sample_period;
    if !(seconds.is_finite() && every.is_finite() && every > 0.0 && seconds > every) {
        return 1;
    }
    // Rounded down: a model at least every `seconds`.
    let n = libm::floor(seconds / every);
    if n >= f64::from(u32::MAX) {
        u32::MAX
    } else {
        (n as u32).max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::model_stride_for;
    use lssi_core::Config;

    #[test]
    fn the_model_stride_gives_a_model_at_least_every_so_many_seconds() {
        let at = |hz: f64, period: u32| Config {
            sample_period: 1.0 / hz,
            screening_period: period,
            ..Config::default()
        };
        // 10 000 rows at 210 Hz: a screening every 47.6 s, six of them in 5 minutes.
        assert_eq!(model_stride_for(300.0, &at(210.0, 10_000)), 6);
        assert_eq!(model_stride_for(300.0, &at(200.0, 10_000)), 6);
        // Screenings rarer than the interval, or no interval: every one.
        assert_eq!(model_stride_for(300.0, &at(10.0, 10_000)), 1);
        assert_eq!(model_stride_for(0.0, &at(210.0, 10_000)), 1);
        assert_eq!(model_stride_for(f64::NAN, &at(210.0, 10_000)), 1);
        // 1 000 rows at 10 kHz: every 0.1 s.
        assert_eq!(model_stride_for(300.0, &at(10_000.0, 1_000)), 3000);
    }
}
