//! The held-out halves A and B: where each regression row goes, written once.
//!
//! Rows are folded into two square-root factors in alternating blocks, so that each half
//! can score the models fitted on the other (the held-out error of the screening). Row
//! number k (counted from 0) belongs to block ⌊k / block_len⌋, and an even block goes to A,
//! an odd one to B ([`Halves::goes_to_a`]).

use super::{Row, WARMUP_ROWS};
use crate::factor::{Factor, FactorPair};
use crate::real::Real;
use crate::weak::TestRows;

/// Test-function sums per block of A or B (two test functions' worth).
pub(super) const TEST_BLOCK: u64 = 8;

/// The two halves A and B of the data, or, until the column scales are known, the warm-up
/// rows. The halves are empty while rows wait in the warm-up buffer, so the two share their
/// memory (the buffer's 1.5 KB of RAM on the M4F with P = 16). A and B are one
/// [`FactorPair`]: two triangles in about one square.
pub(super) enum Store<T, const P: usize> {
    Warmup(heapless::Vec<Row<T>, WARMUP_ROWS>),
    Halves(FactorPair<T, P>),
}

impl<T: Real, const P: usize> Clone for Store<T, P> {
    fn clone(&self) -> Self {
        match self {
            Store::Warmup(rows) => Store::Warmup(rows.clone()),
            Store::Halves(pair) => Store::Halves(pair.clone()),
        }
    }

    /// In place (a snapshot's copy, in a device's identify interrupt): the derived one
    /// builds the copy on the stack first. A change of variant writes a constant first.
    fn clone_from(&mut self, source: &Self) {
        match source {
            Store::Warmup(from) => {
                if !matches!(self, Store::Warmup(_)) {
                    *self = const { Store::Warmup(heapless::Vec::new()) };
                }
                if let Store::Warmup(rows) = self {
                    rows.clear();
                    // Same capacity: every row fits.
                    let _ = rows.extend_from_slice(from);
                }
            }
            Store::Halves(from) => {
                if !matches!(self, Store::Halves(_)) {
                    *self = const { Store::Halves(FactorPair::new(0)) };
                }
                if let Store::Halves(pair) = self {
                    pair.copy_from(from);
                }
            }
        }
    }
}

/// What gathers the rows before they reach A or B. The two never coexist, so the sums take
/// no memory beyond the block factor's.
pub(super) enum Collector<T, const P: usize> {
    /// Rows as they are, gathered in a block factor that is merged into A or B when full.
    Block(Factor<T, P>),
    /// The test-function sums (`Config::test_rows`); each completed one goes into A or B.
    Sums(TestRows<T, P>),
}

impl<T: Real, const P: usize> Clone for Collector<T, P> {
    fn clone(&self) -> Self {
        match self {
            Collector::Block(block) => Collector::Block(block.clone()),
            Collector::Sums(sums) => Collector::Sums(sums.clone()),
        }
    }

    /// In place, as [`Store`]'s.
    fn clone_from(&mut self, source: &Self) {
        match source {
            Collector::Block(from) => {
                if !matches!(self, Collector::Block(_)) {
                    *self = const { Collector::Block(Factor::new(0)) };
                }
                if let Collector::Block(block) = self {
                    block.copy_from(from);
                }
            }
            Collector::Sums(from) => match self {
                Collector::Sums(sums) => sums.clone_from(from),
                _ => *self = Collector::Sums(from.clone()),
            },
        }
    }
}

/// A test-function sum whose fold into A or B is half done: [`Halves::push`] rotates its
/// first columns in on the row that completes it and the rest on the next row it takes, so
/// that no single sample pays for a whole fold (and an evaluation of ε(K) or a resync of the
/// phasor, which the identifier moves off both rows).
///
/// Not an `Option`: its niche would make "none" non-zero bits, and the halves live in the
/// device's `.bss`.
#[derive(Clone, Copy)]
struct Pending<T, const P: usize> {
    /// Whether a fold is pending (the fields below mean something).
    active: bool,
    /// What is left of the sum's columns (zero before `split`) and of its target.
    row: [T; P],
    target: T,
    /// The first column not rotated in yet.
    split: usize,
    /// Whether it goes to A.
    to_a: bool,
}

