//! k-neighbour smoothing (paper eqs. 1–6), streaming, one channel at a time.
//!
//! Each point of a channel is rebuilt from its K nearest neighbours among the rows around it.
//! A point is described by its context — the values just before and after it, Xᵢ = (sᵢ₋₁, sᵢ₊₁)
//! — and its neighbours are the candidates with the closest context (eq. 1). The weights are
//! those of eq. 5, wᵢ = Z⁻¹1 / 1ᵀZ⁻¹1, with the local Gram matrix Z regularised as
//! Z + r·tr(Z)·I because it is singular whenever K exceeds the context's dimension. The
//! smoothed value is the same combination of the neighbours' own values (eq. 6). The point's
//! own value is never part of its reconstruction, so the reconstruction error
//!
//!   ε(K) = mean over rows of (sᵢ − s̄ᵢ(K))²
//!
//! is a leave-one-out prediction error: it falls while more neighbours average the noise away
//! and rises once they are too far to share the point's value. K is the minimiser of ε(K)
//! (the paper's Fig. 4), taking the largest K within 1 % of the minimum, and is re-chosen
//! every time the identifier screens. With one fixed regularisation (from the largest K) the
//! Gram matrices of all K are leading blocks of one matrix, so one Cholesky factorisation
//! gives ε(K) for every K at once.

use crate::real::Real;

/// The largest K.
pub const MAX_NEIGHBOURS: usize = 8;
/// The smallest K.
pub const MIN_NEIGHBOURS: usize = 2;
/// Candidates lie within this many rows either side of the point.
pub const SPAN: usize = 6;
/// Rows of history: the candidates and one row of context beyond each end.
const RING: usize = 2 * SPAN + 3;
/// Regularisation r of Z + r·tr(Z)·I.
const REGULARISATION: f64 = 0.1;
/// ε(K) is evaluated on one row in this many while the smoothing is applied (the cost is
/// spread out).
const EVALUATE_EVERY: u32 = 4;
/// ... and on one row in this many while it is not ([`KnnSmoother::push_with`] with
/// `apply` false): ε(K) then only feeds the decision to switch the smoothing on and the
/// choice of K, for which a mean over a quarter of the rows is as good (the screening
/// period holds ~2 500 rows, so ~150 evaluations per channel and period), and the rows in
/// between cost a ring-buffer write instead of a neighbour search and a Cholesky
/// factorisation.
const EVALUATE_EVERY_IDLE: u32 = 16;

/// A streaming k-neighbour smoother for one channel.
#[derive(Clone, Debug)]
pub struct KnnSmoother<T> {
    ring: [T; RING],
    filled: usize,
    head: usize,
    k: usize,
    errors: [T; MAX_NEIGHBOURS + 1],
    evaluations: T,
    rows: u32,
    /// Multiplies both evaluation intervals ([`KnnSmoother::set_sparseness`]).
    sparseness: u32,
    /// Rows by which this smoother's evaluations are shifted ([`KnnSmoother::set_phase`]).
    phase: u32,
}

impl<T: Real> Default for KnnSmoother<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real> KnnSmoother<T> {
    /// A smoother that has seen nothing; K starts at the largest value until ε(K) speaks.
    pub fn new() -> Self {
        Self {
            ring: [T::ZERO; RING],
            filled: 0,
            head: 0,
            k: MAX_NEIGHBOURS,
            errors: [T::ZERO; MAX_NEIGHBOURS + 1],
            evaluations: T::ZERO,
            rows: 0,
            sparseness: 1,
            phase: 0,
        }
    }

    /// Evaluates ε(K) `factor` times less often (at least 1): rows taken at every sample
    /// instead of every fourth come four times as often, and ε(K) needs as many
    /// evaluations per screening period, not per row.
    pub fn set_sparseness(&mut self, factor: u32) {
        self.sparseness = factor.max(1);
    }

    /// Shifts the rows on which ε(K) is evaluated by `rows`: two smoothers fed the same
    /// rows (x and v) then evaluate on different rows, so that no single row pays for both
    /// (on the M4F an evaluation is ~7 000 instructions a channel).
    pub fn set_phase(&mut self, rows: u32) {
        self.phase = rows;
    }

    /// Rows between a value going in and its smoothed value coming out.
    pub const LAG: usize = SPAN + 1;

