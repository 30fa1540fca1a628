//! Conversions between lssi-core's types and their wire forms, used by both ends of the link.
//!
//! The host computes an `lssi_core::Config` from a recording (`lssi identify`'s
//! `configure()`), sends it with [`config_to_wire`], and the device rebuilds exactly that
//! `Config` with [`config_from_wire`]: every field travels at its own width, so the round
//! trip is the identity (bit for bit, NaN payloads included).
//!
//! ```
//! use lssi_core::Config;
//! use lssi_device::wire::{config_from_wire, config_to_wire};
//!
//! let config = Config { omega: 21.4, memory: Some(30.0), ..Config::default() };
//! let wire = config_to_wire(&config).unwrap();
//! assert_eq!((wire.sample_period, wire.memory), (config.sample_period, config.memory));
//! assert_eq!(config_from_wire(&wire), config);
//! ```
//!
//! The device reports the model with [`snapshot`]; the host turns the snapshot back into an
//! `lssi_core::Model<f32, P>` with [`model_from_snapshot`] and reports it with the same
//! code as `lssi identify` (the model's derived figures, resonance and wells, come out the
//! same because the coefficients are the device's f32 values, bit for bit).

use core::fmt;
use lssi_core::library::Library;
use lssi_core::{Channels, Config, LibraryConfig, Model, PolyFamily, Real, Solution, Term};
use lssi_proto::{
    MAX_SOLUTIONS, MAX_TERMS, ModelSnapshot, SnapshotCause, SolutionSummary, TermCode, TermKind,
    WireChannels, WireConfig, WireLibrary,
};

/// Why a value cannot cross the link, or does not fit the other end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum WireError {
    /// The derivative window does not fit the wire's `u16` (or the device's capacity).
    Window {
        /// Requested, in samples.
        window: usize,
        /// Largest allowed.
        max: usize,
    },
    /// The library has more terms than the wire (or the device) carries.
    TooManyTerms {
        /// Terms the model or configuration has.
        terms: usize,
        /// Room there is.
        capacity: usize,
    },
    /// The model has more solutions than a snapshot carries.
    TooManySolutions(usize),
    /// A snapshot's term code names no lssi-core term.
    BadTerm(TermCode),
    /// A system snapshot's term code names no term of a shared library.
    #[cfg(feature = "system")]
    BadStateTerm(lssi_proto::StateTermCode),
    /// A system with two displacements (the device and the wire take one).
    #[cfg(feature = "system")]
    Displacements(u8),
    /// A snapshot has a different number of coefficients than terms.
    CoefficientCount {
        /// Terms in the snapshot.
        terms: usize,
        /// Coefficients in the snapshot.
        coefficients: usize,
    },
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WireError::Window { window, max } => write!(
                f,
                "the derivative window is {window} samples, but at most {max} fit the device"
            ),
            WireError::TooManyTerms { terms, capacity } => write!(
                f,
                "the library has {terms} terms, but at most {capacity} fit the device and the wire"
            ),
            WireError::TooManySolutions(n) => write!(
                f,
                "the model has {n} solutions, but a snapshot carries at most {MAX_SOLUTIONS}"
            ),
            #[cfg(feature = "system")]
            WireError::BadStateTerm(code) => write!(
                f,
                "the system snapshot's term code {:?} {:?} is not a library term",
                code.kind, code.powers
            ),
            #[cfg(feature = "system")]
            WireError::Displacements(d) => write!(
                f,
                "the system has {d} displacements, but the device and the wire take one"
            ),
            WireError::BadTerm(code) => write!(
                f,
                "the snapshot's term code {:?} ({}, {}) is not a library term",
                code.kind, code.a, code.b
            ),
            WireError::CoefficientCount {
                terms,
                coefficients,
            } => write!(
                f,
                "the snapshot has {coefficients} coefficients for {terms} terms"
            ),
        }
    }
}

impl core::error::Error for WireError {}

