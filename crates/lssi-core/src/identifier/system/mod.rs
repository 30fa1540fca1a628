//! The streaming identifier of a system of equations: a harvester's mechanical equation and
//! its electrical ones, from the channels a lab records.
//!
//! A recording's channels are states. The displacement x (with its velocity v = x',
//! measured or differentiated) gets a second-order equation x'' = f, each electrical
//! channel (the voltage V across the load, or the current i) a first-order one, V' = f.
//! Every equation is sparse over one shared library of the states
//! ([`StateLibrary`]: 1, x, v, V, x², x·V, v·V, …, sin/cos kΩt, u) and is selected on its
//! own (its own threshold sweep and held-out MES, the `screen` module's, unchanged). A
//! piezoelectric harvester's standard form comes out as
//!
//! ```text
//! x'' = a x + b x³ + c v + χ V + F cos Ωt      V' = −λ V − κ v
//! ```
//!
//! # Design: several right-hand sides over one square-root factor
//!
//! The equations share the row θ(states, t, u); only their targets (x̂'', V̂', …) differ. So
//! the rows go into one square-root factor R with one z and ρ² per equation
//! ([`MultiFactor`]): the Givens rotations are made once per row and applied to R once,
//! each target costs a rotation of its z. A rotation application is 7 flops, a Givens
//! about 10 and a square root, so a row with n columns and E equations costs
//! 7·n(n − 1)/2 + 7·E·n + 10·n flops, against E·(7·n(n − 1)/2 + 17·n) for one factor per
//! equation: with n = 16 and E = 2, 1 224 flops instead of 2 224 (−45 %; measured on the
//! host in f32, 630–710 ns a row instead of 1 510–1 530, `cost_on_the_host`). Memory: the
//! held-out halves A and B and the block in progress are three such factors,
//! P² + E·P + E + 1 numbers each instead of E·(P² + P + 2) (1 184 bytes instead of 2 208
//! with f32, P = 16, E = 2). At a screening each equation's (R, z_k, ρ²_k) is copied out
//! into an ordinary [`Factor`] (the factor its own single-target regression would have
//! built, to rounding) and swept and selected as one equation is; the screening's stack
//! holds three such factors, one P × P scratch matrix and a sweep (about 5 KB with f32,
//! P = 16).
//!
//! # The front end and the cost of a sample
//!
//! One ring buffer of `W` samples per channel and the one set of folded Savitzky–Golay taps
//! of the single-equation path ([`FoldedTaps`]): x̂, x̂' and x̂'' from x (or v̂ and v̂' from a
//! measured v), and V̂ and V̂' from V with the value and first-derivative taps, so that every
//! state and target lags the newest sample by the same half window. Each estimate costs
//! ⌈N/2⌉ multiply-adds. With test-function rows (`Config::test_rows`, the weak form of the
//! single-equation path, one sum of rows and of each target) a row is made at
//! every sample: with x, V and u, N = 21 and 16 terms, about 130 flops of taps, 70 of
//! library row and 150 of sums a sample, plus one row into A or B every L/4 samples (with
//! L = 340, 15 flops a sample): about 370 flops a sample. With rows as they are, every
//! fourth sample, N = 127: 770 flops of taps, 70 of library, 1 224 of factor and 80 of
//! block merges a row, about 540 a sample. Measured on the host in f32 with one screening:
//! 380–550 ns a sample for either (the single-equation identifier on x and u with the same
//! settings: 280–300 ns).
//!
//! Memory: `SystemIdentifier<f32, 256, 16, 2, 2>` (x and V, 16 terms, two equations) is
//! 9 856 bytes on the host (`memory_of_the_two_equation_identifier`; the single-equation
//! `Identifier<f32, 256, 16, 2>`: 8 784): taps 2 KB, two rings 2 KB, the warm-up rows or
//! the halves A and B 2.5 KB, the block 1.2 KB, the sums 0.3 KB, the model 1.1 KB.
//!
//! What the single-equation path has and this one has not (yet): the k-neighbour smoothing
//! of the states (`Config::smoothing` is ignored), the search of the sensor origins
//! (`Config::offsets` is ignored: a constant term takes a static offset, but a misplaced
//! origin of x shows as even powers), the excitation gate, the noise correction (refused).
//!
//! # Two displacements
//!
//! `SystemConfig::displacements` 2 (a two-degree-of-freedom harvester: a primary mass x1 and
//! a secondary beam x2 on it) adds the rings of x2 (and v2), the states x2, v2 and the
//! equation x2'' (second in the model, after x1'', before the electrical ones). The shared
//! library is then linear in every state, with each displacement's own powers x1^k, x2^k up
//! to `poly_order` (all the monomials of four states would make order 3 34 terms): with
//! order 3, the constant, one V, one harmonic and u, 13 terms, so `SystemIdentifier<f32,
//! 256, 16, 3, 3>` holds x1, x2, V (its size: `memory_of_the_two_displacement_identifier`).
//!
//! # What the data must hold
//!
//! V is v through a first-order lag: under one forcing tone in steady state it is, at that
//! frequency, a combination of x and v, and so is cos Ωt. Only the harmonics a
//! nonlinearity adds then tell χ·V from the stiffness, damping and forcing terms of x''
//! (the V' equation, whose target is V' itself, comes out regardless). A record with a
//! broadband excitation (a measured base acceleration u, a sweep, chaos) or transients
//! identifies both equations; one with a single tone may give x'' without its χ·V.
//!
//! ```
//! use lssi_core::identifier::system::{SystemConfig, SystemIdentifier, SystemSample, Target};
//! use lssi_core::library::{Electrical, StateTerm};
//! use lssi_core::Config;
//! let config = SystemConfig {
//!     base: Config { sample_period: 0.02, window: 63, omega: 1.0, screening_period: 50_000,
//!                    ..Config::default() },
//!     electrical: [Some(Electrical::Voltage), None],
//!     coupling_order: 1,
//!     displacements: 1,
//! };
//! let mut id: Box<SystemIdentifier<f64, 64, 16>> = Box::new(SystemIdentifier::new(config).unwrap());
//! // x'' = -x - 0.1 v + 0.2 V + cos t, V' = -V - 0.5 v, by semi-implicit Euler.
//! let (mut x, mut v, mut e, dt) = (0.0f64, 0.0f64, 0.0f64, 0.001f64);
//! for i in 0..1_000_000u32 {
//!     let t = f64::from(i) * dt;
//!     if i % 20 == 0 {
//!         id.push(&SystemSample { t, x, x2: None, v: None, v2: None, u: None, electrical: &[e] }).unwrap();
//!     }
//!     v += dt * (-x - 0.1 * v + 0.2 * e + t.cos());
//!     x += dt * v;
//!     e += dt * (-e - 0.5 * v);
//! }
//! id.screen();
//! let model = id.model().unwrap();
//! let kappa = model.coefficient(Target::Rate(Electrical::Voltage), StateTerm::Monomial([0, 1, 0, 0, 0, 0]));
//! assert!((kappa.unwrap() + 0.5).abs() < 0.01, "{kappa:?}");
//! ```

