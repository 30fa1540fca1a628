//! Ω polished on the weak form's rows: the excitation frequency that the identifier's own
//! equation explains best.
//!
//! [`super::omega::estimate_omega`] finds Ω from a spectrum and a least-squares fit on
//! second derivatives taken as they are, and on a record of 20 s it misses by about 10⁻³
//! rad/s (a record's resolution is 2π/T; the decaying start leaks into it; x'' estimated at
//! 30–60 samples a period is noisy). Over the record the phase of cos(Ωt) then drifts by
//! 0.02 rad, and the regression takes a spurious sin(Ωt) term of 2 % of the forcing to
//! follow it. The weak form's rows (test-function sums over a short derivative window, as
//! the identifier takes them) cancel most of the derivative's noise, so the same fit on them
//! finds Ω ten to a hundred times closer (bench/choice/testset.py's low-rate kinds, seeds
//! 1–3: 1–3 × 10⁻³ rad/s off before, 10⁻⁶–2.6 × 10⁻⁴ after).
//!
//! The polish scans ± a quarter of the record's resolution about the estimate and keeps the
//! ω whose residual (library terms and sin/cos of each harmonic, least squares over the
//! test-function sums) is least; the estimate stays when nothing explains more.

use lssi_core::derivative::Taps;
use lssi_core::factor::Factor;
use lssi_core::{Config, Library, LibraryConfig};

use super::{TERM_CAPACITY, WINDOW_CAPACITY, golden};
use crate::identify::blemish::{CleanWindows, Scan};
use crate::recording::Recording;

/// Test-function sums over runs of consecutive rows, with the polynomial columns and the
/// target summed once (they do not depend on ω).
struct Sums {
    /// Per run of consecutive rows: each row's time.
    times: Vec<Vec<f64>>,
    /// The weights φ over a test function's rows.
    weights: Vec<f64>,
    /// Per sum: its run and first row.
    places: Vec<(usize, usize)>,
    /// Per sum: the summed library columns (without harmonics).
    columns: Vec<[f64; TERM_CAPACITY]>,
    /// Per sum: the summed target.
    targets: Vec<f64>,
}

/// Ω polished on the weak form's rows (see the module's text), or `omega` as it is when the
/// weak form is off, the record is too short for it, or no ω nearby explains more. `extra`:
/// channels the equation also holds (a harvester's V or i, a second displacement), each a
/// column of its smoothed value: without them the fit leans on the forcing's phase to stand
/// in for them, and Ω comes out biased (a system's piezo record at 2,920 Hz: 2.8 × 10⁻³ rad/s
/// off, a spurious sin(Ωt) of 1.8 % of the forcing).
pub fn polish_omega(recording: &Recording, config: &Config, omega: f64, extra: &[&[f64]]) -> f64 {
    let harmonics = usize::from(config.library.harmonics);
    let width = usize::from(config.test_rows);
    if harmonics == 0 || width < 4 || !(omega.is_finite() && omega > 0.0) {
        return omega;
    }
    let Some(sums) = sums(recording, config, width, extra) else {
        return omega;
    };
    let p = Library::<TERM_CAPACITY>::new(&LibraryConfig {
        harmonics: 0,
        input: false,
        ..config.library
    })
    .map_or(0, |l| l.len())
        + extra.len();
    if p == 0 || p + 2 * harmonics > TERM_CAPACITY || sums.targets.len() < 4 * (p + 2 * harmonics) {
        return omega;
    }
    let residual = |w: f64| -> f64 {
        let mut f: Factor<f64, TERM_CAPACITY> = Factor::new(p + 2 * harmonics);
        // sin/cos(kωt) once per row, then each sum is a weighted dot product.
        let waves: Vec<Vec<Vec<(f64, f64)>>> = (1..=harmonics)
            .map(|k| {
                sums.times
                    .iter()
                    .map(|run| run.iter().map(|t| (k as f64 * w * t).sin_cos()).collect())
                    .collect()
            })
            .collect();
        for (((run, first), columns), y) in sums.places.iter().zip(&sums.columns).zip(&sums.targets)
        {
            let mut r = *columns;
            for (k, wave) in waves.iter().enumerate() {
                let (mut s, mut c) = (0.0, 0.0);
                for (phi, (sn, cs)) in sums.weights.iter().zip(&wave[*run][*first..]) {
                    s += phi * sn;
                    c += phi * cs;
                }
                r[p + 2 * k] = s;
                r[p + 2 * k + 1] = c;
            }
            f.update(&r, *y, 1.0);
        }
        f.residual_energy()
    };
    let t0 = recording.t.first().copied().unwrap_or(0.0);
    let t1 = recording.t.last().copied().unwrap_or(t0);
    let span = t1 - t0;
    if !(span.is_finite() && span > 0.0) {
        return omega;
    }
    let half = 0.25 * 2.0 * std::f64::consts::PI / span;
    let nyquist = std::f64::consts::PI / config.sample_period;
    let steps = 16;
    let grid = half / f64::from(steps);
    let (mut best, mut best_w) = (residual(omega), omega);
    let start = best;
    for i in -steps..=steps {
        let w = omega + grid * f64::from(i);
        if i == 0 || w <= 0.0 || w * harmonics as f64 >= nyquist {
            continue;
        }
        let r = residual(w);
        if r < best {
            (best, best_w) = (r, w);
        }
    }
    let w = golden(residual, best_w - grid, best_w + grid, 30);
    let (w, r) = match residual(w) {
        r if r < best => (w, r),
        _ => (best_w, best),
    };
    if r.is_finite() && r < start && w > 0.0 {
        w
    } else {
        omega
    }
}