/// The wire form of a configuration; fails only for a window beyond `u16::MAX` samples.
pub fn config_to_wire(config: &Config) -> Result<WireConfig, WireError> {
    let window = u16::try_from(config.window).map_err(|_| WireError::Window {
        window: config.window,
        max: usize::from(u16::MAX),
    })?;
    let library = &config.library;
    Ok(WireConfig {
        sample_period: config.sample_period,
        window,
        derivative_degree: config.derivative_degree,
        library: WireLibrary {
            poly_order: library.poly_order,
            family: family_to_wire(library.family),
            constant: library.constant,
            harmonics: library.harmonics,
            input: library.input,
        },
        omega: config.omega,
        channels: WireChannels {
            velocity: config.channels.velocity,
            input: config.channels.input,
        },
        memory: config.memory,
        screening_period: config.screening_period,
        thresholds: config.thresholds,
        smoothing: config.smoothing,
        row_stride: config.row_stride,
        parsimony: config.parsimony,
        offsets: config.offsets,
        max_abs: config.max_abs,
        test_rows: config.test_rows,
        // The host picks the compact encoding, if it wants one, after the conversion.
        encoding: lssi_proto::SampleEncoding::F32,
        // A duty cycle, if any, is set by the host after the conversion too.
        duty: None,
    })
}

/// The configuration a [`WireConfig`] describes, unvalidated (`Identifier::new` validates).
pub fn config_from_wire(wire: &WireConfig) -> Config {
    Config {
        sample_period: wire.sample_period,
        window: usize::from(wire.window),
        derivative_degree: wire.derivative_degree,
        library: LibraryConfig {
            poly_order: wire.library.poly_order,
            family: family_from_wire(wire.library.family),
            constant: wire.library.constant,
            harmonics: wire.library.harmonics,
            input: wire.library.input,
        },
        omega: wire.omega,
        channels: Channels {
            velocity: wire.channels.velocity,
            input: wire.channels.input,
        },
        memory: wire.memory,
        screening_period: wire.screening_period,
        thresholds: wire.thresholds,
        smoothing: wire.smoothing,
        row_stride: wire.row_stride,
        parsimony: wire.parsimony,
        offsets: wire.offsets,
        max_abs: wire.max_abs,
        // A host-side experiment that the protocol does not carry.
        noise_correction: false,
        test_rows: wire.test_rows,
    }
}

/// Whether `config` fits a device that announced `window_capacity` and `max_terms` in its
/// `HelloReply`: the host's check before `Configure`, with an error that says what is wrong
/// (the device itself can only nak `BadConfig`).
pub fn fits(config: &Config, window_capacity: u16, max_terms: u8) -> Result<(), WireError> {
    if config.window > usize::from(window_capacity) {
        return Err(WireError::Window {
            window: config.window,
            max: usize::from(window_capacity),
        });
    }
    let terms = Library::<32>::count(&config.library);
    let capacity = usize::from(max_terms).min(MAX_TERMS);
    if terms > capacity {
        return Err(WireError::TooManyTerms { terms, capacity });
    }
    Ok(())
}

/// The nak of a `Configure` that `error` refused: [`NakReason::TooManyTerms`] with the size
/// asked for and the limit when the library is too large, [`NakReason::BadConfig`] otherwise.
///
/// [`NakReason::TooManyTerms`]: lssi_proto::NakReason::TooManyTerms
/// [`NakReason::BadConfig`]: lssi_proto::NakReason::BadConfig
pub fn config_nak(error: &lssi_core::ConfigError) -> lssi_proto::NakReason {
    let byte = |n: usize| u8::try_from(n).unwrap_or(u8::MAX);
    match error {
        lssi_core::ConfigError::Library(lssi_core::library::LibraryError::TooManyTerms {
            wanted,
            capacity,
        }) => lssi_proto::NakReason::TooManyTerms {
            terms: byte(*wanted),
            capacity: byte(*capacity),
        },
        _ => lssi_proto::NakReason::BadConfig,
    }
}

/// lssi-core's polynomial family as the wire names it.
pub const fn family_to_wire(family: PolyFamily) -> lssi_proto::PolyFamily {
    match family {
        PolyFamily::All => lssi_proto::PolyFamily::All,
        PolyFamily::Families => lssi_proto::PolyFamily::Families,
        PolyFamily::OddFamilies => lssi_proto::PolyFamily::OddFamilies,
    }
}

