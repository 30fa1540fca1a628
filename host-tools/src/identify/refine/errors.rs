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
/// `None` when a simulation diverges or the normal matrix is singular.
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
                (sigma2 * inverse[(j, j)] + shift * shift).max(0.0).sqrt()
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
