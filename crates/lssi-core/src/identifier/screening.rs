//! The screening: the factors it works on, the origin candidates and the published model.

use super::*;

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// Fills `w` with the screening's factors: A and B with the block in progress, their
    /// union, all with v's origin moved by `offset_v` and x's by `c`. With `halves` false,
    /// only the union is moved by `c` (A and B are left at x's own origin).
    ///
    /// The screening rebuilds them from the identifier's state for each origin it tries
    /// instead of keeping an unshifted copy besides the shifted one: the operations are the
    /// same, in the same order, so the factors are bit for bit those of a copy, and the
    /// stack holds three factors and one matrix instead of seven factors and four matrices
    /// (20 KB on the M4F with P = 16). The cost is a merge and up to five transforms per
    /// origin, about 2 % of a sweep.
    #[inline(never)]
    pub(super) fn prepare(&self, offset_v: T, c: T, halves: bool, w: &mut Work<T, P>) {
        match &self.store {
            Store::Halves(a, b) => {
                w.a.copy_from(a);
                w.b.copy_from(b);
            }
            Store::Warmup(_) => {
                w.a.clear();
                w.b.clear();
            }
        }
        if let Collector::Block(block) = &self.collector
            && block.weight() > T::ZERO
        {
            if (self.regression_rows / self.block_len).is_multiple_of(2) {
                w.a.merge(block)
            } else {
                w.b.merge(block)
            }
        }
        if offset_v != T::ZERO {
            self.shift_into(T::ZERO, offset_v, &mut w.m);
            w.a.transform(&w.m);
            w.b.transform(&w.m);
        }
        w.all.copy_from(&w.a);
        w.all.merge(&w.b);
        if c != T::ZERO {
            self.shift_into(c, T::ZERO, &mut w.m);
            if halves {
                w.a.transform(&w.m);
                w.b.transform(&w.m);
            }
            w.all.transform(&w.m);
        }
        // Last, in the coordinates the sweep will use: the noise of x̂ and v̂ out.
        #[cfg(feature = "noise-correction")]
        if self.config.noise_correction {
            let noise = self.row_noise();
            let terms = self.library.terms();
            if halves {
                eiv::correct(&mut w.a, terms, &noise, &mut w.m);
                eiv::correct(&mut w.b, terms, &noise, &mut w.m);
            }
            eiv::correct(&mut w.all, terms, &noise, &mut w.m);
        }
    }

    /// The noise covariances of a row's x̂, v̂ and ŷ in the factors' scaled units, from the
    /// raw channels' white-noise variance (fourth differences) through the filters. A
    /// channel whose k-neighbour smoothing is applied has no known noise left: its terms
    /// are 0 (see `eiv`).
    #[cfg(feature = "noise-correction")]
    pub(super) fn row_noise(&self) -> eiv::RowNoise<T> {
        let Some((x2, v2)) = self.raw_noise() else {
            return eiv::RowNoise::default();
        };
        let (ux, uv) = self.state_scales;
        let uy = self.y_scale;
        let (smooth_x, smooth_v) = self.smoothing_applied();
        let mut noise = eiv::RowNoise {
            xx: x2 * self.gains.0 / (ux * ux),
            vv: v2 * self.gains.1 / (uv * uv),
            xy: x2 * self.cross.0 / (ux * uy),
            vy: v2 * self.cross.1 / (uv * uy),
        };
        if smooth_x {
            noise.xx = T::ZERO;
            noise.xy = T::ZERO;
        }
        if smooth_v {
            noise.vv = T::ZERO;
            noise.vy = T::ZERO;
        }
        noise
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
        let (wa, wb) = self.half_weights();
        wa >= enough && wb >= enough
    }

    /// The screening proper, on the state as it is: sensor offsets, the threshold sweep at
    /// each candidate origin and MES; the model selected becomes [`Identifier::model`].
    /// Returns whether one came out. Changes nothing but the model.
    ///
    /// [`Identifier::screen`] runs it after its checks; on a [`Snapshot`] it is the whole
    /// screening of the state the snapshot was taken from (see [`Identifier::push_with`]).
    pub fn select(&mut self) -> bool {
        if !self.can_screen() {
            return false;
        }
        let n = self.library.len();
        let parsimony = T::from_f64(self.config.parsimony);
        let grid = usize::from(self.config.thresholds);
        let (x_closed, v_closed) = self.library.shift_closed();
        let offsets = self.config.offsets && self.library.config().constant;
        // The velocity offset: move v's origin first, so that v = 0 at rest.
        let mut offset_v = T::ZERO;
        if offsets && v_closed && self.config.channels.velocity && self.dv_weight > T::ZERO {
            offset_v = self.velocity_offset();
        }
        let mut w = Work::new(n);
        self.prepare(offset_v, T::ZERO, false, &mut w);
        // Candidate origins: the recording's own, the equilibria of the unforced dense
        // model near the data and (added after the sweep at the recording's own origin) the
        // equilibrium of the model that sweep selected. The sparsest selected model decides;
        // among equally sparse ones the least held-out error (a noisy constant term can
        // misplace an equilibrium).
        let mut candidates: heapless::Vec<T, 7> = heapless::Vec::new();
        let _ = candidates.push(T::ZERO);
        if offsets && x_closed {
            self.equilibria(&w.all, &mut w.m, &mut candidates);
        }
        // The best so far: its support, error and origin; its model is published at once
        // (into `self.model`, whose memory exists anyway) instead of keeping its sweep on the
        // stack.
        let mut best: Option<(u32, T, T)> = None;
        // The sweep at the origin so far, filled in place (a returned sweep was another copy
        // on the stack).
        let mut result = screen::Sweep::new();
        // Whether a support holds the constant term: a misplaced origin shows first as a
        // static force at the data's zero, f(−c) ≈ c·f'(0).
        let constant = self.library.index_of(Term::Constant);
        let holds_constant = |support: u32| constant.is_some_and(|k| support & (1u32 << k) != 0);
        // `next` (counted from 1) of the candidate from the selected model, if any.
        let mut from_selected = usize::MAX;
        let mut next = 0;
        while let Some(&start) = candidates.get(next) {
            next += 1;
            // Refine the origin on the sparse model: the dense model's constant term is
            // poorly determined (it is nearly collinear with the even powers), the sparse
            // support's is not. Two passes move the origin to the sparse model's equilibrium.
            let mut c = start;
            self.sweep_at(offset_v, c, &mut w, grid, parsimony, &mut result);
            // The dense model's equilibria are poorly determined (the constant and the even
            // powers are nearly collinear, and with test-function rows the harmonics too):
            // the model selected at the recording's own origin gives one more candidate, if
            // it holds the constant term.
            if offsets
                && x_closed
                && start == T::ZERO
                && let Some(selected) = result.chosen()
                && holds_constant(selected.support)
                && let Some(step) = self.refine_origin(offset_v, c, selected.support, &mut w)
                && step != T::ZERO
                && candidates.push(step).is_ok()
            {
                from_selected = candidates.len();
            }
            // (The candidate from the selected model is that model's equilibrium already.)
            if offsets && x_closed && start != T::ZERO && next != from_selected {
                for _ in 0..2 {
                    let Some(selected) = result.chosen() else {
                        break;
                    };
                    let Some(step) = self.refine_origin(offset_v, c, selected.support, &mut w)
                    else {
                        break;
                    };
                    c += step;
                    self.sweep_at(offset_v, c, &mut w, grid, parsimony, &mut result);
                }
            }
            // A sensor zero that is off by a little leaves small terms that the shift of x
            // creates (x·v from x²·v, a constant from x², ...): the selected support then
            // holds one of them. Try the next sparser supports of the sweep with the origin
            // that fits each best; a sweep at that origin that selects a subset of the
            // terms wins.
            if offsets && x_closed {
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
                    let Some(c2) = self.best_origin(offset_v, c, sparser.support, &mut w) else {
                        break;
                    };
                    let mut trial = screen::Sweep::new();
                    self.sweep_at(offset_v, c2, &mut w, grid, parsimony, &mut trial);
                    match trial.chosen() {
                        // Only a removal counts: the shift may take out the terms it
                        // created, never trade one term for another.
                        Some(t)
                            if t.len() < selected.len() && t.support & !selected.support == 0 =>
                        {
                            c = c2;
                            result = trial;
                        }
                        _ => break,
                    }
                }
            }
            let Some(selected) = result.chosen() else {
                continue;
            };
            // Fewer terms win; between equally sparse models whose held-out errors are
            // within ORIGIN_TIE of each other, the origin nearer the recording's own zero
            // (at high noise a shifted origin can trade a true term for a false one at the
            // same error); else the lesser error.
            let better = match &best {
                None => true,
                Some((support, err, at)) => {
                    let len = support.count_ones();
                    let near = (selected.mean_error - *err).abs()
                        <= T::from_f64(ORIGIN_TIE) * selected.mean_error.min(*err);
                    selected.len() < len
                        || (selected.len() == len
                            && if near {
                                c.abs() < at.abs()
                            } else {
                                selected.mean_error < *err
                            })
                }
            };
            if better {
                best = Some((selected.support, selected.mean_error, c));
                self.publish(&result, c, offset_v);
            }
        }
        // Terms that only a misplaced origin needs: drop them one at a time while the model
        // without the term, at its own best origin, fits (all rows) within `parsimony` of
        // the model with it; then sweep at the origin reached, which wins if it selects
        // fewer terms. With test-function rows the fit is sharp enough that an origin off
        // by 5 % of the offset keeps five spurious terms, more than the steps above remove.
        // Once, on the best model, and only if it holds the constant term (each try is a
        // golden-section search, 0.4 M instructions on the M4F).
        if offsets
            && x_closed
            && let Some((support, _, at)) = best
            && holds_constant(support)
            && let Some(c2) = self.shed_by_shift(offset_v, at, support, parsimony, &mut w)
        {
            self.sweep_at(offset_v, c2, &mut w, grid, parsimony, &mut result);
            if result
                .chosen()
                .is_some_and(|t| t.len() < support.count_ones())
            {
                self.publish(&result, c2, offset_v);
            }
        }
        best.is_some()
    }

    /// Makes the model of a sweep (at x origin `offset_x`, v origin `offset_v`) the current
    /// one, in physical units. Out of line: the model it builds (0.5 KB with P = 16) would
    /// otherwise sit in `screen`'s frame under every sweep.
    #[inline(never)]
    pub(super) fn publish(&mut self, sweep: &screen::Sweep<T, P>, offset_x: T, offset_v: T) {
        let n = self.library.len();
        let mut coefficients = [T::ZERO; P];
        for j in 0..n {
            coefficients[j] = sweep.coefficients[j] * self.y_scale / self.scales[j];
        }
        let y2 = self.y_scale * self.y_scale;
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
        let k = |s: &KnnSmoother<T>, on: bool| {
            if self.config.smoothing && on {
                s.k() as u8
            } else {
                0
            }
        };
        self.model = Some(Model {
            terms,
            coefficients,
            solutions,
            selected: sweep.selected,
            k: (
                k(&self.smooth_x, self.smoothing_on.0),
                k(&self.smooth_v, self.smoothing_on.1),
            ),
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
        offset_v: T,
        c: T,
        w: &mut Work<T, P>,
        grid: usize,
        parsimony: T,
        out: &mut screen::Sweep<T, P>,
    ) {
        self.prepare(offset_v, c, true, w);
        // The column map is spent once the factors are moved: it is the solves' scratch.
        screen::sweep(&w.a, &w.b, &w.all, &mut w.m, grid, parsimony, out);
    }
}
