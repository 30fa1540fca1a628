//! Configuring: checking a configuration and setting every field from it.

use super::*;

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// Everything about `config` that can fail: it is checked (against `W`, `P` and `C`),
    /// its library built and its taps designed (the small part: the rest is per sample).
    pub(super) fn plan(config: Config) -> Result<Plan<T, P>, crate::ConfigError> {
        config.validate::<W, P, C>()?;
        let library = Library::new(&config.library)?;
        let design = Design::new(
            config.window,
            usize::from(config.derivative_degree),
            config.sample_period,
            W,
        )
        .map_err(|_| crate::ConfigError::Window {
            window: config.window,
            min: 0,
            max: W,
        })?;
        Ok(Plan {
            config,
            library,
            design,
        })
    }

    /// Storage for an identifier, not a usable one: every field zero (bits), the
    /// configuration's too. [`Identifier::apply`] sets every field. `const` and all zero,
    /// so that a static [`IdentifierSlot`] holding it lies in `.bss`: no flash, and no
    /// start-up code building it on the stack.
    pub(super) const fn zeroed() -> Self {
        Self {
            config: Config {
                sample_period: 0.0,
                window: 0,
                derivative_degree: 0,
                library: LibraryConfig {
                    poly_order: 0,
                    family: PolyFamily::All,
                    constant: false,
                    harmonics: 0,
                    input: false,
                },
                omega: 0.0,
                channels: Channels {
                    velocity: false,
                    input: false,
                },
                memory: None,
                screening_period: 0,
                thresholds: 0,
                smoothing: false,
                row_stride: 0,
                parsimony: 0.0,
                offsets: false,
                max_abs: 0.0,
                noise_correction: false,
                test_rows: 0,
            },
            library: Library::zeroed(),
            taps: FoldedTaps::empty(),
            rings: [const { HistoryBuf::new() }; C],
            u_ring: 0,
            last_t: None,
            since_row: 0,
            smooth_x: KnnSmoother::zeroed(),
            smooth_v: KnnSmoother::zeroed(),
            smoothing_on: (false, false),
            d4: (T::ZERO, T::ZERO, T::ZERO),
            gains: (T::ZERO, T::ZERO),
            cross: (T::ZERO, T::ZERO),
            state_scales: (T::ZERO, T::ZERO),
            power: (T::ZERO, T::ZERO),
            delay: [(T::ZERO, T::ZERO, 0.0); DELAY],
            delay_len: 0,
            delay_head: 0,
            inverse_scales: [T::ZERO; P],
            scales: [T::ZERO; P],
            y_scale: T::ZERO,
            store: Store::Warmup(heapless::Vec::new()),
            collector: Collector::Block(Factor::new(0)),
            regression_rows: 0,
            block_len: 0,
            sqrt_lambda: T::ZERO,
            sqrt_lambda_blocks: T::ZERO,
            short_v2: T::ZERO,
            long_v2: T::ZERO,
            long_weight: T::ZERO,
            short_alpha: T::ZERO,
            row_lambda: T::ZERO,
            warm_rows: T::ZERO,
            x_min: T::ZERO,
            x_max: T::ZERO,
            dv_sum: T::ZERO,
            dv_weight: T::ZERO,
            dv_prev: T::ZERO,
            dv_rows: 0,
            dv_last: T::ZERO,
            inverse_row_period: T::ZERO,
            phasor: (T::ZERO, T::ZERO),
            phasor_t: None,
            phasor_age: 0,
            rotation: (T::ZERO, T::ZERO),
            max_abs_sure: T::ZERO,
            too_early: 0.0,
            gap_after: 0.0,
            row_lag: 0.0,
            row_step: (0.0, 0.0),
            counters: Counters {
                accepted: 0,
                non_finite: 0,
                out_of_range: 0,
                out_of_order: 0,
                channels: 0,
                gaps: 0,
                rows: 0,
                gated: 0,
                screenings: 0,
            },
            since_screen: 0,
            model: None,
        }
    }

    /// Sets every field for the plan's configuration, in place: the state of a new
    /// identifier. The one way every identifier is configured (`new`, `reconfigure` and
    /// [`IdentifierSlot::configure`]), so that all three agree bit for bit. Out of line:
    /// each of them would otherwise inline a copy.
    #[inline(never)]
    pub(super) fn apply(&mut self, plan: &Plan<T, P>) {
        // Every field by name (no `..`): a field added to the struct and not set here does
        // not compile.
        let Self {
            config,
            library,
            taps,
            rings,
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
            model,
        } = self;
        let c = plan.config;
        *config = c;
        library.clone_from(&plan.library);
        // The taps folded in place; on the way, ‖h‖² of the filters that make x̂ and v̂
        // and the products h·h' with the filter that makes ŷ (sums over k in order, as
        // over the full taps).
        let velocity = c.channels.velocity;
        let v_order = if velocity { 0 } else { 1 };
        let (mut g0, mut g1) = (T::ZERO, T::ZERO);
        let (mut c0, mut c1) = (T::ZERO, T::ZERO);
        taps.design(&plan.design, |h| {
            g0 += h[0] * h[0];
            g1 += h[v_order] * h[v_order];
            if velocity {
                c1 += h[0] * h[1];
            } else {
                c0 += h[0] * h[2];
                c1 += h[1] * h[2];
            }
        });
        *gains = (g0, g1);
        *cross = (c0, c1);
        let n = plan.library.len();
        let stride = usize::from(c.row_stride);
        let blocks = (2 * c.window / stride).max(16) as u64;
        let row_period = c.sample_period * f64::from(c.row_stride);
        let step = c.omega * row_period;
        let lambda = c.memory.map_or(1.0, |tau| libm::exp(-row_period / tau));
        let sqrt_lambda_row = libm::sqrt(lambda);
        for ring in rings.iter_mut() {
            ring.clear();
        }
        // x in ring 0, then v and u in that order, each when measured (`validate` checked
        // that they fit in C).
        *u_ring = V_RING + usize::from(velocity);
        *last_t = None;
        *since_row = 0;
        *smooth_x = KnnSmoother::new();
        *smooth_v = KnnSmoother::new();
        // ε(K) as often per sample as with the default row every 4 samples.
        let sparseness = (4 / u32::from(c.row_stride)).max(1);
        smooth_x.set_sparseness(sparseness);
        smooth_v.set_sparseness(sparseness);
        *smoothing_on = (false, false);
        *d4 = (T::ZERO, T::ZERO, T::ZERO);
        *state_scales = (T::ONE, T::ONE);
        *power = (T::ZERO, T::ZERO);
        *delay = [(T::ZERO, T::ZERO, 0.0); DELAY];
        *delay_len = 0;
        *delay_head = 0;
        *inverse_scales = [T::ONE; P];
        *scales = [T::ONE; P];
        *y_scale = T::ONE;
        *store = Store::Warmup(heapless::Vec::new());
        *regression_rows = 0;
        if c.test_rows == 0 {
            *collector = Collector::Block(Factor::new(n));
            *block_len = blocks;
            *sqrt_lambda = T::from_f64(sqrt_lambda_row);
            // A's content at a merge is two blocks old.
            *sqrt_lambda_blocks = T::from_f64(libm::pow(sqrt_lambda_row, 2.0 * blocks as f64));
        } else {
            // λ and the blocks count in sums (one every L/4 rows); a block of eight sums
            // spans two test functions, so that A's and B's rows share little of the data.
            // A sum goes straight into A or B, whose content at the start of its block is
            // one block old.
            let mut sums = TestRows::zeroed();
            sums.configure(c.test_rows);
            let sqrt_lambda_sum = libm::pow(sqrt_lambda_row, f64::from(sums.quarter()));
            *collector = Collector::Sums(sums);
            *block_len = TEST_BLOCK;
            *sqrt_lambda = T::from_f64(sqrt_lambda_sum);
            *sqrt_lambda_blocks = T::from_f64(libm::pow(sqrt_lambda_sum, TEST_BLOCK as f64));
        }
        *short_v2 = T::ZERO;
        *long_v2 = T::ZERO;
        *long_weight = T::ZERO;
        *short_alpha = T::ONE / T::from_usize(blocks as usize);
        let sqrt_lambda_one = T::from_f64(sqrt_lambda_row);
        *row_lambda = sqrt_lambda_one * sqrt_lambda_one;
        *warm_rows = T::from_usize(blocks as usize);
        *x_min = T::MAX;
        *x_max = -T::MAX;
        *dv_sum = T::ZERO;
        *dv_weight = T::ZERO;
        *dv_prev = T::ZERO;
        *dv_rows = 0;
        *dv_last = T::ZERO;
        *inverse_row_period = T::from_f64(1.0 / row_period);
        *phasor = (T::ZERO, T::ONE);
        *phasor_t = None;
        *phasor_age = 0;
        // Through T's own sin/cos: in f32, sinf and cosf are linked already, libm's f64
        // sin and cos would add 4 KB of flash (the rounding of the step to f32 turns
        // the phasor by 10⁻⁹ rad a row at most, re-synced every PHASOR_RESYNC rows).
        *rotation = (T::from_f64(step).sin(), T::from_f64(step).cos());
        *max_abs_sure = T::from_f64(c.max_abs * (1.0 - 1e-6));
        *too_early = 0.5 * c.sample_period;
        *gap_after = 1.5 * c.sample_period;
        // Precomputed: f64 arithmetic is in software on the M4F, and these are per row.
        *row_lag = (c.window - 1) as f64 / 2.0 * c.sample_period;
        *row_step = (
            row_period - 1e-6 * row_period,
            row_period + 1e-6 * row_period,
        );
        *counters = Counters::default();
        *since_screen = 0;
        *model = None;
    }
}
