//! A swept excitation recorded without its `u` column: the frequency of x drifts steadily
//! across the record (a chirp), which no model with a forcing cos(Ωt) at one Ω can follow.
//!
//! The record's longest clean stretch is cut into [`SEGMENTS`] equal segments; in each, the
//! dominant frequency is the peak of the Hann-windowed, zero-padded spectrum (interpolated on
//! its neighbours), taken only when it is a clear line ([`MIN_PROMINENCE`] times the median
//! power) and the segment holds [`MIN_PERIODS`] periods of it. A straight drift is fitted to
//! the lines (Theil–Sen: robust to a transient at the start or a segment where a harmonic
//! wins); the record is a sweep when [`INLIERS`] of the segments lie on it (within
//! [`TOLERANCE`] or a resolution width) over at least half of the record, and
//! it moves by [`MIN_DRIFT`] of the frequency and [`MIN_RESOLUTIONS`] resolution widths.
//!
//! A steady response keeps one line (its drift is the estimate's noise); a chaotic one's line
//! jumps about (its lines do not lie on one straight drift), and a transient that settles
//! leaves the lines of most segments at one frequency.
//!
//! A short record (a few seconds) has segments too short to resolve the drift (12 segments of
//! 0.42 s resolve 15 rad/s), so when the segments find no sweep the whole record is
//! *dechirped* ([`chirp`]): multiplied by exp(−i k t²/2) for chirp rates k on a grid, the
//! linear sweep at rate k becomes one line, which the Hann-windowed spectrum then holds in
//! one resolution width instead of spreading it over the swept band. The record is a sweep
//! when the strongest such line at a chirp rate k ≠ 0 (one that moves at least
//! [`CHIRP_MIN_RESOLUTIONS`] resolution widths over the record, and a local maximum in k) is
//! [`CHIRP_GAIN`] times stronger than the strongest line of the record as it is (k = 0), stands
//! [`CHIRP_PROMINENCE`] times above the median of its spectrum, and its envelope does not die
//! out across the record (a ringdown of a hardening or softening oscillator is a chirp too,
//! but one that decays from its first state).

use crate::recording::Recording;

/// Segments the record is cut into at most.
pub const SEGMENTS: usize = 12;
/// Segments the record is cut into at least (tried with fewer, longer segments when too few
/// hold [`MIN_PERIODS`] periods of their line at [`SEGMENTS`]).
pub const MIN_SEGMENTS: usize = 6;
/// The share of segments whose line must lie on the straight drift.
pub const INLIERS: f64 = 0.75;
/// How far (a fraction of the frequency, at least a resolution width) a segment's line may
/// lie from the straight drift.
pub const TOLERANCE: f64 = 0.04;
/// A segment's line must stand this many times above the median of its spectrum.
pub const MIN_PROMINENCE: f64 = 30.0;
/// Periods of its line a segment must hold.
pub const MIN_PERIODS: f64 = 2.5;
/// The drift from the first segment to the last, a fraction of the lower frequency.
pub const MIN_DRIFT: f64 = 0.08;
/// The drift in resolution widths (2π over a segment's duration).
pub const MIN_RESOLUTIONS: f64 = 1.0;
/// Kendall's τ of the inlying lines against their segment, in the drift's direction, at
/// least: a sweep's lines move one way (segment by segment, within their interpolation's
/// noise), where a weakly forced bistable beam's beating transient, whose lines lie within a
/// resolution width of a straight drift only because a short segment's width is a fifth of
/// the frequency, wander both ways (hostile seed 20733: 36.6, 38.5, 35.8, 32.2, 26.6, 26.2,
/// 30.4, 33.3, 31.2, 27.4, 28.4 rad/s, τ −0.45).
pub const MIN_TAU: f64 = 0.7;

/// How much stronger the dechirped line must be than the record's strongest line.
pub const CHIRP_GAIN: f64 = 1.2;
/// How far the dechirped line must stand above the median of its spectrum (noise's strongest
/// line over all the rates tried stands about 20 times above it; a swept response's, 10⁵).
pub const CHIRP_PROMINENCE: f64 = 100.0;
/// Resolution widths (2π over the record's duration) the dechirped line must move at least.
pub const CHIRP_MIN_RESOLUTIONS: f64 = 2.0;
/// The share of x's variance the dechirped line must hold ([`line_share`]): a swept
/// response's held 0.47–0.96 (5–20 s sweeps, single and double well), a bistable beam's
/// under white base acceleration 0.06–0.18 (8 draws), whose strongest dechirped line
/// stood 1.2–2.2 times above its plain spectrum's and had it named a chirp.
pub const CHIRP_SHARE: f64 = 0.3;
/// Samples the record is reduced to (by block means) for the dechirping, at most about.
const CHIRP_SAMPLES: usize = 8192;
/// Chirp rates tried either side of 0, at most.
const CHIRP_RATES: usize = 80;

