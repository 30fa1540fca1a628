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

use crate::factor::{Factor, FactorRef};
use crate::model::{MAX_SOLUTIONS, Solution};
use crate::real::Real;

/// STLSQ iterations at one threshold before giving up on a fixed point.
const MAX_ITERATIONS: usize = 12;

/// The most thresholds one sweep tries: 0, the dense magnitudes, then the log grid's points
/// from its small end as long as there is room (a grid of more than 96 − 1 − terms points
/// loses its largest ones).
const MAX_THRESHOLDS: usize = 96;

/// hi/lo from which the log grid's points are known to rise with their index. With at most
/// 255 points (`Config::thresholds` is a u8) each is at least a factor (hi/lo)^(1/254) above
/// the one before, here 1 + 3.9·10⁻¹⁵ (17 ulps of f64), while `libm::exp` is within an ulp
/// and the rounding of ln(hi/lo)·i/(grid − 1) moves a point by less (ln(hi/lo) itself is
/// rounded once for every point); rounding to T and scaling by lo keep the order. (exp of a
/// logarithm rather than `libm::pow`: exp is on the device already, pow would add 2.9 KB of
/// flash, log 0.6 KB.)
const GRID_RISES: f64 = 1.0 + 1e-12;

/// The result of one sweep.
pub(crate) struct Sweep<T, const P: usize> {
    pub solutions: heapless::Vec<Solution<T>, MAX_SOLUTIONS>,
    pub selected: usize,
    /// Scaled coefficients of the selected support, solved on A and B together.
    pub coefficients: [T; P],
}

impl<T: Real, const P: usize> Sweep<T, P> {
    /// An empty sweep, to be filled by [`sweep`].
    pub fn new() -> Self {
        Self {
            solutions: heapless::Vec::new(),
            selected: 0,
            coefficients: [T::ZERO; P],
        }
    }

    /// The solution MES selected, if the sweep found any.
    pub fn chosen(&self) -> Option<Solution<T>> {
        self.solutions.get(self.selected).copied()
    }
}

/// The thresholds of a sweep in ascending order, made as they are tried instead of listed
/// and sorted (the list was 388 bytes of the screening's stack on the M4F): 0, each nonzero
/// dense magnitude just exceeded, and the `grid` points lo·(hi/lo)^(i/(grid − 1)) of a
/// logarithmic grid between the least and the greatest magnitude, merged. The values come
/// in the order of the sorted list, bit for bit, duplicates included.
///
/// The grid's points rise with i unless hi/lo is within [`GRID_RISES`] of 1 (two dense
/// magnitudes equal to 12 digits, in f64); then the next one is picked among all of them.
struct Thresholds<T, const P: usize> {
    /// The dense magnitudes just exceeded, ascending, in `dense[..dense_len]`.
    dense: [T; P],
    dense_len: usize,
    next_dense: usize,
    lo: T,
    /// ln(hi/lo).
    log_ratio: f64,
    /// grid − 1, the exponent's denominator.
    steps: f64,
    grid_len: usize,
    /// Grid points taken so far; the last one picked (value, index) when they do not rise.
    grid_taken: usize,
    last_grid: Option<(T, usize)>,
    grid_rises: bool,
    /// The next grid point, once made.
    pending: Option<T>,
    zero_taken: bool,
}