use super::intake::{Counters, Rejection, Schedule, below};
use super::phasor::Phasor;
use crate::config::{Config, ConfigError};
use crate::derivative::{Design, FoldedTaps};
use crate::factor::{Factor, FactorPair, MultiFactor};
use crate::library::{
    Electrical, MAX_ELECTRICAL, STATES, StateLibrary, StateLibraryConfig, StateLibraryError,
};
use crate::real::Real;
use crate::screen;
use core::fmt;
use heapless::HistoryBuf;

mod model;
mod weak;
pub use model::{Equation, SystemModel, Target, TargetName};
use weak::SystemTestRows;

/// Test-function sums per block of A or B (as the single-equation path's).
const TEST_BLOCK: u64 = super::halves::TEST_BLOCK;

/// Regression rows kept before the column scales are known (as the single-equation path).
const WARMUP_ROWS: usize = super::WARMUP_ROWS;

/// A system's configuration: the single-equation one for what they share, and the
/// electrical channels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SystemConfig {
    /// Sample period, derivative window and degree, Ω, the measured v and u
    /// (`channels`), memory, screening period, thresholds, row stride, parsimony, max_abs;
    /// `library` is the mechanical part of the shared library. `smoothing` and `offsets`
    /// do not apply; `test_rows` must be 0 and `noise_correction` off.
    pub base: Config,
    /// The electrical channels a sample carries, in its order: `Some` first, each kind once.
    pub electrical: [Option<Electrical>; MAX_ELECTRICAL],
    /// The highest total degree of a coupling term (1: V; 2: also x·V, v·V, V²).
    pub coupling_order: u8,
    /// Displacements: 1 (x, one second-order equation) or 2 (x1 and x2 of a
    /// two-degree-of-freedom harvester, an equation each; a sample then carries
    /// [`SystemSample::x2`], and [`SystemSample::v2`] when velocities are measured).
    pub displacements: u8,
}

impl SystemConfig {
    /// The shared library's configuration.
    pub fn library(&self) -> StateLibraryConfig {
        StateLibraryConfig {
            mechanical: self.base.library,
            electrical: self.electrical,
            coupling_order: self.coupling_order,
            displacements: self.displacements,
        }
    }

    /// Equations: one per displacement and one per electrical channel.
    pub fn equations(&self) -> usize {
        usize::from(self.displacements) + self.library().electrical_count()
    }

    /// Ring buffers the samples need: x, v and u when measured, the electrical channels,
    /// x2 and v2 when there are two displacements.
    pub fn rings(&self) -> usize {
        let second = if self.displacements > 1 {
            1 + usize::from(self.base.channels.velocity)
        } else {
            0
        };
        self.base.channels.count() + self.library().electrical_count() + second
    }

    /// Checks every field against the capacities `W` (window), `P` (terms), `E` (equations)
    /// and `C` (ring buffers).
    pub fn validate<const W: usize, const P: usize, const E: usize, const C: usize>(
        &self,
    ) -> Result<(), SystemConfigError> {
        // The mechanical library alone may be larger than the shared one's capacity allows;
        // the shared one is checked below.
        let mut base = self.base;
        base.library.poly_order = base.library.poly_order.clamp(1, 9);
        match base.validate::<W, 32, 3>() {
            Ok(()) => {}
            Err(ConfigError::Library(_)) => {}
            Err(e) => return Err(SystemConfigError::Config(e)),
        }
        if self.base.noise_correction {
            return Err(SystemConfigError::NoiseCorrection);
        }
        StateLibrary::<P>::new(&self.library())?;
        if self.equations() > E {
            return Err(SystemConfigError::Equations {
                equations: self.equations(),
                capacity: E,
            });
        }
        if self.rings() > C {
            return Err(SystemConfigError::Config(ConfigError::Channels {
                channels: self.rings(),
                capacity: C,
            }));
        }
        Ok(())
    }
}

