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
//! every time the identifier screens.
//!
//! Z is small in rank: with D the K × 2 matrix of the neighbours' context differences
//! (Xᵢ − Xₐ), Z = DDᵀ + μI. By the Woodbury identity 1ᵀZ⁻¹s = (1ᵀs − aᵀM⁻¹b)/μ with
//! a = Dᵀ1, b = Dᵀs and M = μI + DᵀD (2 × 2), and the same for 1ᵀZ⁻¹1; with one fixed
//! regularisation μ (from the largest K) the sums a, b, DᵀD and 1ᵀs of K neighbours are
//! running sums, so every K's estimate, and ε(K) for all K at once, costs a 2 × 2 solve per K
//! instead of a K × K factorisation (on the M4F an evaluation, with its neighbour search,
//! went from ≈ 6,900 instructions to ≈ 2,100).

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
/// between cost a ring-buffer write instead of a neighbour search and the weights.
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
    /// An evaluation was due on a row that asked to defer it: the next row makes it.
    owed: bool,
    /// Whether the last push evaluated ε(K).
    evaluated: bool,
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
            owed: false,
            evaluated: false,
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
    /// (on the M4F an evaluation is ≈ 2,100 instructions a channel).
    pub fn set_phase(&mut self, rows: u32) {
        self.phase = rows;
    }

    /// Whether the last push evaluated ε(K) (the costly part of a smoother's row).
    pub fn evaluated(&self) -> bool {
        self.evaluated
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
            owed: false,
            evaluated: false,
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
        self.push_with(value, true, false)
    }

    /// [`Self::push`], when `apply` is true. When it is false the smoothing is not applied:
    /// ε(K) is still accumulated, on one row in 16 instead of one in 4, the other rows only
    /// go into the history, and what comes back is the unsmoothed value ([`Self::centre`]).
    ///
    /// With `defer`, an evaluation of ε(K) due on this row moves to the next row without
    /// `defer` (the identifier defers it from a row that also folds a test-function sum into
    /// its factors, so that no sample pays for both).
    ///
    /// Inline: the rows that only go into the history (most of them while the smoothing is
    /// not applied) cost a ring write and a count, not a call into the neighbour search.
    #[inline(always)]
    pub fn push_with(&mut self, value: T, apply: bool, defer: bool) -> Option<T> {
        self.evaluated = false;
        if !self.record(value) {
            return None;
        }
        let own = self.at(SPAN + 1);
        if !apply {
            self.rows = self.rows.wrapping_add(1);
            let due = self.owed
                || (self.rows.wrapping_add(self.phase))
                    .is_multiple_of(EVALUATE_EVERY_IDLE * self.sparseness);
            if !due || defer {
                self.owed = due;
                return Some(own);
            }
            // Undo the count: the evaluation below counts the row itself.
            self.rows = self.rows.wrapping_sub(1);
        }
        Some(self.smooth(own, apply, defer))
    }

    /// The neighbour search and the weights of [`Self::push_with`] for a row whose history
    /// is full, with its own value `own`.
    ///
    /// The weighted mean of K neighbours' values s (eqs. 5–6) is 1ᵀZₖ⁻¹s / 1ᵀZₖ⁻¹1, and by
    /// the module's Woodbury form (the 1/μ cancels)
    ///
    ///   s̄(K) = (1ᵀs − aᵀM⁻¹b) / (K − aᵀM⁻¹a),
    ///
    /// a, b, M and 1ᵀs summed over the K nearest. The values enter relative to `own` (the
    /// weights sum to one, so this is the same mean), which keeps f32's rounding on the
    /// neighbours' differences rather than on the signal's level. The denominator is at
    /// least K·r/(1 + r) (μ is r = 0.1 of the trace), so nothing cancels badly.
    #[inline(never)]
    fn smooth(&mut self, own: T, apply: bool, defer: bool) -> T {
        let centre = SPAN + 1;
        // The history in order, oldest first: one modulo per value instead of one per read.
        let mut h = [T::ZERO; RING];
        for (i, v) in h.iter_mut().enumerate() {
            *v = self.at(i);
        }
        let (cl, cr) = (h[centre - 1], h[centre + 1]);
        let order = nearest(&h, cl, cr);
        self.rows = self.rows.wrapping_add(1);
        let due = !apply
            || self.owed
            || (self.rows.wrapping_add(self.phase))
                .is_multiple_of(EVALUATE_EVERY * self.sparseness);
        let evaluate = due && !defer;
        self.owed = due && defer;
        self.evaluated = evaluate;
        let k_used = if evaluate { MAX_NEIGHBOURS } else { self.k };
        // The context differences of the largest K's neighbours, whose Gram trace fixes μ.
        let mut d = [[T::ZERO; 2]; MAX_NEIGHBOURS];
        let mut trace = T::ZERO;
        for (da, &j) in d.iter_mut().zip(order.iter()) {
            let (p, q) = (cl - h[j - 1], cr - h[j + 1]);
            *da = [p, q];
            trace += p * p + q * q;
        }
        let mu = T::from_f64(REGULARISATION) * trace + T::EPSILON * (own * own + T::EPSILON);
        // Running sums over the nearest: DᵀD, a = Dᵀ1, b = Dᵀ(s − own), 1ᵀ(s − own).
        let mut sums = Sums::default();
        let mut chosen = own;
        let neighbours = d.iter().zip(order.iter()).take(k_used);
        if evaluate {
            // Every K's estimate, from its leading sums.
            for (a, (&[p, q], &j)) in neighbours.enumerate() {
                let k = a + 1;
                sums.add(p, q, h[j] - own);
                let estimate = sums.estimate(k, mu, own);
                if k >= MIN_NEIGHBOURS {
                    let e = own - estimate;
                    self.errors[k] += e * e;
                }
                if k == self.k {
                    chosen = estimate;
                }
            }
        } else {
            // Only the chosen K's.
            for (&[p, q], &j) in neighbours {
                sums.add(p, q, h[j] - own);
            }
            chosen = sums.estimate(k_used, mu, own);
        }
        if evaluate {
            self.evaluations += T::ONE;
            if !apply {
                return own;
            }
        }
        chosen
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
}

