//! From samples to regression rows: the row, the warm-up and the fold into A or B.

use super::*;

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// Forgets the window (after a gap): the factors and statistics are kept.
    pub(super) fn restart(&mut self) {
        self.front.clear();
        self.schedule.restart_rows();
        self.smoothing.restart();
        // Close the velocity-offset segment: its end correction becomes final.
        self.offset.restart();
    }

    /// Computes the regression row whose centre lies half a window behind `t_newest`: the
    /// stages in the order a sample's data flows through them.
    pub(super) fn row(&mut self, t_newest: f64) {
        let channels = self.config.channels;
        let estimate = self.front.estimate(channels);
        if channels.velocity {
            self.offset.observe(estimate.x, estimate.v);
        }
        self.measure_noise(estimate.x, estimate.v);
        let t = t_newest - self.schedule.row_lag;
        // A row that folds (part of) a test-function sum into A or B defers an evaluation of
        // ε(K) due on it to the next row, and a row that does either defers the phasor's
        // resync: a sample pays for one of the three at most.
        let folds = self.halves.folds_next();
        let Some(row) = self
            .smoothing
            .push(self.config.smoothing, estimate, t, folds)
        else {
            return;
        };
        if !self.gate.admit(row.v) {
            self.counters.gated += 1;
            return;
        }
        self.extent.include(row.x);
        // Until the column scales are known, rows wait in the warm-up buffer; then they are
        // folded in, in order, and every later row goes straight to the factors.
        if self.counters.rows == 0 {
            if self.halves.keep(row) {
                self.flush_warmup();
            }
            return;
        }
        let busy = folds || self.smoothing.evaluated();
        self.fold(&row, busy);
    }

    /// What the smoothing decision (and the noise correction) needs from a row.
    #[inline]
    fn measure_noise(&mut self, x_hat: T, v_hat: T) {
        let velocity = self.config.channels.velocity;
        if self.config.smoothing || self.config.noise_correction {
            self.noise
                .observe(self.front.fourth_differences(velocity), velocity);
        }
        if self.config.smoothing {
            self.noise.observe_power(x_hat, v_hat);
        }
    }

    /// Ends the warm-up: sets the column scales and folds the buffered rows in, in order.
    /// Out of line (and run once): the rows move out of the shared store onto this frame's
    /// 1.5 KB, which would otherwise sit in `push`'s frame under every screening too.
    #[inline(never)]
    #[cold]
    pub(super) fn flush_warmup(&mut self) {
        let rows = self.halves.end_warmup(self.library.len());
        self.columns.set(&self.library, &rows);
        for r in rows.iter() {
            self.fold(r, false);
        }
    }

    /// A row through the library (with the phasor of its time) into A or B; on a `busy`
    /// row the phasor's resync may wait a few rows.
    pub(super) fn fold(&mut self, r: &Row<T>, busy: bool) {
        if self.config.library.harmonics > 0 {
            self.phasor.turn_to(r.t, self.config.omega, busy);
        }
        let phasor = self.phasor.sin_cos();
        let y = self
            .columns
            .row(&self.library, r, phasor, &mut self.scratch);
        self.counters.rows += 1;
        self.halves.push(&self.scratch.theta, y, self.library.len());
    }
}
