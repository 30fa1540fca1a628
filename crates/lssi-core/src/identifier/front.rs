//! The front end: the raw samples' ring buffers and the fixed-lag local-polynomial (FIR)
//! estimates of x, x', x'' (and u) at the window's centre.

use super::Sample;
use crate::config::Channels;
use crate::derivative::FoldedTaps;
use crate::real::Real;
use heapless::HistoryBuf;

/// The ring buffer of v, when v is measured (x's is ring 0, u's the next one).
pub(super) const V_RING: usize = 1;

/// The local-polynomial estimates at a window's centre.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Estimate<T> {
    /// x̂.
    pub x: T,
    /// v̂: the measured v smoothed, or dx̂/dt.
    pub v: T,
    /// ŷ = x̂''.
    pub y: T,
    /// û (0 when u is not measured).
    pub u: T,
}

/// `C` ring buffers of `W` samples (x, then v and u, each when measured) and the folded
/// derivative taps.
///
/// ```text
/// front.write(&sample);
/// if front.len() >= window { let e = front.estimate(channels); }
/// ```
pub(super) struct Front<T, const W: usize, const C: usize> {
    pub(super) taps: FoldedTaps<T, W>,
    /// The raw samples of each channel: x in ring 0, then v and u, each when measured.
    rings: [HistoryBuf<T, W>; C],
    /// The ring of u (meaningful only when u is measured): the one after v's, if any.
    u_ring: usize,
}

impl<T: Real, const W: usize, const C: usize> Front<T, W, C> {
    /// Storage, not a usable front end (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            taps: FoldedTaps::empty(),
            rings: [const { HistoryBuf::new() }; C],
            u_ring: 0,
        }
    }

    /// Empties the rings and lays them out for `channels` (`validate` checked that they fit
    /// in C). The taps are designed separately ([`FoldedTaps::design`]).
    pub(super) fn configure(&mut self, channels: Channels) {
        self.clear();
        // x in ring 0, then v and u in that order, each when measured.
        self.u_ring = V_RING + usize::from(channels.velocity);
    }

    /// Forgets the samples (after a gap).
    pub(super) fn clear(&mut self) {
        for ring in self.rings.iter_mut() {
            ring.clear();
        }
    }

    /// Samples buffered (of x).
    pub(super) fn len(&self) -> usize {
        self.rings[0].len()
    }

    /// Writes a checked sample: its v and u come exactly when configured, so they have rings.
    #[inline]
    pub(super) fn write(&mut self, sample: &Sample<T>) {
        self.rings[0].write(sample.x);
        if let Some(v) = sample.v {
            self.rings[V_RING].write(v);
        }
        if let Some(u) = sample.u {
            self.rings[self.u_ring].write(u);
        }
    }

    /// x̂, v̂, ŷ and û at the centre of the (full) window.
    #[inline]
    pub(super) fn estimate(&self, channels: Channels) -> Estimate<T> {
        let taps = &self.taps;
        let (xa, xb) = self.rings[0].as_slices();
        let x = taps.apply(0, xa, xb);
        let (v, y) = if channels.velocity {
            let (va, vb) = self.rings[V_RING].as_slices();
            (taps.apply(0, va, vb), taps.apply(1, va, vb))
        } else {
            (taps.apply(1, xa, xb), taps.apply(2, xa, xb))
        };
        let u = if channels.input {
            let (ua, ub) = self.rings[self.u_ring].as_slices();
            taps.apply(0, ua, ub)
        } else {
            T::ZERO
        };
        Estimate { x, v, y, u }
    }

    /// The squared fourth differences of the newest samples of x and (when measured) v, whose
    /// mean is 70 times the white-noise variance; the window holds at least five samples
    /// (its minimum is degree + 3 ≥ 5).
    #[inline]
    pub(super) fn fourth_differences(&self, velocity: bool) -> (T, T) {
        // The five newest samples, newest first (0 where fewer were written), read from the
        // ring's two slices directly: the buffer's reversed chained iterator and the
        // coefficients' run-time f64 → T conversions cost about 100 instructions a row on
        // the M4F. The same products summed in the same order as before.
        let d4 = |buffer: &HistoryBuf<T, W>| {
            let (older, newer) = buffer.as_slices();
            // Almost always the five lie in the newer slice: read them straight (no zeroed
            // array, no branch per sample).
            if let Some(&[r4, r3, r2, r1, r0]) = newer.last_chunk::<5>() {
                return fourth_difference([r0, r1, r2, r3, r4]);
            }
            let mut recent = [T::ZERO; 5];
            for (k, r) in recent.iter_mut().enumerate() {
                *r = if k < newer.len() {
                    newer[newer.len() - 1 - k]
                } else if k - newer.len() < older.len() {
                    older[older.len() - 1 - (k - newer.len())]
                } else {
                    T::ZERO
                };
            }
            fourth_difference(recent)
        };
        let dv = if velocity {
            d4(&self.rings[V_RING])
        } else {
            T::ZERO
        };
        (d4(&self.rings[0]), dv)
    }
}

