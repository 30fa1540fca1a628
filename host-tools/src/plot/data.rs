//! What the figures show, computed from a recording with the public lssi-core API: the
//! k-neighbour reconstruction error ε(K) per channel, the model after each periodic
//! screening, the phase-plane trajectory, and envelope decimation for long series.

use lssi_core::derivative::Taps;
use lssi_core::smoothing::{KnnSmoother, MAX_NEIGHBOURS, MIN_NEIGHBOURS};
use lssi_core::{Config, Identifier, Real, Sample, Term};

use crate::identify::{TERM_CAPACITY, WINDOW_CAPACITY};
use crate::recording::Recording;

/// The k-neighbour reconstruction error of one channel (the paper's Fig. 4).
#[derive(Clone, Debug, PartialEq)]
pub struct Reconstruction {
    /// (K, RMS leave-one-out reconstruction error at K) for K = 2..=8, in the channel's unit.
    pub rms: Vec<(usize, f64)>,
    /// K chosen by the smoother's rule (the largest K within 1 % of the least ε(K)).
    pub chosen: usize,
}

/// ε(K) of x and of v over the whole recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Neighbours {
    /// The displacement channel.
    pub x: Reconstruction,
    /// The velocity channel (measured, or the local-polynomial derivative of x).
    pub v: Reconstruction,
}

/// The local-polynomial estimates (x̂, v̂) of every regression row, as the identifier forms
/// them: every `row_stride` samples once the window is full, restarted at a gap or a
/// non-finite value.
fn rows(recording: &Recording, config: &Config) -> Option<Vec<(f64, f64)>> {
    let taps: Taps<f64, WINDOW_CAPACITY> = Taps::design(
        config.window,
        usize::from(config.derivative_degree),
        config.sample_period,
    )
    .ok()?;
    let n = config.window;
    let stride = usize::from(config.row_stride.max(1));
    let dt = config.sample_period;
    let mut out = Vec::with_capacity(recording.len() / stride + 1);
    let mut run_start = 0usize;
    let mut since_row = 0usize;
    for i in 0..recording.len() {
        let finite = recording.t[i].is_finite()
            && recording.x[i].is_finite()
            && recording.v.as_ref().is_none_or(|v| v[i].is_finite());
        let gap = i > 0 && recording.t[i] - recording.t[i - 1] > 1.5 * dt;
        if !finite || gap {
            run_start = if finite { i } else { i + 1 };
            since_row = 0;
            continue;
        }
        if i + 1 - run_start < n {
            continue;
        }
        since_row += 1;
        if since_row < stride {
            continue;
        }
        since_row = 0;
        let window = i + 1 - n..i + 1;
        let x = &recording.x[window.clone()];
        let (xh, vh) = match &recording.v {
            Some(v) => (taps.apply(0, x, &[]), taps.apply(0, &v[window], &[])),
            None => (taps.apply(0, x, &[]), taps.apply(1, x, &[])),
        };
        out.push((xh, vh));
    }
    Some(out)
}

fn reconstruction(smoother: &KnnSmoother<f64>, evaluated: usize) -> Reconstruction {
    let errors = smoother.errors();
    let count = evaluated.max(1) as f64;
    let rms: Vec<(usize, f64)> = (MIN_NEIGHBOURS..=MAX_NEIGHBOURS)
        .map(|k| (k, (errors[k] / count).sqrt()))
        .collect();
    // The smoother's own rule, on the same sums.
    let mut copy = smoother.clone();
    copy.choose_k(1.0);
    Reconstruction {
        rms,
        chosen: copy.k(),
    }
}

/// ε(K) per channel, from the regression rows' x̂ and v̂ pushed through one
/// [`KnnSmoother`] each (in f64, accumulated over the whole recording).
pub fn neighbours(recording: &Recording, config: &Config) -> Option<Neighbours> {
    let rows = rows(recording, config)?;
    let mut sx: KnnSmoother<f64> = KnnSmoother::new();
    let mut sv: KnnSmoother<f64> = KnnSmoother::new();
    let mut smoothed = 0usize;
    for (x, v) in rows {
        let a = sx.push(x);
        let _ = sv.push(v);
        if a.is_some() {
            smoothed += 1;
        }
    }
    // The smoother evaluates ε(K) on one smoothed row in four.
    let evaluated = smoothed / 4;
    if evaluated == 0 {
        return None;
    }
    Some(Neighbours {
        x: reconstruction(&sx, evaluated),
        v: reconstruction(&sv, evaluated),
    })
}

/// The model identified from growing prefixes of the record.
#[derive(Clone, Debug, PartialEq)]
pub struct History {
    /// Term names, in library order.
    pub names: Vec<String>,
    /// (end time of the prefix in s, coefficient of every term in physical units).
    pub points: Vec<(f64, Vec<f64>)>,
}