/// A sweep found: the straight drift of the segments' lines.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// The drift's frequency at the start of the record (its longest clean stretch), rad/s.
    pub from: f64,
    /// The drift's frequency at the end of the record, rad/s.
    pub to: f64,
    /// Each segment's duration, seconds.
    pub seconds: f64,
    /// Segments.
    pub segments: usize,
}

impl Sweep {
    /// The gate's sentence.
    pub fn sentence(&self) -> String {
        let (first, last) = (self.from, self.to);
        if self.segments == 0 {
            return format!(
                "the forcing sweeps in frequency (a chirp): x holds a line that moves steadily from {first:.3} rad/s to {last:.3} rad/s over the record ({:.3} s; found by dechirping it whole), which no forcing cos(Ωt) at one Ω describes; give the excitation as a u column (--u-col) or identify a stretch at one frequency",
                self.seconds
            );
        }
        format!(
            "the forcing sweeps in frequency (a chirp): x's dominant frequency moves steadily from {first:.3} rad/s to {last:.3} rad/s over the record ({} segments of {:.3} s), which no forcing cos(Ωt) at one Ω describes; give the excitation as a u column (--u-col) or identify a stretch at one frequency",
            self.segments, self.seconds
        )
    }
}

/// Each segment's dominant line (rad/s), or `None` when it has no clear one.
pub fn segment_lines(t: &[f64], x: &[f64], segments: usize) -> Option<(Vec<Option<f64>>, f64)> {
    use rustfft::{FftPlanner, num_complex::Complex};
    let n = x.len() / segments;
    if n < 256 || t.len() != x.len() {
        return None;
    }
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    if !(dt > 0.0) {
        return None;
    }
    let size = (n.next_power_of_two() * 4).min(1 << 20);
    let n = n.min(size);
    let seconds = n as f64 * dt;
    let mut planner = FftPlanner::new();
    let fft = planner.plan_fft_forward(size);
    let lines = (0..segments)
        .map(|s| {
            let seg = &x[s * n..(s + 1) * n];
            let mean = seg.iter().sum::<f64>() / n as f64;
            let mut buf: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); size];
            for (i, v) in seg.iter().enumerate() {
                let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
                buf[i] = Complex::new((v - mean) * w, 0.0);
            }
            fft.process(&mut buf);
            let power: Vec<f64> = buf[..size / 2].iter().map(|c| c.norm_sqr()).collect();
            // Bins per resolution width: size / n; the lowest line taken is two widths up.
            let lowest = 2 * size / n;
            let (k, peak) = power
                .iter()
                .enumerate()
                .skip(lowest)
                .take(size / 2 - lowest - 1)
                .max_by(|a, b| a.1.total_cmp(b.1))?;
            let mut sorted: Vec<f64> = power[lowest..].to_vec();
            sorted.sort_by(f64::total_cmp);
            let median = sorted[sorted.len() / 2];
            if !(*peak > MIN_PROMINENCE * median) {
                return None;
            }
            // Parabolic interpolation on the log power.
            let (a, b, c) = (power[k - 1].ln(), peak.ln(), power[k + 1].ln());
            let denominator = a - 2.0 * b + c;
            let shift = if denominator < 0.0 {
                (0.5 * (a - c) / denominator).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            let omega = 2.0 * std::f64::consts::PI * (k as f64 + shift) / (size as f64 * dt);
            (omega * seconds / (2.0 * std::f64::consts::PI) >= MIN_PERIODS).then_some(omega)
        })
        .collect();
    Some((lines, seconds))
}

/// Whether the recording's x is a sweep (see the module docs); never with a `u` column.
pub fn sweep(recording: &Recording) -> Option<Sweep> {
    if recording.u.is_some() {
        return None;
    }
    let stretch = crate::identify::stretch::longest(recording)?;
    let t = &recording.t[stretch.clone()];
    let x = &recording.x[stretch];
    // Fewer, longer segments when a sweep's low end is too slow for short ones.
    [SEGMENTS, (SEGMENTS + MIN_SEGMENTS) / 2, MIN_SEGMENTS]
        .into_iter()
        .find_map(|segments| drift(t, x, segments))
        .or_else(|| chirp(t, x))
}