/// Why a system's configuration is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SystemConfigError {
    /// A field shared with the single-equation configuration is out of range.
    Config(ConfigError),
    /// The shared library cannot be built.
    Library(StateLibraryError),
    /// More equations than the identifier's capacity `E`.
    Equations {
        /// Equations the configuration has (displacements + electrical channels).
        equations: usize,
        /// Equations the identifier was built for.
        capacity: usize,
    },
    /// `noise_correction` is on (the system path has none).
    NoiseCorrection,
}

impl fmt::Display for SystemConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SystemConfigError::Config(e) => fmt::Display::fmt(e, f),
            SystemConfigError::Library(e) => fmt::Display::fmt(e, f),
            SystemConfigError::Equations {
                equations,
                capacity,
            } => write!(
                f,
                "the system has {equations} equations, but this identifier was built for {capacity}"
            ),
            SystemConfigError::NoiseCorrection => {
                f.write_str("noise_correction is not available for a system of equations")
            }
        }
    }
}

impl core::error::Error for SystemConfigError {}

impl From<StateLibraryError> for SystemConfigError {
    fn from(e: StateLibraryError) -> Self {
        SystemConfigError::Library(e)
    }
}

/// One measurement of a system's channels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SystemSample<'a, T> {
    /// Time, seconds.
    pub t: f64,
    /// Displacement (x1 of two).
    pub x: T,
    /// The second displacement, when the configuration has two (`displacements` 2).
    pub x2: Option<T>,
    /// The second displacement's measured velocity, when it has two and measures velocities.
    pub v2: Option<T>,
    /// Measured velocity, when the configuration says there is one.
    pub v: Option<T>,
    /// Measured excitation, when the configuration says there is one.
    pub u: Option<T>,
    /// The electrical channels, one value each, in the configuration's order.
    pub electrical: &'a [T],
}

/// A regression row before the library: the states at the row's time, the input, the
/// targets (x̂'', x̂2'' when there are two displacements, then each electrical channel's
/// derivative) and the time.
#[derive(Clone, Copy, Debug)]
struct Row<T, const E: usize> {
    states: [T; STATES],
    u: T,
    y: [T; E],
    t: f64,
}

/// The warm-up rows, then the halves A and B (one memory: they never coexist).
enum Store<T, const P: usize, const E: usize> {
    Warmup(heapless::Vec<Row<T, E>, WARMUP_ROWS>),
    Halves([MultiFactor<T, P, E>; 2]),
}

impl<T: Real, const P: usize, const E: usize> Clone for Store<T, P, E> {
    fn clone(&self) -> Self {
        match self {
            Store::Warmup(rows) => Store::Warmup(rows.clone()),
            Store::Halves(halves) => Store::Halves(halves.clone()),
        }
    }

    /// In place (a snapshot's copy, in a device's identify interrupt): the derived one
    /// builds the 2.5 KB copy on the stack first. Only a change of variant (once, at the
    /// end of the warm-up) writes a whole new value, an empty one.
    fn clone_from(&mut self, source: &Self) {
        match source {
            Store::Warmup(from) => {
                if !matches!(self, Store::Warmup(_)) {
                    *self = Store::Warmup(heapless::Vec::new());
                }
                if let Store::Warmup(rows) = self {
                    rows.clear();
                    // Same capacity: every row fits.
                    let _ = rows.extend_from_slice(from);
                }
            }
            Store::Halves([a, b]) => {
                if !matches!(self, Store::Halves(_)) {
                    self.become_halves(0, 0);
                }
                if let Store::Halves([to_a, to_b]) = self {
                    to_a.clone_from(a);
                    to_b.clone_from(b);
                }
            }
        }
    }
}

impl<T: Real, const P: usize, const E: usize> Store<T, P, E> {
    /// Empty halves over `n` columns and `targets` equations, written in place: a constant
    /// copied straight into `self` (a value built from `n` and `targets` was built on the
    /// stack first, 2.4 KB with f32, P = 16, E = 2), then the two counts set.
    #[inline(never)]
    fn become_halves(&mut self, n: usize, targets: usize) {
        *self = const { Store::Halves([MultiFactor::new(0, 0), MultiFactor::new(0, 0)]) };
        if let Store::Halves(halves) = self {
            for half in halves {
                half.reshape(n, targets);
            }
        }
    }
}

/// The streaming identifier of a system: `W` samples of window capacity, `P` terms of the
/// shared library, `E` equations (the mechanical one and up to `E − 1` electrical ones),
/// `C` ring buffers (x, v and u when measured, the electrical channels).
///
/// `SystemIdentifier<f32, 256, 16, 2, 2>` (x and V, 16 terms) takes 8.9 KiB; see
/// the module's documentation for the design and its cost.
pub struct SystemIdentifier<
    T: Real,
    const W: usize,
    const P: usize,
    const E: usize = 2,
    const C: usize = 2,
