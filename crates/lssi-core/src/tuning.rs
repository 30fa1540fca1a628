//! Data-driven choice of the derivative window (DESIGN.md, "Derivatives"): no hand-set
//! window, as there is no hand-set K.
//!
//! The target x'' is estimated by a local polynomial of degree p over N samples. A longer
//! window averages more noise away but bends the signal more (bias); which wins depends on
//! the noise, the signal's bandwidth and how many samples the fit will average over. For each
//! candidate (N, p) this estimates, on a stretch of the recording:
//!
//! - the white-noise variance σ² of the channel the target is taken from (x, or a measured v),
//!   from fourth differences: E[(Δ⁴s)²] = 70σ² when the signal is smooth at the sample rate;
//! - the bias, from the disagreement with a degree p + 2 fit on the same window (whose bias
//!   is far smaller): E[(ŷ_p − ŷ_(p+2))²] − σ²‖h_p − h_(p+2)‖²;
//! - the noise variance σ²‖h_p‖², which the regression averages over the about n/N
//!   independent windows of the n samples it remembers, while the bias does not average out,
//!
//! and picks the (N, p) with the least bias² + σ²‖h_p‖²·N/n.

use crate::derivative::Taps;
use crate::real::Real;

/// Candidate window lengths (odd, so the centre is a sample).
pub const WINDOWS: [usize; 13] = [15, 23, 31, 47, 63, 95, 127, 191, 255, 383, 511, 767, 1023];
/// Candidate polynomial degrees.
pub const DEGREES: [usize; 3] = [3, 5, 7];
/// Evaluation points per candidate.
const POINTS: usize = 2000;

/// The chosen window and what was estimated about it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowChoice {
    /// Samples in the window.
    pub window: usize,
    /// Polynomial degree.
    pub degree: u8,
    /// Estimated white-noise standard deviation of the target's source channel.
    pub noise: f64,
    /// Estimated RMS bias of the target estimate.
    pub bias: f64,
    /// RMS of the target estimate (for scale).
    pub target_rms: f64,
}

/// Chooses (N, p) for a recording: `source` is x (x only) or the measured v, `order` the
/// derivative of `source` that gives x'' (2 or 1), `n_memory` the samples the fit will
/// average over (the record's length, or the memory time constant over the period).
/// Returns `None` when the stretch is shorter than the shortest window. `W` caps N.
pub fn choose_window<T: Real, const W: usize>(
    source: &[T],
    order: usize,
    sample_period: f64,
    n_memory: usize,
) -> Option<WindowChoice> {
    let n = source.len();
    if n < WINDOWS[0] + 4 {
        return None;
    }
    // σ² from fourth differences.
    let mut d4 = 0.0;
    for w in source.windows(5) {
        let d = w[0].to_f64() - 4.0 * w[1].to_f64() + 6.0 * w[2].to_f64() - 4.0 * w[3].to_f64()
            + w[4].to_f64();
        d4 += d * d;
    }
    let sigma2 = d4 / (n - 4) as f64 / 70.0;
    let mut best: Option<(f64, WindowChoice)> = None;
    for &len in WINDOWS.iter().filter(|&&l| l <= W && l + 4 <= n) {
        for &p in DEGREES.iter() {
            if len < p + 2 + 3 {
                continue;
            }
            let (Ok(taps), Ok(reference)) = (
                Taps::<f64, W>::design(len, p, sample_period),
                Taps::<f64, W>::design(len, p + 2, sample_period),
            ) else {
                continue;
            };
            let (h, r) = (taps.taps(order), reference.taps(order));
            let gain: f64 = h.iter().map(|v| v * v).sum();
            let diff_gain: f64 = h.iter().zip(r).map(|(a, b)| (a - b) * (a - b)).sum();
            let positions = n - len + 1;
            let step = (positions / POINTS).max(1);
            let (mut disagreement, mut power, mut count) = (0.0, 0.0, 0usize);
            let mut start = 0;
            while start < positions {
                let window = &source[start..start + len];
                let (mut a, mut b) = (0.0, 0.0);
                for ((s, hv), rv) in window.iter().zip(h).zip(r) {
                    let s = s.to_f64();
                    a += hv * s;
                    b += rv * s;
                }
                disagreement += (a - b) * (a - b);
                power += a * a;
                count += 1;
                start += step;
            }
            let count = count.max(1) as f64;
            let bias2 = (disagreement / count - sigma2 * diff_gain).max(0.0);
            let variance = sigma2 * gain;
            let cost = bias2 + variance * len as f64 / n_memory.max(len) as f64;
            let choice = WindowChoice {
                window: len,
                degree: p as u8,
                noise: libm::sqrt(sigma2),
                bias: libm::sqrt(bias2),
                target_rms: libm::sqrt(power / count),
            };
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, choice));
            }
        }
    }
    best.map(|(_, c)| c)
}