/// The record dechirped whole (see the module docs): the sweep, with `segments` 0, when it
/// is one.
pub fn chirp(t: &[f64], x: &[f64]) -> Option<Sweep> {
    use rustfft::{FftPlanner, num_complex::Complex};
    use std::f64::consts::PI;
    let n = x.len();
    if n < 256 || t.len() != n || x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    if !(dt > 0.0) {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let hann = |i: usize, n: usize| 0.5 - 0.5 * (2.0 * PI * i as f64 / (n - 1) as f64).cos();
    let mut planner = FftPlanner::new();
    // The record's strongest line (three resolution widths up at least), for the reduction.
    let resolution = 2.0 * PI / (t[n - 1] - t[0]);
    let size = (n.next_power_of_two() * 2).min(1 << 22);
    let mut buf: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); size];
    for (i, v) in x.iter().enumerate().take(size) {
        buf[i] = Complex::new((v - mean) * hann(i, n), 0.0);
    }
    planner.plan_fft_forward(size).process(&mut buf);
    let bin = 2.0 * PI / (size as f64 * dt);
    let lowest = (3.0 * resolution / bin).ceil() as usize;
    if lowest + 2 >= size / 2 {
        return None;
    }
    let (k0, _) = buf[lowest..size / 2]
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.norm_sqr().total_cmp(&b.1.norm_sqr()))?;
    let line = (k0 + lowest) as f64 * bin;
    // Block means of m samples, keeping the Nyquist frequency four times the line.
    let m = (n / CHIRP_SAMPLES)
        .min((PI / (4.0 * line * dt)).floor() as usize)
        .max(1);
    let count = n / m;
    let y: Vec<f64> = (0..count)
        .map(|b| x[b * m..(b + 1) * m].iter().map(|v| v - mean).sum::<f64>() / m as f64)
        .collect();
    let step = dt * m as f64;
    let duration = (count - 1) as f64 * step;
    let centre = |i: usize| i as f64 * step - 0.5 * duration;
    let size = count.next_power_of_two() * 2;
    let bin = 2.0 * PI / (size as f64 * step);
    let lowest = (3.0 * 2.0 * PI / duration / bin).ceil() as usize;
    if lowest + 2 >= size / 2 {
        return None;
    }
    // Chirp rates k (rad/s²): steps of 2π/T² (a quarter-turn of phase mismatch at the ends),
    // up to a drift of twice the line over the record.
    let k_max = 2.0 * line / duration;
    let mut k_step = 2.0 * PI / (duration * duration);
    let mut steps = (k_max / k_step).floor() as usize;
    if steps > CHIRP_RATES {
        k_step = k_max / CHIRP_RATES as f64;
        steps = CHIRP_RATES;
    }
    if steps < 2 {
        return None;
    }
    let fft = planner.plan_fft_forward(size);
    let window: Vec<f64> = (0..count).map(|i| hann(i, count)).collect();
    // Each rate's strongest line: (power, frequency).
    let rows: Vec<(f64, f64)> = (0..=2 * steps)
        .map(|a| {
            let k = (a as f64 - steps as f64) * k_step;
            let mut buf: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); size];
            for i in 0..count {
                let tc = centre(i);
                buf[i] = Complex::from_polar(y[i] * window[i], -0.5 * k * tc * tc);
            }
            fft.process(&mut buf);
            let (j, p) = buf[lowest..size / 2]
                .iter()
                .map(|c| c.norm_sqr())
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((0, 0.0));
            (p, (j + lowest) as f64 * bin)
        })
        .collect();
    let still = rows[steps].0;
    if std::env::var_os("LSSI_SWEEP_DEBUG").is_some() {
        let window: Vec<f64> = (0..count).map(|i| hann(i, count)).collect();
        for a in 1..2 * steps {
            if rows[a].0 >= rows[a - 1].0 && rows[a].0 >= rows[a + 1].0 {
                let k = (a as f64 - steps as f64) * k_step;
                let (p, w) = rows[a];
                eprintln!(
                    "lssi: sweep: candidate k {k:.3} line {w:.3} ({:.3} -> {:.3}) gain {:.2} share {:.3}",
                    w - 0.5 * k * duration,
                    w + 0.5 * k * duration,
                    p / still,
                    line_share(p, &y, &window)
                );
            }
        }
    }
    let k_min = CHIRP_MIN_RESOLUTIONS * 2.0 * PI / (duration * duration);
    let (a, &(power, omega)) = rows
        .iter()
        .enumerate()
        .filter(|&(a, _)| {
            let k = (a as f64 - steps as f64) * k_step;
            a > 0
                && a < 2 * steps
                && k.abs() >= k_min
                && rows[a].0 >= rows[a - 1].0
                && rows[a].0 >= rows[a + 1].0
        })
        .max_by(|a, b| a.1.0.total_cmp(&b.1.0))?;
    let k = (a as f64 - steps as f64) * k_step;
    if std::env::var_os("LSSI_SWEEP_DEBUG").is_some() {
        eprintln!(
            "lssi: sweep: dechirped line at {omega:.3} rad/s, rate {k:.3} rad/s², {:.2} times the record's strongest line, mirror {:.3}",
            power / still,
            rows[2 * steps - a].0 / power
        );
    }
    if !(still > 0.0 && power >= CHIRP_GAIN * still) {
        return None;
    }
    // The line must stand clear of its spectrum (noise has a strongest line at every rate).
    let mut buf: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); size];
    for i in 0..count {
        let tc = centre(i);
        buf[i] = Complex::from_polar(y[i] * window[i], -0.5 * k * tc * tc);
    }
    fft.process(&mut buf);
    let mut spectrum: Vec<f64> = buf[lowest..size / 2].iter().map(|c| c.norm_sqr()).collect();
    let middle = spectrum.len() / 2;
    let median = *spectrum.select_nth_unstable_by(middle, f64::total_cmp).1;
    if !(power >= CHIRP_PROMINENCE * median) {
        return None;
    }
    // The line must hold a good part of x's variance: a swept forcing's response is mostly
    // at the swept frequency, where a random (broadband) one's strongest dechirped line,
    // the best of many spectra, is a sliver of it.
    let share = line_share(power, &y, &window);
    if std::env::var_os("LSSI_SWEEP_DEBUG").is_some() {
        eprintln!("lssi: sweep: the dechirped line holds {share:.3} of x's variance");
    }
    if !(share >= CHIRP_SHARE) {
        return None;
    }
    // The line's envelope: x demodulated along it, averaged over two of its periods.
    let width = ((4.0 * PI / omega / step).round() as usize).max(1);
    if count < 2 * width + 8 {
        return None;
    }
    let mut prefix = vec![Complex::new(0.0, 0.0); count + 1];
    for i in 0..count {
        let tc = centre(i);
        prefix[i + 1] = prefix[i] + Complex::from_polar(y[i], -(omega * tc + 0.5 * k * tc * tc));
    }
    let envelope: Vec<f64> = (width..count - width)
        .map(|i| {
            let (lo, hi) = (i - width / 2, i - width / 2 + width);
            (prefix[hi] - prefix[lo]).norm() / width as f64
        })
        .collect();
    let quarter = envelope.len() / 4;
    let q: Vec<f64> = (0..4)
        .map(|j| {
            let part = &envelope[j * quarter..(j + 1) * quarter];
            part.iter().sum::<f64>() / part.len().max(1) as f64
        })
        .collect();
    let decays = q.windows(2).all(|w| w[1] < w[0]) && q[3] < 0.8 * q[0];
    if std::env::var_os("LSSI_SWEEP_DEBUG").is_some() {
        let still_share = line_share(still, &y, &window);
        eprintln!(
            "lssi: sweep: envelope quarters {:.3e} {:.3e} {:.3e} {:.3e}; the still line at {:.3} holds {still_share:.3}; from {:.3} to {:.3}",
            q[0],
            q[1],
            q[2],
            q[3],
            rows[steps].1,
            omega - 0.5 * k * duration,
            omega + 0.5 * k * duration
        );
    }
    if decays {
        return None;
    }
    // A sweep's line stays a line the record resolves: above three of its resolution widths at
    // both ends (the floor under which no line is taken above). A heavily damped single well
    // over 5.5 periods (hostile 21145, 1.3 s) gathered its decay from x₀ and its forced line
    // into a "chirp" from −4.2 to 43.5 rad/s; a bistable beam's slow transient in its well
    // (hostile 21224) one from 8.5 to 1.8 rad/s, under its floor of 2.9.
    let floor = 3.0 * 2.0 * PI / duration;
    let within =
        |omega: f64, k: f64| (omega - 0.5 * k * duration).min(omega + 0.5 * k * duration) >= floor;
    if !within(omega, k) {
        return None;
    }
    // Where segments of the record resolve the drift claimed, the lines of its second half
    // must not move against it: a bistable beam's transient whose lines wander (hostile
    // 20975: 7.0, 9.5, 5.4, then 7.2, 7.7, 8.8 rad/s over six segments) was dechirped into a
    // fall from 11.5 to 5.0 rad/s.
    if against_segments(t, x, omega - 0.5 * k * duration, omega + 0.5 * k * duration) {
        return None;
    }
    // The range: of the dechirped lines (local maxima in the rate) standing clear of their
    // spectrum, the one dechirping gathers most, against the record's own spectrum over the
    // band it sweeps. The strongest line can be the oscillator's own, which drifts a little
    // (a 10→30 rad/s sweep over 5 s, no u: x's strongest dechirped line was the well's at
    // 38→45 rad/s, 1.4 times its plain spectrum's peak; the sweep's at 9.9→30.0 rad/s, weaker,
    // but 0.66 of that peak gathered from a band the plain spectrum holds little of).
    let mut plain: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); size];
    for i in 0..count {
        plain[i] = Complex::new(y[i] * window[i], 0.0);
    }
    fft.process(&mut plain);
    let plain: Vec<f64> = plain[..size / 2].iter().map(|c| c.norm_sqr()).collect();
    let gathered = |a: usize| -> Option<(f64, f64, f64)> {
        let (power, omega) = rows[a];
        let k = (a as f64 - steps as f64) * k_step;
        let (lo, hi) = (
            omega - 0.5 * k.abs() * duration,
            omega + 0.5 * k.abs() * duration,
        );
        let bin_of = |w: f64| ((w / bin).round().max(0.0) as usize).clamp(lowest, size / 2 - 1);
        let peak = plain[bin_of(lo)..=bin_of(hi)]
            .iter()
            .copied()
            .fold(0.0, f64::max);
        let mut buf: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); size];
        for i in 0..count {
            let tc = centre(i);
            buf[i] = Complex::from_polar(y[i] * window[i], -0.5 * k * tc * tc);
        }
        fft.process(&mut buf);
        let mut spectrum: Vec<f64> = buf[lowest..size / 2].iter().map(|c| c.norm_sqr()).collect();
        let middle = spectrum.len() / 2;
        let median = *spectrum.select_nth_unstable_by(middle, f64::total_cmp).1;
        (peak > 0.0 && power >= CHIRP_PROMINENCE * median).then_some((power / peak, omega, k))
    };
    let (_, omega, k) = (1..2 * steps)
        .filter(|&a| {
            let k = (a as f64 - steps as f64) * k_step;
            k.abs() >= k_min && rows[a].0 >= rows[a - 1].0 && rows[a].0 >= rows[a + 1].0
        })
        .filter_map(gathered)
        .filter(|&(_, omega, k)| within(omega, k))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap_or((0.0, omega, k));
    Some(Sweep {
        from: omega - 0.5 * k * duration,
        to: omega + 0.5 * k * duration,
        seconds: duration,
        segments: 0,
    })
}