/// The solver stage: the warm-up rows, then A, B and the block (or sums) in progress.
///
/// ```text
/// let mut halves = Halves::zeroed();
/// halves.configure(n, test_rows, blocks, sqrt_lambda_row);
/// // ... warm-up, then for every scaled row θ, y:
/// halves.push(&theta, y, n);
/// let (weight_a, weight_b) = halves.weights();
/// ```
pub(super) struct Halves<T, const P: usize> {
    store: Store<T, P>,
    /// What gathers the rows before they reach A or B.
    collector: Collector<T, P>,
    /// A sum's fold begun and not finished.
    pending: Pending<T, P>,
    /// Rows given to A and B: the rows themselves, or the test-function sums.
    regression_rows: u64,
    /// Regression rows per block of A or B.
    block_len: u64,
    sqrt_lambda: T,
    sqrt_lambda_blocks: T,
}

impl<T: Real, const P: usize> Clone for Halves<T, P> {
    fn clone(&self) -> Self {
        Self {
            store: self.store.clone(),
            collector: self.collector.clone(),
            pending: self.pending,
            regression_rows: self.regression_rows,
            block_len: self.block_len,
            sqrt_lambda: self.sqrt_lambda,
            sqrt_lambda_blocks: self.sqrt_lambda_blocks,
        }
    }

    /// In place, field by field (a snapshot's copy: the derived one built the whole copy,
    /// 5 KB with f32 and P = 16, on the identify interrupt's stack first).
    fn clone_from(&mut self, source: &Self) {
        self.store.clone_from(&source.store);
        self.collector.clone_from(&source.collector);
        self.pending = source.pending;
        self.regression_rows = source.regression_rows;
        self.block_len = source.block_len;
        self.sqrt_lambda = source.sqrt_lambda;
        self.sqrt_lambda_blocks = source.sqrt_lambda_blocks;
    }
}

impl<T: Real, const P: usize> Halves<T, P> {
    /// Storage, not usable halves (all zero bits but the empty enums' tags).
    pub(super) const fn zeroed() -> Self {
        Self {
            store: Store::Warmup(heapless::Vec::new()),
            collector: Collector::Block(Factor::new(0)),
            pending: Pending {
                active: false,
                row: [T::ZERO; P],
                target: T::ZERO,
                split: 0,
                to_a: false,
            },
            regression_rows: 0,
            block_len: 0,
            sqrt_lambda: T::ZERO,
            sqrt_lambda_blocks: T::ZERO,
        }
    }

    /// Empty halves over `n` columns, in the warm-up: rows as they are in blocks of `blocks`
    /// rows (`test_rows == 0`), or test-function sums of width `test_rows` in blocks of
    /// [`TEST_BLOCK`]; forgetting by `sqrt_lambda_row`² a row.
    pub(super) fn configure(
        &mut self,
        n: usize,
        test_rows: u16,
        blocks: u64,
        sqrt_lambda_row: f64,
    ) {
        self.store = Store::Warmup(heapless::Vec::new());
        self.pending.active = false;
        self.regression_rows = 0;
        if test_rows == 0 {
            self.collector = Collector::Block(Factor::new(n));
            self.block_len = blocks;
            self.sqrt_lambda = T::from_f64(sqrt_lambda_row);
            // A's content at a merge is two blocks old.
            self.sqrt_lambda_blocks = T::from_f64(power(sqrt_lambda_row, 2.0 * blocks as f64));
        } else {
            // λ and the blocks count in sums (one every L/4 rows); a block of eight sums
            // spans two test functions, so that A's and B's rows share little of the data.
            // A sum goes straight into A or B, whose content at the start of its block is
            // one block old.
            // The bump of sums of the same width is kept (the same bits as designed anew).
            let kept = match &self.collector {
                Collector::Sums(sums) => sums.bump_for(test_rows),
                Collector::Block(_) => None,
            };
            let mut sums = TestRows::zeroed();
            sums.configure_with(test_rows, kept);
            let sqrt_lambda_sum = power(sqrt_lambda_row, f64::from(sums.quarter()));
            self.collector = Collector::Sums(sums);
            self.block_len = TEST_BLOCK;
            self.sqrt_lambda = T::from_f64(sqrt_lambda_sum);
            self.sqrt_lambda_blocks = T::from_f64(power(sqrt_lambda_sum, TEST_BLOCK as f64));
        }
    }

    /// The held-out rule: regression row number `row` (from 0) goes to A when its block's
    /// number is even, to B when it is odd.
    #[inline]
    fn goes_to_a(row: u64, block_len: u64) -> bool {
        (row / block_len).is_multiple_of(2)
    }

