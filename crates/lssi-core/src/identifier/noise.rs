//! What is known of the raw channels' noise: white-noise variances from fourth differences,
//! and the gains of the filters that make x̂, v̂ and ŷ from them.

#[cfg(feature = "noise-correction")]
use crate::eiv;
use crate::real::Real;

/// Noise statistics over the rows.
///
/// ```text
/// noise.observe(front.fourth_differences(velocity), velocity);
/// let (sigma2_x, sigma2_v) = noise.raw(velocity)?;
/// ```
#[derive(Clone, Copy, Debug)]
pub(super) struct ChannelNoise<T> {
    /// Σ(Δ⁴x)², Σ(Δ⁴v)² over the rows and their count: the white-noise variance of the raw
    /// channels is Σ/(70·count).
    d4: (T, T, T),
    /// ‖h‖² of the filters that make x̂ and v̂ from the raw channels.
    gains: (T, T),
    /// h·h' of the filters that make x̂ and ŷ, and v̂ and ŷ (0 for different channels).
    #[cfg_attr(not(feature = "noise-correction"), allow(dead_code))]
    cross: (T, T),
    /// Σx̂², Σv̂² over the same rows as `d4`.
    power: (T, T),
}

/// What the smoothing decision weighs: σ²‖h‖² left on x̂ and v̂, Σx̂², Σv̂², and the rows.
#[derive(Clone, Copy, Debug)]
pub(super) struct Levels<T> {
    pub noise: (T, T),
    pub power: (T, T),
    pub rows: T,
}

impl<T: Real> ChannelNoise<T> {
    /// Storage (all zero bits), and the state before any row with unknown gains.
    pub(super) const fn zeroed() -> Self {
        Self {
            d4: (T::ZERO, T::ZERO, T::ZERO),
            gains: (T::ZERO, T::ZERO),
            cross: (T::ZERO, T::ZERO),
            power: (T::ZERO, T::ZERO),
        }
    }

    /// The filters' ‖h‖² it was made with.
    pub(super) fn gains(&self) -> (T, T) {
        self.gains
    }

    /// The filters' h·h' it was made with.
    pub(super) fn cross(&self) -> (T, T) {
        self.cross
    }

    /// No rows yet, with the filters' ‖h‖² (`gains`) and h·h' (`cross`).
    pub(super) fn new(gains: (T, T), cross: (T, T)) -> Self {
        Self {
            gains,
            cross,
            ..Self::zeroed()
        }
    }

    /// Adds a row's squared fourth differences of x and (if measured) v.
    #[inline]
    pub(super) fn observe(&mut self, (dx, dv): (T, T), velocity: bool) {
        self.d4.0 += dx;
        if velocity {
            self.d4.1 += dv;
        }
        self.d4.2 += T::ONE;
    }

    /// Adds a row's x̂² and v̂².
    #[inline]
    pub(super) fn observe_power(&mut self, x: T, v: T) {
        self.power.0 += x * x;
        self.power.1 += v * v;
    }

    /// The white-noise variances of the raw channels that x̂ and v̂ are made from (x, and the
    /// measured v or x again), from the fourth differences so far; `None` before any row.
    pub(super) fn raw(&self, velocity: bool) -> Option<(T, T)> {
        let (sx, sv, n) = self.d4;
        if n <= T::ZERO {
            return None;
        }
        let sigma2 = |sum: T| sum / (T::from_f64(crate::tuning::FOURTH_DIFFERENCE_GAIN) * n);
        let x2 = sigma2(sx);
        let v2 = if velocity { sigma2(sv) } else { x2 };
        Some((x2, v2))
    }

    /// The noise left on x̂ and v̂ with the power of both; `None` before any row.
    pub(super) fn levels(&self, velocity: bool) -> Option<Levels<T>> {
        let (x2, v2) = self.raw(velocity)?;
        Some(Levels {
            noise: (x2 * self.gains.0, v2 * self.gains.1),
            power: self.power,
            rows: self.d4.2,
        })
    }

    /// The noise covariances of a row's x̂, v̂ and ŷ in the factors' scaled units (x̂ and v̂
    /// in `units`, ŷ in `uy`), from the raw channels' white-noise variance through the
    /// filters. A channel whose k-neighbour smoothing is `smoothed` has no known noise left:
    /// its terms are 0 (see `eiv`).
    #[cfg(feature = "noise-correction")]
    pub(super) fn row_noise(
        &self,
        velocity: bool,
        (ux, uv): (T, T),
        uy: T,
        (smooth_x, smooth_v): (bool, bool),
    ) -> eiv::RowNoise<T> {
        let Some((x2, v2)) = self.raw(velocity) else {
            return eiv::RowNoise::default();
        };
        let mut noise = eiv::RowNoise {
            xx: x2 * self.gains.0 / (ux * ux),
            vv: v2 * self.gains.1 / (uv * uv),
            xy: x2 * self.cross.0 / (ux * uy),
            vy: v2 * self.cross.1 / (uv * uy),
        };
        if smooth_x {
            noise.xx = T::ZERO;
            noise.xy = T::ZERO;
        }
        if smooth_v {
            noise.vv = T::ZERO;
            noise.vy = T::ZERO;
        }
        noise
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_noise_variance_from_fourth_differences() {
        // Fourth differences of white noise of variance σ² have variance 70σ².
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
        };
        let mut noise = ChannelNoise::<f64>::new((0.5, 0.25), (0.0, 0.0));
        assert!(noise.raw(false).is_none());
        let mut w: Vec<f64> = (0..5).map(|_| next()).collect();
        for _ in 0..200_000 {
            w.remove(0);
            w.push(next());
            let d = w[0] - 4.0 * w[1] + 6.0 * w[2] - 4.0 * w[3] + w[4];
            noise.observe((d * d, 0.0), false);
            noise.observe_power(1.0, 2.0);
        }
        let (x2, v2) = noise.raw(false).expect("rows");
        assert!((x2 - 1.0).abs() < 0.03, "{x2}");
        assert_eq!(x2, v2);
        let levels = noise.levels(false).expect("rows");
        assert_eq!(levels.noise, (x2 * 0.5, x2 * 0.25));
        assert_eq!(levels.power, (200_000.0, 800_000.0));
        assert_eq!(levels.rows, 200_000.0);
    }
}