    /// Every field zero (K too): storage that [`KnnSmoother::new`] then overwrites.
    pub(crate) const fn zeroed() -> Self {
        Self {
            ring: [T::ZERO; RING],
            filled: 0,
            head: 0,
            k: 0,
            errors: [T::ZERO; MAX_NEIGHBOURS + 1],
            evaluations: T::ZERO,
            rows: 0,
            sparseness: 0,
            phase: 0,
        }
    }

    /// Forgets the history (after a gap in the data), keeping K and ε(K).
    pub fn restart(&mut self) {
        self.filled = 0;
        self.head = 0;
    }

    /// The current K.
    pub fn k(&self) -> usize {
        self.k
    }

    /// The accumulated ε(K) for K = `MIN_NEIGHBOURS..=MAX_NEIGHBOURS` (index K).
    pub fn errors(&self) -> &[T; MAX_NEIGHBOURS + 1] {
        &self.errors
    }

    /// The mean ε(K) of the current accumulation (`None` before any row was evaluated, or
    /// for a K out of range).
    pub fn mean_error(&self, k: usize) -> Option<T> {
        if !(MIN_NEIGHBOURS..=MAX_NEIGHBOURS).contains(&k) || !(self.evaluations > T::ZERO) {
            return None;
        }
        Some(self.errors[k] / self.evaluations)
    }

    /// The value of the row [`Self::LAG`] rows back, unsmoothed (what the last
    /// [`Self::push`] smoothed).
    pub fn centre(&self) -> T {
        self.at(SPAN + 1)
    }

    /// Re-chooses K from ε(K) and starts a new accumulation weighted by `keep` (0 forgets the
    /// past errors, 1 keeps them all).
    pub fn choose_k(&mut self, keep: T) {
        let mut best = T::MAX;
        for k in MIN_NEIGHBOURS..=MAX_NEIGHBOURS {
            best = best.min(self.errors[k]);
        }
        if best == T::MAX || best <= T::ZERO && self.rows == 0 {
            return;
        }
        let tolerance = best * T::from_f64(1.01);
        for k in (MIN_NEIGHBOURS..=MAX_NEIGHBOURS).rev() {
            if self.errors[k] <= tolerance {
                self.k = k;
                break;
            }
        }
        for e in self.errors.iter_mut() {
            *e *= keep;
        }
        self.evaluations *= keep;
    }

    fn at(&self, i: usize) -> T {
        // i = 0 is the oldest of the RING rows.
        self.ring[(self.head + i) % RING]
    }

    /// Pushes the next row's value; once the history is full, returns the smoothed value of
    /// the row [`Self::LAG`] rows back.
    pub fn push(&mut self, value: T) -> Option<T> {
        self.push_with(value, true)
    }

    /// [`Self::push`], when `apply` is true. When it is false the smoothing is not applied:
    /// ε(K) is still accumulated, on one row in 16 instead of one in 4, the other rows only
    /// go into the history, and what comes back is the unsmoothed value ([`Self::centre`]).
    ///
    /// Inline: the rows that only go into the history (most of them while the smoothing is
    /// not applied) cost a ring write and a count, not a call into the neighbour search.
    #[inline(always)]
    pub fn push_with(&mut self, value: T, apply: bool) -> Option<T> {
        if !self.record(value) {
            return None;
        }
        let own = self.at(SPAN + 1);
        if !apply {
            self.rows = self.rows.wrapping_add(1);
            if !(self.rows.wrapping_add(self.phase))
                .is_multiple_of(EVALUATE_EVERY_IDLE * self.sparseness)
            {
                return Some(own);
            }
            // Undo the count: the evaluation below counts the row itself.
            self.rows = self.rows.wrapping_sub(1);
        }
        Some(self.smooth(own, apply))
    }

    /// The neighbour search and the weights of [`Self::push_with`] for a row whose history
    /// is full, with its own value `own`.
    #[inline(never)]
    fn smooth(&mut self, own: T, apply: bool) -> T {
        let centre = SPAN + 1;
        let (cl, cr) = (self.at(centre - 1), self.at(centre + 1));
        let order = self.nearest(cl, cr);
        self.rows = self.rows.wrapping_add(1);
        let evaluate = !apply
            || (self.rows.wrapping_add(self.phase))
                .is_multiple_of(EVALUATE_EVERY * self.sparseness);
        let k_used = if evaluate { MAX_NEIGHBOURS } else { self.k };
        let mut z = self.gram(&order, k_used, evaluate, (cl, cr), own);
        cholesky(&mut z, k_used);
        let mut values = [T::ZERO; MAX_NEIGHBOURS];
        for (a, slot) in values.iter_mut().enumerate().take(k_used) {
            *slot = self.at(order[a]);
        }
        let g = forward_ones(&z, k_used);
        let weights_for = |k: usize| weighted(&z, &g, &values, k, own);
        if evaluate {
            self.evaluations += T::ONE;
            let mut chosen = own;
            for k in MIN_NEIGHBOURS..=MAX_NEIGHBOURS {
                let estimate = weights_for(k);
                let e = own - estimate;
                self.errors[k] += e * e;
                if apply && k == self.k {
                    chosen = estimate;
                }
            }
            chosen
        } else {
            weights_for(self.k)
        }
    }