    /// Keeps a row while the column scales are unknown. Returns `true` once the warm-up
    /// is full (or over): then [`Halves::end_warmup`] is due.
    pub(super) fn keep(&mut self, row: Row<T>) -> bool {
        if let Store::Warmup(rows) = &mut self.store
            && rows.push(row).is_ok()
            && rows.len() < WARMUP_ROWS
        {
            return false;
        }
        true
    }

    /// Ends the warm-up: the halves, empty, take the warm-up's memory; returns its rows.
    #[inline(always)]
    pub(super) fn end_warmup(&mut self, n: usize) -> heapless::Vec<Row<T>, WARMUP_ROWS> {
        let rows = match &mut self.store {
            Store::Warmup(rows) => core::mem::take(rows),
            Store::Halves(..) => heapless::Vec::new(),
        };
        self.store = Store::Halves(FactorPair::new(n));
        rows
    }

    /// Folds a scaled row (the first `n` entries of `theta`, target `y`) into A or B.
    #[inline]
    pub(super) fn push(&mut self, theta: &[T; P], y: T, n: usize) {
        let Self {
            collector,
            store,
            pending,
            regression_rows,
            block_len,
            sqrt_lambda,
            sqrt_lambda_blocks,
        } = self;
        let Store::Halves(pair) = store else {
            // Rows reach the collector only after the warm-up, so the halves exist.
            return;
        };
        let (block_len, sqrt_lambda, sqrt_lambda_blocks) =
            (*block_len, *sqrt_lambda, *sqrt_lambda_blocks);
        match collector {
            // Rows go into a block factor first; a whole block is then merged into A or B.
            // The big factors thus grow by block-sized increments, which f32 resolves,
            // instead of by single rows, whose relative size 1/n falls below f32's rounding
            // after ~10⁵ rows.
            Collector::Block(block) => {
                block.update(theta, y, sqrt_lambda);
                *regression_rows += 1;
                if regression_rows.is_multiple_of(block_len) {
                    // The block's last row decides.
                    let to_a = Self::goes_to_a(*regression_rows - 1, block_len);
                    let mut factor = pair.half_mut(to_a);
                    factor.forget(sqrt_lambda_blocks);
                    factor.merge(block.view());
                    block.clear();
                }
            }
            // A sum weighs as much as L/4 rows and there are few of them (10⁵ samples make
            // 400): each goes straight into A or B, blocks of TEST_BLOCK alternating, its
            // fold split over two rows (`Pending`).
            Collector::Sums(sums) => {
                if pending.active {
                    pending.active = false;
                    pair.half_mut(pending.to_a).finish_update(
                        &mut pending.row,
                        pending.target,
                        pending.split,
                    );
                }
                sums.push(theta, y, n, |sum, target| {
                    let to_a = Self::goes_to_a(*regression_rows, block_len);
                    let mut factor = pair.half_mut(to_a);
                    if regression_rows.is_multiple_of(block_len) {
                        factor.forget(sqrt_lambda_blocks);
                    }
                    let split = fold_split(n);
                    pending.row = *sum;
                    pending.target =
                        factor.begin_update(&mut pending.row, target, split, sqrt_lambda);
                    pending.split = split;
                    pending.to_a = to_a;
                    pending.active = true;
                    *regression_rows += 1;
                });
            }
        }
    }

    /// Whether the next row [`Halves::push`] takes folds (part of) a test-function sum into
    /// A or B: it completes a sum, or finishes the fold of the last one.
    #[inline]
    pub(super) fn folds_next(&self) -> bool {
        match (&self.collector, &self.store) {
            (Collector::Sums(sums), Store::Halves(_)) => {
                self.pending.active || sums.completes_next()
            }
            _ => false,
        }
    }

    /// The block in progress, if it holds rows, and whether it goes to A.
    fn open_block(&self) -> Option<(&Factor<T, P>, bool)> {
        match &self.collector {
            // The next row is in the same block: a block with rows is not full.
            Collector::Block(block) if block.weight() > T::ZERO => {
                Some((block, Self::goes_to_a(self.regression_rows, self.block_len)))
            }
            _ => None,
        }
    }

