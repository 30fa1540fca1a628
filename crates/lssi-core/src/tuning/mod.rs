//! Data-driven choice of the derivative window (docs/design.md, "Derivatives"): no hand-set
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
//!   independent windows of the n samples it remembers, while the bias does not average out;
//! - with x only, the bias that the noise of the regressors x̂ and v̂ causes, which does not
//!   average out either: x̂'s noise is correlated with x''-hat's (σ²h₀·h₂), v̂'s variance
//!   σ²‖h₁‖² shrinks the v terms,
//!
//! and picks the (N, p) with the least sum (bias² + regressor bias² + σ²‖h_p‖²·N/n). Where
//! a bias is too small to measure against the noise it is extrapolated from a longer window
//! (see `choose_capped`).
//!
//! # The period cap
//!
//! The disagreement measures the bias only while the reference degree p + 2 fit follows the
//! signal across the window. Once a window spans more than a period, both fits are low-pass
//! filters whose stop band holds the signal: both return nearly 0, they agree, the estimated
//! bias is 0 and the longest window wins, although it has removed the signal it should
//! differentiate. On the measured records this is what happened (the FrID beam at 24 samples
//! per period and Silverbox at about 10 got the longest window, 1023 samples, degree 3); the
//! fourth-difference σ² made it worse there, as signal content near Nyquist inflates it and
//! the bias is over-subtracted, but an exact σ² would not have saved a window of 40 periods.
//!
//! So the candidates are capped at the signal's mean period T: N ≤ T, or the shortest
//! candidate alone when even that is longer. Over one period a polynomial of degree ≥ 5 (the
//! reference) follows a sinusoid to about 1 % (the Chebyshev bound π⁷/(7!·2⁶)), so within the
//! cap the disagreement is a faithful bias estimate again. T is measured without a transform
//! (this runs in `no_std`): the mean-removed source is passed through a Schmitt trigger with
//! thresholds ±3σ, clamped to [¼ RMS, ½ RMS], and T = 2 · samples / crossings, the
//! zero-crossing (Rice) rate, which for a broadband signal is its RMS frequency, the
//! conservative side for a derivative. The hysteresis keeps noise from chattering at the
//! crossings; the upper clamp keeps a σ² inflated by content near Nyquist (3 samples per
//! period make it as large as the signal) from lifting the thresholds above the signal. The
//! price: a source whose white noise is above about a third of its RMS chatters through
//! ±½ RMS and gets a short cap, a record no window makes identifiable anyway. A source
//! slower than two periods over the stretch gets no cap. On the synthetic recordings the cap does not bind (eq. 17: T ≈ 1600 samples of v
//! against the chosen 191; the bistable harvester: T ≈ 590 samples of x against 95), so their
//! choices are unchanged.

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
    /// Mean period of the source in samples ([`mean_period`]), which caps the window; `None`
    /// when the source showed too few crossings to tell (no cap).
    pub period: Option<f64>,
}

/// Chooses (N, p) for a recording: `source` is x (x only) or the measured v, `order` the
/// derivative of `source` that gives x'' (2 or 1), `n_memory` the samples the fit will
/// average over (the record's length, or the memory time constant over the period).
/// Returns `None` when the stretch is shorter than the shortest window. `W` caps N, and so
/// does the source's mean period (see the module docs).
pub fn choose_window<T: Real, const W: usize>(
    source: &[T],
    order: usize,
    sample_period: f64,
    n_memory: usize,
) -> Option<WindowChoice> {
    if source.len() < WINDOWS[0] + 4 {
        return None;
    }
    let sigma2 = noise_variance(source);
    let period = mean_period(source, libm::sqrt(sigma2));
    // The shortest candidate stays allowed whatever the period.
    let cap = period.map_or(W, |t| (t as usize).max(WINDOWS[0]).min(W));
    let mut choice = choose_capped::<T, W>(source, order, sample_period, n_memory, sigma2, cap)?;
    choice.period = period;
    Some(choice)
}

