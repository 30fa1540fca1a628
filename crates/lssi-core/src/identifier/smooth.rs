//! The k-neighbour smoothing of x̂ and v̂ (paper eqs. 1–6) and the delay line that keeps ŷ,
//! û and t in step with them: estimates in, regression rows out.

use super::Row;
use super::front::Estimate;
use super::noise::Levels;
use crate::real::Real;
use crate::smoothing::KnnSmoother;

/// Rows of the delay line that keeps x'', u and t in step with the smoothed x and v.
pub(super) const DELAY: usize = KnnSmoother::<f32>::LAG + 1;

/// Two smoothers, whether each is applied, and the delay line.
///
/// ```text
/// let mut smoothing = Smoothing::new(row_stride);
/// if let Some(row) = smoothing.push(config.smoothing, estimate, t, defer) { /* a row */ }
/// smoothing.adapt(noise.levels(velocity)); // at a scheduled screening
/// ```
#[derive(Clone, Debug)]
pub(super) struct Smoothing<T> {
    x: KnnSmoother<T>,
    v: KnnSmoother<T>,
    /// Whether each channel's smoothing is applied (decided from ε(K) against the noise).
    on: (bool, bool),
    delay: [(T, T, f64); DELAY],
    delay_len: usize,
    delay_head: usize,
}