/// The running sums of [`KnnSmoother::smooth`] over the nearest neighbours: DᵀD (s11, s12,
/// s22), a = Dᵀ1, b = Dᵀ(s − own) and 1ᵀ(s − own).
#[derive(Clone, Copy, Default)]
struct Sums<T> {
    s11: T,
    s12: T,
    s22: T,
    a1: T,
    a2: T,
    b1: T,
    b2: T,
    sum: T,
}

impl<T: Real> Sums<T> {
    /// One more neighbour: context differences (p, q), value relative to the point's `r`.
    #[inline(always)]
    fn add(&mut self, p: T, q: T, r: T) {
        self.s11 += p * p;
        self.s12 += p * q;
        self.s22 += q * q;
        self.a1 += p;
        self.a2 += q;
        self.b1 += p * r;
        self.b2 += q * r;
        self.sum += r;
    }

    /// The weighted mean of the `k` neighbours summed, (1ᵀs − aᵀM⁻¹b)/(k − aᵀM⁻¹a) with
    /// M = μI + DᵀD, as a value near `own` (`own` itself were the weights' sum lost).
    #[inline(always)]
    fn estimate(&self, k: usize, mu: T, own: T) -> T {
        let (m11, m22) = (mu + self.s11, mu + self.s22);
        let det = m11 * m22 - self.s12 * self.s12;
        // det·M⁻¹a, then aᵀM⁻¹a and bᵀM⁻¹a (M is symmetric).
        let (x1, x2) = (
            m22 * self.a1 - self.s12 * self.a2,
            m11 * self.a2 - self.s12 * self.a1,
        );
        let ones = T::from_usize(k) - (self.a1 * x1 + self.a2 * x2) / det;
        let dot = self.sum - (self.b1 * x1 + self.b2 * x2) / det;
        if ones > T::EPSILON {
            own + dot / ones
        } else {
            own
        }
    }
}

