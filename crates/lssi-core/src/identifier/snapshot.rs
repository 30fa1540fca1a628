//! Screening without a stall: what a screening reads, copied out of the identifier so that
//! the screening can run elsewhere (at a lower priority on a device) while samples go on.

use super::*;

/// What a screening reads, without the ring buffers and the derivative taps: an
/// [`Identifier`] of window capacity 1 and one channel, filled by
/// [`Identifier::snapshot_into`] and screened by [`Identifier::select`].
///
/// It keeps its own model between screenings (a screening that selects nothing leaves the
/// previous model, as in the identifier). About half the identifier's size (4.4 KiB with
/// f32 and P = 16, against 10 KiB for W = 256, C = 2).
///
/// ```
/// use lssi_core::{Config, Identifier, Sample, Snapshot};
/// let config = Config { sample_period: 0.01, window: 31, omega: 1.0,
///                       screening_period: 1500, ..Config::default() };
/// let mut inline: Identifier<f32, 64, 16> = Identifier::new(config).unwrap();
/// let mut deferred: Identifier<f32, 64, 16> = Identifier::new(config).unwrap();
/// let mut snapshot: Box<Snapshot<f32, 16>> = Box::new(Snapshot::empty());
/// for i in 0..3000u32 {
///     let t = f64::from(i) * 0.01;
///     let sample = Sample { t, x: (1.3 * t).sin() as f32 + 0.2 * (0.7 * t).cos() as f32,
///                           v: None, u: None };
///     inline.push(sample).unwrap();
///     deferred.push_with(sample, |id| { id.snapshot_into(&mut snapshot); false }).unwrap();
/// }
/// // The screening of the copy (later, elsewhere) gives the model of the inline one.
/// snapshot.select();
/// assert_eq!(snapshot.model().unwrap().coefficients, inline.model().unwrap().coefficients);
/// assert!(deferred.model().is_none());
/// ```
pub type Snapshot<T, const P: usize> = Identifier<T, 1, P, 1>;

impl<T: Real, const P: usize> Identifier<T, 1, P, 1> {
    /// An empty snapshot: `const`, all zero bytes (a static of it lies in `.bss`).
    pub const fn empty() -> Self {
        Self::zeroed()
    }

    /// Forgets the model (after the identifier it is taken from was configured anew).
    pub fn clear_model(&mut self) {
        self.model = None;
    }
}

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// Copies into `s` everything a screening reads (all but the ring buffers and the
    /// derivative taps, and `s`'s own model, which it keeps). Then `s.select()` is the
    /// screening of this identifier as it is now.
    ///
    /// Destructured field by field, so that a field added to the identifier does not
    /// compile until it is either copied here or said to be left out.
    pub fn snapshot_into<const W2: usize, const C2: usize>(
        &self,
        s: &mut Identifier<T, W2, P, C2>,
    ) {
        let Identifier {
            config,
            library,
            taps: _,
            rings: _,
            u_ring,
            last_t,
            since_row,
            smooth_x,
            smooth_v,
            smoothing_on,
            d4,
            gains,
            cross,
            state_scales,
            power,
            delay,
            delay_len,
            delay_head,
            inverse_scales,
            scales,
            y_scale,
            store,
            collector,
            regression_rows,
            block_len,
            sqrt_lambda,
            sqrt_lambda_blocks,
            short_v2,
            long_v2,
            long_weight,
            short_alpha,
            row_lambda,
            warm_rows,
            x_min,
            x_max,
            dv_sum,
            dv_weight,
            dv_prev,
            dv_rows,
            dv_last,
            inverse_row_period,
            phasor,
            phasor_t,
            phasor_age,
            rotation,
            max_abs_sure,
            too_early,
            gap_after,
            row_lag,
            row_step,
            counters,
            since_screen,
            model: _,
        } = self;
        s.config = *config;
        s.library.clone_from(library);
        s.u_ring = *u_ring;
        s.last_t = *last_t;
        s.since_row = *since_row;
        s.smooth_x.clone_from(smooth_x);
        s.smooth_v.clone_from(smooth_v);
        s.smoothing_on = *smoothing_on;
        s.d4 = *d4;
        s.gains = *gains;
        s.cross = *cross;
        s.state_scales = *state_scales;
        s.power = *power;
        s.delay = *delay;
        s.delay_len = *delay_len;
        s.delay_head = *delay_head;
        s.inverse_scales = *inverse_scales;
        s.scales = *scales;
        s.y_scale = *y_scale;
        s.store.clone_from(store);
        s.collector.clone_from(collector);
        s.regression_rows = *regression_rows;
        s.block_len = *block_len;
        s.sqrt_lambda = *sqrt_lambda;
        s.sqrt_lambda_blocks = *sqrt_lambda_blocks;
        s.short_v2 = *short_v2;
        s.long_v2 = *long_v2;
        s.long_weight = *long_weight;
        s.short_alpha = *short_alpha;
        s.row_lambda = *row_lambda;
        s.warm_rows = *warm_rows;
        s.x_min = *x_min;
        s.x_max = *x_max;
        s.dv_sum = *dv_sum;
        s.dv_weight = *dv_weight;
        s.dv_prev = *dv_prev;
        s.dv_rows = *dv_rows;
        s.dv_last = *dv_last;
        s.inverse_row_period = *inverse_row_period;
        s.phasor = *phasor;
        s.phasor_t = *phasor_t;
        s.phasor_age = *phasor_age;
        s.rotation = *rotation;
        s.max_abs_sure = *max_abs_sure;
        s.too_early = *too_early;
        s.gap_after = *gap_after;
        s.row_lag = *row_lag;
        s.row_step = *row_step;
        s.counters = *counters;
        s.since_screen = *since_screen;
    }
}
