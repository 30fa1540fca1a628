//! The streaming identifier: one sample in, now and then a model out.
//!
//! A sample's way through it (docs/design.md): ring buffer → fixed-lag local polynomial estimates
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

pub use snapshot::Snapshot;

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
#[derive(Clone)]
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
#[derive(Clone)]
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
        self.push_with(sample, Self::select)
    }

    /// Feeds one sample like [`Identifier::push`], but at a scheduled screening hands the
    /// identifier to `screening` instead of screening in place, and returns what it returns.
    ///
    /// `push` passes [`Identifier::select`]. A device that must not stall passes a closure
    /// that copies the state into a [`Snapshot`] ([`Identifier::snapshot_into`]) and returns
    /// `false`; the snapshot's `select` then runs at a lower priority while samples go on
    /// and gives, bit for bit, the model `push` would have made here: the rows never read
    /// the model, and the only state a screening changes besides it, the smoothing's K
    /// (re-chosen after every scheduled screening), is re-chosen here, after `screening`
    /// returns, in both cases. `screening` is called only when a screening can run (enough
    /// rows in both halves), with the screening already counted.
    pub fn push_with(
        &mut self,
        sample: Sample<T>,
        screening: impl FnOnce(&mut Self) -> bool,
    ) -> Result<bool, Rejection> {
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
            if !self.can_screen() {
                return Ok(false);
            }
            self.counters.screenings += 1;
            let screened = screening(self);
            // The periodic screening also re-chooses K from ε(K) (the paper's Fig. 4); a
            // screening on request does not, so asking for a model changes nothing after it.
            self.adapt_smoothing();
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
}

mod origin;
mod plan;
mod rows;
mod screening;
mod snapshot;
#[cfg(test)]
mod tests;