impl<T: Real, const P: usize> Thresholds<T, P> {
    fn new(magnitude: &[T; P], dense_support: u32, n: usize, grid: usize) -> Self {
        let mut dense = [T::ZERO; P];
        let mut dense_len = 0;
        let (mut lo, mut hi) = (T::MAX, T::ZERO);
        for j in 0..n {
            if dense_support & (1 << j) != 0 && magnitude[j] > T::ZERO {
                if dense_len < MAX_THRESHOLDS - 1 {
                    dense[dense_len] = magnitude[j] * T::from_f64(1.000_001);
                    dense_len += 1;
                }
                lo = lo.min(magnitude[j]);
                hi = hi.max(magnitude[j]);
            }
        }
        let d = &mut dense[..dense_len];
        for i in 1..d.len() {
            let mut k = i;
            while k > 0 && d[k - 1] > d[k] {
                d.swap(k - 1, k);
                k -= 1;
            }
        }
        let (grid_len, ratio) = if hi > lo && grid > 1 {
            (grid.min(MAX_THRESHOLDS - 1 - dense_len), (hi / lo).to_f64())
        } else {
            (0, 1.0)
        };
        Self {
            dense,
            dense_len,
            next_dense: 0,
            lo,
            log_ratio: libm::log(ratio),
            steps: grid.saturating_sub(1) as f64,
            grid_len,
            grid_taken: 0,
            last_grid: None,
            grid_rises: ratio >= GRID_RISES,
            pending: None,
            zero_taken: false,
        }
    }

    fn grid_point(&self, i: usize) -> T {
        self.lo * T::from_f64(libm::exp(self.log_ratio * (i as f64 / self.steps)))
    }

    /// The next grid point in ascending order (equal ones in index order).
    fn next_grid(&mut self) -> Option<T> {
        if self.grid_taken >= self.grid_len {
            return None;
        }
        self.grid_taken += 1;
        if self.grid_rises {
            return Some(self.grid_point(self.grid_taken - 1));
        }
        let mut next: Option<(T, usize)> = None;
        for i in 0..self.grid_len {
            let v = self.grid_point(i);
            let after = self
                .last_grid
                .is_none_or(|(last, at)| v > last || (v == last && i > at));
            if after && next.is_none_or(|(least, _)| v < least) {
                next = Some((v, i));
            }
        }
        self.last_grid = next;
        next.map(|(v, _)| v)
    }
}

impl<T: Real, const P: usize> Iterator for Thresholds<T, P> {
    type Item = T;

    fn next(&mut self) -> Option<T> {
        // 0 comes first: every other threshold is positive.
        if !self.zero_taken {
            self.zero_taken = true;
            return Some(T::ZERO);
        }
        if self.pending.is_none() {
            self.pending = self.next_grid();
        }
        let dense = self.dense[..self.dense_len].get(self.next_dense).copied();
        match (dense, self.pending) {
            (Some(d), Some(g)) if g < d => self.pending.take(),
            (Some(d), _) => {
                self.next_dense += 1;
                Some(d)
            }
            (None, _) => self.pending.take(),
        }
    }
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

/// Supports solved on the union factor in one sweep, remembered for the next thresholds.
const SOLVED: usize = 4;

/// The last [`SOLVED`] solves of one sweep on `all`, by support. Every threshold's STLSQ starts
/// from the dense support and the thresholds are close together, so most of their chains
/// of supports repeat (measured on the M4F: about half a screening's instructions were
/// solves already made). A solve is a pure function of the factor and the support, so a
/// remembered one is the same bits as solving again.
struct Solved<T, const P: usize> {
    /// (support asked for, columns used, the solution); a slot of support 0 is empty
    /// (support 0 is never remembered: its solve returns at once).
    entries: [(u32, u32, [T; P]); SOLVED],
    /// The slot the next new solve goes to (round robin).
    next: usize,
}

impl<T: Real, const P: usize> Solved<T, P> {
    fn new() -> Self {
        Self {
            entries: [(0, 0, [T::ZERO; P]); SOLVED],
            next: 0,
        }
    }