> {
    config: SystemConfig,
    library: StateLibrary<P>,
    taps: FoldedTaps<T, W>,
    rings: [HistoryBuf<T, W>; C],
    /// Where v, u, the first electrical channel, x2 and v2 are (each meaningful when present).
    v_ring: usize,
    u_ring: usize,
    e_ring: usize,
    x2_ring: usize,
    v2_ring: usize,
    electrical: usize,
    /// Displacements (1 or 2).
    displacements: usize,
    max_abs_sure: T,
    too_early: f64,
    gap_after: f64,
    last_t: Option<f64>,
    schedule: Schedule,
    phasor: Phasor<T>,
    /// 1 / the column scales, and the scales of the columns and targets.
    inverse_scales: [T; P],
    scales: [T; P],
    y_scales: [T; E],
    store: Store<T, P, E>,
    /// The rows as they are gather here, a block at a time (`test_rows` 0).
    block: MultiFactor<T, P, E>,
    /// The test-function sums (`test_rows` > 0), each straight into A or B.
    sums: SystemTestRows<T, P, E>,
    regression_rows: u64,
    block_len: u64,
    sqrt_lambda: T,
    sqrt_lambda_blocks: T,
    counters: Counters,
    /// The latest model, valid when `has_model` (not an `Option`: its `None` would be a
    /// non-zero niche byte, and an empty slot must be all zero bits to lie in `.bss`).
    model: SystemModel<T, P, E>,
    has_model: bool,
}