/// The wire's polynomial family as lssi-core names it.
pub const fn family_from_wire(family: lssi_proto::PolyFamily) -> PolyFamily {
    match family {
        lssi_proto::PolyFamily::All => PolyFamily::All,
        lssi_proto::PolyFamily::Families => PolyFamily::Families,
        lssi_proto::PolyFamily::OddFamilies => PolyFamily::OddFamilies,
    }
}

/// A term's wire code.
pub const fn term_code(term: Term) -> TermCode {
    let (kind, a, b) = match term {
        Term::Constant => (TermKind::Constant, 0, 0),
        Term::Monomial { px, pv } => (TermKind::Monomial, px, pv),
        Term::Sin(k) => (TermKind::Sin, k, 0),
        Term::Cos(k) => (TermKind::Cos, k, 0),
        Term::Input => (TermKind::Input, 0, 0),
    };
    TermCode { kind, a, b }
}

/// The term a wire code names; `None` for codes [`term_code`] never makes.
pub const fn term_from_code(code: TermCode) -> Option<Term> {
    match (code.kind, code.a, code.b) {
        (TermKind::Constant, 0, 0) => Some(Term::Constant),
        (TermKind::Monomial, px, pv) if px > 0 || pv > 0 => Some(Term::Monomial { px, pv }),
        (TermKind::Sin, k, 0) if k > 0 => Some(Term::Sin(k)),
        (TermKind::Cos, k, 0) if k > 0 => Some(Term::Cos(k)),
        (TermKind::Input, 0, 0) => Some(Term::Input),
        _ => None,
    }
}

/// The snapshot of a model: exact for `T = f32` (a device's), rounded to f32 for f64.
///
/// Fails when the model has more terms than [`MAX_TERMS`] (a host library of up to 32;
/// never on a device, whose `P` is at most [`MAX_TERMS`]).
pub fn snapshot<T: Real, const P: usize>(
    model: &Model<T, P>,
    cause: SnapshotCause,
) -> Result<ModelSnapshot, WireError> {
    let n = model.terms.len();
    let too_many = WireError::TooManyTerms {
        terms: n,
        capacity: MAX_TERMS,
    };
    let mut terms = heapless::Vec::new();
    let mut coefficients = heapless::Vec::new();
    for (&term, &c) in model.terms.iter().zip(model.coefficients.iter()) {
        terms.push(term_code(term)).map_err(|_| too_many)?;
        coefficients.push(to_f32(c)).map_err(|_| too_many)?;
    }
    let mut solutions = heapless::Vec::new();
    for s in model.solutions.iter() {
        let summary = SolutionSummary {
            threshold: to_f32(s.threshold),
            mean_error: to_f32(s.mean_error),
            support: s.support,
        };
        solutions
            .push(summary)
            .map_err(|_| WireError::TooManySolutions(model.solutions.len()))?;
    }
    Ok(ModelSnapshot {
        terms,
        coefficients,
        solutions,
        // At most MAX_SOLUTIONS = 32.
        selected: u8::try_from(model.selected).unwrap_or(u8::MAX),
        k_x: model.k.0,
        k_v: model.k.1,
        omega: model.omega,
        resonance_hz: model.resonance_hz(),
        wells: model.wells(),
        offset_x: to_f32(model.offset_x),
        offset_v: to_f32(model.offset_v),
        samples: model.samples,
        rejected: model.rejected,
        rows: model.rows,
        cause,
    })
}

/// The lssi-core model a snapshot describes (f32, as the device computed it), so that the
/// host can report it with the code it reports its own models with.
pub fn model_from_snapshot<const P: usize>(
    snapshot: &ModelSnapshot,
) -> Result<Model<f32, P>, WireError> {
    let n = snapshot.terms.len();
    if snapshot.coefficients.len() != n {
        return Err(WireError::CoefficientCount {
            terms: n,
            coefficients: snapshot.coefficients.len(),
        });
    }
    let too_many = WireError::TooManyTerms {
        terms: n,
        capacity: P,
    };
    let mut terms = heapless::Vec::new();
    let mut coefficients = [0.0f32; P];
    for ((&code, &c), slot) in snapshot
        .terms
        .iter()
        .zip(snapshot.coefficients.iter())
        .zip(coefficients.iter_mut())
    {
        let term = term_from_code(code).ok_or(WireError::BadTerm(code))?;
        terms.push(term).map_err(|_| too_many)?;
        *slot = c;
    }
    if terms.len() != n {
        return Err(too_many);
    }
    let mut solutions = heapless::Vec::new();
    for s in snapshot.solutions.iter() {
        let solution = Solution {
            threshold: s.threshold,
            mean_error: s.mean_error,
            support: s.support,
        };
        solutions
            .push(solution)
            .map_err(|_| WireError::TooManySolutions(snapshot.solutions.len()))?;
    }
    Ok(Model {
        terms,
        coefficients,
        solutions,
        selected: usize::from(snapshot.selected),
        k: (snapshot.k_x, snapshot.k_v),
        omega: snapshot.omega,
        offset_x: snapshot.offset_x,
        offset_v: snapshot.offset_v,
        samples: snapshot.samples,
        rejected: snapshot.rejected,
        rows: snapshot.rows,
    })
}