    /// Writes the next row's value into the history; returns whether the history is full.
    #[inline(always)]
    fn record(&mut self, value: T) -> bool {
        self.ring[(self.head + self.filled) % RING] = value;
        if self.filled < RING {
            self.filled += 1;
            if self.filled < RING {
                return false;
            }
        } else {
            self.head = (self.head + 1) % RING;
        }
        true
    }

    /// The candidate rows 1..=2·SPAN+1 but the centre, nearest context (cl, cr) first.
    #[inline(always)]
    fn nearest(&self, cl: T, cr: T) -> [usize; 2 * SPAN] {
        let centre = SPAN + 1;
        let mut order = [0usize; 2 * SPAN];
        let mut distance = [T::ZERO; 2 * SPAN];
        let mut count = 0;
        for j in 1..=2 * SPAN + 1 {
            if j == centre {
                continue;
            }
            let (dl, dr) = (self.at(j - 1) - cl, self.at(j + 1) - cr);
            // Insertion into the sorted prefix (2·SPAN candidates: cheap).
            let d = dl * dl + dr * dr;
            let mut p = count;
            while p > 0 && distance[p - 1] > d {
                distance[p] = distance[p - 1];
                order[p] = order[p - 1];
                p -= 1;
            }
            distance[p] = d;
            order[p] = j;
            count += 1;
        }
        order
    }

    /// The local Gram matrix Z (eq. 4) of the `k_used` nearest contexts, regularised.
    #[inline(always)]
    fn gram(
        &self,
        order: &[usize; 2 * SPAN],
        k_used: usize,
        evaluate: bool,
        (cl, cr): (T, T),
        own: T,
    ) -> [[T; MAX_NEIGHBOURS]; MAX_NEIGHBOURS] {
        let mut diff = [[T::ZERO; 2]; MAX_NEIGHBOURS];
        for (a, d) in diff.iter_mut().enumerate().take(k_used) {
            let j = order[a];
            *d = [cl - self.at(j - 1), cr - self.at(j + 1)];
        }
        let mut z = [[T::ZERO; MAX_NEIGHBOURS]; MAX_NEIGHBOURS];
        let mut trace = T::ZERO;
        for a in 0..k_used {
            for b in 0..=a {
                let v = diff[a][0] * diff[b][0] + diff[a][1] * diff[b][1];
                z[a][b] = v;
                z[b][a] = v;
            }
            trace += z[a][a];
        }
        // The regularisation is fixed by the largest K so that every K's Gram matrix is a
        // leading block of this one.
        let full_trace = if evaluate {
            trace
        } else {
            let mut t = trace;
            for &j in order.iter().take(MAX_NEIGHBOURS).skip(k_used) {
                let (dl, dr) = (cl - self.at(j - 1), cr - self.at(j + 1));
                t += dl * dl + dr * dr;
            }
            t
        };
        let mu = T::from_f64(REGULARISATION) * full_trace + T::EPSILON * (own * own + T::EPSILON);
        for (a, row) in z.iter_mut().enumerate().take(k_used) {
            row[a] += mu;
        }
        z
    }
}

/// Cholesky Z = L Lᵀ of the leading `k` × `k` block, in place in the lower triangle.
#[inline(always)]
fn cholesky<T: Real>(z: &mut [[T; MAX_NEIGHBOURS]; MAX_NEIGHBOURS], k: usize) {
    for a in 0..k {
        for b in 0..=a {
            let mut s = z[a][b];
            for c in 0..b {
                s -= z[a][c] * z[b][c];
            }
            if a == b {
                z[a][a] = if s > T::ZERO { s.sqrt() } else { T::EPSILON };
            } else {
                z[a][b] = s / z[b][b];
            }
        }
    }
}

