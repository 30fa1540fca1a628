//! Standard errors of refined coefficients (see the module doc of [`super`]).

use lssi_core::Term;

use super::Data;
use super::normal::BlockNormal;
use super::shooting::{Shape, Solution, jacobian, offset_column, rss};

/// The standard errors of a solution's coefficients (see the module doc): the marginal
/// covariance of the coefficients in the inverse of the full normal matrix (coefficients,
/// every segment's initial state and, when the model has a sin/cos term, the excitation
/// frequency Ω), scaled by the residual variance and the residuals' correlation factor, plus
/// the shift of the coefficients that freeing Ω would make (one Gauss–Newton step), squared:
/// the coefficients are refined at the streaming model's Ω, and its error moves them.
/// And, when the model is driven by a measured u, the variance that u's own noise puts on
/// them ([`input_noise_shift`]). `None` when a simulation diverges or the normal matrix is
/// singular.
pub(crate) fn standard_errors(shape: &Shape, data: &Data, sol: &Solution) -> Option<Vec<f64>> {
    let n = data.len();
    let k = sol.coefficients.len();
    let (c, segs, states) = (&sol.coefficients, &sol.segments, &sol.states);
    let (mut base, mut plus, mut minus) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let rss0 = rss(shape, c, data, segs, states, &mut base)?;
    let mut columns = jacobian(shape, c, data, segs, states, k)?;
    // x's offset, when fitted, is a shared parameter too (its column after the states').
    let offset = sol.offset_fitted;
    if offset {
        columns.push(offset_column(&columns[k], segs, n));
    }
    let periodic = shape
        .terms
        .iter()
        .any(|t| matches!(t, Term::Sin(_) | Term::Cos(_)));
    if periodic {
        let h = 1e-6 * shape.omega.abs().max(1e-9);
        let moved = |by: f64| Shape {
            omega: shape.omega + by,
            ..shape.clone()
        };
        rss(&moved(h), c, data, segs, states, &mut plus)?;
        rss(&moved(-h), c, data, segs, states, &mut minus)?;
        columns.push((0..n).map(|i| (plus[i] - minus[i]) / (2.0 * h)).collect());
    }
    // Shared parameters: the coefficients, then x's offset (when fitted), then Ω (when
    // periodic); two per segment.
    let mut shared: Vec<&[f64]> = columns[..k].iter().map(Vec::as_slice).collect();
    if offset {
        shared.push(&columns[k + 2]);
    }
    if periodic {
        shared.push(&columns[k + 2 + usize::from(offset)]);
    }
    let normal = BlockNormal::assemble(
        &shared,
        [&columns[k], &columns[k + 1]],
        |i| base[i] - data.x[i],
        segs,
    );
    let inverse = normal.shared_inverse()?;
    // u's noise through the model (coefficients and states refitted, Ω held).
    let input = input_noise_shift(
        shape,
        data,
        sol,
        &shared[..k + usize::from(offset)],
        [&columns[k], &columns[k + 1]],
        &base,
    )
    .unwrap_or_else(|| vec![0.0; k]);
    let p = normal.parameters();
    let m: usize = segs.iter().map(|&(a, b)| b - a).sum();
    let sigma2 = rss0 / m.saturating_sub(p).max(1) as f64 * correlation_factor(&sol.residuals);
    // The coefficients' shift were Ω refined too (zero in the coefficients' and states' own
    // directions at the optimum: only Ω's gradient moves them).
    let step = if periodic {
        Some(normal.solve(0.0)?.0)
    } else {
        None
    };
    Some(
        (0..k)
            .map(|j| {
                let shift = step.as_ref().map_or(0.0, |s| s[j]);
                (sigma2 * inverse[(j, j)] + shift * shift + input[j])
                    .max(0.0)
                    .sqrt()
            })
            .collect(),
    )
}

/// 1 + 2 Σ ρₖ over the residuals' autocorrelation, summed while it stays above 0.05.
fn correlation_factor(residuals: &[f64]) -> f64 {
    let n = residuals.len();
    if n < 4 {
        return 1.0;
    }
    let mean = residuals.iter().sum::<f64>() / n as f64;
    let var = residuals.iter().map(|r| (r - mean).powi(2)).sum::<f64>();
    if var == 0.0 {
        return 1.0;
    }
    let mut factor = 1.0;
    for lag in 1..n.min(2000) {
        let rho = (0..n - lag)
            .map(|i| (residuals[i] - mean) * (residuals[i + lag] - mean))
            .sum::<f64>()
            / var;
        if rho < 0.05 {
            break;
        }
        factor += 2.0 * rho;
    }
    factor
}