/// Samples streamed in all for the history, at most (the prefixes are re-run).
const HISTORY_BUDGET: usize = 4_000_000;

/// The model `lssi identify` reports from the record up to each of 8 to 30 equally spaced
/// times, run in precision `T`: the streaming identifier's view as the record grows. The
/// last point is the model of the whole record.
pub fn history<T: Real>(recording: &Recording, config: &Config) -> Option<History> {
    let n = recording.len();
    let count = (HISTORY_BUDGET / (n / 2).max(1)).clamp(8, 30).min(n);
    let omega = config.omega;
    let mut names = Vec::new();
    let mut points = Vec::new();
    for k in 1..=count {
        let end = n * k / count;
        let mut identifier: Identifier<T, WINDOW_CAPACITY, TERM_CAPACITY> =
            Identifier::new(*config).ok()?;
        if names.is_empty() {
            names = identifier
                .library()
                .terms()
                .iter()
                .map(|t: &Term| t.name(omega).to_string())
                .collect();
        }
        for s in recording.samples().take(end) {
            // Rejected samples are counted by the identifier, as in `lssi identify`.
            let _ = identifier.push(Sample {
                t: s.t,
                x: T::from_f64(s.x),
                v: s.v.map(T::from_f64),
                u: s.u.map(T::from_f64),
            });
        }
        identifier.screen();
        let t = recording.t[..end]
            .iter()
            .rev()
            .find(|t| t.is_finite())
            .copied();
        if let (Some(model), Some(t)) = (identifier.model(), t) {
            let p = model.terms.len();
            points.push((
                t,
                model.coefficients[..p].iter().map(|c| c.to_f64()).collect(),
            ));
        }
    }
    Some(History { names, points })
}

/// Velocity of every sample: the measured one, or the local-polynomial first derivative of x
/// (centred; `None` near the ends and around gaps).
pub fn velocity(recording: &Recording, config: &Config) -> Vec<Option<f64>> {
    if let Some(v) = &recording.v {
        return v.iter().map(|v| v.is_finite().then_some(*v)).collect();
    }
    let mut out = vec![None; recording.len()];
    let Ok(taps) = Taps::<f64, WINDOW_CAPACITY>::design(
        config.window,
        usize::from(config.derivative_degree),
        config.sample_period,
    ) else {
        return out;
    };
    let n = config.window;
    let half = (n - 1) / 2;
    let dt = config.sample_period;
    for end in n..=recording.len() {
        let range = end - n..end;
        let span = recording.t[end - 1] - recording.t[end - n];
        if !(span.is_finite() && span < (n as f64 + 0.5) * dt) {
            continue;
        }
        let w = &recording.x[range];
        let d = taps.apply(1, w, &[]);
        if d.is_finite() {
            out[end - n + half] = Some(d);
        }
    }
    out
}

/// At most `2 * buckets` points tracing the envelope of a long series: the minimum and the
/// maximum of each of `buckets` equal runs, in time order. Non-finite points are dropped.
pub fn envelope(t: &[f64], y: &[f64], buckets: usize) -> Vec<(f64, f64)> {
    let points: Vec<(f64, f64)> = t
        .iter()
        .zip(y)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(a, b)| (*a, *b))
        .collect();
    let buckets = buckets.max(1);
    if points.len() <= 2 * buckets {
        return points;
    }
    let size = points.len().div_ceil(buckets);
    let mut out = Vec::with_capacity(2 * buckets);
    for chunk in points.chunks(size) {
        let (mut lo, mut hi) = (0, 0);
        for (i, p) in chunk.iter().enumerate() {
            if p.1 < chunk[lo].1 {
                lo = i;
            }
            if p.1 > chunk[hi].1 {
                hi = i;
            }
        }
        let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        out.push(chunk[a]);
        if b != a {
            out.push(chunk[b]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_keeps_extremes_and_order() {
        let t: Vec<f64> = (0..1000).map(f64::from).collect();
        let y: Vec<f64> = t.iter().map(|t| (t * 0.1).sin()).collect();
        let e = envelope(&t, &y, 50);
        assert!(e.len() <= 100);
        assert!(e.windows(2).all(|w| w[0].0 < w[1].0));
        let max = e.iter().map(|p| p.1).fold(f64::MIN, f64::max);
        assert!((max - 1.0).abs() < 1e-3);
    }

    #[test]
    fn envelope_passes_short_series_through() {
        let e = envelope(&[0.0, 1.0, f64::NAN], &[1.0, 2.0, 3.0], 10);
        assert_eq!(e, vec![(0.0, 1.0), (1.0, 2.0)]);
    }
}