/// The squared fourth difference of five samples, newest first.
#[inline(always)]
fn fourth_difference<T: Real>(recent: [T; 5]) -> T {
    let (one, four, six) = (T::ONE, T::from_f64(4.0), T::from_f64(6.0));
    let mut d = T::ZERO;
    d += one * recent[0];
    d += -four * recent[1];
    d += six * recent[2];
    d += -four * recent[3];
    d += one * recent[4];
    d * d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::derivative::Design;

    fn front(channels: Channels) -> Front<f64, 64, 3> {
        let mut f = Front::<f64, 64, 3>::zeroed();
        f.configure(channels);
        let design = Design::new(31, 3, 0.01, 64).expect("a valid design");
        f.taps.design(&design, |_| {});
        f
    }

    #[test]
    fn estimates_a_polynomial_exactly_at_the_centre() {
        let channels = Channels {
            velocity: false,
            input: true,
        };
        let mut f = front(channels);
        for i in 0..40 {
            let t = f64::from(i) * 0.01;
            f.write(&Sample {
                t,
                x: 1.0 + 2.0 * t + 3.0 * t * t,
                v: None,
                u: Some(5.0),
            });
        }
        assert_eq!(f.len(), 40);
        // The window's centre is 15 samples behind the newest (t = 0.39).
        let tc = 0.24;
        let e = f.estimate(channels);
        assert!(
            (e.x - (1.0 + 2.0 * tc + 3.0 * tc * tc)).abs() < 1e-9,
            "{e:?}"
        );
        assert!((e.v - (2.0 + 6.0 * tc)).abs() < 1e-7, "{e:?}");
        assert!((e.y - 6.0).abs() < 1e-5, "{e:?}");
        assert!((e.u - 5.0).abs() < 1e-9, "{e:?}");
        // A cubic... has no fourth difference.
        assert!(f.fourth_differences(false).0 < 1e-20);
        f.clear();
        assert_eq!(f.len(), 0);
    }

    #[test]
    fn a_measured_velocity_has_its_own_ring() {
        let channels = Channels {
            velocity: true,
            input: false,
        };
        let mut f = front(channels);
        for i in 0..40 {
            let t = f64::from(i) * 0.01;
            f.write(&Sample {
                t,
                x: t,
                v: Some(7.0 + (-1.0f64).powi(i)),
                u: None,
            });
        }
        let e = f.estimate(channels);
        assert!((e.x - 0.24).abs() < 1e-9);
        // The alternating noise on v shows in its fourth differences (16² each).
        assert!((e.v - 7.0).abs() < 0.5, "{e:?}");
        assert_eq!(f.fourth_differences(true).1, 256.0);
    }

    /// Wherever the ring wraps (the five newest samples in its newer slice, or split across
    /// both), the fourth differences are those of the five newest samples, bit for bit, and
    /// 0 stands in for samples not written yet.
    #[test]
    fn fourth_differences_read_the_newest_samples_at_every_wrap() {
        let channels = Channels {
            velocity: true,
            input: false,
        };
        let mut f = front(channels);
        let value = |i: i32| (0.37 * f64::from(i)).sin() + 0.01 * f64::from(i * i % 7);
        for i in 0..200 {
            f.write(&Sample {
                t: f64::from(i) * 0.01,
                x: value(i),
                v: Some(value(i + 3)),
                u: None,
            });
            let recent = |shift: i32| {
                core::array::from_fn(|k| {
                    let j = i - k as i32;
                    if j >= 0 { value(j + shift) } else { 0.0 }
                })
            };
            let expected = (fourth_difference(recent(0)), fourth_difference(recent(3)));
            assert_eq!(f.fourth_differences(true), expected, "{i}");
        }
    }
}