/// The source's mean period over the test function's width (see [`choose_test_rows`]).
pub const TEST_PERIOD_DIVISOR: f64 = 3.0;
/// The shortest test function worth having, in rows: below it the weights cannot be smooth
/// and the rows go into the regression as they are.
pub const MIN_TEST_ROWS: usize = 64;
/// The derivative window under test-function rows, as a fraction of the test function.
pub const TEST_WINDOW_FRACTION: usize = 16;
/// The polynomial degree under test-function rows.
pub const TEST_DEGREE: u8 = 5;
/// At a field device's rates (a third of the period under [`MIN_TEST_ROWS`]), the test
/// function spans half the period, at most [`MIN_TEST_ROWS`] rows, and at least this many.
pub const LOW_RATE_MIN_TEST_ROWS: usize = 12;
/// The derivative window under a low rate's test function, in samples.
pub const LOW_RATE_WINDOW: usize = 11;
/// Its polynomial degree.
pub const LOW_RATE_DEGREE: u8 = 7;

/// Test-function rows for a recording, and the short derivative window under them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TestRowsChoice {
    /// Rows (one per sample) per test function: `Config::test_rows`.
    pub test_rows: u16,
    /// Samples in the derivative window.
    pub window: usize,
    /// Its polynomial degree.
    pub degree: u8,
}

/// The weak form's set-up (the `weak` module, `Config::test_rows`) from the source's mean
/// period in samples ([`WindowChoice::period`]) and the samples the fit averages over.
///
/// The test function spans a third of the mean period: long enough that the weighted sum
/// of the target cancels its noise (the weights' second difference is small), short enough
/// that the weights pass the motion's first harmonics. On eq. 17 (T ≈ 3150 samples, the
/// zero-mean δ = 0.1 rows) a third was the best overall of 512, 768, 1024 and 1536 samples:
/// at 512 the ε = 0.3 x-only rows lost their weak terms (32 %), at 1536 two ε = 1 x-only
/// seeds took spurious terms. It is also at most a sixteenth of the samples, so that the
/// fit has 64 sums at least. Rows are taken at every sample: summing rows a stride apart
/// leaves the derivative filter's polyphase sums, which do not vanish, and the noise comes
/// back.
///
/// The derivative window is a sixteenth of the test function (odd, within the capacity
/// `W`), degree 5: short, so that the library terms are evaluated on nearly unbent signals;
/// the test function does the averaging. Between 31 and 127 samples the eq. 17 results
/// hardly moved.
///
/// At the rates a field device samples (30–190 samples a period, a third of it under
/// [`MIN_TEST_ROWS`]), the test function spans half the period (at most [`MIN_TEST_ROWS`]
/// rows) over a window of [`LOW_RATE_WINDOW`] samples of degree [`LOW_RATE_DEGREE`]. Rows
/// as they are lose the damping there: the second derivative of a signal sampled that
/// coarsely is too noisy for a term 2 % of x'' (the eveh harvester at 30–60 samples a
/// period, 1 % noise, x only: 26–56 % mean coefficient error, v dropped). Half a period and
/// 11 samples of degree 7 were the best of (⅓, ½, ¾, 1) × (7/4, 9/5, 11/5, 11/7) on seeds
/// 1–5 of bench/choice/testset.py's low-rate kinds, with Ω given.
///
/// `None` (rows as they are, the window from [`choose_window`]) without a period or when
/// the test function would be under [`LOW_RATE_MIN_TEST_ROWS`] samples (a signal sampled
/// that coarsely, under 24 samples a period, leaves no room for smooth weights).
pub fn choose_test_rows<const W: usize>(
    period: Option<f64>,
    samples: usize,
) -> Option<TestRowsChoice> {
    let period = period?;
    if !(period.is_finite() && period > 0.0) {
        return None;
    }
    let third = (period / TEST_PERIOD_DIVISOR) as usize;
    if third < MIN_TEST_ROWS {
        let width = ((period / 2.0) as usize)
            .min(MIN_TEST_ROWS)
            .min(samples / 16);
        let width = width - width % 4;
        if width < LOW_RATE_MIN_TEST_ROWS || W < LOW_RATE_WINDOW {
            return None;
        }
        return Some(TestRowsChoice {
            test_rows: width as u16,
            window: LOW_RATE_WINDOW,
            degree: LOW_RATE_DEGREE,
        });
    }
    let width = third.min(samples / 16).min(usize::from(u16::MAX));
    let width = width - width % 4;
    if width < MIN_TEST_ROWS {
        return None;
    }
    let min_window = usize::from(TEST_DEGREE) + 3;
    // Odd (the centre is a sample), rounded up, within the capacity.
    let mut window = (width / TEST_WINDOW_FRACTION).max(min_window) | 1;
    if window > W {
        window = W - (1 - W % 2);
    }
    if window < min_window {
        return None;
    }
    Some(TestRowsChoice {
        test_rows: width as u16,
        window,
        degree: TEST_DEGREE,
    })
}

