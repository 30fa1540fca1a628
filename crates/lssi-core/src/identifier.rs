//! The streaming identifier: one sample in, now and then a model out.
//!
//! A sample's way through it (DESIGN.md): ring buffer → fixed-lag local polynomial estimates
//! of x, x', x'' → k-neighbour smoothing of x and x' → library row θ(x, x', t [, u]) scaled to
//! unit size → with `Config::test_rows`, sums of rows under a smooth test function (the weak
//! form, `weak`) → square-root RLS update (into one of two interleaved factors) → every
//! `screening_period` samples: sensor offsets, threshold sweep, MES → [`Model`].
//!
//! ```
//! use lssi_core::{Config, Identifier, Sample};
//! let config = Config { sample_period: 0.01, window: 63, omega: 1.0, screening_period: 2000,
//!                       ..Config::default() };
//! let mut id: Identifier<f32, 128, 16> = Identifier::new(config).unwrap();
//! // x'' = -4x - 0.2x' + 3cos(t): a forced linear oscillator, integrated by semi-implicit Euler.
//! let (mut x, mut v, dt) = (0.0f64, 0.0f64, 0.0001f64);
//! for i in 0..2_000_000u32 {
//!     let t = f64::from(i) * dt;
//!     if i % 100 == 0 {
//!         id.push(Sample { t, x: x as f32, v: None, u: None }).unwrap();
//!     }
//!     v += dt * (-4.0 * x - 0.2 * v + 3.0 * t.cos());
//!     x += dt * v;
//! }
//! id.screen();
//! let model = id.model().unwrap();
//! let k = model.coefficient(lssi_core::Term::Monomial { px: 1, pv: 0 }).unwrap();
//! assert!((k + 4.0).abs() < 0.05, "{k}");
//! ```

use crate::config::{Channels, Config};
use crate::derivative::{Design, FoldedTaps};
#[cfg(feature = "noise-correction")]
use crate::eiv;
use crate::factor::Factor;
use crate::library::{Library, LibraryConfig, PolyFamily, Term};
use crate::model::{MAX_SOLUTIONS, Model, Solution};
use crate::real::Real;
use crate::screen;
use crate::smoothing::KnnSmoother;
use crate::weak::TestRows;
use heapless::HistoryBuf;

/// The ring buffer of v, when v is measured (x's is ring 0, u's the next one).
const V_RING: usize = 1;

/// Regression rows kept before the column scales are known.
const WARMUP_ROWS: usize = 64;
/// Rows of the delay line that keeps x'', u and t in step with the smoothed x and v.
const DELAY: usize = KnnSmoother::<f32>::LAG + 1;
/// The excitation gate closes when the recent RMS velocity falls below this fraction of the
/// long-run RMS velocity: the factor then neither learns nor forgets.
const GATE: f64 = 0.01;

/// Relative difference of held-out error under which two equally sparse models found at
/// different x origins count as a tie (decided by the origin nearer the recording's zero).
/// Measured on eq. 17: a true sensor offset lowers the error by 3 % or more at δ ≤ 0.01; a
/// spurious origin at δ = 0.1 with x only differs by under 0.5 %.
const ORIGIN_TIE: f64 = 0.01;

/// Rows the (sin, cos) phasor of Ωt is rotated across before it is recomputed from t.
///
/// Each rotation by the fixed (sin, cos) of Ω·(row period) rounds the phasor by about
/// 2 ulp in magnitude and angle, so after 64 rows its error is at most 64·2·2⁻²⁴ ≈ 8·10⁻⁶
/// in f32 (10⁻¹⁴ in f64), far below the sensor noise and the 1-ulp error of sinf itself;
/// the exact recomputation costs a sinf and a cosf (about 3 000 instructions on the M4F in
/// software f64 range reduction), 1/64 of what every row paid before.
const PHASOR_RESYNC: u16 = 64;

/// Golden-section steps of the origin search (each one transform and one solve), by
/// precision. Near its minimum the residual energy is flat to second order, so an origin is
/// resolved only to about √ε of the bracket: 0.618ⁿ ≤ √ε needs n ≥ 17 in f32 and 38 in f64.
/// Steps beyond that only chase rounding; in f32 they were a third of a screening.
fn golden_steps<T: Real>() -> usize {
    if T::EPSILON.to_f64() > 1e-10 { 20 } else { 40 }
}

/// The two halves A and B of the data, or, until the column scales are known, the warm-up
/// rows. The halves are empty while rows wait in the warm-up buffer, so the two share their
/// memory (the buffer's 1.5 KB of RAM on the M4F with P = 16).
enum Store<T, const P: usize> {
    Warmup(heapless::Vec<Row<T>, WARMUP_ROWS>),
    Halves(Factor<T, P>, Factor<T, P>),
}

/// The screening's working factors: A and B (with the block in progress), their union, and
/// one column map. One set, filled anew for each origin tried (see `Identifier::prepare`).
struct Work<T, const P: usize> {
    a: Factor<T, P>,
    b: Factor<T, P>,
    all: Factor<T, P>,
    m: [[T; P]; P],
}

impl<T: Real, const P: usize> Work<T, P> {
    fn new(n: usize) -> Self {
        Self {
            a: Factor::new(n),
            b: Factor::new(n),
            all: Factor::new(n),
            m: [[T::ZERO; P]; P],
        }
    }
}

