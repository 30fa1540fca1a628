//! The excitation frequency Ω from the data (`lssi identify` without `--omega`).

use lssi_core::derivative::Taps;
use lssi_core::factor::Factor;
use lssi_core::{Config, Library, LibraryConfig};

use super::{IdentifyError, TERM_CAPACITY, WINDOW_CAPACITY, golden};
use crate::recording::Recording;

/// The excitation frequency: the spectral peak of the part of x'' that the library's
/// polynomial terms cannot explain, refined on the exact transform.
pub fn estimate_omega(recording: &Recording, config: &Config) -> Result<f64, IdentifyError> {
    let file = recording.path.display();
    let taps: Taps<f64, WINDOW_CAPACITY> = Taps::design(
        config.window,
        usize::from(config.derivative_degree),
        config.sample_period,
    )
    .map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    let n = config.window;
    // Every fourth window on a long record; on a short one (a few periods, a few hundred
    // samples) every window, so that the scan still has rows to fit.
    let stride = if recording.t.len().saturating_sub(n) / 4 >= 128 {
        4
    } else {
        1
    };
    let library: Library<TERM_CAPACITY> = Library::new(&LibraryConfig {
        harmonics: 0,
        input: false,
        ..config.library
    })
    .map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    let mut rows = Vec::new();
    // Windows within clean, evenly sampled stretches only (a repaired spike with its repaired
    // value); each row's place on the time grid.
    let scan = crate::identify::blemish::Scan::of(recording);
    let x_repaired = scan.repaired(recording, 0).unwrap_or_default();
    let v_repaired = scan
        .repaired(recording, 1)
        .filter(|_| recording.v.is_some());
    let x = &x_repaired;
    let clean = crate::identify::blemish::CleanWindows::new(&scan.with_repairs_kept(), n);
    let mut places = Vec::new();
    let mut start = 0;
    while start + n <= x.len() {
        if !clean.ok(start) {
            start += stride;
            continue;
        }
        let w = &x[start..start + n];
        let (xh, vh, yh) = match &v_repaired {
            Some(v) => {
                let vw = &v[start..start + n];
                (
                    taps.apply(0, w, &[]),
                    taps.apply(0, vw, &[]),
                    taps.apply(1, vw, &[]),
                )
            }
            None => (
                taps.apply(0, w, &[]),
                taps.apply(1, w, &[]),
                taps.apply(2, w, &[]),
            ),
        };
        if xh.is_finite() && vh.is_finite() && yh.is_finite() {
            let mut row = [0.0; TERM_CAPACITY];
            library.evaluate(xh, vh, 0.0, 0.0, &mut row);
            rows.push((recording.t[start + (n - 1) / 2], row, yh));
            places.push((start + clean.missing_before(start)) / stride);
        }
        start += stride;
    }
    if rows.len() < 64 && recording.t.len() < 128 + n {
        // Too short for the identifier as well: --omega would not help.
        return Err(IdentifyError(format!(
            "{file}: only {} samples, too few to estimate the excitation frequency or to identify a model (the identifier needs a few hundred at least); record longer.",
            recording.t.len()
        )));
    }
    if rows.len() < 64 {
        return Err(IdentifyError(format!(
            "{file}: too few samples to estimate the excitation frequency{}; give --omega.",
            crate::identify::blemish::because(&crate::identify::blemish::Scan::of(recording))
        )));
    }
    let p = library.len();
    // Residual energy of the polynomial library plus sin/cos(ωt): the excitation frequency is
    // the ω that explains most. (The polynomial terms alone absorb much of a harmonic forcing,
    // so the residual's spectrum is no guide; the fit is.) The polynomial columns (every
    // other row) are orthonormalised once (modified Gram–Schmidt, a column that is nearly a
    // combination of the others dropped), so that each ω costs two projections: the residual
    // energy is that of the polynomial fit less what sin/cos(ωt), made orthogonal to the
    // polynomial columns, explain of its residual.
    let fit_rows: Vec<&(f64, [f64; TERM_CAPACITY], f64)> = rows.iter().step_by(2).collect();
    let count = fit_rows.len();
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(p);
    for j in 0..p {
        let mut q: Vec<f64> = fit_rows.iter().map(|(_, row, _)| row[j]).collect();
        let norm0 = q.iter().map(|a| a * a).sum::<f64>().sqrt();
        for _ in 0..2 {
            for b in &basis {
                let d: f64 = q.iter().zip(b).map(|(a, b)| a * b).sum();
                q.iter_mut().zip(b).for_each(|(a, b)| *a -= d * b);
            }
        }
        let norm = q.iter().map(|a| a * a).sum::<f64>().sqrt();
        if norm.is_finite() && norm > 1e-9 * norm0 && norm > 0.0 {
            q.iter_mut().for_each(|a| *a /= norm);
            basis.push(q);
        }
    }
    let mut residual: Vec<f64> = fit_rows.iter().map(|(_, _, y)| *y).collect();
    for b in &basis {
        let d: f64 = residual.iter().zip(b).map(|(a, b)| a * b).sum();
        residual.iter_mut().zip(b).for_each(|(a, b)| *a -= d * b);
    }
    let none = residual.iter().map(|a| a * a).sum::<f64>();
    let rss = |w: f64| {
        let (mut ss, mut sc, mut cc, mut sr, mut cr) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let mut qs = vec![0.0; basis.len()];
        let mut qc = vec![0.0; basis.len()];
        let waves: Vec<(f64, f64)> = fit_rows.iter().map(|(t, _, _)| (w * t).sin_cos()).collect();
        for (i, &(sn, cs)) in waves.iter().enumerate() {
            ss += sn * sn;
            sc += sn * cs;
            cc += cs * cs;
            sr += sn * residual[i];
            cr += cs * residual[i];
        }
        for (j, b) in basis.iter().enumerate() {
            let (mut a, mut c) = (0.0, 0.0);
            for (q, &(sn, cs)) in b.iter().zip(&waves) {
                a += q * sn;
                c += q * cs;
            }
            qs[j] = a;
            qc[j] = c;
        }
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
        let (a11, a12, a22) = (ss - dot(&qs, &qs), sc - dot(&qs, &qc), cc - dot(&qc, &qc));
        // What the 2 x 2 system [a11 a12; a12 a22] β = [sr cr] explains: βᵀ [sr cr].
        let det = a11 * a22 - a12 * a12;
        let scale = (count as f64).max(1.0);
        let explained = if det > 1e-12 * scale * scale {
            (a22 * sr * sr - 2.0 * a12 * sr * cr + a11 * cr * cr) / det
        } else if a11.max(a22) > 1e-9 * scale {
            // sin and cos are collinear on these rows (ω near 0 or Nyquist): one of them.
            (sr * sr / a11.max(f64::MIN_POSITIVE)).max(cr * cr / a22.max(f64::MIN_POSITIVE))
        } else {
            0.0
        };
        (none - explained).max(0.0)
    };
    // Candidates: the peaks of the spectrum of x''.
    // Rows on the time grid (a row left out, or a gap, leaves zeros): the span, not the count.
    let m = places
        .last()
        .map_or(0, |p| p - places[0] + 1)
        .max(rows.len());
    let size = (4 * m).next_power_of_two();
    let mut buffer = vec![rustfft::num_complex::Complex::new(0.0, 0.0); size];
    for ((_, _, y), place) in rows.iter().zip(&places) {
        buffer[place - places[0]] = rustfft::num_complex::Complex::new(*y, 0.0);
    }
    rustfft::FftPlanner::new()
        .plan_fft_forward(size)
        .process(&mut buffer);
    let step = config.sample_period * stride as f64;
    let span = step * m as f64;
    let bin_omega = |k: usize| 2.0 * std::f64::consts::PI * k as f64 / (size as f64 * step);
    // Fewer than two periods in the record are no excitation.
    let first = (1..size / 2)
        .find(|&k| bin_omega(k) * span > 4.0 * std::f64::consts::PI)
        .unwrap_or(1);
    let power: Vec<f64> = buffer[..size / 2].iter().map(|c| c.norm_sqr()).collect();
    let mut peaks: Vec<usize> = (first.max(1)..size / 2 - 1)
        .filter(|&k| power[k] > power[k - 1] && power[k] >= power[k + 1])
        .collect();
    peaks.sort_by(|&a, &b| power[b].total_cmp(&power[a]));
    // Distinct peaks only: the zero padding turns a strong line's side lobes into local
    // maxima, within a couple of resolution widths (size / m bins each) of it.
    let separation = 2 * size / m;
    let mut distinct: Vec<usize> = Vec::new();
    for k in peaks {
        if distinct.iter().all(|&d| d.abs_diff(k) > separation) {
            distinct.push(k);
            if distinct.len() == 12 {
                break;
            }
        }
    }
    let peaks = distinct;
    // Each candidate is refined before they are compared: on a record of T seconds a bin is
    // 2π/T wide, and half a bin of phase drift spoils the fit of the true line more than a
    // harmonic's fit is spoiled (a 60 s record then prefers 2Ω to Ω). On a record of a few
    // periods a peak can lie most of a resolution width (2π/T) from its line (the leakage of
    // a stronger neighbour, a transient), so ω is scanned over ± one resolution width about
    // it, in quarter widths, and the best point refined by a golden-section search.
    let resolution = 2.0 * std::f64::consts::PI / span;
    let nyquist = std::f64::consts::PI / step;
    let refine = |centre: f64, half: f64| {
        let quarter = 0.25 * half;
        let (_, best) = (-4..=4)
            .map(|i| centre + quarter * f64::from(i))
            .filter(|&w| w > 0.0 && w < nyquist)
            .map(|w| (rss(w), w))
            .fold(
                (f64::INFINITY, centre),
                |a, b| if b.0 < a.0 { b } else { a },
            );
        let w = golden(rss, (best - quarter).max(0.5 * best), best + quarter, 20);
        (w, rss(w))
    };
    let mut candidates: Vec<(f64, f64)> = peaks
        .iter()
        .take(8)
        .map(|&k| refine(bin_omega(k), resolution))
        .filter(|c| c.1.is_finite())
        .collect();
    // Candidates that explain as much (within 1 %: x'' has no forcing these terms do not
    // already explain, a free oscillation) go by their peak's power, the strongest first.
    let Some(best) = candidates.iter().map(|c| c.1).min_by(f64::total_cmp) else {
        return Err(IdentifyError(format!(
            "{file}: x'' has no spectral peak to take for the excitation{}; give --omega.",
            crate::identify::blemish::because(&crate::identify::blemish::Scan::of(recording))
        )));
    };
    let mut omega = candidates
        .iter()
        .find(|c| c.1 <= 1.01 * best)
        .map_or(candidates[0].0, |c| c.0);
    candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
    // The fundamental, not a harmonic: a nonlinear response to a forcing at Ω has lines at
    // 2Ω and 3Ω, often stronger in x'' (which weighs a line by ω²) than the one at Ω; and a
    // record of a few periods may show no peak at Ω at all. ω/2 … ω/5 of every
    // candidate are refined as the peaks are (over their resolution width / k). The
    // sub-multiple of the chosen ω is taken when it explains about as much (a residual within
    // 3 % of ω's, and at least half of what ω explains beyond the polynomial terms alone).
    // When no candidate explains 1 % of x'' beyond the polynomial terms, refinement only fits
    // the noise: the strongest peak, as it lies.
    if !(none - best > 0.01 * none) {
        return Ok(peaks.first().map_or(omega, |&k| bin_omega(k)));
    }
    let lowest = bin_omega(first.max(1));
    let mut subs: Vec<(f64, f64, f64)> = Vec::new();
    for &(w, _) in &candidates {
        for k in [2.0, 3.0, 4.0, 5.0] {
            if w / k >= lowest {
                let (s, r) = refine(w / k, resolution / k);
                if r.is_finite() {
                    subs.push((w, s, r));
                }
            }
        }
    }
    // The finalists' residuals on the exact fit (the square-root factor of the polynomial
    // columns with sin/cos(ωt), as the identifier solves it), not the projections above.
    let exact = |w: f64| {
        let mut f: Factor<f64, TERM_CAPACITY> = Factor::new(p + 2);
        for (t, row, y) in &fit_rows {
            let mut r = *row;
            r[p] = (w * t).sin();
            r[p + 1] = (w * t).cos();
            f.update(&r, *y, 1.0);
        }
        f.residual_energy()
    };
    // A sub-multiple that explains more than every candidate (by more than the 1 % of a tie)
    // is the fundamental outright; one of the chosen ω that explains about as much is
    // preferred to it, when ω explains anything (1 % of x'' beyond the polynomial terms).
    let best_sub = subs.iter().min_by(|a, b| a.2.total_cmp(&b.2)).copied();
    let own_sub = subs
        .iter()
        .filter(|s| s.0 == omega)
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .copied();
    if let Some((_, s, r)) = best_sub
        && r < 0.99 * best
    {
        omega = s;
    } else if let Some((_, s, _)) = own_sub {
        let (harmonic, sub) = (exact(omega), exact(s));
        if none - harmonic > 0.01 * none
            && sub <= 1.03 * harmonic
            && none - sub >= 0.5 * (none - harmonic)
        {
            omega = s;
        }
    }
    Ok(omega)
}