    /// `all.solve_in(support, xi, work)`, from memory when this support was solved before.
    fn solve(
        &mut self,
        all: &Factor<T, P>,
        support: u32,
        xi: &mut [T; P],
        work: &mut [[T; P]; P],
    ) -> u32 {
        if support != 0
            && let Some((_, used, solution)) = self.entries.iter().find(|e| e.0 == support)
        {
            *xi = *solution;
            return *used;
        }
        let used = all.solve_in(support, xi, work);
        if support != 0 {
            self.entries[self.next] = (support, used, *xi);
            self.next = (self.next + 1) % SOLVED;
        }
        used
    }
}

/// Sequential thresholding at `threshold`, starting from the columns in `start`.
fn stlsq<T: Real, const P: usize>(
    all: &Factor<T, P>,
    work: &mut [[T; P]; P],
    solved: &mut Solved<T, P>,
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
        support = solved.solve(all, support, &mut xi, work);
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
    a: FactorRef<'_, T, P>,
    b: FactorRef<'_, T, P>,
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

/// Runs the sweep and MES over factors `a`, `b` and their union `all` (same columns), into
/// `out` (filled in place: a returned sweep was a second copy on the stack). `grid` is the
/// number of logarithmic thresholds, `parsimony` the near-tie tolerance; `work` is scratch
/// for the solves.
pub(crate) fn sweep<T: Real, const P: usize>(
    a: FactorRef<'_, T, P>,
    b: FactorRef<'_, T, P>,
    all: &Factor<T, P>,
    work: &mut [[T; P]; P],
    grid: usize,
    parsimony: T,
    out: &mut Sweep<T, P>,
) {
    let n = all.columns();
    let full: u32 = if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
    let mut norms = [T::ZERO; P];
    all.column_norms(&mut norms);
    let y_norm = all.target_norm();
    // The dense solution in the output's place (it is overwritten at the end): one P-vector
    // less on the screening's stack.
    let dense_support = all.solve_in(full, &mut out.coefficients, work);
    let mut magnitude = [T::ZERO; P];
    scaled(&out.coefficients, &norms, y_norm, n, &mut magnitude);

    // The thresholds, ascending, so that solutions run from dense to sparse.
    let thresholds = Thresholds::new(&magnitude, dense_support, n, grid);
    let solutions = &mut out.solutions;
    solutions.clear();
    let mut solved = Solved::new();
    for threshold in thresholds {
        let support = stlsq(
            all,
            work,
            &mut solved,
            &norms,
            y_norm,
            dense_support,
            threshold,
        );
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
    let selected = mes(solutions, all, y_norm, parsimony);
    out.selected = selected;
    out.coefficients = [T::ZERO; P];
    if let Some(s) = out.solutions.get(selected) {
        solved.solve(all, s.support, &mut out.coefficients, work);
    }
}

/// Minimum-error sparsity (MES) with the parsimony rule: among the solutions whose held-out
/// error is within `parsimony` of the least (plus a floor of rounding), the sparsest, then
/// the least error. The index of the selected one (0 when there are none).
#[inline(always)]
fn mes<T: Real, const P: usize>(
    solutions: &[Solution<T>],
    all: &Factor<T, P>,
    y_norm: T,
    parsimony: T,
) -> usize {
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
    selected
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_remembered_solve_is_the_solve_bit_for_bit() {
        // Six columns with a nearly dependent pair (the rank test drops one of them).
        let mut all = Factor::<f32, 8>::new(6);
        for k in 0..200 {
            let t = k as f32 * 0.05;
            let row = [
                1.0,
                t.sin(),
                t.cos(),
                t.sin() * t.cos(),
                t.sin() + 1e-9,
                (2.0 * t).sin(),
            ];
            all.update(
                &row,
                0.3 * t.sin() - 2.0 * t.cos() + 0.01 * (k % 3) as f32,
                1.0,
            );
        }
        let mut work = [[0.0f32; 8]; 8];
        let mut solved = Solved::<f32, 8>::new();
        // More supports than the memory holds, each asked for twice in a row and again later.
        let supports = [
            0b111111u32,
            0b000110,
            0b010111,
            0b100001,
            0b011110,
            0b000001,
            0,
        ];
        for round in 0..3 {
            for &support in &supports {
                for _ in 0..2 {
                    let (mut fresh, mut kept) = ([0.0f32; 8], [7.0f32; 8]);
                    let used = all.solve_in(support, &mut fresh, &mut work);
                    let remembered = solved.solve(&all, support, &mut kept, &mut work);
                    assert_eq!(remembered, used, "{round} {support:b}");
                    assert_eq!(
                        kept.map(f32::to_bits),
                        fresh.map(f32::to_bits),
                        "{support:b}"
                    );
                }
            }
        }
        // The nearly dependent column went from the full support.
        assert_ne!(all.solve_in(0b111111, &mut [0.0; 8], &mut work), 0b111111);
    }

    /// The thresholds as the sweep once made them: listed (at most 96), then sorted.
    fn listed<T: Real, const P: usize>(
        magnitude: &[T; P],
        dense_support: u32,
        n: usize,
        grid: usize,
    ) -> Vec<T> {
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
            let log_ratio = libm::log((hi / lo).to_f64());
            for i in 0..grid {
                let f = libm::exp(log_ratio * (i as f64 / (grid - 1) as f64));
                let _ = thresholds.push(lo * T::from_f64(f));
            }
        }
        let t = thresholds.as_mut_slice();
        for i in 1..t.len() {
            let mut k = i;
            while k > 0 && t[k - 1] > t[k] {
                t.swap(k - 1, k);
                k -= 1;
            }
        }
        thresholds.to_vec()
    }

    fn bits<T: Real>(values: &[T]) -> Vec<u64> {
        values.iter().map(|v| v.to_f64().to_bits()).collect()
    }

    /// Both ways of making the grid (rising, and picked one by one) against the sorted list.
    fn check<T: Real, const P: usize>(magnitude: &[T; P], support: u32, n: usize, grid: usize) {
        let expected = bits(&listed(magnitude, support, n, grid));
        let made: Vec<T> = Thresholds::new(magnitude, support, n, grid).collect();
        assert_eq!(bits(&made), expected);
        let mut picked = Thresholds::new(magnitude, support, n, grid);
        picked.grid_rises = false;
        assert_eq!(bits(&picked.collect::<Vec<T>>()), expected);
    }

    fn to_array<T: Real, const P: usize>(values: &[f64]) -> [T; P] {
        let mut out = [T::ZERO; P];
        for (o, v) in out.iter_mut().zip(values) {
            *o = T::from_f64(*v);
        }
        out
    }

    proptest! {
        #[test]
        fn thresholds_come_in_the_sorted_lists_order(
            exponents in proptest::collection::vec(-12.0f64..6.0, 32),
            zeros in any::<u32>(),
            support in any::<u32>(),
            repeat in 0usize..32,
            n in 0usize..=32,
            grid in 0usize..=255,
        ) {
            let mut values: Vec<f64> = exponents
                .iter()
                .enumerate()
                .map(|(j, e)| if zeros & (1 << j) != 0 && j % 3 == 0 { 0.0 } else { libm::pow(10.0, *e) })
                .collect();
            // Equal magnitudes make equal thresholds.
            values[repeat] = values[(repeat * 7) % 32];
            check::<f32, 32>(&to_array(&values), support, n, grid);
            check::<f64, 32>(&to_array(&values), support, n, grid);
            check::<f32, 16>(&to_array(&values), support, n.min(16), grid);
        }

        #[test]
        fn a_grid_between_nearly_equal_magnitudes_is_in_order(
            base in 1e-6f64..1e3,
            ulps in 1u64..4096,
            grid in 2usize..=255,
        ) {
            // hi/lo within 10⁻¹² of 1: the grid's points need not rise with their index.
            let hi = f64::from_bits(base.to_bits() + ulps);
            let values = [base, hi, base, 0.0];
            check::<f64, 4>(&to_array(&values), 0b1111, 4, grid);
            check::<f32, 4>(&to_array(&values), 0b1111, 4, grid);
        }
    }

    #[test]
    fn a_grid_too_long_for_the_list_loses_its_largest_points() {
        let values: Vec<f64> = (0..16).map(|j| 1.5f64.powi(j)).collect();
        let magnitude: [f32; 16] = to_array(&values);
        let made: Vec<f32> = Thresholds::new(&magnitude, u32::MAX, 16, 255).collect();
        assert_eq!(made.len(), MAX_THRESHOLDS);
        check(&magnitude, u32::MAX, 16, 255);
        check(&magnitude, u32::MAX, 16, 24);
        check(&magnitude, 0, 16, 24);
    }
}