impl<T: Real, const W: usize, const P: usize, const E: usize, const C: usize>
    SystemIdentifier<T, W, P, E, C>
{
    /// Builds an identifier, checking the configuration once. The value is built on the
    /// stack and moved (9.6 KiB with f32, W = 256, P = 16, E = 2, C = 2); a device keeps
    /// its identifier in a [`SystemSlot`] instead.
    pub fn new(config: SystemConfig) -> Result<Self, SystemConfigError> {
        let mut id = Self::empty();
        id.reconfigure(config)?;
        Ok(id)
    }

    /// Storage, not a usable identifier: `const`, all zero bits but the empty enums' tags.
    const fn empty() -> Self {
        Self {
            config: SystemConfig {
                base: Config::zeroed(),
                electrical: [None; MAX_ELECTRICAL],
                coupling_order: 0,
                displacements: 0,
            },
            library: StateLibrary::zeroed(),
            taps: FoldedTaps::empty(),
            rings: [const { HistoryBuf::new() }; C],
            v_ring: 0,
            u_ring: 0,
            e_ring: 0,
            x2_ring: 0,
            v2_ring: 0,
            electrical: 0,
            displacements: 0,
            max_abs_sure: T::ZERO,
            too_early: 0.0,
            gap_after: 0.0,
            last_t: None,
            schedule: Schedule::zeroed(),
            phasor: Phasor::zeroed(),
            inverse_scales: [T::ZERO; P],
            scales: [T::ZERO; P],
            y_scales: [T::ZERO; E],
            store: Store::Warmup(heapless::Vec::new()),
            block: MultiFactor::new(0, 0),
            sums: SystemTestRows::zeroed(),
            regression_rows: 0,
            block_len: 0,
            sqrt_lambda: T::ZERO,
            sqrt_lambda_blocks: T::ZERO,
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
            model: SystemModel {
                terms: heapless::Vec::new(),
                electrical: [None; MAX_ELECTRICAL],
                displacements: 0,
                equations: heapless::Vec::new(),
                omega: 0.0,
                samples: 0,
                rejected: 0,
                rows: 0,
            },
            has_model: false,
        }
    }

    /// Configures this identifier anew, in place: afterwards it is what
    /// `SystemIdentifier::new(config)` builds (every sample, row, factor and model
    /// forgotten). On an error (the configuration is checked first) nothing changes.
    pub fn reconfigure(&mut self, config: SystemConfig) -> Result<(), SystemConfigError> {
        config.validate::<W, P, E, C>()?;
        let library = StateLibrary::new(&config.library())?;
        let c = &config.base;
        let design = Design::new(
            c.window,
            usize::from(c.derivative_degree),
            c.sample_period,
            W,
        )
        .map_err(|_| {
            SystemConfigError::Config(ConfigError::Window {
                window: c.window,
                min: usize::from(c.derivative_degree) + 3,
                max: W,
            })
        })?;
        self.taps.design(&design, |_| {});
        self.library = library;
        self.config = config;
        self.start();
        Ok(())
    }

    /// Forgets every sample, row, factor and model, keeping the configuration, its library
    /// and its designed taps: afterwards the identifier is, bit for bit, what
    /// [`SystemIdentifier::reconfigure`] with its own configuration makes, without designing
    /// the taps again (as `Identifier::forget`).
    pub fn forget(&mut self) {
        self.start();
    }

    /// Sets every field but the configuration, the library and the taps for the
    /// configuration: the state of a new identifier.
    fn start(&mut self) {
        let config = self.config;
        let c = &config.base;
        let n = self.library.len();
        let electrical = config.library().electrical_count();
        let displacements = usize::from(config.displacements);
        let equations = displacements + electrical;
        let stride = usize::from(c.row_stride);
        let row_period = c.sample_period * f64::from(c.row_stride);
        let lambda = c.memory.map_or(1.0, |tau| libm::exp(-row_period / tau));
        let sqrt_lambda_row = libm::sqrt(lambda);
        // The bump of sums of the same width is kept (the same bits as designed anew).
        self.sums = SystemTestRows::new_with(c.test_rows, self.sums.bump_for(c.test_rows));
        // λ and the blocks count in rows, or in sums (one every L/4 rows); A's content at a
        // merge of a block of rows is two blocks old, at the start of a block of sums one.
        let (block_len, sqrt_lambda, blocks_old) = if self.sums.on() {
            let quarter = f64::from(c.test_rows / 4);
            (
                TEST_BLOCK,
                power(sqrt_lambda_row, quarter),
                TEST_BLOCK as f64,
            )
        } else {
            let len = (2 * c.window / stride).max(16) as u64;
            (len, sqrt_lambda_row, 2.0 * len as f64)
        };
        for ring in self.rings.iter_mut() {
            ring.clear();
        }
        self.v_ring = 1;
        self.u_ring = self.v_ring + usize::from(c.channels.velocity);
        self.e_ring = self.u_ring + usize::from(c.channels.input);
        self.x2_ring = self.e_ring + electrical;
        self.v2_ring = self.x2_ring + 1;
        self.electrical = electrical;
        self.displacements = displacements;
        self.max_abs_sure = T::from_f64(c.max_abs * (1.0 - 1e-6));
        self.too_early = 0.5 * c.sample_period;
        self.gap_after = 1.5 * c.sample_period;
        self.last_t = None;
        self.schedule = Schedule::new(c);
        self.phasor = Phasor::new(c.omega, row_period);
        self.inverse_scales = [T::ONE; P];
        self.scales = [T::ONE; P];
        self.y_scales = [T::ONE; E];
        // In place (values built on the stack and moved in were 1.2 KB and more with f32).
        if let Store::Warmup(rows) = &mut self.store {
            rows.clear();
        } else {
            self.store = const { Store::Warmup(heapless::Vec::new()) };
        }
        self.block.reshape(n, equations);
        self.regression_rows = 0;
        self.block_len = block_len;
        self.sqrt_lambda = T::from_f64(sqrt_lambda);
        self.sqrt_lambda_blocks = T::from_f64(power(sqrt_lambda, blocks_old));
        self.counters = Counters::default();
        self.has_model = false;
    }

    /// The configuration.
    pub fn config(&self) -> &SystemConfig {
        &self.config
    }

    /// The shared library.
    pub fn library(&self) -> &StateLibrary<P> {
        &self.library
    }

    /// What happened to the samples so far.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The latest model, once a screening has run.
    pub fn model(&self) -> Option<&SystemModel<T, P, E>> {
        self.has_model.then_some(&self.model)
    }

    /// Samples in the derivative window (fill level of the displacement's ring buffer).
    pub fn buffered(&self) -> usize {
        self.rings
            .first()
            .map_or(0, |r| r.len().min(self.config.base.window))
    }

    /// Samples between a sample arriving and its regression row (the fixed lag).
    pub fn lag_samples(&self) -> usize {
        (self.config.base.window - 1) / 2
    }

    /// Why `s` cannot be fed in, if it cannot.
    fn check(&self, s: &SystemSample<'_, T>) -> Result<(), Rejection> {
        let channels = self.config.base.channels;
        let two = self.displacements > 1;
        if s.v.is_some() != channels.velocity
            || s.u.is_some() != channels.input
            || s.electrical.len() != self.electrical
            || s.x2.is_some() != two
            || s.v2.is_some() != (two && channels.velocity)
        {
            return Err(Rejection::Channels);
        }
        let mut values = [Some(s.x), s.v, s.u, s.x2, s.v2]
            .into_iter()
            .flatten()
            .chain(s.electrical.iter().copied());
        if !s.t.is_finite() || values.clone().any(|v| !v.is_finite()) {
            return Err(Rejection::NonFinite);
        }
        let limit = self.config.base.max_abs;
        if values.any(|v| !(v.abs() < self.max_abs_sure) && v.abs().to_f64() > limit) {
            return Err(Rejection::OutOfRange);
        }
        if self
            .last_t
            .is_some_and(|last| below(s.t - last, self.too_early))
        {
            return Err(Rejection::OutOfOrder);
        }
        Ok(())
    }

    /// Feeds one sample. Returns `Ok(true)` when a screening just ran (a new model is in
    /// [`SystemIdentifier::model`]), `Ok(false)` otherwise, and `Err` (counted) for a sample
    /// that was not fed in.
    pub fn push(&mut self, sample: &SystemSample<'_, T>) -> Result<bool, Rejection> {
        self.push_with(sample, Self::select)
    }

    /// Feeds one sample like [`SystemIdentifier::push`], but at a scheduled screening hands
    /// the identifier to `screening` instead of screening in place, and returns what it
    /// returns (`push` passes [`SystemIdentifier::select`]). A device that must not stall
    /// passes a closure that copies the state into a [`SystemSnapshot`]
    /// ([`SystemIdentifier::snapshot_into`]) and returns `false`; the snapshot's `select`
    /// then gives, bit for bit, the model `push` would have made here (a screening changes
    /// nothing but the model). `screening` is called only when a screening can run, with
    /// the screening already counted.
    pub fn push_with(
        &mut self,
        sample: &SystemSample<'_, T>,
        screening: impl FnOnce(&mut Self) -> bool,
    ) -> Result<bool, Rejection> {
        if let Err(r) = self.check(sample) {
            self.counters.reject(r);
            return Err(r);
        }
        if let Some(last) = self.last_t
            && below(self.gap_after, sample.t - last)
        {
            for ring in self.rings.iter_mut() {
                ring.clear();
            }
            self.schedule.restart_rows();
            self.counters.gaps += 1;
        }
        self.last_t = Some(sample.t);
        self.counters.accepted += 1;
        self.rings[0].write(sample.x);
        if let Some(v) = sample.v {
            self.rings[self.v_ring].write(v);
        }
        if let Some(u) = sample.u {
            self.rings[self.u_ring].write(u);
        }
        for (k, &e) in sample.electrical.iter().enumerate() {
            self.rings[self.e_ring + k].write(e);
        }
        if let Some(x2) = sample.x2 {
            self.rings[self.x2_ring].write(x2);
        }
        if let Some(v2) = sample.v2 {
            self.rings[self.v2_ring].write(v2);
        }
        let window = self.config.base.window;
        if self.rings[0].len() >= window && self.schedule.row_due(self.config.base.row_stride) {
            self.row(sample.t);
        }
        if !self
            .schedule
            .screening_due(self.config.base.screening_period)
            || !self.can_screen()
        {
            return Ok(false);
        }
        self.counters.screenings += 1;
        Ok(screening(self))
    }

    /// The states, input and targets at the centre of the (full) window.
    fn estimate(&self, t: f64) -> Row<T, E> {
        let taps = &self.taps;
        let apply = |ring: usize, order: usize| {
            let (a, b) = self.rings[ring].as_slices();
            taps.apply(order, a, b)
        };
        let channels = self.config.base.channels;
        let x = apply(0, 0);
        let (v, acceleration) = if channels.velocity {
            (apply(self.v_ring, 0), apply(self.v_ring, 1))
        } else {
            (apply(0, 1), apply(0, 2))
        };
        let u = if channels.input {
            apply(self.u_ring, 0)
        } else {
            T::ZERO
        };
        let mut states = [T::ZERO; STATES];
        states[0] = x;
        states[1] = v;
        let mut y = [T::ZERO; E];
        y[0] = acceleration;
        let d = self.displacements;
        if d > 1 && E > 1 {
            let (x2, v2, a2) = if channels.velocity {
                (
                    apply(self.x2_ring, 0),
                    apply(self.v2_ring, 0),
                    apply(self.v2_ring, 1),
                )
            } else {
                (
                    apply(self.x2_ring, 0),
                    apply(self.x2_ring, 1),
                    apply(self.x2_ring, 2),
                )
            };
            states[4] = x2;
            states[5] = v2;
            y[1] = a2;
        }
        for k in 0..self.electrical.min(MAX_ELECTRICAL).min(E.saturating_sub(d)) {
            states[2 + k] = apply(self.e_ring + k, 0);
            y[d + k] = apply(self.e_ring + k, 1);
        }
        Row { states, u, y, t }
    }

    /// The regression row whose centre lies half a window behind `t_newest`.
    fn row(&mut self, t_newest: f64) {
        let row = self.estimate(t_newest - self.schedule.row_lag);
        if let Store::Warmup(rows) = &mut self.store {
            let _ = rows.push(row);
            if rows.len() < WARMUP_ROWS {
                return;
            }
            self.end_warmup();
            return;
        }
        self.fold(&row);
    }

    /// The warm-up's rows are all in: the scales from them, then the halves, and the rows
    /// folded into them. Not inlined: its copy of the rows (2.5 KB with f32) is on the
    /// stack only while it runs, not in the frame of every push.
    #[inline(never)]
    fn end_warmup(&mut self) {
        if let Store::Warmup(rows) = &mut self.store {
            let rows = core::mem::take(rows);
            self.set_scales(&rows);
            let n = self.library.len();
            let equations = self.displacements + self.electrical;
            self.store.become_halves(n, equations);
            for r in rows.iter() {
                self.fold(r);
            }
        }
    }

    /// The column and target scales from the warm-up rows' RMS values.
    fn set_scales(&mut self, rows: &[Row<T, E>]) {
        let count = T::from_usize(rows.len().max(1));
        let rms = |f: &dyn Fn(&Row<T, E>) -> T| {
            let mut s = T::ZERO;
            for r in rows {
                let v = f(r);
                s += v * v;
            }
            let r = (s / count).sqrt();
            if r > T::ZERO && r.is_finite() {
                r
            } else {
                T::ONE
            }
        };
        let mut states = [T::ONE; STATES];
        for (i, s) in states.iter_mut().enumerate() {
            *s = rms(&|r| r.states[i]);
        }
        let u = rms(&|r| r.u);
        for k in 0..E {
            self.y_scales[k] = rms(&|r| r.y[k]);
        }
        self.library.scales(&states, u, &mut self.scales);
        for (inv, s) in self.inverse_scales.iter_mut().zip(self.scales) {
            *inv = T::ONE / s;
        }
    }

    /// A row through the library into the block in progress; a full block goes to A or B.
    fn fold(&mut self, r: &Row<T, E>) {
        if self.config.base.library.harmonics > 0 {
            self.phasor.turn_to(r.t, self.config.base.omega, false);
        }
        let mut theta = [T::ZERO; P];
        self.library.evaluate(
            &r.states,
            self.phasor.sin_cos(),
            r.u,
            &self.inverse_scales,
            &mut theta,
        );
        let mut y = [T::ZERO; E];
        for ((y, r), s) in y.iter_mut().zip(r.y).zip(self.y_scales) {
            *y = r / s;
        }
        self.counters.rows += 1;
        let n = self.library.len();
        if self.sums.on() {
            let Self {
                sums,
                store,
                regression_rows,
                block_len,
                sqrt_lambda,
                sqrt_lambda_blocks,
                ..
            } = self;
            let Store::Halves(halves) = store else {
                return;
            };
            sums.push(&theta, &y, n, |sum, targets| {
                // Blocks of TEST_BLOCK sums alternate between A and B.
                let to_a = (*regression_rows / *block_len).is_multiple_of(2);
                let half = &mut halves[usize::from(!to_a)];
                if regression_rows.is_multiple_of(*block_len) {
                    half.forget(*sqrt_lambda_blocks);
                }
                half.update(sum, targets, *sqrt_lambda);
                *regression_rows += 1;
            });
            return;
        }
        self.block.update(&theta, &y, self.sqrt_lambda);
        self.regression_rows += 1;
        if self.regression_rows.is_multiple_of(self.block_len)
            && let Store::Halves(halves) = &mut self.store
        {
            // The block's last row decides: even blocks go to A, odd ones to B.
            let to_a = ((self.regression_rows - 1) / self.block_len).is_multiple_of(2);
            let half = &mut halves[usize::from(!to_a)];
            half.forget(self.sqrt_lambda_blocks);
            half.merge(&self.block);
            self.block.clear();
        }
    }

    /// The weights of A and B with the block in progress.
    fn weights(&self) -> (T, T) {
        let Store::Halves([a, b]) = &self.store else {
            return (T::ZERO, T::ZERO);
        };
        let (mut wa, mut wb) = (a.weight(), b.weight());
        if (self.regression_rows / self.block_len).is_multiple_of(2) {
            wa += self.block.weight();
        } else {
            wb += self.block.weight();
        }
        (wa, wb)
    }

    /// Whether a screening can run: enough rows (twice the terms) in both halves.
    pub fn can_screen(&self) -> bool {
        let enough = T::from_usize(2 * self.library.len());
        let (wa, wb) = self.weights();
        wa >= enough && wb >= enough
    }

    /// Runs a screening now (it also runs by itself every `screening_period` samples): each
    /// equation's threshold sweep and MES on its own factors. Returns whether a model came
    /// out (it needs enough rows in both halves). Changes nothing but the model.
    pub fn screen(&mut self) -> bool {
        if !self.can_screen() {
            return false;
        }
        self.counters.screenings += 1;
        self.select()
    }

    /// The screening proper, on the state as it is: each equation's sweep and MES; the
    /// model becomes [`SystemIdentifier::model`]. Returns whether one came out. Changes
    /// nothing but the model. [`SystemIdentifier::screen`] runs it after its checks; on a
    /// [`SystemSnapshot`] it is the screening of the state the snapshot was taken from.
    pub fn select(&mut self) -> bool {
        if !self.can_screen() {
            return false;
        }
        let Self {
            config,
            library,
            store,
            block,
            scales,
            y_scales,
            electrical,
            displacements,
            regression_rows,
            block_len,
            counters,
            model,
            has_model,
            ..
        } = self;
        let Store::Halves([a_all, b_all]) = &*store else {
            return false;
        };
        let n = library.len();
        let d = *displacements;
        let equations = (d + *electrical).min(E);
        let to_a = (*regression_rows / *block_len).is_multiple_of(2);
        // The model is written in place (a second one on the stack would be 1 KB with f32,
        // P = 16, E = 2); A and B are one pair, as in the single-equation screening.
        *has_model = true;
        model.terms.clear();
        model.electrical = config.electrical;
        model.displacements = config.displacements;
        model.equations.clear();
        model.omega = config.base.omega;
        model.samples = counters.accepted;
        model.rejected = counters.rejected();
        model.rows = counters.rows;
        for &t in library.terms() {
            let _ = model.terms.push(t);
        }
        let mut ab = FactorPair::new(n);
        let mut all = Factor::new(n);
        let mut work = [[T::ZERO; P]; P];
        let mut sweep = screen::Sweep::new();
        let grid = usize::from(config.base.thresholds);
        let parsimony = T::from_f64(config.base.parsimony);
        for k in 0..equations {
            let (Some(a), Some(b)) = (a_all.equation_view(k), b_all.equation_view(k)) else {
                break;
            };
            ab.a_mut().copy_from(a);
            ab.b_mut().copy_from(b);
            // The block in progress belongs to the half its next row goes to.
            if let Some(open) = block.equation_view(k)
                && open.weight() > T::ZERO
            {
                ab.half_mut(to_a).merge(open);
            }
            all.copy_from_view(ab.a());
            all.view_mut().merge(ab.b());
            screen::sweep(ab.a(), ab.b(), &all, &mut work, grid, parsimony, &mut sweep);
            let y_scale = y_scales[k];
            let target = if k == 0 {
                Target::Acceleration
            } else if k < d {
                Target::Acceleration2
            } else {
                Target::Rate(config.electrical[k - d].unwrap_or(Electrical::Voltage))
            };
            // The equation is filled in place (its coefficients and solutions built on the
            // stack and moved in were 0.9 KB of the screening's stack with f32, P = 16).
            if model
                .equations
                .push(Equation {
                    target,
                    coefficients: [T::ZERO; P],
                    solutions: heapless::Vec::new(),
                    selected: sweep.selected,
                })
                .is_err()
            {
                continue;
            }
            let Some(equation) = model.equations.last_mut() else {
                continue;
            };
            for j in 0..n {
                equation.coefficients[j] = sweep.coefficients[j] * y_scale / scales[j];
            }
            for s in sweep.solutions.iter() {
                let _ = equation.solutions.push(crate::model::Solution {
                    mean_error: s.mean_error * y_scale * y_scale,
                    ..*s
                });
            }
        }
        true
    }
}

