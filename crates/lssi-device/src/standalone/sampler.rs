//! The sampling interrupt's part.

use super::{Counters, Event, Reading, Screening, Shared};
use crate::decimate::Decimator;
use core::sync::atomic::Ordering;
use heapless::spsc::Producer;

/// Identical readings in a row after which the sensor counts as stuck: the readings that
/// follow, while they stay identical, are passed on as NaN (rejected and skipped like a
/// gap, so a stuck sensor cannot teach the identifier a flat line). 256 samples: 25.6 ms at
/// 10 kHz; a 12-bit ADC on a 1 Hz harvester at full scale holds one code for about 5 ms at
/// a turning point, and sensor noise moves the last bit far more often.
pub const STUCK_RUN: u32 = 256;

/// When the sensor is sampled: windows of `window` conversions every `window + interval`
/// conversions (the duty cycle, in ADC conversions since sampling started), or always.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Schedule {
    /// Conversions a window (0: sample always).
    pub window: u64,
    /// Conversions asleep between windows.
    pub interval: u64,
}

impl Schedule {
    /// Sampling always.
    pub const ALWAYS: Self = Self {
        window: 0,
        interval: 0,
    };

    /// Windows of `window` s every `window + interval` s for an ADC at `adc_hz` and rows of
    /// `factor` conversions: both rounded to whole rows (a window of at least one row).
    pub fn duty(window: f32, interval: f32, adc_hz: f64, factor: u32) -> Self {
        let row = f64::from(factor.max(1));
        let rows = |seconds: f32| libm::round(f64::from(seconds) * adc_hz / row);
        let w = rows(window);
        let i = rows(interval);
        if !(w.is_finite() && i.is_finite() && w >= 1.0 && i >= 0.0) || i == 0.0 {
            return Self::ALWAYS;
        }
        // At most 2^40 rows either way (years at kilohertz rates).
        let cap = (1u64 << 40) as f64;
        Self {
            window: (w.min(cap) * row) as u64,
            interval: (i.min(cap) * row) as u64,
        }
    }

    /// Whether it has windows.
    pub fn is_duty(&self) -> bool {
        self.window > 0 && self.interval > 0
    }
}