/// The candidate rows 1..=2·SPAN+1 of the history `h` but the centre, nearest context
/// (cl, cr) first.
#[inline(always)]
fn nearest<T: Real>(h: &[T; RING], cl: T, cr: T) -> [usize; 2 * SPAN] {
    let centre = SPAN + 1;
    let mut order = [0usize; 2 * SPAN];
    let mut distance = [T::ZERO; 2 * SPAN];
    let mut count = 0;
    for j in 1..=2 * SPAN + 1 {
        if j == centre {
            continue;
        }
        let (dl, dr) = (h[j - 1] - cl, h[j + 1] - cr);
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
                x.push_with(value, apply, false);
                v.push_with(value, apply, false);
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

    /// An evaluation due on a deferred row happens on the next row that is not deferred,
    /// never on the deferred one, and none is lost.
    #[test]
    fn a_deferred_evaluation_moves_to_the_next_row() {
        for apply in [false, true] {
            let (mut plain, mut deferring) = (KnnSmoother::<f32>::new(), KnnSmoother::<f32>::new());
            let (mut due, mut made) = (std::vec::Vec::new(), std::vec::Vec::new());
            let mut defer_next = false;
            for i in 0..3000u32 {
                let value = (i as f32 * 0.05).sin() + 0.01 * ((i * 7919) % 13) as f32;
                plain.push_with(value, apply, false);
                // Defer every due row, and the row after every third one as well.
                let defer = plain.evaluated() || defer_next;
                defer_next = plain.evaluated() && due.len() % 3 == 0;
                deferring.push_with(value, apply, defer);
                if plain.evaluated() {
                    due.push(i);
                }
                if deferring.evaluated() {
                    assert!(!defer, "row {i} was deferred");
                    made.push(i);
                }
            }
            assert_eq!(made.len(), due.len(), "apply {apply}");
            for (d, m) in due.iter().zip(&made) {
                assert!(m - d == 1 || m - d == 2, "apply {apply}: due {d}, made {m}");
            }
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

    /// The reconstruction of eqs. 4–6 as written: the K nearest contexts' Gram matrix
    /// Z = DDᵀ + μI solved for w = Z⁻¹1 by a dense factorisation (nalgebra, f64), and
    /// wᵀs / 1ᵀw. `history` is the RING newest values, oldest first.
    fn reference(history: &[f64], k: usize) -> f64 {
        let centre = SPAN + 1;
        let (cl, cr) = (history[centre - 1], history[centre + 1]);
        let mut candidates: std::vec::Vec<(f64, usize)> = (1..=2 * SPAN + 1)
            .filter(|&j| j != centre)
            .map(|j| {
                (
                    (history[j - 1] - cl).powi(2) + (history[j + 1] - cr).powi(2),
                    j,
                )
            })
            .collect();
        // Stable: equal distances keep the older candidate first, as the insertion does.
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        let diff = |j: usize| [cl - history[j - 1], cr - history[j + 1]];
        let trace: f64 = candidates[..MAX_NEIGHBOURS]
            .iter()
            .map(|&(_, j)| diff(j)[0].powi(2) + diff(j)[1].powi(2))
            .sum();
        let own = history[centre];
        let mu = REGULARISATION * trace + f64::EPSILON * (own * own + f64::EPSILON);
        let z = nalgebra::DMatrix::from_fn(k, k, |a, b| {
            let (da, db) = (diff(candidates[a].1), diff(candidates[b].1));
            da[0] * db[0] + da[1] * db[1] + if a == b { mu } else { 0.0 }
        });
        let w = z
            .lu()
            .solve(&nalgebra::DVector::from_element(k, 1.0))
            .expect("Z is positive definite");
        let values = nalgebra::DVector::from_fn(k, |a, _| history[candidates[a].1]);
        w.dot(&values) / w.sum()
    }

    /// The running-sum (Woodbury) weights give the same smoothed values and the same ε(K)
    /// as the dense solve, for every K, on a noisy signal and on one sitting far from zero
    /// (an offset 10⁴ times its variation).
    #[test]
    fn running_sums_match_the_dense_solve() {
        for offset in [0.0, 1.0e3] {
            let mut state = 99u64;
            let mut noise = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.05
            };
            let values: std::vec::Vec<f64> = (0..400)
                .map(|i| offset + (i as f64 * 0.07).sin() + noise())
                .collect();
            for k in MIN_NEIGHBOURS..=MAX_NEIGHBOURS {
                let mut s: KnnSmoother<f64> = KnnSmoother::new();
                s.k = k;
                let mut expected_errors = [0.0; MAX_NEIGHBOURS + 1];
                for (i, &v) in values.iter().enumerate() {
                    let Some(out) = s.push(v) else { continue };
                    let history = &values[i + 1 - RING..=i];
                    let expected = reference(history, k);
                    let scale = 1e-9 * (1.0 + offset);
                    assert!(
                        (out - expected).abs() < scale,
                        "K {k}, row {i}: {out} vs {expected}"
                    );
                    // ε(K) is evaluated on one row in 4: the rows whose count is a multiple.
                    if s.rows.is_multiple_of(EVALUATE_EVERY) {
                        for (kk, e) in expected_errors.iter_mut().enumerate().skip(MIN_NEIGHBOURS) {
                            *e += (history[SPAN + 1] - reference(history, kk)).powi(2);
                        }
                    }
                }
                for kk in MIN_NEIGHBOURS..=MAX_NEIGHBOURS {
                    let (got, want) = (s.errors()[kk], expected_errors[kk]);
                    assert!(
                        (got - want).abs() <= 1e-6 * want,
                        "offset {offset}, K {k}: ε({kk}) {got} vs {want}"
                    );
                }
            }
        }
    }
}
