//! Seeded link faults and baud-rate pacing, one instance per direction.

use std::time::{Duration, Instant};

/// Probability per byte that a garbage burst starts before it, when bursts are on
/// (`--burst N` > 0), unless `--burst-rate` says otherwise: one burst per 4 KiB.
pub const DEFAULT_BURST_RATE: f64 = 1.0 / 4096.0;

/// What can go wrong on one direction of the line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Faults {
    /// Probability per byte of flipping one random bit of it.
    pub flip_rate: f64,
    /// Probability per byte of losing it.
    pub drop_rate: f64,
    /// Longest garbage burst, in bytes (0: no bursts).
    pub burst: u16,
    /// Probability per byte that a burst of 1..=`burst` random bytes is inserted before it.
    pub burst_rate: f64,
}

impl Faults {
    /// Whether any fault can happen.
    pub fn any(&self) -> bool {
        self.flip_rate > 0.0 || self.drop_rate > 0.0 || (self.burst > 0 && self.burst_rate > 0.0)
    }
}

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny, well-mixed, seedable generator; the
/// fault pattern of a seed is reproducible on every platform.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1), 53 bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// True with probability `p` (never for p = 0, without drawing).
    pub fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.unit() < p
    }

    /// Uniform in 0..n (n > 0).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n.max(1)
    }
}

/// Applies [`Faults`] to a byte stream.
#[derive(Clone, Debug)]
pub struct Injector {
    faults: Faults,
    rng: SplitMix64,
    /// Bytes flipped, dropped, and garbage bytes inserted so far.
    pub counts: [u64; 3],
}

impl Injector {
    /// An injector drawing from `seed`.
    pub fn new(faults: Faults, seed: u64) -> Self {
        Self {
            faults,
            rng: SplitMix64::new(seed),
            counts: [0; 3],
        }
    }

    /// Appends `input`, damaged, to `out`.
    pub fn apply(&mut self, input: &[u8], out: &mut Vec<u8>) {
        if !self.faults.any() {
            out.extend_from_slice(input);
            return;
        }
        for &byte in input {
            if self.faults.burst > 0 && self.rng.chance(self.faults.burst_rate) {
                let len = 1 + self.rng.below(u64::from(self.faults.burst));
                for _ in 0..len {
                    out.push(self.rng.next_u64() as u8);
                }
                self.counts[2] += len;
            }
            if self.rng.chance(self.faults.drop_rate) {
                self.counts[1] += 1;
                continue;
            }
            let mut byte = byte;
            if self.rng.chance(self.faults.flip_rate) {
                byte ^= 1 << self.rng.below(8);
                self.counts[0] += 1;
            }
            out.push(byte);
        }
    }
}

/// How far behind its schedule the pacer may be and still count the line as busy.
pub const CATCH_UP: Duration = Duration::from_millis(3);

/// Holds bytes back so that they leave at a UART's pace: `baud / 10` bytes a second (8N1).
#[derive(Clone, Debug)]
pub struct Pacer {
    byte_time: Duration,
    /// When the line is free again.
    free_at: Instant,
}

impl Pacer {
    /// A pacer for `baud` bits per second (> 0).
    pub fn new(baud: u32) -> Self {
        Self {
            byte_time: Duration::from_secs_f64(10.0 / f64::from(baud.max(1))),
            free_at: Instant::now(),
        }
    }

    /// Most bytes to pace as one slice: about a millisecond of line time, at least 1.
    pub fn slice(&self) -> usize {
        let per_ms = Duration::from_millis(1).as_nanos() / self.byte_time.as_nanos().max(1);
        usize::try_from(per_ms).unwrap_or(usize::MAX).clamp(1, 256)
    }

    /// Sleeps until `n` more bytes, queued after everything before them, are through the line.
    ///
    /// A sleep overshoots by a fraction of a millisecond; on a line kept busy, that overshoot
    /// is not idle line time, so the schedule is kept when it is behind by less than
    /// [`CATCH_UP`] (otherwise every ~1 ms slice would lose its overshoot: about 20 % of the
    /// line on a loaded machine). A line idle for longer starts afresh, as a UART does.
    pub fn wait(&mut self, n: usize) {
        let now = Instant::now();
        let start = if now.saturating_duration_since(self.free_at) < CATCH_UP {
            self.free_at
        } else {
            now
        };
        self.free_at = start + self.byte_time * u32::try_from(n).unwrap_or(u32::MAX);
        if let Some(left) = self.free_at.checked_duration_since(now) {
            std::thread::sleep(left);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_faults_pass_bytes_through() {
        let mut injector = Injector::new(
            Faults {
                flip_rate: 0.0,
                drop_rate: 0.0,
                burst: 0,
                burst_rate: DEFAULT_BURST_RATE,
            },
            1,
        );
        let mut out = Vec::new();
        injector.apply(&[1, 2, 0, 3], &mut out);
        assert_eq!(out, [1, 2, 0, 3]);
    }

    #[test]
    fn rates_are_honoured_and_seeds_reproduce() {
        let faults = Faults {
            flip_rate: 0.01,
            drop_rate: 0.02,
            burst: 8,
            burst_rate: 0.001,
        };
        let input = vec![0x55u8; 200_000];
        let run = |seed| {
            let mut injector = Injector::new(faults, seed);
            let mut out = Vec::new();
            injector.apply(&input, &mut out);
            (out, injector.counts)
        };
        let (a, counts) = run(7);
        assert_eq!(run(7).0, a);
        assert_ne!(run(8).0, a);
        let n = input.len() as f64;
        assert!(
            (counts[0] as f64 / n - 0.01 * 0.98).abs() < 0.002,
            "{counts:?}"
        );
        assert!((counts[1] as f64 / n - 0.02).abs() < 0.002, "{counts:?}");
        // Bursts: 0.001 per byte, 4.5 bytes on average.
        assert!((counts[2] as f64 / n - 0.0045).abs() < 0.0015, "{counts:?}");
    }

    #[test]
    fn pacing_takes_line_time() {
        let mut pacer = Pacer::new(115_200);
        let start = Instant::now();
        for _ in 0..10 {
            pacer.wait(115);
        }
        // 1150 bytes at 11 520 bytes/s: about 100 ms.
        let elapsed = start.elapsed().as_secs_f64();
        assert!((0.095..0.3).contains(&elapsed), "{elapsed}");
    }
}
