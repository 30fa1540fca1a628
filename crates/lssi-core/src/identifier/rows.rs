//! From samples to regression rows: the row, the warm-up and the fold into A or B.

use super::*;

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    pub(super) fn restart(&mut self) {
        for ring in self.rings.iter_mut() {
            ring.clear();
        }
        self.since_row = 0;
        self.smooth_x.restart();
        self.smooth_v.restart();
        self.delay_len = 0;
        self.delay_head = 0;
        // Close the velocity-offset segment: its end correction becomes final.
        self.dv_sum -= T::from_f64(0.5) * self.dv_last;
        self.dv_last = T::ZERO;
        self.dv_rows = 0;
    }

    /// The velocity offset mean(v̂ − dx/dt) over the rows so far.
    pub(super) fn velocity_offset(&self) -> T {
        (self.dv_sum - T::from_f64(0.5) * self.dv_last) / self.dv_weight
    }

    /// Computes the regression row whose centre lies half a window behind `t_newest`.
    pub(super) fn row(&mut self, t_newest: f64) {
        let taps = &self.taps;
        let (xa, xb) = self.rings[0].as_slices();
        let x_hat = taps.apply(0, xa, xb);
        // White noise of the raw channels from fourth differences of the newest samples.
        let d4 = |buffer: &HistoryBuf<T, W>| {
            let mut recent = buffer.oldest_ordered().rev().take(5);
            let mut d = T::ZERO;
            for c in [1.0, -4.0, 6.0, -4.0, 1.0] {
                d += T::from_f64(c) * recent.next().copied().unwrap_or(T::ZERO);
            }
            d * d
        };
        let (v_hat, y_hat) = if self.config.channels.velocity {
            let (va, vb) = self.rings[V_RING].as_slices();
            let v_hat = taps.apply(0, va, vb);
            // The velocity offset shows as mean(v) − mean(dx/dt). The sum of dx/dt over the
            // rows of a segment (between gaps) telescopes: by the midpoint rule,
            // h·Σ_{r=1..R} x'(t_r) = x̂(t_R + h/2) − x̂(t_1 − h/2) + O(h³x‴·R), and the half
            // steps past the ends are extrapolated by the end differences, so
            //   Σ dx/dt ≈ (x̂_R − x̂_1)/h + ½(x̂_2 − x̂_1)/h + ½(x̂_R − x̂_(R−1))/h.
            // That is the same estimate as a 255-tap derivative filter on every row (which
            // it replaced) to O(h²x'') per segment, from the x̂ the row computes anyway.
            // Each row adds v̂ minus its backward difference (keeping the sum small), the
            // second row also the start correction; the end correction is `dv_last`.
            let mut dv = v_hat;
            if self.dv_rows > 0 {
                let d = (x_hat - self.dv_prev) * self.inverse_row_period;
                dv -= d;
                if self.dv_rows == 1 {
                    dv -= T::from_f64(0.5) * d;
                }
                self.dv_last = d;
            }
            self.dv_prev = x_hat;
            self.dv_rows = self.dv_rows.saturating_add(1);
            self.dv_sum += dv;
            self.dv_weight += T::ONE;
            (v_hat, taps.apply(1, va, vb))
        } else {
            (taps.apply(1, xa, xb), taps.apply(2, xa, xb))
        };
        let u_hat = if self.config.channels.input {
            let (ua, ub) = self.rings[self.u_ring].as_slices();
            taps.apply(0, ua, ub)
        } else {
            T::ZERO
        };
        // What the smoothing decision needs (`adapt_smoothing`); the window holds at least
        // five samples (its minimum is degree + 3 ≥ 5).
        if self.config.smoothing || self.config.noise_correction {
            self.d4.0 += d4(&self.rings[0]);
            if self.config.channels.velocity {
                self.d4.1 += d4(&self.rings[V_RING]);
            }
            self.d4.2 += T::ONE;
        }
        if self.config.smoothing {
            self.power.0 += x_hat * x_hat;
            self.power.1 += v_hat * v_hat;
        }
        let t_centre = t_newest - self.row_lag;
        let row = if self.config.smoothing {
            // A channel whose smoothing is off needs only its ε(K) (sampled more sparsely).
            let sx = self.smooth_x.push_with(x_hat, self.smoothing_on.0);
            let sv = self.smooth_v.push_with(v_hat, self.smoothing_on.1);
            // Delay x'', u and t by the smoother's lag.
            let slot = (self.delay_head + self.delay_len) % DELAY;
            self.delay[slot] = (y_hat, u_hat, t_centre);
            if self.delay_len < DELAY {
                self.delay_len += 1;
            } else {
                self.delay_head = (self.delay_head + 1) % DELAY;
            }
            match (sx, sv) {
                (Some(x), Some(v)) if self.delay_len == DELAY => {
                    let (y, u, t) = self.delay[self.delay_head];
                    Row { x, v, y, u, t }
                }
                _ => return,
            }
        } else {
            Row {
                x: x_hat,
                v: v_hat,
                y: y_hat,
                u: u_hat,
                t: t_centre,
            }
        };
        // The excitation gate.
        let v2 = row.v * row.v;
        self.short_v2 += self.short_alpha * (v2 - self.short_v2);
        let warm = self.long_weight > self.warm_rows;
        if warm && self.short_v2 < T::from_f64(GATE * GATE) * self.long_v2 {
            self.counters.gated += 1;
            return;
        }
        let lambda = self.row_lambda;
        self.long_weight = lambda * self.long_weight + T::ONE;
        self.long_v2 += (v2 - self.long_v2) / self.long_weight;
        self.x_min = self.x_min.min(row.x);
        self.x_max = self.x_max.max(row.x);
        // Until the column scales are known, rows wait in the warm-up buffer; then they are
        // folded in, in order, and every later row goes straight to the factors.
        if self.counters.rows == 0 {
            if let Store::Warmup(rows) = &mut self.store
                && rows.push(row).is_ok()
                && rows.len() < WARMUP_ROWS
            {
                return;
            }
            self.flush_warmup();
            return;
        }
        self.fold(&row);
    }

    /// Ends the warm-up: sets the column scales and folds the buffered rows in, in order.
    /// Out of line (and run once): the rows move out of the shared store onto this frame's
    /// 1.5 KB, which would otherwise sit in `push`'s frame under every screening too.
    #[inline(never)]
    #[cold]
    pub(super) fn flush_warmup(&mut self) {
        let n = self.library.len();
        let empty = Store::Halves(Factor::new(n), Factor::new(n));
        let rows = match core::mem::replace(&mut self.store, empty) {
            Store::Warmup(rows) => rows,
            Store::Halves(..) => heapless::Vec::new(),
        };
        self.set_scales(&rows);
        for r in rows.iter() {
            self.fold(r);
        }
    }

    /// Column scales from the warm-up rows: each column and x'' become O(1).
    pub(super) fn set_scales(&mut self, warmup: &[Row<T>]) {
        let mut sums = [T::ZERO; 4];
        for r in warmup.iter() {
            for (s, v) in sums.iter_mut().zip([r.x, r.v, r.u, r.y]) {
                *s += v * v;
            }
        }
        let count = T::from_usize(warmup.len().max(1));
        let rms = sums.map(|s| {
            let r = (s / count).sqrt();
            if r > T::ZERO && r.is_finite() {
                r
            } else {
                T::ONE
            }
        });
        let (sx, sv, su, sy) = (rms[0], rms[1], rms[2], rms[3]);
        self.state_scales = (sx, sv);
        for (j, term) in self.library.terms().iter().enumerate() {
            let d = match *term {
                Term::Monomial { px, pv } => {
                    crate::library::powi(sx, px) * crate::library::powi(sv, pv)
                }
                Term::Input => su,
                _ => T::ONE,
            };
            self.scales[j] = d;
            self.inverse_scales[j] = T::ONE / d;
        }
        self.y_scale = sy;
    }

    pub(super) fn fold(&mut self, r: &Row<T>) {
        let mut theta = [T::ZERO; P];
        if self.config.library.harmonics > 0 {
            // The phasor (sin, cos) of Ωt turns by a fixed rotation from one row to the next
            // when they are one row period apart (to 10⁻⁶ of it); after a gap, a gated row,
            // irregular time stamps or PHASOR_RESYNC rotations it is computed from t.
            let (lo, hi) = self.row_step;
            let consecutive = self.phasor_t.is_some_and(|t0| {
                let d = r.t - t0;
                lo <= d && d <= hi
            });
            if consecutive && self.phasor_age < PHASOR_RESYNC {
                let (s, c) = self.phasor;
                let (sr, cr) = self.rotation;
                self.phasor = (s * cr + c * sr, c * cr - s * sr);
                self.phasor_age += 1;
            } else {
                let p = self.config.omega * r.t;
                let tau = 2.0 * core::f64::consts::PI;
                let phase = T::from_f64(p - tau * libm::floor(p / tau));
                self.phasor = (phase.sin(), phase.cos());
                self.phasor_age = 0;
            }
            self.phasor_t = Some(r.t);
        }
        let (s1, c1) = self.phasor;
        self.library
            .evaluate_sin_cos(r.x, r.v, s1, c1, r.u, &mut theta);
        for (t, s) in theta.iter_mut().zip(self.inverse_scales.iter()) {
            *t *= *s;
        }
        let y = r.y / self.y_scale;
        self.counters.rows += 1;
        let Self {
            collector,
            store,
            regression_rows,
            block_len,
            sqrt_lambda,
            sqrt_lambda_blocks,
            ..
        } = self;
        let Store::Halves(a, b) = store else {
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
                block.update(&theta, y, sqrt_lambda);
                *regression_rows += 1;
                if regression_rows.is_multiple_of(block_len) {
                    let parity = (*regression_rows / block_len) % 2;
                    let factor = if parity == 1 { a } else { b };
                    factor.forget(sqrt_lambda_blocks);
                    factor.merge(block);
                    block.clear();
                }
            }
            // A sum weighs as much as L/4 rows and there are few of them (10⁵ samples make
            // 400): each goes straight into A or B, blocks of TEST_BLOCK alternating.
            Collector::Sums(sums) => {
                let n = self.library.len();
                sums.push(&theta, y, n, |sum, target| {
                    let k = *regression_rows / block_len;
                    let factor = if k % 2 == 0 { &mut *a } else { &mut *b };
                    if regression_rows.is_multiple_of(block_len) {
                        factor.forget(sqrt_lambda_blocks);
                    }
                    factor.update(sum, target, sqrt_lambda);
                    *regression_rows += 1;
                });
            }
        }
    }

    /// The weights the two halves A and B have with the block in progress merged in.
    pub(super) fn half_weights(&self) -> (T, T) {
        let (mut a, mut b) = match &self.store {
            Store::Halves(a, b) => (a.weight(), b.weight()),
            Store::Warmup(_) => (T::ZERO, T::ZERO),
        };
        if let Collector::Block(block) = &self.collector
            && block.weight() > T::ZERO
        {
            if (self.regression_rows / self.block_len).is_multiple_of(2) {
                a += block.weight();
            } else {
                b += block.weight();
            }
        }
        (a, b)
    }
}
