//! Systems of equations on the wire (since version 6): a harvester's mechanical equation
//! and its electrical ones, identified by the device from x and the electrical channel(s).
//!
//! Three messages, appended to the enums so that every older message keeps its bytes:
//! [`HostMsg::ConfigureSystem`](crate::HostMsg::ConfigureSystem) (a [`WireConfig`] and the
//! electrical channels: `lssi_core::SystemConfig` field for field),
//! [`HostMsg::SystemSamples`](crate::HostMsg::SystemSamples) (samples that carry the
//! electrical values beside t, x, v and u) and
//! [`DeviceMsg::SystemModel`](crate::DeviceMsg::SystemModel) (every equation's coefficients
//! over the one shared library).
//!
//! ```
//! use lssi_proto::{encode, HostFrameDecoder, HostMsg, SystemBatch, SystemWireSample,
//!                  MAX_HOST_FRAME_LEN};
//! let mut batch = SystemBatch::new(0);
//! let mut electrical = heapless::Vec::new();
//! electrical.push(0.25).unwrap();
//! batch.samples.push(SystemWireSample { t: 0.0, x: 1e-3, v: None, u: None, electrical }).unwrap();
//! let mut frame = [0u8; MAX_HOST_FRAME_LEN];
//! let len = encode(&HostMsg::SystemSamples(batch.clone()), &mut frame).unwrap();
//! let mut decoder = HostFrameDecoder::new();
//! let got: Vec<_> = decoder.feed::<HostMsg>(&frame[..len]).collect();
//! assert_eq!(got, [Ok(HostMsg::SystemSamples(batch))]);
//! ```

use crate::size::vec_max_size;
use crate::{MAX_TERMS, SnapshotCause, SolutionSummary, TermKind, WireConfig};
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

/// Most electrical channels a system carries (`lssi_core::library::MAX_ELECTRICAL`).
pub const MAX_ELECTRICAL: usize = 2;
/// Most equations in a [`SystemSnapshot`]: the mechanical one and one per electrical channel.
pub const MAX_EQUATIONS: usize = 1 + MAX_ELECTRICAL;
/// Most samples in one [`SystemBatch`]: 12 samples with x, v, u and two electrical values
/// keep the host frame under 512 bytes (`MAX_HOST_FRAME_LEN`).
pub const MAX_SYSTEM_BATCH: usize = 12;

/// An electrical channel: `lssi_core::library::Electrical`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireElectrical {
    /// The voltage across the load, V (equation V' = …).
    Voltage,
    /// The current, i (equation i' = …).
    Current,
}

/// A system's configuration: `lssi_core::SystemConfig` field for field.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireSystemConfig {
    /// What the system shares with one equation (`SystemConfig::base`); its `encoding`
    /// must be `F32` (system samples travel as [`SystemBatch`]).
    pub base: WireConfig,
    /// The electrical channels, in the samples' order: `Some` first, each kind once.
    pub electrical: [Option<WireElectrical>; MAX_ELECTRICAL],
    /// The highest total degree of a coupling term (1: V; 2: also x·V, v·V, V²).
    pub coupling_order: u8,
}

/// One sample of a system: t, x, the measured v and u when configured, and one value per
/// configured electrical channel, in order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SystemWireSample {
    /// Time, seconds.
    pub t: f64,
    /// Displacement.
    pub x: f32,
    /// Measured velocity.
    pub v: Option<f32>,
    /// Measured excitation.
    pub u: Option<f32>,
    /// The electrical channels' values.
    pub electrical: heapless::Vec<f32, MAX_ELECTRICAL>,
}

impl MaxSize for SystemWireSample {
    const POSTCARD_MAX_SIZE: usize = f64::POSTCARD_MAX_SIZE
        + f32::POSTCARD_MAX_SIZE
        + 2 * <Option<f32>>::POSTCARD_MAX_SIZE
        + vec_max_size::<f32>(MAX_ELECTRICAL);
}

