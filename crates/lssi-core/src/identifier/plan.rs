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
            config: Config::zeroed(),
            library: Library::zeroed(),
            intake: Intake::zeroed(),
            schedule: Schedule::zeroed(),
            front: Front::zeroed(),
            noise: ChannelNoise::zeroed(),
            smoothing: Smoothing::zeroed(),
            offset: VelocityOffset::zeroed(),
            gate: Gate::zeroed(),
            extent: Extent::zeroed(),
            phasor: Phasor::zeroed(),
            columns: Columns::zeroed(),
            scratch: Scratch::zeroed(),
            halves: Halves::zeroed(),
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
            model: None,
        }
    }

    /// Sets every field for the plan's configuration, in place: the state of a new
    /// identifier. The one way every identifier is configured (`new`, `reconfigure` and
    /// [`IdentifierSlot::configure`]), so that all three agree bit for bit. Out of line:
    /// each of them would otherwise inline a copy.
    #[inline(never)]
    pub(super) fn apply(&mut self, plan: &Plan<T, P>) {
        self.config = plan.config;
        self.library.clone_from(&plan.library);
        self.front.configure(plan.config.channels);
        let (gains, cross) = Self::design_taps(&mut self.front, plan);
        self.noise = ChannelNoise::new(gains, cross);
        self.start();
    }

    /// Forgets every sample, row, factor and model, keeping the configuration, its library
    /// and its designed taps: afterwards the identifier is, bit for bit, what
    /// [`Identifier::reconfigure`] with its own configuration makes, without designing the
    /// taps again (the f64 part of configuring: on the M4F, in software, most of its
    /// instructions). A standalone device that restarts its identifier mid-recording (its
    /// channels' references learnt) does this between two rows.
    pub fn forget(&mut self) {
        self.front.configure(self.config.channels);
        self.noise = ChannelNoise::new(self.noise.gains(), self.noise.cross());
        self.start();
    }

    /// Sets every field but the configuration, the library, the front end's taps and the
    /// noise's gains for the configuration: the state of a new identifier.
    fn start(&mut self) {
        // Every field by name (no `..`): a field added to the struct and not set here (or
        // in `apply`, for those bound to `_`) does not compile.
        let Self {
            config,
            library,
            intake,
            schedule,
            front: _,
            noise: _,
            smoothing,
            offset,
            gate,
            extent,
            phasor,
            columns,
            scratch,
            halves,
            counters,
            model,
        } = self;
        let c = *config;
        *intake = Intake::new(&c);
        *schedule = Schedule::new(&c);
        *smoothing = Smoothing::new(c.row_stride);
        let stride = usize::from(c.row_stride);
        let blocks = (2 * c.window / stride).max(16) as u64;
        let row_period = c.sample_period * f64::from(c.row_stride);
        let lambda = c.memory.map_or(1.0, |tau| libm::exp(-row_period / tau));
        let sqrt_lambda_row = libm::sqrt(lambda);
        *offset = VelocityOffset::new(row_period);
        *gate = Gate::new(blocks, sqrt_lambda_row);
        *extent = Extent::new();
        *phasor = Phasor::new(c.omega, row_period);
        *columns = Columns::new();
        *scratch = Scratch::zeroed();
        halves.configure(library.len(), c.test_rows, blocks, sqrt_lambda_row);
        *counters = Counters::default();
        *model = None;
    }

    /// Designs the front end's taps, folded in place; on the way, ‖h‖² of the filters that
    /// make x̂ and v̂ and the products h·h' with the filter that makes ŷ (sums over k in
    /// order, as over the full taps): the gains of the noise statistics.
    fn design_taps(front: &mut Front<T, W, C>, plan: &Plan<T, P>) -> ((T, T), (T, T)) {
        let velocity = plan.config.channels.velocity;
        let v_order = if velocity { 0 } else { 1 };
        let (mut g0, mut g1) = (T::ZERO, T::ZERO);
        let (mut c0, mut c1) = (T::ZERO, T::ZERO);
        front.taps.design(&plan.design, |h| {
            g0 += h[0] * h[0];
            g1 += h[v_order] * h[v_order];
            if velocity {
                c1 += h[0] * h[1];
            } else {
                c0 += h[0] * h[2];
                c1 += h[1] * h[2];
            }
        });
        ((g0, g1), (c0, c1))
    }
}