fn to_f32<T: Real>(value: T) -> f32 {
    value.to_f64() as f32
}

/// A duty cycle's drift as `Health` carries it (protocol version 7), field for field.
pub const fn drift_to_wire(drift: &crate::standalone::Drift) -> lssi_proto::WireDrift {
    lssi_proto::WireDrift {
        windows: drift.windows,
        relative: drift.relative,
        largest: drift.largest,
        largest_term: drift.largest_term,
        support_changes: drift.support_changes,
    }
}

#[cfg(test)]
mod drift_tests {
    use super::drift_to_wire;
    use crate::standalone::Drift;
    use lssi_proto::{DeviceMsg, ModelSnapshot, TermCode, TermKind, decode_frame, encode};

    fn model(coefficients: &[f32]) -> ModelSnapshot {
        let mut m = ModelSnapshot::default();
        for (a, &c) in coefficients.iter().enumerate() {
            let code = TermCode {
                kind: TermKind::Monomial,
                a: u8::try_from(a + 1).unwrap(),
                b: 0,
            };
            m.terms.push(code).unwrap();
            m.coefficients.push(c).unwrap();
        }
        m
    }

    /// The drift a reporter computes between two windows reaches the host in `Health`
    /// unchanged: the largest change (term 1, 0.5 → 0.6: 20 %), a term that left (1), the
    /// RMS over the three terms in either model.
    #[test]
    fn the_drift_crosses_in_health_field_for_field() {
        let before = model(&[-1.0, 0.5, 0.25, 0.0]);
        let after = model(&[-1.0, 0.6, 0.0, 0.0]);
        let drift = Drift::between(&before, &after, 4);
        assert_eq!(drift.windows, 4);
        assert_eq!(drift.support_changes, 1);
        assert_eq!(drift.largest, 1.0);
        assert_eq!(drift.largest_term, 2);
        let rms = libm::sqrtf((0.0 + 0.2f32 * 0.2 / 1.0 + 1.0) / 3.0);
        assert!((drift.relative - rms).abs() < 1e-3, "{}", drift.relative);
        let wire = drift_to_wire(&drift);
        let health = DeviceMsg::Health {
            samples: 5,
            rejected: 0,
            buffer_fill: 0,
            cost_mean: 0,
            cost_max: 0,
            cost_unit: lssi_proto::CostUnit::Ticks,
            watchdog: 0,
            crc_errors: 0,
            frames_ok: 0,
            screen_cost: 0,
            screen_cost_max: 0,
            screenings: 0,
            duplicates: 0,
            decode_errors: 0,
            overruns: 0,
            queue_high_water: 0,
            latency_max_ns: 0,
            screenings_skipped: 0,
            sample_rate_hz: 200.0,
            drift: Some(wire),
            reference: None,
        };
        let mut frame = [0u8; lssi_proto::MAX_DEVICE_FRAME_LEN];
        let len = encode(&health, &mut frame).unwrap();
        let back: DeviceMsg = decode_frame(&mut frame[..len]).unwrap();
        let DeviceMsg::Health {
            drift: Some(got), ..
        } = back
        else {
            panic!("{back:?}");
        };
        assert_eq!(
            (
                got.windows,
                got.relative,
                got.largest,
                got.largest_term,
                got.support_changes
            ),
            (
                drift.windows,
                drift.relative,
                drift.largest,
                drift.largest_term,
                drift.support_changes
            )
        );
    }
}