/// The test-function sums of the record's clean stretches, as the identifier's weak form
/// takes them: rows at every sample (the derivative window's estimates, the target from v
/// when it is measured), φ(τ) = (1 − τ²)⁴ over `width` rows normalised to sum 1, a sum
/// started every quarter of `width`.
fn sums(recording: &Recording, config: &Config, width: usize, extra: &[&[f64]]) -> Option<Sums> {
    let n = config.window;
    let taps: Taps<f64, WINDOW_CAPACITY> = Taps::design(
        n,
        usize::from(config.derivative_degree),
        config.sample_period,
    )
    .ok()?;
    let library: Library<TERM_CAPACITY> = Library::new(&LibraryConfig {
        harmonics: 0,
        input: false,
        ..config.library
    })
    .ok()?;
    let scan = Scan::of(recording);
    let x = scan.repaired(recording, 0)?;
    let v = scan
        .repaired(recording, 1)
        .filter(|_| recording.v.is_some());
    let clean = CleanWindows::new(&scan.with_repairs_kept(), n);
    let q = library.len();
    if q + extra.len() > TERM_CAPACITY || extra.iter().any(|c| c.len() != x.len()) {
        return None;
    }
    // Rows at every sample; a run of consecutive rows is cut where a window is not clean.
    let mut runs: Vec<Vec<(f64, [f64; TERM_CAPACITY], f64)>> = vec![Vec::new()];
    let mut start = 0;
    while start + n <= x.len() {
        let row = clean.ok(start).then(|| {
            let w = &x[start..start + n];
            let (xh, vh, yh) = match &v {
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
            let t = recording.t[start + (n - 1) / 2];
            let mut row = [0.0; TERM_CAPACITY];
            library.evaluate(xh, vh, 0.0, 0.0, &mut row);
            for (j, c) in extra.iter().enumerate() {
                row[q + j] = taps.apply(0, &c[start..start + n], &[]);
            }
            (xh.is_finite()
                && vh.is_finite()
                && yh.is_finite()
                && t.is_finite()
                && row[q..q + extra.len()].iter().all(|e| e.is_finite()))
            .then_some((t, row, yh))
        });
        match row.flatten() {
            Some(r) => runs.last_mut()?.push(r),
            None => {
                if !runs.last()?.is_empty() {
                    runs.push(Vec::new());
                }
            }
        }
        start += 1;
    }
    let weights: Vec<f64> = {
        let l = width as f64;
        let raw: Vec<f64> = (0..width)
            .map(|i| {
                let tau = (2.0 * i as f64 + 1.0) / l - 1.0;
                let b = 1.0 - tau * tau;
                (b * b) * (b * b)
            })
            .collect();
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|w| w / sum).collect()
    };
    let hop = (width / 4).max(1);
    let p = q + extra.len();
    let mut out = Sums {
        times: Vec::with_capacity(runs.len()),
        weights,
        places: Vec::new(),
        columns: Vec::new(),
        targets: Vec::new(),
    };
    for (r, run) in runs.iter().enumerate() {
        let mut first = 0;
        while first + width <= run.len() {
            let mut columns = [0.0; TERM_CAPACITY];
            let mut target = 0.0;
            for (phi, (_, row, y)) in out.weights.iter().zip(&run[first..first + width]) {
                for j in 0..p {
                    columns[j] += phi * row[j];
                }
                target += phi * y;
            }
            out.places.push((r, first));
            out.columns.push(columns);
            out.targets.push(target);
            first += hop;
        }
        out.times.push(run.iter().map(|(t, _, _)| *t).collect());
    }
    Some(out)
}