/// Whether the lines of the second half of [`MIN_SEGMENTS`] segments, all within the band
/// `from`..`to` (rad/s, the drift claimed over the record) or a resolution width of it, move
/// steadily against the drift (each against the one before), where they resolve it (half the
/// drift at least one of their resolution widths, and a line in each). The second half: a
/// sweep's first segments may hold the transient from x₀ at the well's own frequency (a
/// 23 → 33 rad/s sweep: 42.8, 37.7, 39.5, then 29.1, 30.9, 32.6 rad/s), its later ones a
/// harmonic (a 9.6 → 44.6 rad/s sweep: 46.3, 49.0, 41.7 rad/s), neither of them a line that
/// moves against the sweep in its band.
fn against_segments(t: &[f64], x: &[f64], from: f64, to: f64) -> bool {
    let Some((lines, seconds)) = segment_lines(t, x, MIN_SEGMENTS) else {
        return false;
    };
    let resolution = 2.0 * std::f64::consts::PI / seconds;
    let late: Vec<f64> = lines[MIN_SEGMENTS / 2..]
        .iter()
        .flatten()
        .copied()
        .collect();
    let change = to - from;
    if 0.5 * change.abs() < resolution || late.len() < MIN_SEGMENTS - MIN_SEGMENTS / 2 {
        return false;
    }
    let (low, high) = (from.min(to) - resolution, from.max(to) + resolution);
    let in_band = late.iter().all(|l| (low..=high).contains(l));
    let against = late
        .windows(2)
        .all(|w| (w[1] - w[0]) * change.signum() < 0.0);
    if std::env::var_os("LSSI_SWEEP_DEBUG").is_some() {
        eprintln!(
            "lssi: sweep: the later segments' lines {late:?}: in the band {in_band}, against the chirp {against}"
        );
    }
    in_band && against
}