/// E[(Δ⁴s)²] / σ² for white noise of variance σ² on a signal smooth at the sample rate
/// (1 + 16 + 36 + 16 + 1): the identifier's running noise estimate uses it too.
pub(crate) const FOURTH_DIFFERENCE_GAIN: f64 = 70.0;

/// White-noise variance from fourth differences: E[(Δ⁴s)²] = 70σ² when the signal is smooth
/// at the sample rate (an over-estimate when it is not).
fn noise_variance<T: Real>(source: &[T]) -> f64 {
    let n = source.len();
    if n < 5 {
        return 0.0;
    }
    let mut d4 = 0.0;
    for w in source.windows(5) {
        let d = w[0].to_f64() - 4.0 * w[1].to_f64() + 6.0 * w[2].to_f64() - 4.0 * w[3].to_f64()
            + w[4].to_f64();
        d4 += d * d;
    }
    d4 / (n - 4) as f64 / FOURTH_DIFFERENCE_GAIN
}

/// Mean period of `source` in samples, from its zero-crossing rate: the mean-removed signal
/// through a Schmitt trigger with thresholds ±3·`noise`, clamped to [RMS/4, RMS/2],
/// T = 2 · samples / crossings. `None` with fewer than 4 crossings (under two periods, or a source whose noise
/// hides it).
pub fn mean_period<T: Real>(source: &[T], noise: f64) -> Option<f64> {
    let n = source.len();
    if n < 2 {
        return None;
    }
    let mean = source.iter().map(|s| s.to_f64()).sum::<f64>() / n as f64;
    let power = source
        .iter()
        .map(|s| {
            let d = s.to_f64() - mean;
            d * d
        })
        .sum::<f64>()
        / n as f64;
    let rms = libm::sqrt(power);
    let threshold = (3.0 * noise).max(0.25 * rms).min(0.5 * rms);
    if !(threshold > 0.0) || !threshold.is_finite() {
        return None;
    }
    let (mut state, mut crossings) = (0i8, 0usize);
    for s in source {
        let d = s.to_f64() - mean;
        let next = if d > threshold {
            1
        } else if d < -threshold {
            -1
        } else {
            state
        };
        if next != state {
            if state != 0 {
                crossings += 1;
            }
            state = next;
        }
    }
    (crossings >= 4).then(|| 2.0 * n as f64 / crossings as f64)
}

/// What was measured of one candidate (N, p).
#[derive(Clone, Copy, Default)]
struct Measured {
    /// Mean square disagreement with the degree p + 2 fit, and its expected noise part
    /// σ²‖h_p − h_(p+2)‖².
    disagreement: f64,
    noise: f64,
    /// σ²‖h_p‖² and the mean square of the estimate.
    variance: f64,
    power: f64,
    /// The bias the noise of the regressors causes, squared (x only; see `choose_capped`).
    regressors: f64,
    valid: bool,
}