    /// The weights the two halves A and B have with the block in progress merged in.
    pub(super) fn weights(&self) -> (T, T) {
        let (mut a, mut b) = match &self.store {
            Store::Halves(pair) => (pair.a().weight(), pair.b().weight()),
            Store::Warmup(_) => (T::ZERO, T::ZERO),
        };
        // A half-folded sum's weight is added when its fold finishes.
        match (self.pending.active, self.pending.to_a) {
            (true, true) => a += T::ONE,
            (true, false) => b += T::ONE,
            (false, _) => {}
        }
        if let Some((block, to_a)) = self.open_block() {
            if to_a {
                a += block.weight();
            } else {
                b += block.weight();
            }
        }
        (a, b)
    }

    /// Copies A and B, with the block in progress merged in (or a sum's fold finished),
    /// into `pair`.
    pub(super) fn copy_into(&self, pair: &mut FactorPair<T, P>) {
        match &self.store {
            Store::Halves(stored) => pair.copy_from(stored),
            Store::Warmup(_) => pair.clear(),
        }
        // The same rotations the next row will make on the stored halves: the copy is what
        // they will be, bit for bit.
        let p = &self.pending;
        if p.active {
            let mut row = p.row;
            pair.half_mut(p.to_a)
                .finish_update(&mut row, p.target, p.split);
        }
        if let Some((block, to_a)) = self.open_block() {
            pair.half_mut(to_a).merge(block.view());
        }
    }
}

/// The columns of a sum whose rotations go in on the row that completes it; the rest go in
/// on the next. The first part also ages the whole factor (about the cost of rotating a
/// quarter of the columns in), so a quarter of the columns balances the two rows.
#[inline]
fn fold_split(n: usize) -> usize {
    n / 4
}

/// x^n for the forgetting factors (0 < x ≤ 1), as exp(n·ln x): `libm::exp` and `libm::log`
/// are on the device anyway (the memory's λ, the threshold grid), `libm::pow` would add
/// 2.9 KB of flash for these three calls at configuration. Within a few ulps of pow.
fn power(x: f64, n: f64) -> f64 {
    libm::exp(n * libm::log(x))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(i: usize) -> ([f64; 4], f64) {
        let x = (i as f64 * 0.37).sin();
        let v = (i as f64 * 0.11).cos();
        ([1.0, x, v, x * v], 2.0 * x - v)
    }

    fn filled(rows: usize, test_rows: u16) -> Halves<f64, 4> {
        let mut h = Halves::<f64, 4>::zeroed();
        h.configure(4, test_rows, 16, 1.0);
        assert!(!h.keep(Row::default()));
        let kept = h.end_warmup(4);
        assert_eq!(kept.len(), 1);
        for i in 0..rows {
            let (theta, y) = row(i);
            h.push(&theta, y, 4);
        }
        h
    }

    #[test]
    fn blocks_alternate_between_a_and_b() {
        // 3 whole blocks (A, B, A) and 5 rows of a fourth (B's).
        let h = filled(3 * 16 + 5, 0);
        let (a, b) = h.weights();
        assert_eq!((a, b), (32.0, 21.0));
        let mut pair = FactorPair::new(4);
        h.copy_into(&mut pair);
        assert_eq!((pair.a().weight(), pair.b().weight()), (32.0, 21.0));
    }

    #[test]
    fn the_halves_together_are_all_the_rows() {
        let h = filled(100, 0);
        let mut pair = FactorPair::new(4);
        h.copy_into(&mut pair);
        let mut fa = Factor::new(4);
        fa.copy_from_view(pair.a());
        fa.view_mut().merge(pair.b());
        let mut all = Factor::<f64, 4>::new(4);
        for i in 0..100 {
            let (theta, y) = row(i);
            all.update(&theta, y, 1.0);
        }
        let (mut p, mut q) = ([0.0; 4], [0.0; 4]);
        fa.solve(0b1111, &mut p);
        all.solve(0b1111, &mut q);
        for (p, q) in p.iter().zip(q) {
            assert!((p - q).abs() < 1e-9, "{p} {q}");
        }
    }

    #[test]
    fn the_warm_up_fills_then_ends() {
        let mut h = Halves::<f32, 4>::zeroed();
        h.configure(4, 0, 16, 1.0);
        for _ in 0..WARMUP_ROWS - 1 {
            assert!(!h.keep(Row::default()));
        }
        assert!(h.keep(Row::default()));
        assert_eq!(h.end_warmup(4).len(), WARMUP_ROWS);
        assert_eq!(h.weights(), (0.0, 0.0));
    }
}
