//! The sampling interrupt's part.

use super::{Counters, Event, Reading, Shared};
use crate::decimate::Decimator;
use core::sync::atomic::Ordering;
use heapless::spsc::Producer;

/// Identical readings in a row after which the sensor counts as stuck: the readings that
/// follow, while they stay identical, are passed on as NaN (rejected and skipped like a
/// gap, so a stuck sensor cannot teach the identifier a flat line). 256 samples: 25.6 ms at
/// 10 kHz; a 12-bit ADC on a 1 Hz harvester at full scale holds one code for about 5 ms at
/// a turning point, and sensor noise moves the last bit far more often.
pub const STUCK_RUN: u32 = 256;

/// The sampling interrupt's part: decimates the ADC's conversions to rows and queues each
/// row with its index and stamp.
pub struct Sampler<'q> {
    producer: Producer<'q, Event>,
    /// Conversions to rows (factor 1: every conversion is a row).
    decimator: Decimator,
    /// Conversions taken.
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
            conversions: 0,
            next: 0,
            ended: false,
            last_x: 0,
            run: 0,
        }
    }

    /// Decimates by `decimator` from the next conversion on (the rows in progress dropped).
    pub fn set_decimator(&mut self, decimator: Decimator) {
        self.decimator = decimator;
        self.decimator.restart();
    }

    /// The decimator in use.
    pub fn decimator(&self) -> &Decimator {
        &self.decimator
    }

    /// One timer interrupt's conversion, with the decimator thread mode asked for (if
    /// any) put in first: see [`Sampler::tick`].
    pub fn convert<const P: usize>(
        &mut self,
        stamp: u32,
        reading: Reading,
        shared: &Shared<P>,
    ) -> bool {
        if let Some(decimator) = shared.take_decimator() {
            self.set_decimator(decimator);
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
        self.conversions += 1;
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
        // x, then v and u packed after it when present (1 to 3 channels accumulated).
        let (values, channels) = match (reading.v, reading.u) {
            (None, None) => ([reading.x, 0.0, 0.0], 1),
            (Some(v), None) => ([reading.x, v, 0.0], 2),
            (None, Some(u)) => ([reading.x, u, 0.0], 2),
            (Some(v), Some(u)) => ([reading.x, v, u], 3),
        };
        let Some(row) = self.decimator.push_channels(values, channels) else {
            return false;
        };
        let (x, v, u) = match (reading.v, reading.u) {
            (None, None) => (row[0], None, None),
            (Some(_), None) => (row[0], Some(row[1]), None),
            (None, Some(_)) => (row[0], None, Some(row[1])),
            (Some(_), Some(_)) => (row[0], Some(row[1]), Some(row[2])),
        };
        let reading = Reading { x, v, u };
        let index = self.next;
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