/// What a system's screening reads, without the front end (ring buffers and taps): a
/// [`SystemIdentifier`] of window capacity 1 and one ring, filled by
/// [`SystemIdentifier::snapshot_into`] and screened by [`SystemIdentifier::select`].
pub type SystemSnapshot<T, const P: usize, const E: usize = 2> = SystemIdentifier<T, 1, P, E, 1>;

impl<T: Real, const P: usize, const E: usize> SystemIdentifier<T, 1, P, E, 1> {
    /// An empty snapshot: `const` (a static of it lies in `.bss`).
    pub const fn snapshot() -> Self {
        Self::empty()
    }

    /// Forgets the model (after the identifier it is taken from was configured anew).
    pub fn clear_model(&mut self) {
        self.has_model = false;
    }
}

impl<T: Real, const W: usize, const P: usize, const E: usize, const C: usize>
    SystemIdentifier<T, W, P, E, C>
{
    /// Copies into `s` everything a screening reads (all but the ring buffers, the taps and
    /// `s`'s own model, which it keeps). Then `s.select()` is the screening of this
    /// identifier as it is now. Destructured field by field, so that a field added to the
    /// identifier does not compile until it is copied here or said to be left out.
    pub fn snapshot_into<const W2: usize, const C2: usize>(
        &self,
        s: &mut SystemIdentifier<T, W2, P, E, C2>,
    ) {
        let SystemIdentifier {
            config,
            library,
            taps: _,
            rings: _,
            v_ring,
            u_ring,
            e_ring,
            x2_ring,
            v2_ring,
            electrical,
            displacements,
            max_abs_sure,
            too_early,
            gap_after,
            last_t,
            schedule,
            phasor,
            inverse_scales,
            scales,
            y_scales,
            store,
            block,
            sums,
            regression_rows,
            block_len,
            sqrt_lambda,
            sqrt_lambda_blocks,
            counters,
            model: _,
            has_model: _,
        } = self;
        s.config = *config;
        s.library.clone_from(library);
        s.v_ring = *v_ring;
        s.u_ring = *u_ring;
        s.e_ring = *e_ring;
        s.x2_ring = *x2_ring;
        s.v2_ring = *v2_ring;
        s.electrical = *electrical;
        s.displacements = *displacements;
        s.max_abs_sure = *max_abs_sure;
        s.too_early = *too_early;
        s.gap_after = *gap_after;
        s.last_t = *last_t;
        s.schedule = *schedule;
        s.phasor = *phasor;
        s.inverse_scales = *inverse_scales;
        s.scales = *scales;
        s.y_scales = *y_scales;
        s.store.clone_from(store);
        s.block.clone_from(block);
        s.sums.clone_from(sums);
        s.regression_rows = *regression_rows;
        s.block_len = *block_len;
        s.sqrt_lambda = *sqrt_lambda;
        s.sqrt_lambda_blocks = *sqrt_lambda_blocks;
        s.counters = *counters;
    }
}