/// The straight drift of the lines of `segments` segments, when it is a sweep's.
fn drift(t: &[f64], x: &[f64], segments: usize) -> Option<Sweep> {
    let (lines, seconds) = segment_lines(t, x, segments)?;
    let debug = std::env::var_os("LSSI_SWEEP_DEBUG").is_some();
    if debug {
        eprintln!("lssi: sweep: lines {lines:?}");
    }
    let measured: Vec<(usize, f64)> = lines
        .iter()
        .enumerate()
        .filter_map(|(i, l)| l.map(|l| (i, l)))
        .collect();
    let needed = (INLIERS * segments as f64).ceil() as usize;
    if measured.len() < needed {
        return None;
    }
    // Theil–Sen: the median of the pairwise slopes, then the median intercept.
    let mut slopes: Vec<f64> = Vec::new();
    for (a, &(i, li)) in measured.iter().enumerate() {
        for &(j, lj) in &measured[a + 1..] {
            slopes.push((lj - li) / (j - i) as f64);
        }
    }
    slopes.sort_by(f64::total_cmp);
    let slope = slopes[slopes.len() / 2];
    let mut intercepts: Vec<f64> = measured
        .iter()
        .map(|&(i, l)| l - slope * i as f64)
        .collect();
    intercepts.sort_by(f64::total_cmp);
    let intercept = intercepts[intercepts.len() / 2];
    let resolution = 2.0 * std::f64::consts::PI / seconds;
    let inliers: Vec<usize> = measured
        .iter()
        .filter(|&&(i, l)| {
            let fit = intercept + slope * i as f64;
            (l - fit).abs() <= (TOLERANCE * fit.abs()).max(resolution)
        })
        .map(|&(i, _)| i)
        .collect();
    let spans = match (inliers.first(), inliers.last()) {
        (Some(a), Some(b)) => b - a >= segments / 2,
        _ => false,
    };
    let first = intercept;
    let last = intercept + slope * (segments - 1) as f64;
    let total = (last - first).abs();
    let low = first.min(last);
    // A sweep keeps moving to the end; a transient at the well's own frequency that dies
    // out into a steady forced response (a few high lines, then a flat tail at Ω) tilts the
    // fit, but the kept lines of its later half stay at one frequency.
    let (late_low, late_high) = measured
        .iter()
        .filter(|(i, _)| *i >= segments / 2 && inliers.contains(i))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, l)| {
            (lo.min(l), hi.max(l))
        });
    let late = late_high - late_low;
    let kept: Vec<(usize, f64)> = measured
        .iter()
        .filter(|(i, _)| inliers.contains(i))
        .copied()
        .collect();
    let values: Vec<f64> = kept.iter().map(|&(_, l)| l).collect();
    let tau = kendall_tau(&values) * slope.signum();
    let drifts = low > 0.0
        && tau >= MIN_TAU
        && total >= MIN_DRIFT * low
        && total >= MIN_RESOLUTIONS * resolution
        && late >= 0.5 * MIN_DRIFT * late_low
        && keeps_moving(&kept, slope);
    if debug {
        eprintln!(
            "lssi: sweep: {first:.3} -> {last:.3} rad/s, {} inliers, spans {spans}, tau {tau:.2}, drifts {drifts}",
            inliers.len()
        );
    }
    // The range over the record: the drift carried on half a segment beyond the first and
    // the last segments' centres (a 10→30 rad/s sweep over 20 s read 10.65→29.20 at the
    // centres).
    (inliers.len() >= needed && spans && drifts).then_some(Sweep {
        from: first - 0.5 * slope,
        to: last + 0.5 * slope,
        seconds,
        segments,
    })
}

