//! The screening: the factors it works on, the origin candidates and the published model.

use super::*;
use crate::model::{MAX_SOLUTIONS, Solution};

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// Fills `w` with the screening's factors: A and B with the block in progress, their
    /// union, all with v's origin moved by `offset_v` and x's by `c`. With `halves` false,
    /// only the union is moved by `c` (A and B are left at x's own origin).
    ///
    /// The screening rebuilds them from the identifier's state for each origin it tries
    /// instead of keeping an unshifted copy besides the shifted one: the operations are the
    /// same, in the same order, so the factors are bit for bit those of a copy, and the
    /// stack holds A and B as one pair, the union and one matrix instead of seven factors and
    /// four matrices (20 KB on the M4F with P = 16). The cost is a merge and up to five transforms per
    /// origin, about 2 % of a sweep.
    #[inline(never)]
    pub(super) fn prepare(&self, offset_v: T, c: T, halves: bool, w: &mut Work<T, P>) {
        self.halves.copy_into(&mut w.ab);
        if offset_v != T::ZERO {
            self.shift_into(T::ZERO, offset_v, &mut w.m);
            w.ab.a_mut().transform(&w.m);
            w.ab.b_mut().transform(&w.m);
        }
        w.all.copy_from_view(w.ab.a());
        w.all.view_mut().merge(w.ab.b());
        if c != T::ZERO {
            self.shift_into(c, T::ZERO, &mut w.m);
            if halves {
                w.ab.a_mut().transform(&w.m);
                w.ab.b_mut().transform(&w.m);
            }
            w.all.transform(&w.m);
        }
        // Last, in the coordinates the sweep will use: the noise of x̂ and v̂ out.
        #[cfg(feature = "noise-correction")]
        if self.config.noise_correction {
            let noise = self.row_noise();
            let terms = self.library.terms();
            if halves {
                for a in [true, false] {
                    // Through a whole factor: the correction writes R in place.
                    let mut half = Factor::new(w.all.columns());
                    half.copy_from_view(if a { w.ab.a() } else { w.ab.b() });
                    eiv::correct(&mut half, terms, &noise, &mut w.m);
                    w.ab.half_mut(a).copy_from(half.view());
                }
            }
            eiv::correct(&mut w.all, terms, &noise, &mut w.m);
        }
    }

    /// The noise covariances of a row's x̂, v̂ and ŷ in the factors' scaled units (see
    /// `ChannelNoise::row_noise`).
    #[cfg(feature = "noise-correction")]
    pub(super) fn row_noise(&self) -> eiv::RowNoise<T> {
        self.noise.row_noise(
            self.config.channels.velocity,
            self.columns.state_scales(),
            self.columns.y_scale(),
            self.smoothing_applied(),
        )
    }

    /// Runs a screening now (it also runs by itself every `screening_period` samples).
    /// Returns whether a model came out (it needs enough rows in both halves).
    ///
    /// A screening on request leaves the identifier's state as it was (only the model is
    /// new): the rows that follow are processed exactly as without it. The periodic one
    /// also re-chooses the smoothing's K.
    pub fn screen(&mut self) -> bool {
        if !self.can_screen() {
            return false;
        }
        self.counters.screenings += 1;
        self.select()
    }

    /// Whether a screening can run: enough rows (twice the terms) in both halves.
    pub(super) fn can_screen(&self) -> bool {
        let enough = T::from_usize(2 * self.library.len());
        let (wa, wb) = self.halves.weights();
        wa >= enough && wb >= enough
    }

    /// The screening proper, on the state as it is: sensor offsets, the threshold sweep at
    /// each candidate origin and MES; the model selected becomes [`Identifier::model`].
    /// Returns whether one came out. Changes nothing but the model.
    ///
    /// [`Identifier::screen`] runs it after its checks; on a [`Snapshot`] it is the whole
    /// screening of the state the snapshot was taken from (see [`Identifier::push_with`]).
    ///
    /// Candidate origins: the recording's own, the equilibria of the unforced dense model
    /// near the data and (added after the sweep at the recording's own origin) the
    /// equilibrium of the model that sweep selected. The sparsest selected model decides;
    /// among equally sparse ones the least held-out error (a noisy constant term can
    /// misplace an equilibrium).
    pub fn select(&mut self) -> bool {
        if !self.can_screen() {
            return false;
        }
        let search = self.search();
        let mut w = Work::new(self.library.len());
        self.prepare(search.offset_v, T::ZERO, false, &mut w);
        let mut candidates: heapless::Vec<T, 7> = heapless::Vec::new();
        let _ = candidates.push(T::ZERO);
        if search.shift {
            self.equilibria(&w.all, &mut w.m, &mut candidates);
        }
        // The best so far: its support, error and origin; its model is published at once
        // (into `self.model`, whose memory exists anyway) instead of keeping its sweep on the
        // stack. The sweep at the origin so far is filled in place.
        let mut best: Option<(u32, T, T)> = None;
        let mut result = screen::Sweep::new();
        // `next` (counted from 1) of the candidate from the selected model, if any.
        let mut from_selected = usize::MAX;
        let mut next = 0;
        while let Some(&start) = candidates.get(next) {
            next += 1;
            let mut c = start;
            self.sweep_at(&search, c, &mut w, &mut result);
            if start == T::ZERO
                && self.origin_of_selected(&search, &result, &mut w, &mut candidates)
            {
                from_selected = candidates.len();
            }
            // (The candidate from the selected model is that model's equilibrium already.)
            if search.shift && start != T::ZERO && next != from_selected {
                c = self.refine_twice(&search, c, &mut w, &mut result);
            }
            if search.shift {
                c = self.try_sparser(&search, c, &mut w, &mut result);
            }
            if let Some(selected) = result.chosen()
                && Self::better(best, &selected, c)
            {
                best = Some((selected.support, selected.mean_error, c));
                self.publish(&result, c, search.offset_v);
            }
        }
        if let Some(best) = best {
            self.shed_on_best(&search, best, &mut w, &mut result);
        }
        best.is_some()
    }

    /// What every sweep of a screening shares: the velocity offset (v's origin is moved
    /// first, so that v = 0 at rest), the grid, the parsimony, and whether x's origin is
    /// searched.
    fn search(&self) -> Search<T> {
        let (x_closed, v_closed) = self.library.shift_closed();
        let offsets = self.config.offsets && self.library.config().constant;
        let mut offset_v = T::ZERO;
        if offsets && v_closed && self.config.channels.velocity && self.offset.has_rows() {
            offset_v = self.offset.value();
        }
        Search {
            offset_v,
            grid: usize::from(self.config.thresholds),
            parsimony: T::from_f64(self.config.parsimony),
            shift: offsets && x_closed,
        }
    }

    /// Whether a support holds the constant term: a misplaced origin shows first as a
    /// static force at the data's zero, f(−c) ≈ c·f'(0).
    fn holds_constant(&self, support: u32) -> bool {
        let constant = self.library.index_of(Term::Constant);
        constant.is_some_and(|k| support & (1u32 << k) != 0)
    }

    /// The dense model's equilibria are poorly determined (the constant and the even
    /// powers are nearly collinear, and with test-function rows the harmonics too): the
    /// model selected at the recording's own origin gives one more candidate, if it holds
    /// the constant term. Returns whether it was added.
    #[inline(always)]
    fn origin_of_selected(
        &self,
        search: &Search<T>,
        result: &screen::Sweep<T, P>,
        w: &mut Work<T, P>,
        candidates: &mut heapless::Vec<T, 7>,
    ) -> bool {
        if search.shift
            && let Some(selected) = result.chosen()
            && self.holds_constant(selected.support)
            && let Some(step) = self.refine_origin(search.offset_v, T::ZERO, selected.support, w)
            && step != T::ZERO
            && candidates.push(step).is_ok()
        {
            return true;
        }
        false
    }

    /// Refines the origin `c` on the sparse model: the dense model's constant term is
    /// poorly determined (it is nearly collinear with the even powers), the sparse
    /// support's is not. Two passes move the origin to the sparse model's equilibrium.
    #[inline(always)]
    fn refine_twice(
        &self,
        search: &Search<T>,
        mut c: T,
        w: &mut Work<T, P>,
        result: &mut screen::Sweep<T, P>,
    ) -> T {
        for _ in 0..2 {
            let Some(selected) = result.chosen() else {
                break;
            };
            let Some(step) = self.refine_origin(search.offset_v, c, selected.support, w) else {
                break;
            };
            c += step;
            self.sweep_at(search, c, w, result);
        }
        c
    }

    /// A sensor zero that is off by a little leaves small terms that the shift of x creates
    /// (x·v from x²·v, a constant from x², ...): the selected support then holds one of
    /// them. Tries the next sparser supports of the sweep with the origin that fits each
    /// best; a sweep at that origin that selects a subset of the terms wins. Returns the
    /// origin of `result`.
    #[inline(always)]
    fn try_sparser(
        &self,
        search: &Search<T>,
        mut c: T,
        w: &mut Work<T, P>,
        result: &mut screen::Sweep<T, P>,
    ) -> T {
        for _ in 0..SPARSER_STEPS {
            let Some(selected) = result.chosen() else {
                break;
            };
            let Some(sparser) = result
                .solutions
                .iter()
                .filter(|s| s.len() < selected.len() && s.len() + 2 >= selected.len())
                .min_by(|p, q| {
                    p.mean_error
                        .partial_cmp(&q.mean_error)
                        .unwrap_or(core::cmp::Ordering::Equal)
                })
                .copied()
            else {
                break;
            };
            let Some(c2) = self.best_origin(search.offset_v, c, sparser.support, w) else {
                break;
            };
            let mut trial = screen::Sweep::new();
            self.sweep_at(search, c2, w, &mut trial);
            match trial.chosen() {
                // Only a removal counts: the shift may take out the terms it created,
                // never trade one term for another.
                Some(t) if t.len() < selected.len() && t.support & !selected.support == 0 => {
                    c = c2;
                    *result = trial;
                }
                _ => break,
            }
        }
        c
    }

    /// Whether `selected` at origin `c` beats the best so far (support, error, origin).
    /// Fewer terms win; between equally sparse models whose held-out errors are within
    /// ORIGIN_TIE of each other, the origin nearer the recording's own zero (at high noise a
    /// shifted origin can trade a true term for a false one at the same error); else the
    /// lesser error.
    fn better(best: Option<(u32, T, T)>, selected: &Solution<T>, c: T) -> bool {
        let Some((support, err, at)) = best else {
            return true;
        };
        let len = support.count_ones();
        let near = (selected.mean_error - err).abs()
            <= T::from_f64(ORIGIN_TIE) * selected.mean_error.min(err);
        selected.len() < len
            || (selected.len() == len
                && if near {
                    c.abs() < at.abs()
                } else {
                    selected.mean_error < err
                })
    }

    /// Terms that only a misplaced origin needs: drop them one at a time while the model
    /// without the term, at its own best origin, fits (all rows) within `parsimony` of the
    /// model with it; then sweep at the origin reached, which wins if it selects fewer
    /// terms. With test-function rows the fit is sharp enough that an origin off by 5 % of
    /// the offset keeps five spurious terms, more than the steps of `select` remove. Once,
    /// on the best model, and only if it holds the constant term (each try is a
    /// golden-section search, 0.4 M instructions on the M4F).
    #[inline(always)]
    fn shed_on_best(
        &mut self,
        search: &Search<T>,
        (support, _, at): (u32, T, T),
        w: &mut Work<T, P>,
        result: &mut screen::Sweep<T, P>,
    ) {
        if search.shift
            && self.holds_constant(support)
            && let Some(c2) = self.shed_by_shift(search.offset_v, at, support, search.parsimony, w)
        {
            self.sweep_at(search, c2, w, result);
            if result
                .chosen()
                .is_some_and(|t| t.len() < support.count_ones())
            {
                self.publish(result, c2, search.offset_v);
            }
        }
    }

    /// Makes the model of a sweep (at x origin `offset_x`, v origin `offset_v`) the current
    /// one, in physical units. Out of line: the model it builds (0.5 KB with P = 16) would
    /// otherwise sit in `screen`'s frame under every sweep.
    #[inline(never)]
    pub(super) fn publish(&mut self, sweep: &screen::Sweep<T, P>, offset_x: T, offset_v: T) {
        let n = self.library.len();
        let mut coefficients = [T::ZERO; P];
        for j in 0..n {
            coefficients[j] = self.columns.physical(j, sweep.coefficients[j]);
        }
        let y2 = self.columns.y_scale() * self.columns.y_scale();
        let mut solutions: heapless::Vec<Solution<T>, MAX_SOLUTIONS> = heapless::Vec::new();
        for s in sweep.solutions.iter() {
            let _ = solutions.push(Solution {
                mean_error: s.mean_error * y2,
                ..*s
            });
        }
        let mut terms = heapless::Vec::new();
        for &t in self.library.terms() {
            let _ = terms.push(t);
        }
        self.model = Some(Model {
            terms,
            coefficients,
            solutions,
            selected: sweep.selected,
            k: self.smoothing.ks(self.config.smoothing),
            omega: self.config.omega,
            offset_x,
            offset_v,
            samples: self.counters.accepted,
            rejected: self.counters.rejected(),
            rows: self.counters.rows,
        });
    }

    /// The sweep with the x origin moved by `c` (and v's by `offset_v`), into `out`.
    pub(super) fn sweep_at(
        &self,
        search: &Search<T>,
        c: T,
        w: &mut Work<T, P>,
        out: &mut screen::Sweep<T, P>,
    ) {
        self.prepare(search.offset_v, c, true, w);
        // The column map is spent once the factors are moved: it is the solves' scratch.
        let (grid, parsimony) = (search.grid, search.parsimony);
        screen::sweep(w.ab.a(), w.ab.b(), &w.all, &mut w.m, grid, parsimony, out);
    }
}

/// What every sweep of one screening shares.
#[derive(Clone, Copy, Debug)]
pub(super) struct Search<T> {
    /// v's origin (the velocity offset).
    offset_v: T,
    /// Thresholds in the sweep.
    grid: usize,
    /// MES's parsimony.
    parsimony: T,
    /// Whether x's origin is searched (offsets on, and the library closed under x-shifts).
    shift: bool,
}