/// A configuration that passed every check, with what configuring needs from it that could
/// fail: its library and the design of its taps.
struct Plan<T, const P: usize> {
    config: Config,
    library: Library<P>,
    design: Design<T>,
}

/// One measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample<T> {
    /// Time, seconds (f64: a device runs for days).
    pub t: f64,
    /// Displacement.
    pub x: T,
    /// Measured velocity, when the configuration says there is one.
    pub v: Option<T>,
    /// Measured excitation, when the configuration says there is one.
    pub u: Option<T>,
}

/// Why a sample was not fed in. Each is counted in [`Counters`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Rejection {
    /// A value (or the time) is NaN or infinite.
    NonFinite,
    /// A value's magnitude exceeds `max_abs`.
    OutOfRange,
    /// The time is not later than the previous sample's (by at least half a period).
    OutOfOrder,
    /// A channel the configuration declares is missing (or one it does not declare is present).
    Channels,
}

impl core::fmt::Display for Rejection {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Rejection::NonFinite => "the sample has a NaN or infinite value",
            Rejection::OutOfRange => "the sample's magnitude exceeds max_abs",
            Rejection::OutOfOrder => "the sample's time is not after the previous sample's",
            Rejection::Channels => "the sample's channels differ from the configured ones",
        })
    }
}

impl core::error::Error for Rejection {}

/// What happened to the samples so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Samples fed in.
    pub accepted: u64,
    /// Rejected: non-finite.
    pub non_finite: u64,
    /// Rejected: beyond `max_abs`.
    pub out_of_range: u64,
    /// Rejected: time not increasing.
    pub out_of_order: u64,
    /// Rejected: wrong channels.
    pub channels: u64,
    /// Gaps in time (more than 1.5 periods) after which the window restarted.
    pub gaps: u64,
    /// Regression rows folded into the factors.
    pub rows: u64,
    /// Rows held back by the excitation gate.
    pub gated: u64,
    /// Screenings run.
    pub screenings: u64,
}

impl Counters {
    /// All rejected samples.
    pub fn rejected(&self) -> u64 {
        self.non_finite + self.out_of_range + self.out_of_order + self.channels
    }
}

/// Sparser supports tried with their own best origin, one after another (each must remove
/// a term).
const SPARSER_STEPS: usize = 2;

/// Test-function sums per block of A or B (two test functions' worth).
const TEST_BLOCK: u64 = 8;

/// What gathers the rows before they reach A or B. The two never coexist, so the sums take
/// no memory beyond the block factor's.
enum Collector<T, const P: usize> {
    /// Rows as they are, gathered in a block factor that is merged into A or B when full.
    Block(Factor<T, P>),
    /// The test-function sums (`Config::test_rows`); each completed one goes into A or B.
    Sums(TestRows<T, P>),
}

#[derive(Clone, Copy, Debug, Default)]
struct Row<T> {
    x: T,
    v: T,
    y: T,
    u: T,
    t: f64,
}

