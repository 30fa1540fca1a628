//! Proptest strategies for the wire configuration, [`lssi_proto::WireConfig`]: one copy
//! for lssi-proto's encoding tests and lssi-device's fuzzing (feature `wire`).
//!
//! ```
//! use lssi_testkit::wire::{any_wire_config, valid_wire_config};
//! use proptest::strategy::{Strategy, ValueTree};
//! use proptest::test_runner::TestRunner;
//!
//! let mut runner = TestRunner::deterministic();
//! let any = any_wire_config().new_tree(&mut runner).unwrap().current();
//! let near = valid_wire_config().new_tree(&mut runner).unwrap().current();
//! assert!(near.window < 80 && near.library.poly_order < 11);
//! # let _ = any;
//! ```

use lssi_proto::{PolyFamily, SampleEncoding, WireChannels, WireConfig, WireLibrary};
use proptest::prelude::*;

/// Any f64, bit for bit (NaNs and infinities included): the link carries bits, not values.
pub fn any_f64() -> impl Strategy<Value = f64> {
    any::<u64>().prop_map(f64::from_bits)
}

/// Any f64 (bit for bit), weighted toward the values that break things: 0, a plausible
/// sample period, a negative, NaN, infinity, the smallest normal.
pub fn edge_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        any_f64(),
        Just(0.0),
        Just(1e-3),
        Just(-1.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::MIN_POSITIVE),
    ]
}

/// Each of the three monomial families.
pub fn poly_family() -> impl Strategy<Value = PolyFamily> {
    prop_oneof![
        Just(PolyFamily::All),
        Just(PolyFamily::Families),
        Just(PolyFamily::OddFamilies)
    ]
}

/// Any channels.
pub fn any_wire_channels() -> impl Strategy<Value = WireChannels> {
    (any::<bool>(), any::<bool>()).prop_map(|(velocity, input)| WireChannels { velocity, input })
}

/// A library with every field anywhere.
pub fn any_wire_library() -> impl Strategy<Value = WireLibrary> {
    library(any::<u8>(), any::<u8>())
}

/// A library of order below 11 and fewer than 10 harmonics: around what a device holds.
pub fn valid_wire_library() -> impl Strategy<Value = WireLibrary> {
    library(0u8..11, 0u8..10)
}

fn library(
    poly_order: impl Strategy<Value = u8>,
    harmonics: impl Strategy<Value = u8>,
) -> impl Strategy<Value = WireLibrary> {
    (
        poly_order,
        poly_family(),
        any::<bool>(),
        harmonics,
        any::<bool>(),
    )
        .prop_map(
            |(poly_order, family, constant, harmonics, input)| WireLibrary {
                poly_order,
                family,
                constant,
                harmonics,
                input,
            },
        )
}

/// A configuration with every field any value, floats bit for bit (the encoding `F32`):
/// what the encoding must carry unchanged.
pub fn any_wire_config() -> impl Strategy<Value = WireConfig> {
    (
        (any_f64(), any::<u16>(), any::<u8>(), any_wire_library()),
        (
            any_f64(),
            any_wire_channels(),
            proptest::option::of(any_f64()),
        ),
        (any::<u32>(), any::<u8>(), any::<bool>(), any::<u16>()),
        (any_f64(), any::<bool>(), any_f64(), any::<u16>()),
    )
        .prop_map(assemble)
}

/// A configuration with every field anywhere but weighted toward the edges of the valid
/// range (short windows and screening periods, small libraries and strides, edge floats):
/// what a device must refuse or run without panicking.
pub fn valid_wire_config() -> impl Strategy<Value = WireConfig> {
    (
        (edge_f64(), 0u16..80, 0u8..10, valid_wire_library()),
        (
            edge_f64(),
            any_wire_channels(),
            proptest::option::of(edge_f64()),
        ),
        (0u32..50, any::<u8>(), any::<bool>(), 0u16..6),
        (
            edge_f64(),
            any::<bool>(),
            edge_f64(),
            prop_oneof![Just(0u16), 0u16..40],
        ),
    )
        .prop_map(assemble)
}

/// The fields grouped as the strategies draw them, in [`WireConfig`]'s order.
type Parts = (
    (f64, u16, u8, WireLibrary),
    (f64, WireChannels, Option<f64>),
    (u32, u8, bool, u16),
    (f64, bool, f64, u16),
);

fn assemble(
    (
        (sample_period, window, derivative_degree, library),
        (omega, channels, memory),
        (screening_period, thresholds, smoothing, row_stride),
        (parsimony, offsets, max_abs, test_rows),
    ): Parts,
) -> WireConfig {
    WireConfig {
        sample_period,
        window,
        derivative_degree,
        library,
        omega,
        channels,
        memory,
        screening_period,
        thresholds,
        smoothing,
        row_stride,
        parsimony,
        offsets,
        max_abs,
        test_rows,
        encoding: SampleEncoding::F32,
        duty: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;

    /// Draws `n` values of `strategy`.
    fn draws<S: Strategy>(strategy: S, n: usize) -> Vec<S::Value> {
        let mut runner = TestRunner::deterministic();
        (0..n)
            .map(|_| strategy.new_tree(&mut runner).expect("draws").current())
            .collect()
    }

    #[test]
    fn valid_configs_stay_near_the_valid_range() {
        for c in draws(valid_wire_config(), 500) {
            assert!(c.window < 80 && c.derivative_degree < 10, "{c:?}");
            assert!(
                c.library.poly_order < 11 && c.library.harmonics < 10,
                "{c:?}"
            );
            assert!(
                c.screening_period < 50 && c.row_stride < 6 && c.test_rows < 40,
                "{c:?}"
            );
        }
    }

    #[test]
    fn any_configs_reach_past_the_valid_range() {
        let configs = draws(any_wire_config(), 500);
        assert!(configs.iter().any(|c| c.window >= 80));
        assert!(configs.iter().any(|c| c.library.poly_order >= 11));
        assert!(configs.iter().any(|c| c.screening_period >= 50));
        assert!(
            configs
                .iter()
                .any(|c| c.sample_period.is_nan() || c.sample_period < 0.0)
        );
        // Every family and both values of each flag come up.
        for family in [
            PolyFamily::All,
            PolyFamily::Families,
            PolyFamily::OddFamilies,
        ] {
            assert!(
                configs.iter().any(|c| c.library.family == family),
                "{family:?}"
            );
        }
        assert!(configs.iter().any(|c| c.channels.velocity));
        assert!(configs.iter().any(|c| !c.channels.input));
    }
}
