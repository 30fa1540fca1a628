//! How the link sizes its batches and its window from the error rate it measures.
//!
//! The link counts the sample frames it sends (first sendings and resendings) and those the
//! device acknowledged. From the fraction f of frames that were not acknowledged and their
//! mean length n it estimates the line's byte error rate b = 1 − (1 − f)^(1/n) (an
//! overestimate under go-back-N, which also resends the intact frames behind a lost one:
//! it errs towards shorter frames), and picks
//!
//! - the batch length L that carries the most samples per byte sent when each frame of
//!   n(L) = overhead + bytes_per_sample·L bytes crosses with probability (1 − b)^n(L):
//!   L·(1 − b)^n(L) / n(L), largest at L ≈ 1/(bytes_per_sample·b) under faults, the
//!   longest batch allowed on a clean line;
//! - the window W = ⌈2 / (1 − p)⌉ batches (p the chance such a frame crosses), at least 2 and
//!   at most the window allowed: go-back-N resends up to W frames per loss, so W shrinks
//!   when losses are frequent and grows back to the full window when the line is clean.
//!
//! The counts decay (halved every [`HALF_LIFE`] frames), so the choice follows a line whose
//! error rate changes.

/// Frames after which the counts are halved.
pub const HALF_LIFE: f64 = 256.0;
/// Bytes of a sample frame besides its samples (tag, seq, start, channels, count, CRC, COBS,
/// delimiter), about.
pub const FRAME_OVERHEAD: f64 = 14.0;

/// The error-rate estimate and the choices it makes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adapt {
    frames: f64,
    acked: f64,
    bytes: f64,
    bytes_per_sample: f64,
    max_batch: usize,
    max_window: usize,
}

impl Adapt {
    /// A clean line so far; batches of at most `max_batch` samples of `bytes_per_sample`
    /// bytes, at most `max_window` in flight.
    pub fn new(bytes_per_sample: usize, max_batch: usize, max_window: usize) -> Self {
        Self {
            frames: 0.0,
            acked: 0.0,
            bytes: 0.0,
            bytes_per_sample: bytes_per_sample.max(1) as f64,
            max_batch: max_batch.max(1),
            max_window: max_window.max(1),
        }
    }

    /// A sample frame of `len` bytes was sent (first time or again).
    pub fn sent(&mut self, len: usize) {
        self.frames += 1.0;
        self.bytes += len as f64;
        if self.frames >= 2.0 * HALF_LIFE {
            self.frames /= 2.0;
            self.acked /= 2.0;
            self.bytes /= 2.0;
        }
    }

    /// `n` frames were acknowledged.
    pub fn acked(&mut self, n: usize) {
        self.acked = (self.acked + n as f64).min(self.frames);
    }

    /// Fraction of the sample frames sent recently that were not acknowledged (0 before
    /// the first frame).
    pub fn frame_loss(&self) -> f64 {
        if self.frames > 0.0 {
            (1.0 - self.acked / self.frames).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The byte error rate the losses imply. Frames still in flight count as lost until
    /// acknowledged, so a window's worth is discounted.
    pub fn byte_error_rate(&self) -> f64 {
        let unacked = self.frames - self.acked - self.max_window as f64;
        if self.frames <= 0.0 || unacked <= 0.0 {
            return 0.0;
        }
        let mean_len = (self.bytes / self.frames).max(1.0);
        let crossed = (1.0 - unacked / self.frames).max(1e-6);
        1.0 - crossed.powf(1.0 / mean_len)
    }

    /// The batch length and the window for the line as measured.
    pub fn choose(&self) -> (usize, usize) {
        let b = self.byte_error_rate();
        if b <= 0.0 {
            return (self.max_batch, self.max_window);
        }
        let survive =
            |len: usize| (1.0 - b).powf(FRAME_OVERHEAD + self.bytes_per_sample * len as f64);
        let value = |len: usize| {
            len as f64 * survive(len) / (FRAME_OVERHEAD + self.bytes_per_sample * len as f64)
        };
        let batch = (1..=self.max_batch)
            .max_by(|&a, &b| value(a).total_cmp(&value(b)))
            .unwrap_or(self.max_batch);
        let p = survive(batch);
        let window = if p >= 1.0 {
            self.max_window
        } else {
            (2.0 / (1.0 - p)).ceil().min(self.max_window as f64) as usize
        };
        (batch, window.clamp(2.min(self.max_window), self.max_window))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clean_line_gets_the_longest_batches_and_the_full_window() {
        let mut adapt = Adapt::new(2, 64, 8);
        for _ in 0..1000 {
            adapt.sent(142);
            adapt.acked(1);
        }
        assert_eq!(adapt.choose(), (64, 8));
        // Frames in flight are not losses.
        for _ in 0..8 {
            adapt.sent(142);
        }
        assert_eq!(adapt.choose(), (64, 8));
    }

    #[test]
    fn losses_shorten_the_batches_and_the_window_and_a_clean_run_restores_them() {
        let mut adapt = Adapt::new(2, 64, 8);
        // 2 % of the bytes damaged: a 142-byte frame crosses 6 % of the time.
        for i in 0..400 {
            adapt.sent(142);
            if i % 100 >= 94 {
                adapt.acked(1);
            }
        }
        let b = adapt.byte_error_rate();
        assert!((0.01..0.03).contains(&b), "{b}");
        let (batch, window) = adapt.choose();
        assert!((6..=16).contains(&batch), "{batch}");
        assert!(window <= 5, "{window}");
        for _ in 0..4000 {
            adapt.sent(142);
            adapt.acked(1);
        }
        let (batch, window) = adapt.choose();
        assert!(batch >= 48 && window == 8, "{batch} {window}");
    }
}