/// The streaming LSSI identifier: `W` samples of window capacity, `P` library terms, `C`
/// sample channels (ring buffers of `W` samples each: x, then v and u when measured).
///
/// `C = 3` takes every configuration; a device that never measures both v and u saves a
/// ring buffer (`4·W` bytes in f32) with `C = 2`, or two with `C = 1` (x only). A
/// configuration with more channels than `C` is refused ([`ConfigError::Channels`]).
///
/// [`ConfigError::Channels`]: crate::ConfigError::Channels
pub struct Identifier<T: Real, const W: usize, const P: usize, const C: usize = 3> {
    config: Config,
    library: Library<P>,
    taps: FoldedTaps<T, W>,
    /// The raw samples of each channel: x in ring 0, then v and u, each when measured.
    rings: [HistoryBuf<T, W>; C],
    /// The ring of u (meaningful only when u is measured): the one after v's, if any.
    u_ring: usize,
    last_t: Option<f64>,
    since_row: u16,
    smooth_x: KnnSmoother<T>,
    smooth_v: KnnSmoother<T>,
    /// Whether each channel's smoothing is applied (decided from ε(K) against the noise).
    smoothing_on: (bool, bool),
    /// Σ(Δ⁴x)², Σ(Δ⁴v)² over the rows and their count: the white-noise variance of the raw
    /// channels is Σ/(70·count).
    d4: (T, T, T),
    /// ‖h‖² of the filters that make x̂ and v̂ from the raw channels.
    gains: (T, T),
    /// h·h' of the filters that make x̂ and ŷ, and v̂ and ŷ (0 for different channels).
    #[cfg_attr(not(feature = "noise-correction"), allow(dead_code))]
    cross: (T, T),
    /// RMS of x̂ and v̂ over the warm-up: the units of the scaled columns.
    #[cfg_attr(not(feature = "noise-correction"), allow(dead_code))]
    state_scales: (T, T),
    /// Σx̂², Σv̂² over the same rows as `d4`.
    power: (T, T),
    delay: [(T, T, f64); DELAY],
    delay_len: usize,
    delay_head: usize,
    inverse_scales: [T; P],
    scales: [T; P],
    y_scale: T,
    store: Store<T, P>,
    /// What gathers the rows before they reach A or B.
    collector: Collector<T, P>,
    /// Rows given to A and B: the rows themselves, or the test-function sums.
    regression_rows: u64,
    /// Regression rows per block of A or B.
    block_len: u64,
    sqrt_lambda: T,
    sqrt_lambda_blocks: T,
    short_v2: T,
    long_v2: T,
    long_weight: T,
    short_alpha: T,
    /// λ of one row (the excitation gate's long average forgets by it).
    row_lambda: T,
    /// Rows the gate's long average needs before it gates.
    warm_rows: T,
    x_min: T,
    x_max: T,
    /// Σ(v̂ − dx̂/dt) over the rows, with dx̂/dt telescoped (see `row`), but for the half
    /// difference `dv_last` of the current segment's newest row.
    dv_sum: T,
    dv_weight: T,
    /// x̂ of the previous row of this segment (since the last gap) and the segment's rows.
    dv_prev: T,
    dv_rows: u32,
    /// (x̂ₙ − x̂ₙ₋₁)/h of the newest row of this segment: the end correction.
    dv_last: T,
    /// 1/h, h the time between rows.
    inverse_row_period: T,
    /// sin and cos of Ω t at `phasor_t`, the time of the last folded row.
    phasor: (T, T),
    phasor_t: Option<f64>,
    /// Rotations since the phasor was last computed exactly.
    phasor_age: u16,
    /// sin and cos of Ω h: one row's rotation.
    rotation: (T, T),
    /// Magnitudes below this are within `max_abs` for sure (compared in T, not f64).
    max_abs_sure: T,
    /// 0.5 and 1.5 sample periods: a sample closer than `too_early` to the previous one is
    /// out of order, one later than `gap_after` starts after a gap (precomputed: f64
    /// arithmetic is in software on the M4F).
    too_early: f64,
    gap_after: f64,
    /// (window − 1)/2 sample periods: a row's time behind its newest sample.
    row_lag: f64,
    /// The interval that the time between two consecutive rows falls in (one row period,
    /// ± 10⁻⁶ of it): the phasor then turns by `rotation`.
    row_step: (f64, f64),
    counters: Counters,
    since_screen: u32,
    model: Option<Model<T, P>>,
}

/// Where a device keeps its [`Identifier`]: empty until configured, then configured (and
/// configured again) in place, so that the identifier never exists on the stack (9 KB with
/// f32, W = 256, P = 16, and the 3 KB of full derivative taps that `Identifier::new`
/// would design on top).
///
/// [`IdentifierSlot::new`] is `const` and its bytes are all zero: in a `static` it lies in
/// `.bss` (no flash, no start-up copy).
///
/// ```
/// use lssi_core::{Config, IdentifierSlot};
/// // A firmware's would be a `static` (in `.bss`); a host test's is on the heap.
/// let mut slot: Box<IdentifierSlot<f32, 128, 16, 1>> = Box::new(IdentifierSlot::new());
/// assert!(slot.get().is_none());
/// let config = Config { window: 63, ..Config::default() };
/// slot.configure(config).unwrap();
/// assert_eq!(slot.get().unwrap().config().window, 63);
/// // A refused configuration leaves the slot as it was.
/// assert!(slot.configure(Config { window: 500, ..config }).is_err());
/// assert_eq!(slot.get().unwrap().config().window, 63);
/// ```
pub struct IdentifierSlot<T: Real, const W: usize, const P: usize, const C: usize = 3> {
    configured: bool,
    identifier: Identifier<T, W, P, C>,
}