/// Forward solve L g = 1 once; for each K the weights solve Lₖᵀ w = gₖ (leading block).
#[inline(always)]
fn forward_ones<T: Real>(
    z: &[[T; MAX_NEIGHBOURS]; MAX_NEIGHBOURS],
    k: usize,
) -> [T; MAX_NEIGHBOURS] {
    let mut g = [T::ZERO; MAX_NEIGHBOURS];
    for a in 0..k {
        let mut s = T::ONE;
        for c in 0..a {
            s -= z[a][c] * g[c];
        }
        g[a] = s / z[a][a];
    }
    g
}

/// The weighted mean of the `k` nearest values (weights from Lₖᵀ w = gₖ), or `own` when
/// the weights cancel.
#[inline(always)]
fn weighted<T: Real>(
    z: &[[T; MAX_NEIGHBOURS]; MAX_NEIGHBOURS],
    g: &[T; MAX_NEIGHBOURS],
    values: &[T; MAX_NEIGHBOURS],
    k: usize,
    own: T,
) -> T {
    let mut w = [T::ZERO; MAX_NEIGHBOURS];
    for a in (0..k).rev() {
        let mut s = g[a];
        for c in a + 1..k {
            s -= z[c][a] * w[c];
        }
        w[a] = s / z[a][a];
    }
    let (mut sum, mut value) = (T::ZERO, T::ZERO);
    for a in 0..k {
        sum += w[a];
        value += w[a] * values[a];
    }
    if sum.abs() > T::EPSILON {
        value / sum
    } else {
        own
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_phase_moves_the_evaluations_to_other_rows() {
        for apply in [false, true] {
            let (mut x, mut v) = (KnnSmoother::<f32>::new(), KnnSmoother::<f32>::new());
            x.set_sparseness(4);
            v.set_sparseness(4);
            v.set_phase(8);
            let (mut both, mut each) = (0, [0, 0]);
            for i in 0..2000 {
                let value = (i as f32 * 0.05).sin() + 0.01 * ((i * 7919) % 13) as f32;
                let before = (x.errors()[MIN_NEIGHBOURS], v.errors()[MIN_NEIGHBOURS]);
                x.push_with(value, apply);
                v.push_with(value, apply);
                let moved = (
                    x.errors()[MIN_NEIGHBOURS] != before.0,
                    v.errors()[MIN_NEIGHBOURS] != before.1,
                );
                both += usize::from(moved.0 && moved.1);
                each[0] += usize::from(moved.0);
                each[1] += usize::from(moved.1);
            }
            assert_eq!(both, 0, "apply {apply}");
            // As many evaluations either way (one row in 16, or in 64 while not applied; the
            // first 15 rows fill the history).
            let expected = if apply { 2000 / 16 } else { 2000 / 64 };
            assert!(
                each[0].abs_diff(expected) <= 5 && each[1].abs_diff(expected) <= 5,
                "apply {apply}: {each:?}"
            );
        }
    }

    #[test]
    fn keeps_a_straight_line() {
        let mut s: KnnSmoother<f64> = KnnSmoother::new();
        let mut out = std::vec::Vec::new();
        for i in 0..100 {
            if let Some(v) = s.push(0.5 * i as f64) {
                out.push(v);
            }
        }
        assert_eq!(out.len(), 100 - RING + 1);
        for (i, v) in out.iter().enumerate() {
            let expected = 0.5 * (i + KnnSmoother::<f64>::LAG) as f64;
            assert!((v - expected).abs() < 1e-6, "{i}: {v} vs {expected}");
        }
    }

    extern crate std;

    #[test]
    fn reduces_white_noise_on_a_slow_sine_and_picks_a_large_k() {
        let mut s: KnnSmoother<f64> = KnnSmoother::new();
        let mut state = 12345u64;
        let (mut raw, mut smooth) = (0.0, 0.0);
        let mut clean = std::vec::Vec::new();
        let mut noisy = std::vec::Vec::new();
        for i in 0..20000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let n = ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.2;
            let c = (i as f64 * 0.01).sin();
            clean.push(c);
            noisy.push(c + n);
            if let Some(v) = s.push(c + n) {
                let j = i - KnnSmoother::<f64>::LAG;
                if j > 1000 {
                    raw += (noisy[j] - clean[j]).powi(2);
                    smooth += (v - clean[j]).powi(2);
                }
            }
            if i % 2000 == 1999 {
                s.choose_k(0.0);
            }
        }
        std::println!("ratio {} K {}", smooth / raw, s.k());
        assert!(smooth < 0.5 * raw, "smoothed error {smooth} vs raw {raw}");
        assert!(s.k() >= 6, "K = {}", s.k());
    }
}