/// Where a device keeps its [`SystemIdentifier`]: empty until configured, then configured
/// (and configured again) in place, so that the identifier never exists on the stack.
/// [`SystemSlot::new`] is `const`: in a `static` the slot lies in `.bss`.
///
/// ```
/// use lssi_core::{Config, SystemConfig, SystemSlot};
/// use lssi_core::library::Electrical;
/// let mut slot: Box<SystemSlot<f32, 256, 16, 2, 2>> = Box::new(SystemSlot::new());
/// assert!(slot.get().is_none());
/// let config = SystemConfig { base: Config { window: 63, ..Config::default() },
///                             electrical: [Some(Electrical::Voltage), None], coupling_order: 2,
///                             displacements: 1 };
/// slot.configure(config).unwrap();
/// assert_eq!(slot.get().unwrap().library().len(), 16);
/// // A refused configuration leaves the slot as it was.
/// assert!(slot.configure(SystemConfig { coupling_order: 0, ..config }).is_err());
/// assert_eq!(slot.get().unwrap().config().coupling_order, 2);
/// ```
pub struct SystemSlot<
    T: Real,
    const W: usize,
    const P: usize,
    const E: usize = 2,
    const C: usize = 2,
> {
    configured: bool,
    identifier: SystemIdentifier<T, W, P, E, C>,
}