impl<T: Real, const W: usize, const P: usize, const C: usize> Default
    for IdentifierSlot<T, W, P, C>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real, const W: usize, const P: usize, const C: usize> IdentifierSlot<T, W, P, C> {
    /// An empty slot. `const`, all zero bytes.
    pub const fn new() -> Self {
        Self {
            configured: false,
            identifier: Identifier::zeroed(),
        }
    }

    /// Configures the identifier in place: the first time, or anew (as
    /// [`Identifier::reconfigure`]). Afterwards it is what `Identifier::new(config)` builds,
    /// bit for bit. On an error (the configuration is checked first) the slot is left as it
    /// was, configured or not.
    pub fn configure(
        &mut self,
        config: Config,
    ) -> Result<&mut Identifier<T, W, P, C>, crate::ConfigError> {
        self.identifier.reconfigure(config)?;
        self.configured = true;
        Ok(&mut self.identifier)
    }

    /// The identifier, once configured.
    pub fn get(&self) -> Option<&Identifier<T, W, P, C>> {
        self.configured.then_some(&self.identifier)
    }

    /// The identifier, once configured.
    pub fn get_mut(&mut self) -> Option<&mut Identifier<T, W, P, C>> {
        self.configured.then_some(&mut self.identifier)
    }
}

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// Builds an identifier, checking the configuration once (against `W`, `P` and `C`).
    ///
    /// The value is built on the stack and moved (about 9 KB with f32, W = 256, P = 16); a
    /// device that keeps its identifier in a static configures it there instead, with an
    /// [`IdentifierSlot`]. Both give the same identifier, bit for bit.
    pub fn new(config: Config) -> Result<Self, crate::ConfigError> {
        let plan = Self::plan(config)?;
        let mut id = Self::zeroed();
        id.apply(&plan);
        Ok(id)
    }

    /// Configures this identifier anew, in place: afterwards it is exactly what
    /// `Identifier::new(config)` builds (every sample, row, factor and model forgotten),
    /// without a second identifier or the full derivative taps on the stack. On an error
    /// (the configuration is checked first) nothing changes.
    pub fn reconfigure(&mut self, config: Config) -> Result<(), crate::ConfigError> {
        let plan = Self::plan(config)?;
        self.apply(&plan);
        Ok(())
    }

    /// Everything about `config` that can fail: it is checked (against `W`, `P` and `C`),
    /// its library built and its taps designed (the small part: the rest is per sample).
    fn plan(config: Config) -> Result<Plan<T, P>, crate::ConfigError> {
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
    const fn zeroed() -> Self {
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
    fn apply(&mut self, plan: &Plan<T, P>) {
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

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The library.
    pub fn library(&self) -> &Library<P> {
        &self.library
    }

    /// What happened to the samples so far.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The latest model, once a screening has run.
    pub fn model(&self) -> Option<&Model<T, P>> {
        self.model.as_ref()
    }

    /// Samples in the derivative window (fill level of the ring buffer).
    pub fn buffered(&self) -> usize {
        self.rings[0].len().min(self.config.window)
    }

    /// Samples between a sample arriving and its regression row (the fixed lag).
    pub fn lag_samples(&self) -> usize {
        let smoothing = if self.config.smoothing {
            KnnSmoother::<T>::LAG * usize::from(self.config.row_stride)
        } else {
            0
        };
        (self.config.window - 1) / 2 + smoothing
    }

    /// Feeds one sample. Returns `Ok(true)` when a screening just ran (a new model is in
    /// [`Identifier::model`]), `Ok(false)` otherwise, and `Err` (counted) for a sample that
    /// was not fed in.
    pub fn push(&mut self, sample: Sample<T>) -> Result<bool, Rejection> {
        if let Err(r) = self.check(&sample) {
            match r {
                Rejection::NonFinite => self.counters.non_finite += 1,
                Rejection::OutOfRange => self.counters.out_of_range += 1,
                Rejection::OutOfOrder => self.counters.out_of_order += 1,
                Rejection::Channels => self.counters.channels += 1,
            }
            return Err(r);
        }
        if let Some(last) = self.last_t
            && sample.t - last > self.gap_after
        {
            self.restart();
            self.counters.gaps += 1;
        }
        self.last_t = Some(sample.t);
        self.counters.accepted += 1;
        // `check` made sure that v and u come exactly when configured, so they have rings.
        self.rings[0].write(sample.x);
        if let Some(v) = sample.v {
            self.rings[V_RING].write(v);
        }
        if let Some(u) = sample.u {
            self.rings[self.u_ring].write(u);
        }
        if self.rings[0].len() >= self.config.window {
            self.since_row += 1;
            if self.since_row >= self.config.row_stride {
                self.since_row = 0;
                self.row(sample.t);
            }
        }
        self.since_screen += 1;
        if self.since_screen >= self.config.screening_period {
            self.since_screen = 0;
            let before = self.counters.screenings;
            let screened = self.screen();
            // The periodic screening also re-chooses K from ε(K) (the paper's Fig. 4); a
            // screening on request does not, so asking for a model changes nothing after it.
            if self.counters.screenings != before {
                self.adapt_smoothing();
            }
            return Ok(screened);
        }
        Ok(false)
    }

    fn check(&self, s: &Sample<T>) -> Result<(), Rejection> {
        let channels = self.config.channels;
        if s.v.is_some() != channels.velocity || s.u.is_some() != channels.input {
            return Err(Rejection::Channels);
        }
        let values = [Some(s.x), s.v, s.u];
        if !s.t.is_finite() || values.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Rejection::NonFinite);
        }
        let limit = self.config.max_abs;
        // Compared in T first (soft f64 is dear on the M4F); only a value within 10⁻⁶ of the
        // limit is compared exactly.
        let sure = self.max_abs_sure;
        if values
            .iter()
            .flatten()
            .any(|v| !(v.abs() < sure) && v.abs().to_f64() > limit)
        {
            return Err(Rejection::OutOfRange);
        }
        if let Some(last) = self.last_t
            && s.t - last < self.too_early
        {
            return Err(Rejection::OutOfOrder);
        }
        Ok(())
    }

    /// Forgets the window (after a gap): the factors and statistics are kept.
    /// Re-chooses K per channel from ε(K), and decides whether the smoothing is applied.
    ///
    /// What the smoothing removes is second order: noise in a regressor biases its
    /// coefficient by about σ²‖h‖²/E[ŝ²] (attenuation), where σ²‖h‖² is the noise the local
    /// polynomial leaves on the channel. What it adds is first order: rebuilding a point from
    /// its neighbours bends the signal by about √ε(K)/√E[ŝ²] (ε(K), the leave-one-out error,
    /// bounds that bias from above), and the regression averages noise away but not bias; a
    /// 0.3 % bend of x is amplified many times where the linear and cubic forces nearly
    /// cancel (a double well). So a channel is smoothed only where
    /// σ²‖h‖² > √(ε(K)·E[ŝ²]).
    fn adapt_smoothing(&mut self) {
        let keep = T::from_f64(0.5);
        if let Some((x2, v2)) = self.raw_noise() {
            let n = self.d4.2;
            let noise_x = x2 * self.gains.0;
            let noise_v = v2 * self.gains.1;
            let decide = |s: &KnnSmoother<T>, noise: T, power: T| {
                s.mean_error(s.k())
                    .is_some_and(|e| noise > (e * power / n).sqrt())
            };
            self.smoothing_on = (
                decide(&self.smooth_x, noise_x, self.power.0),
                decide(&self.smooth_v, noise_v, self.power.1),
            );
        }
        self.smooth_x.choose_k(keep);
        self.smooth_v.choose_k(keep);
    }

    /// The white-noise variances of the raw channels that x̂ and v̂ are made from (x, and the
    /// measured v or x again), from the fourth differences so far; `None` before any row.
    fn raw_noise(&self) -> Option<(T, T)> {
        let (sx, sv, n) = self.d4;
        if n <= T::ZERO {
            return None;
        }
        let sigma2 = |sum: T| sum / (T::from_f64(crate::tuning::FOURTH_DIFFERENCE_GAIN) * n);
        let x2 = sigma2(sx);
        let v2 = if self.config.channels.velocity {
            sigma2(sv)
        } else {
            x2
        };
        Some((x2, v2))
    }

    /// Whether the k-neighbour smoothing is applied to (x̂, v̂) now.
    pub fn smoothing_applied(&self) -> (bool, bool) {
        if self.config.smoothing {
            self.smoothing_on
        } else {
            (false, false)
        }
    }

    fn restart(&mut self) {
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
    fn velocity_offset(&self) -> T {
        (self.dv_sum - T::from_f64(0.5) * self.dv_last) / self.dv_weight
    }

    /// Computes the regression row whose centre lies half a window behind `t_newest`.
    fn row(&mut self, t_newest: f64) {
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
    fn flush_warmup(&mut self) {
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
    fn set_scales(&mut self, warmup: &[Row<T>]) {
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

    fn fold(&mut self, r: &Row<T>) {
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
    fn half_weights(&self) -> (T, T) {
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
    fn prepare(&self, offset_v: T, c: T, halves: bool, w: &mut Work<T, P>) {
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
    fn row_noise(&self) -> eiv::RowNoise<T> {
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
        let n = self.library.len();
        let enough = T::from_usize(2 * n);
        let (wa, wb) = self.half_weights();
        if wa < enough || wb < enough {
            return false;
        }
        self.counters.screenings += 1;
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
    fn publish(&mut self, sweep: &screen::Sweep<T, P>, offset_x: T, offset_v: T) {
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
    fn sweep_at(
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

    /// With the origin at `c`: the equilibrium, nearest 0, of the model on `support` and the
    /// columns an x-shift of it needs. Returns the step to it, if Newton's method converges.
    fn refine_origin(&self, offset_v: T, c: T, support: u32, w: &mut Work<T, P>) -> Option<T> {
        self.prepare(offset_v, c, false, w);
        let closure = self.library.x_shift_closure(support);
        let mut xi = [T::ZERO; P];
        w.all.solve_in(closure, &mut xi, &mut w.m);
        let mut poly = [0.0f64; crate::library::MAX_POLY_ORDER as usize + 1];
        for (j, term) in self.library.terms().iter().enumerate() {
            let value = (xi[j] * self.y_scale / self.scales[j]).to_f64();
            match *term {
                Term::Constant => poly[0] = value,
                Term::Monomial { px, pv: 0 } => poly[usize::from(px)] = value,
                _ => {}
            }
        }
        let span = (self.x_max - self.x_min).to_f64().abs();
        let mut x = 0.0f64;
        for _ in 0..30 {
            let (mut p, mut dp) = (0.0, 0.0);
            for &coefficient in poly.iter().rev() {
                dp = dp * x + p;
                p = p * x + coefficient;
            }
            if dp == 0.0 || !dp.is_finite() {
                return None;
            }
            let step = p / dp;
            x -= step;
            if libm::fabs(x) > span {
                return None;
            }
            if libm::fabs(step) <= 1e-12 * span.max(1e-300) {
                break;
            }
        }
        Some(T::from_f64(x))
    }

    /// Drops from `support` (at x origin `c`), one at a time, the term whose removal costs
    /// least once the origin is moved to suit the smaller model ([`Self::best_origin`]), as
    /// long as the residual energy (A and B together) grows by at most `tolerance` of the
    /// full support's; returns the origin reached, or `None` if no term went.
    fn shed_by_shift(
        &self,
        offset_v: T,
        c: T,
        support: u32,
        tolerance: T,
        w: &mut Work<T, P>,
    ) -> Option<T> {
        self.prepare(offset_v, T::ZERO, false, w);
        let limit = self.origin_rss(c, support, w) * (T::ONE + tolerance);
        let (mut kept, mut at, mut moved) = (support, c, false);
        while kept.count_ones() > 1 {
            let mut best: Option<(T, u32, T)> = None;
            let mut rest = kept;
            while rest != 0 {
                let j = rest.trailing_zeros();
                rest &= rest - 1;
                let smaller = kept & !(1u32 << j);
                // Only a term that moving the origin of the others creates can go.
                if self.library.x_shift_closure(smaller) & (1u32 << j) == 0 {
                    continue;
                }
                let Some(origin) = self.best_origin(offset_v, at, smaller, w) else {
                    continue;
                };
                // `best_origin` left `w.all` at x's own origin.
                let rss = self.origin_rss(origin, smaller, w);
                if rss <= limit && best.is_none_or(|(r, _, _)| rss < r) {
                    best = Some((rss, smaller, origin));
                }
            }
            let Some((_, smaller, origin)) = best else {
                break;
            };
            kept = smaller;
            at = origin;
            moved = true;
        }
        moved.then_some(at)
    }

    /// Residual energy of A and B together, at x origin `at`, of the least-squares model on
    /// `support`; `w.all` holds the union at x's own origin, `w.a` is the scratch.
    fn origin_rss(&self, at: T, support: u32, w: &mut Work<T, P>) -> T {
        self.shift_into(at, T::ZERO, &mut w.m);
        w.a.copy_from(&w.all);
        w.a.transform(&w.m);
        let mut xi = [T::ZERO; P];
        w.a.solve_in(support, &mut xi, &mut w.m);
        w.a.error(&xi)
    }

    /// The origin near `c` at which the model on `support` fits best (least residual energy
    /// of A and B together), by golden-section search over ±5 % of the data's span. `None`
    /// when the support is closed under x-shifts (the residual does not depend on the origin).
    fn best_origin(&self, offset_v: T, c: T, support: u32, w: &mut Work<T, P>) -> Option<T> {
        if self.library.x_shift_closure(support) == support {
            return None;
        }
        let span = (self.x_max - self.x_min).abs();
        if !(span > T::ZERO) {
            return None;
        }
        self.prepare(offset_v, T::ZERO, false, w);
        let g = T::from_f64(0.618_033_988_749_894_8);
        let half = span * T::from_f64(0.05);
        let (mut lo, mut hi) = (c - half, c + half);
        let (mut p, mut q) = (hi - g * (hi - lo), lo + g * (hi - lo));
        let (mut fp, mut fq) = (
            self.origin_rss(p, support, w),
            self.origin_rss(q, support, w),
        );
        for _ in 0..golden_steps::<T>() {
            if fp < fq {
                hi = q;
                q = p;
                fq = fp;
                p = hi - g * (hi - lo);
                fp = self.origin_rss(p, support, w);
            } else {
                lo = p;
                p = q;
                fp = fq;
                q = lo + g * (hi - lo);
                fq = self.origin_rss(q, support, w);
            }
        }
        let best = (lo + hi) * T::from_f64(0.5);
        // At the edge of the bracket the minimum is elsewhere: no answer.
        if (best - (c - half)).abs() < span * T::from_f64(1e-3)
            || (c + half - best).abs() < span * T::from_f64(1e-3)
        {
            return None;
        }
        Some(best)
    }

    /// Writes the column map (scaled) that moves the origin of x and v by (cx, cv) into `b`:
    /// the new columns are θ(x − cx, v − cv) = M(−c) θ(x, v), B = diag(d) Mᵀ diag(d)⁻¹.
    /// Built in place (M, then transposed and scaled) so that no second matrix is needed.
    fn shift_into(&self, cx: T, cv: T, b: &mut [[T; P]; P]) {
        let n = self.library.len();
        self.library.shift_matrix(-cx, -cv, b);
        for k in 0..n {
            for j in 0..k {
                let t = b[k][j];
                b[k][j] = b[j][k];
                b[j][k] = t;
            }
        }
        for k in 0..n {
            for j in 0..n {
                // Scaled: B[k][j] = M[j][k] d_k / d_j (columns θ/d).
                b[k][j] = b[k][j] * self.scales[k] * self.inverse_scales[j];
            }
        }
    }

    /// Real roots of the dense model's unforced restoring force p(x) = Σ ξ_(a,0) x^a (v = 0,
    /// no excitation) within the data's range widened by half of it, nearest the middle first.
    fn equilibria(
        &self,
        all: &Factor<T, P>,
        work: &mut [[T; P]; P],
        out: &mut heapless::Vec<T, 7>,
    ) {
        let n = self.library.len();
        let full: u32 = if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
        let mut xi = [T::ZERO; P];
        all.solve_in(full, &mut xi, work);
        let mut poly = [0.0f64; crate::library::MAX_POLY_ORDER as usize + 1];
        let mut any = false;
        for (j, term) in self.library.terms().iter().enumerate() {
            let c = (xi[j] * self.y_scale / self.scales[j]).to_f64();
            match *term {
                Term::Constant => poly[0] = c,
                Term::Monomial { px, pv: 0 } => {
                    poly[usize::from(px)] = c;
                    any = true;
                }
                _ => {}
            }
        }
        if !any || self.x_max < self.x_min {
            return;
        }
        let (lo, hi) = (self.x_min.to_f64(), self.x_max.to_f64());
        let middle = 0.5 * (lo + hi);
        let (lo, hi) = (lo - 0.5 * (hi - lo), hi + 0.5 * (hi - lo));
        let p = |x: f64| poly.iter().rev().fold(0.0, |acc, &c| acc * x + c);
        const STEPS: usize = 256;
        let mut roots: heapless::Vec<f64, 16> = heapless::Vec::new();
        let mut x0 = lo;
        let mut p0 = p(x0);
        for i in 1..=STEPS {
            let x1 = lo + (hi - lo) * i as f64 / STEPS as f64;
            let p1 = p(x1);
            if p0 == 0.0 || p0 * p1 < 0.0 {
                let (mut a, mut b, mut pa) = (x0, x1, p0);
                for _ in 0..80 {
                    let m = 0.5 * (a + b);
                    let pm = p(m);
                    if pa * pm <= 0.0 {
                        b = m;
                    } else {
                        a = m;
                        pa = pm;
                    }
                }
                let _ = roots.push(0.5 * (a + b));
            }
            x0 = x1;
            p0 = p1;
        }
        // Nearest the middle of the data first.
        let r = roots.as_mut_slice();
        for i in 1..r.len() {
            let mut k = i;
            while k > 0 && libm::fabs(r[k - 1] - middle) > libm::fabs(r[k] - middle) {
                r.swap(k - 1, k);
                k -= 1;
            }
        }
        // One place is left for the selected model's equilibrium (see `screen`).
        for &root in roots.iter() {
            if out.len() + 1 >= out.capacity() || out.push(T::from_f64(root)).is_err() {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Channels, ConfigError, LibraryConfig, PolyFamily};

    /// x and a measured v; x and a measured u.
    const XV: Channels = Channels {
        velocity: true,
        input: false,
    };
    const XU: Channels = Channels {
        velocity: false,
        input: true,
    };

    /// A forced Duffing oscillator x'' = −400x − 2x' − 4·10⁴x³ + u, u = 60 cos(15t), by RK4
    /// (10 steps a sample of 1 ms): `n` samples of (t, x, v, u).
    fn duffing(n: usize) -> Vec<(f64, f64, f64, f64)> {
        let dt = 1e-3;
        let u = |t: f64| 60.0 * (15.0 * t).cos();
        let f = |t: f64, x: f64, v: f64| -400.0 * x - 2.0 * v - 4.0e4 * x * x * x + u(t);
        let (mut x, mut v) = (0.01, 0.0);
        let h = dt / 10.0;
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let t0 = i as f64 * dt;
            out.push((t0, x, v, u(t0)));
            for j in 0..10 {
                let t = t0 + j as f64 * h;
                let (k1x, k1v) = (v, f(t, x, v));
                let (k2x, k2v) = (
                    v + 0.5 * h * k1v,
                    f(t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v),
                );
                let (k3x, k3v) = (
                    v + 0.5 * h * k2v,
                    f(t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v),
                );
                let (k4x, k4v) = (v + h * k3v, f(t + h, x + h * k3x, v + h * k3v));
                x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
                v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            }
        }
        out
    }

    fn config(channels: Channels) -> Config {
        Config {
            sample_period: 1e-3,
            window: 63,
            library: LibraryConfig {
                poly_order: 3,
                family: PolyFamily::All,
                constant: true,
                harmonics: if channels.input { 0 } else { 1 },
                input: channels.input,
            },
            omega: 15.0,
            channels,
            screening_period: 5_000,
            ..Config::default()
        }
    }

    /// Everything a model says, floats as bits.
    fn bits<const P: usize>(m: &Model<f32, P>) -> Vec<u64> {
        let mut out: Vec<u64> = m
            .coefficients
            .iter()
            .map(|c| u64::from(c.to_bits()))
            .collect();
        for s in m.solutions.iter() {
            out.extend([
                u64::from(s.threshold.to_bits()),
                u64::from(s.mean_error.to_bits()),
                u64::from(s.support),
            ]);
        }
        out.extend([
            m.terms.len() as u64,
            m.selected as u64,
            u64::from(m.k.0),
            u64::from(m.k.1),
            u64::from(m.offset_x.to_bits()),
            u64::from(m.offset_v.to_bits()),
            m.samples,
            m.rejected,
            m.rows,
        ]);
        out
    }

    /// Every model of the recording (each scheduled screening's, then one on request).
    fn models<const C: usize>(channels: Channels, n: usize) -> Vec<Vec<u64>> {
        let Ok(mut id) = Identifier::<f32, 128, 16, C>::new(config(channels)) else {
            panic!("the configuration fits C = {C}");
        };
        models_of(&mut id, channels, n)
    }

    /// Every model `id` gives on the recording.
    fn models_of<const C: usize>(
        id: &mut Identifier<f32, 128, 16, C>,
        channels: Channels,
        n: usize,
    ) -> Vec<Vec<u64>> {
        let mut out = Vec::new();
        for (t, x, v, u) in duffing(n) {
            let sample = Sample {
                t,
                x: x as f32,
                v: channels.velocity.then_some(v as f32),
                u: channels.input.then_some(u as f32),
            };
            if id.push(sample) == Ok(true) {
                out.push(bits(id.model().expect("a screening made it")));
            }
        }
        assert!(id.screen());
        out.push(bits(id.model().expect("a model")));
        out
    }

    /// Test-function rows (`Config::test_rows`): the Duffing oscillator from x and u, with
    /// a row every sample summed over a third of the period, comes out within 1 %; and an
    /// identifier switched between sums and rows as they are (the block factor and the sums
    /// share their memory) gives the models of a new one, bit for bit, both ways.
    #[test]
    fn test_function_rows_identify_and_switch_cleanly() {
        let sums = |channels| Config {
            window: 9,
            derivative_degree: 5,
            row_stride: 1,
            test_rows: 140,
            ..config(channels)
        };
        let Ok(mut id) = Identifier::<f32, 128, 16, 3>::new(sums(XU)) else {
            panic!("valid");
        };
        let with_sums = models_of(&mut id, XU, 12_000);
        let model = id.model().expect("a model");
        for (term, truth) in [
            (Term::Monomial { px: 1, pv: 0 }, -400.0),
            (Term::Monomial { px: 0, pv: 1 }, -2.0),
            (Term::Monomial { px: 3, pv: 0 }, -4.0e4),
            (Term::Input, 1.0),
        ] {
            let c = f64::from(model.coefficient(term).unwrap_or(0.0));
            assert!(
                (c / truth - 1.0).abs() < 0.01,
                "{term:?}: {c} against {truth}"
            );
        }
        // Sums, then rows as they are, in place: the models of a new identifier.
        assert!(id.reconfigure(config(XV)).is_ok());
        assert_eq!(models_of(&mut id, XV, 12_000), models::<3>(XV, 12_000));
        // And back.
        assert!(id.reconfigure(sums(XU)).is_ok());
        assert_eq!(models_of(&mut id, XU, 12_000), with_sums);
    }

    #[test]
    fn configured_in_place_gives_the_models_of_new_bit_for_bit() {
        let reference = models::<3>(XV, 12_000);
        // A slot, configured first for something else (x and u, a shorter window, no
        // harmonics, forgetting) and run, then configured again in place.
        let mut slot: Box<IdentifierSlot<f32, 128, 16, 3>> = Box::default();
        assert!(slot.get().is_none());
        let other = Config {
            window: 41,
            memory: Some(2.0),
            ..config(XU)
        };
        let Ok(id) = slot.configure(other) else {
            panic!("the other configuration is valid");
        };
        assert_eq!(models_of(id, XU, 11_000).len(), 3);
        // A refused configuration changes nothing: the slot keeps its identifier and state.
        let counters = *id.counters();
        let bad = Config {
            window: 129,
            ..config(XV)
        };
        assert!(slot.configure(bad).is_err());
        let Some(id) = slot.get_mut() else {
            panic!("still configured");
        };
        assert_eq!((*id.config(), *id.counters()), (other, counters));
        let Ok(id) = slot.configure(config(XV)) else {
            panic!("valid");
        };
        assert!(id.model().is_none());
        assert_eq!(id.counters(), &Counters::default());
        assert_eq!(models_of(id, XV, 12_000), reference);
        // `reconfigure` on a used identifier, and `new` on top of the same path.
        let Ok(mut id) = Identifier::<f32, 128, 16, 3>::new(other) else {
            panic!("valid");
        };
        let _ = models_of(&mut id, XU, 7_000);
        assert!(id.reconfigure(bad).is_err());
        assert_eq!(id.config(), &other);
        assert!(id.reconfigure(config(XV)).is_ok());
        assert_eq!(models_of(&mut id, XV, 12_000), reference);
    }

    #[test]
    fn an_empty_slot_is_not_configured() {
        let mut slot: Box<IdentifierSlot<f64, 64, 8, 1>> = Box::default();
        assert!(slot.get().is_none() && slot.get_mut().is_none());
        let bad = Config {
            window: 65,
            ..Config::default()
        };
        assert!(slot.configure(bad).is_err());
        assert!(slot.get().is_none());
    }

    #[test]
    fn more_channels_than_rings_are_refused() {
        let all = Channels {
            velocity: true,
            input: true,
        };
        let expected = ConfigError::Channels {
            channels: 3,
            capacity: 2,
        };
        assert_eq!(config(all).validate::<128, 16, 2>(), Err(expected));
        assert_eq!(
            Identifier::<f32, 128, 16, 2>::new(config(all)).err(),
            Some(expected)
        );
        assert_eq!(
            expected.to_string(),
            "the samples carry 3 channels (x, and v and u when measured), but this identifier \
             was built with ring buffers for 2"
        );
        assert!(Identifier::<f32, 128, 16, 3>::new(config(all)).is_ok());
        assert!(Identifier::<f32, 128, 16, 2>::new(config(XV)).is_ok());
        assert_eq!(
            Identifier::<f32, 128, 16, 1>::new(config(XV)).err(),
            Some(ConfigError::Channels {
                channels: 2,
                capacity: 1
            })
        );
        assert!(Identifier::<f32, 128, 16, 1>::new(config(Channels::default())).is_ok());
    }

    #[test]
    fn two_rings_give_the_models_of_three_bit_for_bit() {
        for channels in [XV, XU] {
            let three = models::<3>(channels, 20_000);
            assert_eq!(three.len(), 5, "{channels:?}");
            assert_eq!(models::<2>(channels, 20_000), three, "{channels:?}");
        }
        let x = Channels::default();
        assert_eq!(models::<1>(x, 12_000), models::<3>(x, 12_000));
    }
}