/// The rule on the candidates of at most `cap` samples, σ² given.
///
/// The bias is measured as the disagreement less its noise part, but where the noise part
/// is most of the disagreement that difference is noise itself (on eq. 17 with x only at
/// δ = 0.001 the 255-sample window measured 0 and the 191-sample one 8·10⁻⁴, the wrong way
/// round, and the bent 255-sample window won, 0.32 % off where 383 samples give 0.06 %). So
/// each degree's bias is measured where it stands three standard errors out of the noise
/// part (averaged over about n/N independent windows, that part is known to a relative
/// √(2N/n)), on the shortest such window N₀, and carried to the shorter windows by its
/// asymptotic law: an even filter of degree p (odd) is exact to
/// degree p + 1 (odd, for the first derivative) and the next term of the signal's
/// expansion it does not annihilate is of degree p + 3 (p + 2), so the bias of the second
/// derivative, τ^(p+3) through a filter of scale N⁻², grows as N^(p+1), as does the first
/// derivative's (τ^(p+2) at scale N⁻¹); its square as N^(2(p+1)). A window below N₀ gets
/// the larger of that law and its own measurement: the law is the asymptote, and a signal
/// whose window spans a good part of its period is not there yet (on the bistable
/// harvester the bias grows as N^5.6 between 191 and 255 samples, not N^16), so the law
/// alone would take a short window's bias for nothing. Windows at or above N₀ keep their
/// own measurement, and so do all windows of a degree whose bias is below the noise
/// everywhere (there is nothing better to go on).
fn choose_capped<T: Real, const W: usize>(
    source: &[T],
    order: usize,
    sample_period: f64,
    n_memory: usize,
    sigma2: f64,
    cap: usize,
) -> Option<WindowChoice> {
    let n = source.len();
    if n < WINDOWS[0] + 4 {
        return None;
    }
    let mut measured = [[Measured::default(); DEGREES.len()]; WINDOWS.len()];
    for (wi, &len) in WINDOWS.iter().enumerate() {
        if len > W || len > cap || len + 4 > n {
            continue;
        }
        for (pi, &p) in DEGREES.iter().enumerate() {
            if len < p + 2 + 3 {
                continue;
            }
            if let Some(m) = measure::<T, W>(source, len, p, order, sample_period, sigma2) {
                measured[wi][pi] = m;
            }
        }
    }
    pick(&measured, n, n_memory, sigma2)
}

/// The disagreement of the window `len` at degree `p` with degree p + 2 over the signal,
/// with its noise and variance parts and the regressors' noise; `None` if either window
/// cannot be designed.
fn measure<T: Real, const W: usize>(
    source: &[T],
    len: usize,
    p: usize,
    order: usize,
    sample_period: f64,
    sigma2: f64,
) -> Option<Measured> {
    let (Ok(taps), Ok(reference)) = (
        Taps::<f64, W>::design(len, p, sample_period),
        Taps::<f64, W>::design(len, p + 2, sample_period),
    ) else {
        return None;
    };
    let (h, r) = (taps.taps(order), reference.taps(order));
    let gain: f64 = h.iter().map(|v| v * v).sum();
    let diff_gain: f64 = h.iter().zip(r).map(|(a, b)| (a - b) * (a - b)).sum();
    // With x only, x̂ and v̂ come from the same samples through h₀ and h₁.
    let (h0, h1) = (taps.taps(0), taps.taps(1));
    let Scan {
        disagreement,
        power,
        count,
        power_x,
        power_v,
    } = scan(source, len, order, (h, r), (h0, h1));
    let count = count.max(1) as f64;
    let power = power / count;
    // Noise in a regressor does not average out: x̂'s, correlated with x̂'s through
    // h₀·h₂, shifts the fit by about σ²h₀·h₂/rms(x̂) in units of x''; v̂'s variance
    // σ²‖h₁‖² shrinks the v terms by that fraction of v̂'s power (at most all of x'').
    let regressors = if order == 2 && power_x > 0.0 && power_v > 0.0 {
        let xy: f64 = h0.iter().zip(h).map(|(a, b)| a * b).sum();
        let vv: f64 = h1.iter().map(|a| a * a).sum();
        let shift = sigma2 * xy / libm::sqrt(power_x / count);
        let shrink = (sigma2 * vv / (power_v / count)).min(1.0);
        shift * shift + shrink * shrink * power
    } else {
        0.0
    };
    Some(Measured {
        disagreement: disagreement / count,
        noise: sigma2 * diff_gain,
        variance: sigma2 * gain,
        power,
        regressors,
        valid: true,
    })
}