impl<T: Real, const W: usize, const P: usize, const E: usize, const C: usize> Default
    for SystemSlot<T, W, P, E, C>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real, const W: usize, const P: usize, const E: usize, const C: usize>
    SystemSlot<T, W, P, E, C>
{
    /// An empty slot.
    pub const fn new() -> Self {
        Self {
            configured: false,
            identifier: SystemIdentifier::empty(),
        }
    }

    /// Configures the identifier in place (as [`SystemIdentifier::reconfigure`]); on an
    /// error the slot is left as it was, configured or not.
    pub fn configure(
        &mut self,
        config: SystemConfig,
    ) -> Result<&mut SystemIdentifier<T, W, P, E, C>, SystemConfigError> {
        self.identifier.reconfigure(config)?;
        self.configured = true;
        Ok(&mut self.identifier)
    }

    /// The identifier, once configured.
    pub fn get(&self) -> Option<&SystemIdentifier<T, W, P, E, C>> {
        self.configured.then_some(&self.identifier)
    }

    /// The identifier, once configured.
    pub fn get_mut(&mut self) -> Option<&mut SystemIdentifier<T, W, P, E, C>> {
        self.configured.then_some(&mut self.identifier)
    }
}

/// x^n for the forgetting factors (0 < x ≤ 1), as exp(n·ln x) (as the single-equation
/// path's, without `libm::pow`).
fn power(x: f64, n: f64) -> f64 {
    libm::exp(n * libm::log(x))
}

#[cfg(test)]
mod tests;