/// Whether the last third of the kept lines (segment, rad/s; three at least) still moves at
/// the drift's pace (at least [`TAIL_PACE`] of its slope, the same way): a sweep moves to its
/// end, where a hardening single well's ringdown into its forced response falls steeply and
/// then stays at Ω (gen seed 4242: 44.6, 40.4, 37.0, 35.8, 35.7, 35.9, 21.5, 21.4, 21.4 rad/s,
/// a drift of −2.9 rad/s a segment that its last three lines, 0.1 rad/s apart, do not follow;
/// its 7.1 rad/s resolution width kept every line within the straight drift's tolerance). The
/// kept lines, not the segments: a sweep's last segments may hold a harmonic instead (gen
/// seed 23's 35 → 18 rad/s sweep: two lines at 40.9 rad/s, left out of the drift).
fn keeps_moving(kept: &[(usize, f64)], slope: f64) -> bool {
    let tail = &kept[kept.len().saturating_sub(kept.len().div_ceil(3).max(3))..];
    if tail.len() < 3 {
        return false;
    }
    let ((a, la), (b, lb)) = (tail[0], tail[tail.len() - 1]);
    let pace = (lb - la) / (b - a) as f64;
    pace * slope.signum() >= TAIL_PACE * slope.abs()
}

/// The share of the drift's slope the lines of the record's last third must keep
/// ([`keeps_moving`]).
pub const TAIL_PACE: f64 = 0.5;

