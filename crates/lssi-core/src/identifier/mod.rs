//! The streaming identifier: one sample in, now and then a model out.
//!
//! [`Identifier`] is a composition of stages, each a type in its own module with its own
//! tests, called in the order a sample's data flows (`push`, then `rows.rs`):
//! `intake` (checks, gaps, schedule) → `front` (ring buffers, fixed-lag local-polynomial
//! estimates of x, x', x'') → `offset` (velocity offset) and `noise` (fourth differences) →
//! `smooth` (k-neighbour smoothing, delay line) → `gate` (excitation) → `phasor` (sin/cos Ωt)
//! → `columns` (library row θ(x, x', t [, u]) scaled to unit size) → `halves` (warm-up, then
//! square-root RLS into one of the two held-out factors A and B; with `Config::test_rows`,
//! sums of rows under a smooth test function, the weak form) → every `screening_period`
//! samples, `screening`: sensor offsets (`origin`), threshold sweep, MES → [`Model`].
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

use crate::config::Config;
use crate::derivative::Design;
#[cfg(feature = "noise-correction")]
use crate::eiv;
use crate::factor::{Factor, FactorPair};
use crate::library::{Library, Term};
use crate::model::Model;
use crate::real::Real;
use crate::screen;
use crate::smoothing::KnnSmoother;

use columns::{Columns, Scratch};
use front::Front;
use gate::Gate;
use halves::Halves;
pub use intake::{Counters, Rejection, Sample};
use intake::{Intake, Schedule};
use noise::ChannelNoise;
use offset::VelocityOffset;
use origin::Extent;
use phasor::Phasor;
use smooth::Smoothing;
pub use snapshot::Snapshot;

/// Regression rows kept before the column scales are known.
const WARMUP_ROWS: usize = 64;

/// Relative difference of held-out error under which two equally sparse models found at
/// different x origins count as a tie (decided by the origin nearer the recording's zero).
/// Measured on eq. 17: a true sensor offset lowers the error by 3 % or more at δ ≤ 0.01; a
/// spurious origin at δ = 0.1 with x only differs by under 0.5 %.
const ORIGIN_TIE: f64 = 0.01;

/// Golden-section steps of the origin search (each one transform and one solve), by
/// precision. Near its minimum the residual energy is flat to second order, so an origin is
/// resolved only to about √ε of the bracket: 0.618ⁿ ≤ √ε needs n ≥ 17 in f32 and 38 in f64.
/// Steps beyond that only chase rounding; in f32 they were a third of a screening.
fn golden_steps<T: Real>() -> usize {
    if T::EPSILON.to_f64() > 1e-10 { 20 } else { 40 }
}

/// The screening's working factors: A and B (with the block in progress), their union, and
/// one column map. One set, filled anew for each origin tried (see `Identifier::prepare`).
struct Work<T, const P: usize> {
    /// A and B, two triangles in about one square.
    ab: FactorPair<T, P>,
    all: Factor<T, P>,
    m: [[T; P]; P],
}

impl<T: Real, const P: usize> Work<T, P> {
    /// All zeros: a constant, which the compiler writes in place.
    const EMPTY: Self = Self {
        ab: FactorPair::new(0),
        all: Factor::new(0),
        m: [[T::ZERO; P]; P],
    };

    fn new(n: usize) -> Self {
        // Zeros first, then the columns: built in place, where a `new(n)` inside the literal
        // would be built on the stack and copied (another 1.2 KB in the screening's frame).
        let mut w = Self::EMPTY;
        w.ab.set_columns(n);
        w.all.set_columns(n);
        w
    }
}

/// A configuration that passed every check, with what configuring needs from it that could
/// fail: its library and the design of its taps.
struct Plan<T, const P: usize> {
    config: Config,
    library: Library<P>,
    design: Design<T>,
}

/// Sparser supports tried with their own best origin, one after another (each must remove
/// a term).
const SPARSER_STEPS: usize = 2;

/// A regression row before the library: the (smoothed) state, x'', u and the row's time.
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
    /// The checks a sample passes, and the time of the last one.
    intake: Intake<T>,
    /// When rows and screenings are due.
    schedule: Schedule,
    /// Ring buffers and derivative taps: x̂, v̂, ŷ, û.
    front: Front<T, W, C>,
    /// The raw channels' noise (fourth differences) and the filters' gains.
    noise: ChannelNoise<T>,
    /// k-neighbour smoothing of x̂ and v̂, and the delay line: the regression rows.
    smoothing: Smoothing<T>,
    /// mean(v̂ − dx̂/dt), when v is measured.
    offset: VelocityOffset<T>,
    /// The excitation gate.
    gate: Gate<T>,
    /// The range of x̂ over the rows (where the origin search looks).
    extent: Extent<T>,
    /// (sin Ωt, cos Ωt) of the row.
    phasor: Phasor<T>,
    /// The column scales of the library row.
    columns: Columns<T, P>,
    /// The library row's tables and the row itself, kept from row to row (not zeroed for
    /// every row; never part of the identifier's state).
    scratch: Scratch<T, P>,
    /// The warm-up, then the held-out halves A and B (square-root factors).
    halves: Halves<T, P>,
    counters: Counters,
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
        self.front.len().min(self.config.window)
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
        let since = match self.intake.check(&sample, &self.config) {
            Ok(since) => since,
            Err(r) => {
                self.counters.reject(r);
                return Err(r);
            }
        };
        if self.intake.accept(sample.t, since) {
            self.restart();
            self.counters.gaps += 1;
        }
        self.counters.accepted += 1;
        self.front.write(&sample);
        if self.front.len() >= self.config.window && self.schedule.row_due(self.config.row_stride) {
            self.row(sample.t);
        }
        if !self.schedule.screening_due(self.config.screening_period) || !self.can_screen() {
            return Ok(false);
        }
        self.counters.screenings += 1;
        let screened = screening(self);
        // The periodic screening also re-chooses K from ε(K) (the paper's Fig. 4); a
        // screening on request does not, so asking for a model changes nothing after it.
        self.smoothing
            .adapt(self.noise.levels(self.config.channels.velocity));
        Ok(screened)
    }

    /// Whether the k-neighbour smoothing is applied to (x̂, v̂) now.
    pub fn smoothing_applied(&self) -> (bool, bool) {
        self.smoothing.applied(self.config.smoothing)
    }
}

mod columns;
mod front;
mod gate;
mod halves;
mod intake;
mod noise;
mod offset;
mod origin;
mod phasor;
mod plan;
mod rows;
mod screening;
mod smooth;
mod snapshot;
pub mod system;
#[cfg(test)]
mod tests;