/// A batch of system samples, numbered like [`SampleBatch`](crate::SampleBatch)es (from 0
/// after every configuration and reset, applied exactly once in `seq` order).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SystemBatch {
    /// Sequence number.
    pub seq: u32,
    /// The samples, in time order.
    pub samples: heapless::Vec<SystemWireSample, MAX_SYSTEM_BATCH>,
}

impl SystemBatch {
    /// An empty batch.
    pub const fn new(seq: u32) -> Self {
        Self {
            seq,
            samples: heapless::Vec::new(),
        }
    }
}

impl MaxSize for SystemBatch {
    const POSTCARD_MAX_SIZE: usize =
        u32::POSTCARD_MAX_SIZE + vec_max_size::<SystemWireSample>(MAX_SYSTEM_BATCH);
}

/// The left-hand side of a system's equation: `lssi_core::identifier::system::Target`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireTarget {
    /// x''.
    Acceleration,
    /// V' or i'.
    Rate(WireElectrical),
}

/// A term of the shared library: `lssi_core::library::StateTerm`, flat.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StateTermCode {
    /// What the term is.
    pub kind: TermKind,
    /// [`TermKind::Monomial`]: the powers of x, v and the electrical channels in order.
    /// [`TermKind::Sin`]/[`TermKind::Cos`]: the harmonic k in `powers[0]`. Otherwise 0.
    pub powers: [u8; 4],
}

/// One equation of a [`SystemSnapshot`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SystemEquation {
    /// Its left-hand side.
    pub target: WireTarget,
    /// Coefficients of the selected solution in physical units, one per term of
    /// [`SystemSnapshot::terms`] (0 if inactive).
    pub coefficients: heapless::Vec<f32, MAX_TERMS>,
    /// The selected solution of its own threshold sweep (threshold, held-out mean error
    /// of this equation's target, support); `None` before its first screening.
    pub selected: Option<SolutionSummary>,
    /// Candidate solutions its sweep found.
    pub solutions: u8,
}

impl MaxSize for SystemEquation {
    const POSTCARD_MAX_SIZE: usize = WireTarget::POSTCARD_MAX_SIZE
        + vec_max_size::<f32>(MAX_TERMS)
        + <Option<SolutionSummary>>::POSTCARD_MAX_SIZE
        + u8::POSTCARD_MAX_SIZE;
}

/// A system's current model: the shared library and every equation over it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SystemSnapshot {
    /// The shared library, in column order.
    pub terms: heapless::Vec<StateTermCode, MAX_TERMS>,
    /// The equations: x'' first, then one per electrical channel.
    pub equations: heapless::Vec<SystemEquation, MAX_EQUATIONS>,
    /// Base angular frequency Ω in rad/s, as configured.
    pub omega: f64,
    /// Samples the model has seen.
    pub samples: u64,
    /// Samples rejected.
    pub rejected: u64,
    /// Regression rows folded into the fit.
    pub rows: u64,
    /// Why the snapshot was sent.
    pub cause: SnapshotCause,
}

impl MaxSize for SystemSnapshot {
    const POSTCARD_MAX_SIZE: usize = vec_max_size::<StateTermCode>(MAX_TERMS)
        + vec_max_size::<SystemEquation>(MAX_EQUATIONS)
        + f64::POSTCARD_MAX_SIZE
        + 3 * u64::POSTCARD_MAX_SIZE
        + SnapshotCause::POSTCARD_MAX_SIZE;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{
        DeviceMsg, HostMsg, MAX_DEVICE_FRAME_LEN, MAX_HOST_FRAME_LEN, decode_frame,
        decode_host_frame, encode,
    };

    fn full_batch() -> SystemBatch {
        let mut batch = SystemBatch::new(u32::MAX - 1);
        for k in 0..MAX_SYSTEM_BATCH {
            let electrical = heapless::Vec::from_slice(&[f32::MAX, -f32::MIN_POSITIVE]).unwrap();
            let sample = SystemWireSample {
                t: k as f64 * 1e-3,
                x: -1.5,
                v: Some(2.0),
                u: Some(f32::NAN),
                electrical,
            };
            batch.samples.push(sample).unwrap();
        }
        batch
    }