/// Draws of u's noise [`input_noise_shift`] averages over.
const INPUT_DRAWS: usize = 8;

/// The variance each coefficient gets from the noise in the measured excitation u, which the
/// simulation is driven by as if it were exact (the residual's variance is x's noise alone,
/// and the response to u's noise, narrow-band at the model's resonance, barely shows in it).
/// u's white noise level is the median power of the upper half of its band
/// ([`white_noise_sd`]); the coefficients' shift when noise of that level is added to u once
/// more (one Gauss–Newton step from the optimum, the segments' states refitted, the
/// coefficients' covariance with them kept) is what the noise already in u moved them by, to
/// first order, and its mean square over [`INPUT_DRAWS`] draws is that variance. Issue 25,
/// `scripts/hostile-more.sh` seeds 20108 and 20153: 1 % and 5 % noise on u moved the damping
/// and the linear stiffness 3–6 times as far as σ²(JᵀJ)⁻¹ allowed (1 % on u alone: the
/// damping over eight noise draws scattered 0.016 against a printed ± of 0.005; these
/// draws' shifts 0.015 RMS).
/// `None` without a u, or when a simulation diverges.
fn input_noise_shift(
    shape: &Shape,
    data: &Data,
    sol: &Solution,
    shared: &[&[f64]],
    state: [&[f64]; 2],
    base: &[f64],
) -> Option<Vec<f64>> {
    use rand::{RngExt, SeedableRng};
    let u = data.u?;
    let sd = white_noise_sd(u)?;
    let k = sol.coefficients.len();
    let step = |sim: &[f64]| {
        BlockNormal::assemble(shared, state, |i| sim[i] - data.x[i], &sol.segments)
            .solve(0.0)
            .map(|s| s.0)
    };
    let at_optimum = step(base)?;
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(25);
    let mut moved = u.to_vec();
    let mut sim = vec![0.0; data.len()];
    let mut variance = vec![0.0; k];
    for _ in 0..INPUT_DRAWS {
        for (m, u) in moved.iter_mut().zip(u) {
            *m = u + sd * rng.sample::<f64, _>(rand_distr::StandardNormal);
        }
        let drawn = Data {
            u: Some(&moved),
            ..*data
        };
        rss(
            shape,
            &sol.coefficients,
            &drawn,
            &sol.segments,
            &sol.states,
            &mut sim,
        )?;
        let s = step(&sim)?;
        for (j, v) in variance.iter_mut().enumerate() {
            *v += (s[j] - at_optimum[j]).powi(2) / INPUT_DRAWS as f64;
        }
    }
    Some(variance)
}

/// The standard deviation of the white noise in `u`: the median power of the upper half of
/// its band (its first 2¹⁶ samples), where an excitation's line (or a few harmonics) is one
/// bin of many and the median is the white floor's (for white noise of variance σ², each
/// bin's power is exponential with mean n σ², median n σ² ln 2). `None` under 64 samples, or
/// when that floor is a quarter of u's variance or more (a broadband u: the floor is u itself).
pub(crate) fn white_noise_sd(u: &[f64]) -> Option<f64> {
    use rustfft::{FftPlanner, num_complex::Complex};
    let head = &u[..u.len().min(1 << 16)];
    let n = head.len();
    if n < 64 {
        return None;
    }
    let mean = head.iter().sum::<f64>() / n as f64;
    // Hann-windowed: unwindowed, a strong line's leakage (falling only as the inverse square
    // of the distance in bins) lies above the floor across the whole band.
    let window = |i: usize| {
        let s = (std::f64::consts::PI * i as f64 / n as f64).sin();
        s * s
    };
    let mut buf: Vec<Complex<f64>> = head
        .iter()
        .enumerate()
        .map(|(i, v)| Complex::new((v - mean) * window(i), 0.0))
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    let mut power: Vec<f64> = buf[n / 4..n / 2].iter().map(|c| c.norm_sqr()).collect();
    power.sort_by(f64::total_cmp);
    let median = *power.get(power.len() / 2)?;
    let energy: f64 = (0..n).map(|i| window(i).powi(2)).sum();
    let sd = (median / (energy * std::f64::consts::LN_2)).sqrt();
    // A u whose upper band holds a quarter of its variance or more is broadband (a random
    // excitation): its floor is the signal, not noise on it, and it is not counted (white
    // base acceleration had x's ± 2.9e3 against 351, the model withheld).
    let variance = head.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
    (sd.is_finite() && sd > 0.0 && sd * sd < 0.25 * variance).then_some(sd)
}