impl<T: Real> Smoothing<T> {
    /// Storage, not usable smoothers (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            x: KnnSmoother::zeroed(),
            v: KnnSmoother::zeroed(),
            on: (false, false),
            delay: [(T::ZERO, T::ZERO, 0.0); DELAY],
            delay_len: 0,
            delay_head: 0,
        }
    }

    /// Fresh smoothers for rows every `row_stride` samples, both off.
    pub(super) fn new(row_stride: u16) -> Self {
        let mut s = Self {
            x: KnnSmoother::new(),
            v: KnnSmoother::new(),
            ..Self::zeroed()
        };
        // ε(K) as often per sample as with the default row every 4 samples.
        let sparseness = (4 / u32::from(row_stride)).max(1);
        s.x.set_sparseness(sparseness);
        s.v.set_sparseness(sparseness);
        // v evaluates ε(K) half an interval after x (the intervals are even multiples of 2).
        s.v.set_phase(2 * sparseness);
        s
    }

    /// Whether the last push evaluated ε(K) on either channel (never while the smoothing is
    /// disabled: the smoothers are then not pushed).
    pub(super) fn evaluated(&self) -> bool {
        self.x.evaluated() || self.v.evaluated()
    }

    /// Forgets the neighbours and the delay line (after a gap).
    pub(super) fn restart(&mut self) {
        self.x.restart();
        self.v.restart();
        self.delay_len = 0;
        self.delay_head = 0;
    }

    /// The regression row of an estimate taken at time `t`: as it is when `enabled` is false;
    /// otherwise x̂ and v̂ smoothed (each where its smoothing is on) with ŷ, û and t delayed
    /// to match, once the smoothers and the delay line are full. With `defer`, an evaluation
    /// of ε(K) due on this row moves to the next ([`KnnSmoother::push_with`]).
    #[inline]
    pub(super) fn push(
        &mut self,
        enabled: bool,
        e: Estimate<T>,
        t: f64,
        defer: bool,
    ) -> Option<Row<T>> {
        if !enabled {
            return Some(Row {
                x: e.x,
                v: e.v,
                y: e.y,
                u: e.u,
                t,
            });
        }
        // A channel whose smoothing is off needs only its ε(K) (sampled more sparsely).
        let sx = self.x.push_with(e.x, self.on.0, defer);
        let sv = self.v.push_with(e.v, self.on.1, defer);
        // Delay x'', u and t by the smoother's lag.
        let slot = (self.delay_head + self.delay_len) % DELAY;
        self.delay[slot] = (e.y, e.u, t);
        if self.delay_len < DELAY {
            self.delay_len += 1;
        } else {
            self.delay_head = (self.delay_head + 1) % DELAY;
        }
        match (sx, sv) {
            (Some(x), Some(v)) if self.delay_len == DELAY => {
                let (y, u, t) = self.delay[self.delay_head];
                Some(Row { x, v, y, u, t })
            }
            _ => None,
        }
    }

    /// Re-chooses K per channel from ε(K), and decides whether the smoothing is applied.
    ///
    /// What the smoothing removes is second order: noise in a regressor biases its
    /// coefficient by about σ²‖h‖²/E[ŝ²] (attenuation), where σ²‖h‖² is the noise the local
    /// polynomial leaves on the channel. What it adds is first order: rebuilding a point
    /// from its neighbours bends the signal by about √ε(K)/√E[ŝ²] (ε(K), the leave-one-out
    /// error, bounds that bias from above), and the regression averages noise away but not
    /// bias; a 0.3 % bend of x is amplified many times where the linear and cubic forces
    /// nearly cancel (a double well). So a channel is smoothed only where
    /// σ²‖h‖² > √(ε(K)·E[ŝ²]).
    pub(super) fn adapt(&mut self, levels: Option<Levels<T>>) {
        let keep = T::from_f64(0.5);
        if let Some(l) = levels {
            let n = l.rows;
            let decide = |s: &KnnSmoother<T>, noise: T, power: T| {
                s.mean_error(s.k())
                    .is_some_and(|e| noise > (e * power / n).sqrt())
            };
            self.on = (
                decide(&self.x, l.noise.0, l.power.0),
                decide(&self.v, l.noise.1, l.power.1),
            );
        }
        self.x.choose_k(keep);
        self.v.choose_k(keep);
    }

    /// Whether the smoothing is applied to (x̂, v̂) now, when `enabled`.
    pub(super) fn applied(&self, enabled: bool) -> (bool, bool) {
        if enabled { self.on } else { (false, false) }
    }

    /// The K of each channel as a model reports it (0 where the smoothing is not applied).
    pub(super) fn ks(&self, enabled: bool) -> (u8, u8) {
        let k = |s: &KnnSmoother<T>, on: bool| {
            if enabled && on { s.k() as u8 } else { 0 }
        };
        (k(&self.x, self.on.0), k(&self.v, self.on.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(i: u32) -> (Estimate<f64>, f64) {
        let t = f64::from(i) * 0.01;
        (
            Estimate {
                x: t.sin(),
                v: t.cos(),
                y: -t.sin(),
                u: 0.5,
            },
            t,
        )
    }

    #[test]
    fn disabled_passes_the_estimate_through() {
        let mut s = Smoothing::<f64>::new(4);
        let (e, t) = estimate(7);
        let row = s.push(false, e, t, false).expect("a row at once");
        assert_eq!((row.x, row.v, row.y, row.u, row.t), (e.x, e.v, e.y, e.u, t));
        assert_eq!(s.applied(false), (false, false));
        assert_eq!(s.ks(false), (0, 0));
    }

    #[test]
    fn the_delay_line_keeps_y_u_and_t_in_step() {
        let mut s = Smoothing::<f64>::new(4);
        let mut first = None;
        for i in 0..200 {
            let (e, t) = estimate(i);
            if let Some(row) = s.push(true, e, t, false) {
                // Smoothing is off until `adapt` turns it on: x is the delayed x̂, at the
                // delayed time.
                let lag = i - (row.t / 0.01).round() as u32;
                first.get_or_insert(lag);
                assert_eq!(Some(lag), first, "{i}");
                assert!((row.x - row.t.sin()).abs() < 1e-12, "{i}");
                assert!((row.y + row.t.sin()).abs() < 1e-12, "{i}");
                assert_eq!(row.u, 0.5);
            }
        }
        assert_eq!(first, Some(KnnSmoother::<f64>::LAG as u32));
        s.restart();
        let (e, t) = estimate(300);
        assert!(s.push(true, e, t, false).is_none());
    }

    #[test]
    fn smooths_only_where_the_noise_outweighs_the_bend() {
        let mut s = Smoothing::<f64>::new(4);
        for i in 0..400 {
            let (e, t) = estimate(i);
            let _ = s.push(true, e, t, false);
        }
        let quiet = Levels {
            noise: (0.0, 0.0),
            power: (200.0, 200.0),
            rows: 400.0,
        };
        s.adapt(Some(quiet));
        assert_eq!(s.applied(true), (false, false));
        let loud = Levels {
            noise: (1.0, 1.0),
            power: (200.0, 200.0),
            rows: 400.0,
        };
        s.adapt(Some(loud));
        assert_eq!(s.applied(true), (true, true));
        assert_eq!(s.applied(false), (false, false));
        let (kx, kv) = s.ks(true);
        assert!(kx > 0 && kv > 0, "{kx} {kv}");
    }
}