    #[test]
    fn the_largest_system_batch_fits_a_host_frame_and_decodes_in_place() {
        let batch = full_batch();
        let mut frame = [0u8; MAX_HOST_FRAME_LEN];
        let len = encode(&HostMsg::SystemSamples(batch.clone()), &mut frame).unwrap();
        assert!(len <= MAX_HOST_FRAME_LEN && MAX_HOST_FRAME_LEN <= 512);
        let mut copy = frame;
        match decode_host_frame(&mut copy[..len]).unwrap() {
            crate::HostCommand::SystemSamples(got) => {
                assert_eq!(got.seq, batch.seq);
                assert_eq!(got.samples.len(), MAX_SYSTEM_BATCH);
                assert!(got.samples[3].u.unwrap().is_nan());
                assert_eq!(got.samples[3].electrical, batch.samples[3].electrical);
            }
            other => panic!("{other:?}"),
        }
        // One sample too many does not decode: the count is checked.
        let mut shape = frame;
        let msg: HostMsg = decode_frame(&mut shape[..len]).unwrap();
        assert!(matches!(msg, HostMsg::SystemSamples(_)));
    }

    #[test]
    fn a_full_system_snapshot_fits_a_device_frame() {
        let mut snapshot = SystemSnapshot {
            omega: 1.0,
            samples: u64::MAX,
            rejected: u64::MAX,
            rows: u64::MAX,
            cause: SnapshotCause::Final,
            ..SystemSnapshot::default()
        };
        for _ in 0..MAX_TERMS {
            let code = StateTermCode {
                kind: TermKind::Monomial,
                powers: [255; 4],
            };
            snapshot.terms.push(code).unwrap();
        }
        for e in [
            WireTarget::Acceleration,
            WireTarget::Rate(WireElectrical::Voltage),
            WireTarget::Rate(WireElectrical::Current),
        ] {
            let equation = SystemEquation {
                target: e,
                coefficients: heapless::Vec::from_slice(&[1.0; MAX_TERMS]).unwrap(),
                selected: Some(SolutionSummary {
                    threshold: 1.0,
                    mean_error: 2.0,
                    support: u32::MAX,
                }),
                solutions: 255,
            };
            snapshot.equations.push(equation).unwrap();
        }
        let msg = DeviceMsg::SystemModel(snapshot);
        let mut frame = [0u8; MAX_DEVICE_FRAME_LEN];
        let len = encode(&msg, &mut frame).unwrap();
        assert!(len <= MAX_DEVICE_FRAME_LEN);
        let back: DeviceMsg = decode_frame(&mut frame[..len]).unwrap();
        assert_eq!(back, msg);
    }

    #[test]
    fn a_system_configuration_round_trips() {
        let base = WireConfig {
            sample_period: 1e-3,
            window: 33,
            derivative_degree: 5,
            library: crate::WireLibrary {
                poly_order: 3,
                family: crate::PolyFamily::OddFamilies,
                constant: false,
                harmonics: 1,
                input: false,
            },
            omega: 2.0,
            channels: crate::WireChannels::default(),
            memory: None,
            screening_period: 5000,
            thresholds: 20,
            smoothing: false,
            row_stride: 1,
            parsimony: 0.05,
            offsets: false,
            max_abs: 1e6,
            test_rows: 0,
            encoding: crate::SampleEncoding::F32,
            duty: None,
        };
        let config = WireSystemConfig {
            base,
            electrical: [Some(WireElectrical::Voltage), None],
            coupling_order: 2,
        };
        let mut frame = [0u8; MAX_HOST_FRAME_LEN];
        let len = encode(&HostMsg::ConfigureSystem(config), &mut frame).unwrap();
        match decode_host_frame(&mut frame[..len]).unwrap() {
            crate::HostCommand::ConfigureSystem(got) => assert_eq!(got, config),
            other => panic!("{other:?}"),
        }
    }
}