/// Sums over the windows a scan visits.
struct Scan {
    /// Σ(h·s − r·s)²: the estimate against the reference's.
    disagreement: f64,
    /// Σ(h·s)².
    power: f64,
    /// Windows visited.
    count: usize,
    /// Σx̂², Σv̂² (from h₀ and h₁; with `order` 2 only).
    power_x: f64,
    power_v: f64,
}

/// Applies the taps `h` and the reference `r` (and, for `order` 2, h₀ and h₁) to about
/// [`POINTS`] windows of `len` samples spread over `source`.
fn scan<T: Real>(
    source: &[T],
    len: usize,
    order: usize,
    (h, r): (&[f64], &[f64]),
    (h0, h1): (&[f64], &[f64]),
) -> Scan {
    let positions = source.len() - len + 1;
    let step = (positions / POINTS).max(1);
    let (mut disagreement, mut power, mut count) = (0.0, 0.0, 0usize);
    let (mut power_x, mut power_v) = (0.0, 0.0);
    let mut start = 0;
    while start < positions {
        let window = &source[start..start + len];
        let (mut a, mut b) = (0.0, 0.0);
        for ((s, hv), rv) in window.iter().zip(h).zip(r) {
            let s = s.to_f64();
            a += hv * s;
            b += rv * s;
        }
        if order == 2 {
            let (mut x, mut v) = (0.0, 0.0);
            for ((s, p0), p1) in window.iter().zip(h0).zip(h1) {
                let s = s.to_f64();
                x += p0 * s;
                v += p1 * s;
            }
            power_x += x * x;
            power_v += v * v;
        }
        disagreement += (a - b) * (a - b);
        power += a * a;
        count += 1;
        start += step;
    }
    Scan {
        disagreement,
        power,
        count,
        power_x,
        power_v,
    }
}

/// The window and degree of least estimated cost (bias² + regressor noise + variance over
/// the memory of `n_memory` samples) among the measured ones, `n` samples long.
fn pick(
    measured: &[[Measured; DEGREES.len()]; WINDOWS.len()],
    n: usize,
    n_memory: usize,
    sigma2: f64,
) -> Option<WindowChoice> {
    let mut best: Option<(f64, WindowChoice)> = None;
    for (pi, &p) in DEGREES.iter().enumerate() {
        // The anchor: the shortest window whose bias stands out of the noise part by three
        // standard errors (the disagreement averages about n/N independent windows, so its
        // noise part is known to a relative √(2N/n)).
        let bias_of = |wi: usize| {
            let m = &measured[wi][pi];
            let se = m.noise * libm::sqrt(2.0 * WINDOWS[wi] as f64 / n as f64);
            (m.valid && m.disagreement - m.noise > 3.0 * se).then_some(m.disagreement - m.noise)
        };
        let anchor = (0..WINDOWS.len()).find(|&wi| bias_of(wi).is_some());
        let exponent = 2.0 * (p + 1) as f64;
        for (wi, &len) in WINDOWS.iter().enumerate() {
            let m = &measured[wi][pi];
            if !m.valid {
                continue;
            }
            let bias2 = match anchor {
                Some(a) if wi < a => {
                    let m0 = &measured[a][pi];
                    let law = (m0.disagreement - m0.noise)
                        * libm::pow(len as f64 / WINDOWS[a] as f64, exponent);
                    law.max(m.disagreement - m.noise)
                }
                _ => (m.disagreement - m.noise).max(0.0),
            };
            let cost = bias2 + m.regressors + m.variance * len as f64 / n_memory.max(len) as f64;
            let choice = WindowChoice {
                window: len,
                degree: p as u8,
                noise: libm::sqrt(sigma2),
                bias: libm::sqrt(bias2),
                target_rms: libm::sqrt(m.power),
                period: None,
            };
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, choice));
            }
        }
    }
    best.map(|(_, c)| c)
}

#[cfg(test)]
mod tests;