/// The sampling interrupt's part: decimates the ADC's conversions to rows and queues each
/// row with its index and stamp; with a duty cycle, samples in windows and queues
/// [`Event::Pause`] at the end of each.
///
/// A row's index counts rows of time since the first conversion (row `r` stands for
/// conversion `r · factor +` the decimator's centre), gaps included: the identifier's time
/// `index · period` jumps over an interval, and the identifier restarts its window there
/// (a gap) and goes on with its model.
pub struct Sampler<'q> {
    producer: Producer<'q, Event>,
    /// Conversions to rows (factor 1: every conversion is a row).
    decimator: Decimator,
    /// The decimator's first block starts at a conversion whose index is a multiple of its
    /// factor: false until one comes.
    aligned: bool,
    schedule: Schedule,
    /// Conversions taken (or slept through, in an interval).
    conversions: u64,
    /// Rows made (queued or lost).
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
            decimator: Decimator::none(),
            aligned: false,
            schedule: Schedule::ALWAYS,
            conversions: 0,
            next: 0,
            ended: false,
            last_x: 0,
            run: 0,
        }
    }

    /// Decimates by `decimator` from the next conversion whose index is a multiple of its
    /// factor on (the rows in progress dropped).
    pub fn set_decimator(&mut self, decimator: Decimator) {
        self.decimator = decimator;
        self.decimator.restart();
        self.aligned = false;
    }

    /// Samples on `schedule` from now on (its phase counted from the first conversion).
    pub fn set_schedule(&mut self, schedule: Schedule) {
        self.schedule = schedule;
    }

    /// Whether the sensor is to be sampled at the next conversion: false in an interval of
    /// the duty cycle (a board may stop its ADC and sleep until [`Sampler::sleep_left`]).
    pub fn sampling(&self) -> bool {
        !self.schedule.is_duty()
            || self.conversions % (self.schedule.window + self.schedule.interval)
                < self.schedule.window
    }

    /// Conversions left in the current interval (0 while sampling): a board that sleeps
    /// through them calls [`Sampler::skip`] with the count when it wakes.
    pub fn sleep_left(&self) -> u64 {
        if self.sampling() {
            return 0;
        }
        let period = self.schedule.window + self.schedule.interval;
        period - self.conversions % period
    }

    /// `n` conversion times passed without a conversion (asleep in an interval).
    pub fn skip(&mut self, n: u64) {
        self.conversions += n;
    }

    /// The decimator in use.
    pub fn decimator(&self) -> &Decimator {
        &self.decimator
    }

    /// One timer interrupt's conversion, with the decimator thread mode asked for (if
    /// any) put in first: see [`Sampler::tick`].
    pub fn convert<const P: usize, S: Screening>(
        &mut self,
        stamp: u32,
        reading: Reading,
        shared: &Shared<P, S>,
    ) -> bool {
        if let Some(decimator) = shared.take_decimator() {
            self.set_decimator(decimator);
        }
        if let Some(schedule) = shared.take_schedule() {
            self.set_schedule(schedule);
        }
        self.tick(stamp, reading, &shared.counters)
    }

    /// One timer interrupt's conversion: into the decimator, and when it completes a row,
    /// the row into the queue. A full queue loses the row, counted in `overruns`: its
    /// index is used all the same, so the next row's time stays the timer's. A reading
    /// that repeats the last one more than [`STUCK_RUN`] times goes on as NaN (counted in
    /// `stuck`). Returns whether a row was made (queued or lost): the board wakes the
    /// identify task only then.
    pub fn tick(&mut self, stamp: u32, mut reading: Reading, counters: &Counters) -> bool {
        let c = self.conversions;
        self.conversions += 1;
        if self.schedule.is_duty() {
            let phase = c % (self.schedule.window + self.schedule.interval);
            if phase >= self.schedule.window {
                if phase == self.schedule.window {
                    // The window is over: the identify task reports, the decimator starts
                    // afresh with the next window.
                    if self.producer.enqueue(Event::Pause).is_err() {
                        counters.overruns.fetch_add(1, Ordering::Relaxed);
                    }
                    self.decimator.restart();
                    self.aligned = false;
                    return true;
                }
                return false;
            }
        }
        let factor = u64::from(self.decimator.factor());
        if !self.aligned {
            if !c.is_multiple_of(factor) {
                return false;
            }
            self.aligned = true;
        }
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
        // x, then v, u and the electrical channel packed after it when present (1 to 3
        // channels accumulated: a fourth, all of v, u and e, is dropped, and the system's
        // identifier rejects the row for its missing channel).
        let mut values = [reading.x, 0.0, 0.0];
        let mut channels = 1;
        for value in [reading.v, reading.u, reading.e].into_iter().flatten() {
            if let Some(slot) = values.get_mut(channels) {
                *slot = value;
            }
            channels += 1;
        }
        let Some(row) = self
            .decimator
            .push_channels(values, channels.min(values.len()))
        else {
            return false;
        };
        let mut next = 1;
        let mut unpack = |present: Option<f32>| {
            present.and_then(|_| {
                let value = row.get(next).copied();
                next += 1;
                value
            })
        };
        let v = unpack(reading.v);
        let u = unpack(reading.u);
        let e = unpack(reading.e);
        let reading = Reading { x: row[0], v, u, e };
        // Row r ends with conversion (r + warm_up) · factor − 1 (the CIC's order, and the
        // compensator's two rows when decimating).
        let warm_up = u64::from(self.decimator.warm_up());
        let index = (c + 1) / factor - warm_up;
        self.next += 1;
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
        true
    }

    /// The sensor has no more samples: queues the end once (false while the queue is full;
    /// call again on the next tick).
    pub fn end(&mut self) -> bool {
        if !self.ended && self.producer.enqueue(Event::End).is_ok() {
            self.ended = true;
        }
        self.ended
    }

    /// Rows made so far (queued or lost).
    pub fn taken(&self) -> u64 {
        self.next
    }

    /// ADC conversions taken so far.
    pub fn conversions(&self) -> u64 {
        self.conversions
    }
}
