//! Periodic sequential thresholding and mean-error screening (paper eqs. 14–15).
//!
//! The threshold grid comes from the data: the scaled magnitudes |ξ_j|·‖θ_j‖/‖y‖ of the dense
//! least-squares solution (each just exceeded gives the next sparser support), plus a
//! logarithmic grid between the smallest and the largest of them. At each threshold,
//! sequential thresholding (STLSQ) alternates an exact least-squares solve on the kept columns
//! (from the factor, no data revisited) with dropping the columns under the threshold, until
//! the support stops changing. The distinct supports are the solutions S_1..S_n.
//!
//! MES (eq. 15) ranks them by mean error measured on data held out of the fit: the rows are
//! dealt to two factors A and B in alternating blocks longer than the smoothing window, and a
//! support's error is the average of A's solution tested on B and B's tested on A (two-fold
//! cross-validation), so a spurious term that only fits the noise makes the error larger,
//! not smaller. Near-ties are broken towards parsimony: the selected solution is the
//! sparsest whose held-out error is within `parsimony` (5 %) of the least; among equally
//! sparse ones, the least error. The final coefficients are solved on A and B together.

use crate::factor::Factor;
use crate::model::{MAX_SOLUTIONS, Solution};
use crate::real::Real;

/// STLSQ iterations at one threshold before giving up on a fixed point.
const MAX_ITERATIONS: usize = 12;

/// The result of one sweep.
pub(crate) struct Sweep<T, const P: usize> {
    pub solutions: heapless::Vec<Solution<T>, MAX_SOLUTIONS>,
    pub selected: usize,
    /// Scaled coefficients of the selected support, solved on A and B together.
    pub coefficients: [T; P],
}

/// |ξ_j|·‖θ_j‖/‖y‖ for the columns in `support`.
fn scaled<T: Real, const P: usize>(
    xi: &[T; P],
    norms: &[T; P],
    y_norm: T,
    n: usize,
    out: &mut [T; P],
) {
    for j in 0..n {
        out[j] = if y_norm > T::ZERO {
            xi[j].abs() * norms[j] / y_norm
        } else {
            xi[j].abs()
        };
    }
}

/// Sequential thresholding at `threshold`, starting from the columns in `start`.
fn stlsq<T: Real, const P: usize>(
    all: &Factor<T, P>,
    work: &mut [[T; P]; P],
    norms: &[T; P],
    y_norm: T,
    start: u32,
    threshold: T,
) -> u32 {
    let n = all.columns();
    let mut support = start;
    let mut xi = [T::ZERO; P];
    let mut magnitude = [T::ZERO; P];
    for _ in 0..MAX_ITERATIONS {
        support = all.solve_in(support, &mut xi, work);
        scaled(&xi, norms, y_norm, n, &mut magnitude);
        let mut next = 0u32;
        for j in 0..n {
            if support & (1 << j) != 0 && magnitude[j] >= threshold {
                next |= 1 << j;
            }
        }
        if next == support {
            break;
        }
        support = next;
    }
    support
}

/// Held-out mean error of a support: A's fit tested on B and B's on A.
fn held_out<T: Real, const P: usize>(
    a: &Factor<T, P>,
    b: &Factor<T, P>,
    support: u32,
    work: &mut [[T; P]; P],
) -> T {
    let mut xi = [T::ZERO; P];
    let mut total = T::ZERO;
    let mut parts = T::ZERO;
    for (fit, test) in [(a, b), (b, a)] {
        if test.weight() <= T::ZERO {
            continue;
        }
        fit.solve_in(support, &mut xi, work);
        total += test.error(&xi) / test.weight();
        parts += T::ONE;
    }
    if parts > T::ZERO {
        total / parts
    } else {
        T::MAX
    }
}

/// Runs the sweep and MES over factors `a`, `b` and their union `all` (same columns).
/// `grid` is the number of logarithmic thresholds, `parsimony` the near-tie tolerance;
/// `work` is scratch for the solves.
pub(crate) fn sweep<T: Real, const P: usize>(
    a: &Factor<T, P>,
    b: &Factor<T, P>,
    all: &Factor<T, P>,
    work: &mut [[T; P]; P],
    grid: usize,
    parsimony: T,
) -> Sweep<T, P> {
    let n = all.columns();
    let full: u32 = if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
    let mut norms = [T::ZERO; P];
    all.column_norms(&mut norms);
    let y_norm = all.target_norm();
    let mut dense = [T::ZERO; P];
    let dense_support = all.solve_in(full, &mut dense, work);
    let mut magnitude = [T::ZERO; P];
    scaled(&dense, &norms, y_norm, n, &mut magnitude);

    // The thresholds: each nonzero dense magnitude, just exceeded, and a log grid.
    let mut thresholds: heapless::Vec<T, 96> = heapless::Vec::new();
    let _ = thresholds.push(T::ZERO);
    let (mut lo, mut hi) = (T::MAX, T::ZERO);
    for j in 0..n {
        if dense_support & (1 << j) != 0 && magnitude[j] > T::ZERO {
            let _ = thresholds.push(magnitude[j] * T::from_f64(1.000_001));
            lo = lo.min(magnitude[j]);
            hi = hi.max(magnitude[j]);
        }
    }
    if hi > lo && grid > 1 {
        let ratio = (hi / lo).to_f64();
        for i in 0..grid {
            let f = libm::pow(ratio, i as f64 / (grid - 1) as f64);
            let _ = thresholds.push(lo * T::from_f64(f));
        }
    }
    // Ascending, so solutions run from dense to sparse.
    let t = thresholds.as_mut_slice();
    for i in 1..t.len() {
        let mut k = i;
        while k > 0 && t[k - 1] > t[k] {
            t.swap(k - 1, k);
            k -= 1;
        }
    }

    let mut solutions: heapless::Vec<Solution<T>, MAX_SOLUTIONS> = heapless::Vec::new();
    for &threshold in thresholds.iter() {
        let support = stlsq(all, work, &norms, y_norm, dense_support, threshold);
        if support == 0 || solutions.iter().any(|s| s.support == support) {
            continue;
        }
        let mean_error = held_out(a, b, support, work);
        if solutions
            .push(Solution {
                threshold,
                mean_error,
                support,
            })
            .is_err()
        {
            break;
        }
    }

    // MES with the parsimony rule.
    let mut selected = 0;
    if !solutions.is_empty() {
        let mut least = T::MAX;
        for s in solutions.iter() {
            least = least.min(s.mean_error);
        }
        // An absolute floor too: differences below 10⁻⁶ of the target's mean square are
        // rounding, not information (a noise-free record would otherwise keep every term).
        let floor = y_norm * y_norm / all.weight().max(T::ONE) * T::from_f64(1e-6);
        let bound = least * (T::ONE + parsimony) + floor;
        let mut best: Option<(u32, T, usize)> = None;
        for (i, s) in solutions.iter().enumerate() {
            if s.mean_error <= bound {
                let better = match best {
                    None => true,
                    Some((len, err, _)) => s.len() < len || (s.len() == len && s.mean_error < err),
                };
                if better {
                    best = Some((s.len(), s.mean_error, i));
                }
            }
        }
        if let Some((_, _, i)) = best {
            selected = i;
        }
    }
    let mut coefficients = [T::ZERO; P];
    if let Some(s) = solutions.get(selected) {
        all.solve_in(s.support, &mut coefficients, work);
    }
    Sweep {
        solutions,
        selected,
        coefficients,
    }
}