/// Kendall's τ of `values` against their order: (concordant − discordant) / pairs, 0 for
/// fewer than two.
fn kendall_tau(values: &[f64]) -> f64 {
    let mut sum = 0.0;
    let mut pairs = 0.0;
    for (a, &p) in values.iter().enumerate() {
        for &q in &values[a + 1..] {
            sum += (q - p).signum() * f64::from(u8::from(q != p));
            pairs += 1.0;
        }
    }
    if pairs > 0.0 { sum / pairs } else { 0.0 }
}

/// Whether the recording keeps oscillating where the model's free run (from the recording's
/// first state, the longest clean stretch) has died out: its RMS about its mean over the last
/// [`SEGMENTS`]th of the stretch more than [`OUTLASTS`] times the free run's. A model without
/// forcing that passes over short horizons but cannot sustain what is recorded (a sweep's
/// forced response) misses the forcing; a ringdown's model dies out with the recording.
pub fn outlasts_model(recording: &Recording, report: &crate::identify::Report) -> Option<bool> {
    use crate::identify::simulate::{SimModel, simulate};
    let stretch = crate::identify::stretch::longest(recording)?;
    let t = &recording.t[stretch.clone()];
    let x = &recording.x[stretch.clone()];
    if x.len() < 64 {
        return None;
    }
    let v0 = match &recording.v {
        Some(v) => v[stretch.start],
        None => (x[2] - x[0]) / (t[2] - t[0]),
    };
    let model = SimModel::from_report(report);
    let run = simulate(&model, t, None, (x[0], v0), 2);
    if run.diverged_at.is_some() || run.x.len() != x.len() {
        return None;
    }
    let tail = x.len() - x.len() / SEGMENTS;
    let rms = crate::identify::stretch::rms;
    Some(rms(&x[tail..]) > OUTLASTS * rms(&run.x[tail..]))
}

/// Whether the model's free run over the whole record, from the state fitted on its first two
/// periods, follows the recording (NRMSE at most [`FOLLOWS_PERCENT`] % of x's standard
/// deviation). A swept forcing's line moves by at least two resolution widths, so a model
/// forced at one Ω slips two cycles and cannot follow it; a hardening (or softening) single
/// well's transient, whose frequency drifts as it dies out beside a steady forcing, is
/// followed by the model that explains it. `None` when it cannot be measured.
pub fn model_follows(recording: &Recording, report: &crate::identify::Report) -> Option<bool> {
    use crate::identify::refine::{Data, free_run_after_fitted_start, mean_period_samples};
    use crate::identify::simulate::SimModel;
    let stretch = crate::identify::stretch::longest(recording)?;
    let data = Data {
        t: &recording.t[stretch.clone()],
        x: &recording.x[stretch.clone()],
        u: recording.u.as_ref().map(|u| &u[stretch.clone()]),
    };
    let period = mean_period_samples(data.x)?;
    let segment = ((2.0 * period).round() as usize).max(16);
    if data.x.len() < 4 * segment {
        return None;
    }
    let fit = free_run_after_fitted_start(&SimModel::from_report(report), &data, segment)?;
    Some(fit.nrmse_percent <= FOLLOWS_PERCENT)
}

/// How closely (NRMSE, % of x's standard deviation) the model's free run must follow the whole
/// record for [`model_follows`].
pub const FOLLOWS_PERCENT: f64 = 30.0;

/// How much more the recording must oscillate at its end than the model's free run for
/// [`outlasts_model`].
pub const OUTLASTS: f64 = 3.0;

