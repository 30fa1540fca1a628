//! The sampling interrupt's part.

use super::{Counters, Event, Reading};
use core::sync::atomic::Ordering;
use heapless::spsc::Producer;

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