/// Whether x's oscillation grows over the record: its RMS about its mean over the last quarter
/// of the longest clean stretch more than [`GROWS`] times over the first quarter. An
/// oscillator without forcing only loses energy, so a record whose frequency drifts while it
/// grows is driven (a ringdown's frequency drifts while it decays).
pub fn grows(recording: &Recording) -> bool {
    quarters_rms(recording).is_some_and(|(first, last)| last > GROWS * first)
}

/// Whether x keeps its oscillation over the record: its RMS about its mean over the last
/// quarter of the longest clean stretch at least [`KEEPS`] times over the first quarter.
pub fn keeps_amplitude(recording: &Recording) -> bool {
    quarters_rms(recording).is_some_and(|(first, last)| last >= KEEPS * first)
}

/// x's RMS about its mean over the first and the last quarter of the record's longest clean
/// stretch (`None` when a quarter is under 16 samples).
fn quarters_rms(recording: &Recording) -> Option<(f64, f64)> {
    crate::identify::stretch::quarters_rms(recording)
}

/// The share of its first quarter's oscillation x must keep over its last for
/// [`keeps_amplitude`].
pub const KEEPS: f64 = 0.9;

/// How much more x must oscillate over its last quarter than its first for [`grows`].
pub const GROWS: f64 = 1.25;

/// The share of the variance of `y` (weighted by `window`) that a line of `power` in its
/// windowed transform (any zero padding) stands for: 1 for a pure tone at a bin's centre.
/// A tone A cos(ωt) puts (A/2 Σw)² in its bin and A²/2 Σw² of variance in y·w.
fn line_share(power: f64, y: &[f64], window: &[f64]) -> f64 {
    let sum_w: f64 = window.iter().sum();
    let sum_w2: f64 = window.iter().map(|w| w * w).sum();
    let energy: f64 = y.iter().zip(window).map(|(v, w)| (v * w).powi(2)).sum();
    2.0 * sum_w2 * power / (sum_w * sum_w * energy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep's last third moves at its drift's pace; gen seed 4242's hardening ringdown
    /// into its forced response (monostable, --amplitude 0.5 --rate 300 --t-end 8 --delta
    /// 0.03) falls, then stays at Ω = 21.4 rad/s.
    #[test]
    fn a_ringdown_that_settles_at_omega_does_not_keep_moving() {
        let indexed =
            |lines: &[f64]| -> Vec<(usize, f64)> { lines.iter().copied().enumerate().collect() };
        let sweep = indexed(&[10.6, 12.1, 13.4, 15.3, 16.8, 18.2, 20.1, 21.4, 23.3]);
        assert!(keeps_moving(&sweep, 1.6));
        let settled = indexed(&[44.6, 40.4, 37.0, 35.8, 35.7, 35.9, 21.5, 21.4, 21.4]);
        assert!(!keeps_moving(&settled, -2.9));
        // Lines at a harmonic in the last segments (10 and 11), left out of the drift: the kept
        // ones count.
        let harmonic = indexed(&[
            34.3, 32.9, 31.5, 30.0, 28.6, 27.2, 25.8, 24.4, 23.0, 21.5, 40.9, 40.9,
        ]);
        assert!(keeps_moving(&harmonic[..10], -1.42));
        assert!(!keeps_moving(&harmonic[..2], -1.42));
    }

    /// A sweep's segment lines move one way; hostile seed 20733's (a weakly forced bistable
    /// beam's beating transient, 0.94 s segments whose resolution width is 6.7 rad/s) wander
    /// both ways and fall short of [`MIN_TAU`] (they passed the straight-drift test).
    #[test]
    fn lines_that_wander_both_ways_are_not_a_drift() {
        let sweep = [10.6, 12.1, 13.4, 15.3, 16.8, 18.2, 20.1, 21.4, 23.3, 24.6];
        assert_eq!(kendall_tau(&sweep), 1.0);
        let jittered = [10.6, 12.1, 11.9, 15.3, 16.8, 16.5, 20.1, 21.4, 23.3, 24.6];
        assert!(kendall_tau(&jittered) >= MIN_TAU);
        let beating = [
            36.6, 38.5, 35.8, 32.2, 26.6, 26.2, 30.4, 33.3, 31.2, 27.4, 28.4,
        ];
        assert!(
            -kendall_tau(&beating) < MIN_TAU,
            "{}",
            kendall_tau(&beating)
        );
        assert_eq!(kendall_tau(&[1.0]), 0.0);
    }
}
