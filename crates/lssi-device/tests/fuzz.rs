//! No input makes the device panic, and after any input it answers a valid `Hello`.

mod common;

use common::*;
use lssi_device::wire::config_to_wire;
use lssi_proto::{
    DeviceMsg, HostMsg, PROTOCOL_VERSION, PolyFamily, WireChannels, WireConfig, WireLibrary,
};
use proptest::collection::vec;
use proptest::prelude::*;

type SmallHost = Host<64, 16>;

fn hello_still_answered(host: &mut SmallHost) -> Result<(), TestCaseError> {
    // A leading 0x00 flushes whatever half frame the garbage left in the decoder.
    host.raw(&[0]);
    let replies = host.exchange(&HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION,
    });
    prop_assert!(
        matches!(
            replies.last(),
            Some(DeviceMsg::HelloReply {
                protocol_version: PROTOCOL_VERSION,
                ..
            })
        ),
        "{replies:?}"
    );
    Ok(())
}

/// A valid session: configure, a few batches, a query, a reset.
fn session() -> Vec<u8> {
    let mut config = duffing_config();
    config.window = 15;
    config.screening_period = 40;
    let mut bytes = frame(&HostMsg::Configure(config_to_wire(&config).expect("fits")));
    for batch in batches(&duffing(120, 1e-3), 0) {
        bytes.extend(frame(&HostMsg::Samples(batch)));
    }
    bytes.extend(frame(&HostMsg::Query));
    bytes.extend(frame(&HostMsg::Reset));
    bytes
}

#[derive(Clone, Debug)]
enum Mutation {
    Flip(usize, u8),
    Drop(usize),
    Insert(usize, u8),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 0u8..8).prop_map(|(i, bit)| Mutation::Flip(i, bit)),
        any::<usize>().prop_map(Mutation::Drop),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Insert(i, b)),
    ]
}

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<u64>().prop_map(f64::from_bits),
        Just(0.0),
        Just(1e-3),
        Just(-1.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::MIN_POSITIVE),
    ]
}

/// Configurations with every field anywhere, weighted toward the edges of the valid range.
fn wire_config() -> impl Strategy<Value = WireConfig> {
    (
        (any_f64(), 0u16..80, 0u8..10, 0u8..11, 0u8..3, any::<bool>()),
        (
            0u8..10,
            any::<bool>(),
            any_f64(),
            any::<bool>(),
            any::<bool>(),
        ),
        (
            proptest::option::of(any_f64()),
            0u32..50,
            any::<u8>(),
            any::<bool>(),
            0u16..6,
        ),
        (
            any_f64(),
            any::<bool>(),
            any_f64(),
            prop_oneof![Just(0u16), 0u16..40],
        ),
    )
        .prop_map(
            |(
                (sample_period, window, derivative_degree, poly_order, family, constant),
                (harmonics, input, omega, velocity, input_channel),
                (memory, screening_period, thresholds, smoothing, row_stride),
                (parsimony, offsets, max_abs, test_rows),
            )| WireConfig {
                sample_period,
                window,
                derivative_degree,
                library: WireLibrary {
                    poly_order,
                    family: [
                        PolyFamily::All,
                        PolyFamily::Families,
                        PolyFamily::OddFamilies,
                    ][usize::from(family)],
                    constant,
                    harmonics,
                    input,
                },
                omega,
                channels: WireChannels {
                    velocity,
                    input: input_channel,
                },
                memory,
                screening_period,
                thresholds,
                smoothing,
                row_stride,
                parsimony,
                offsets,
                max_abs,
                test_rows,
                encoding: lssi_proto::SampleEncoding::F32,
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_break_the_device(bytes in vec(any::<u8>(), 0..2048), chunk in 1usize..100) {
        let mut host = SmallHost::default();
        host.link.chunk = chunk;
        host.raw(&bytes);
        host.replies();
        hello_still_answered(&mut host)?;
    }

    #[test]
    fn mutated_sessions_never_break_the_device(mutations in vec(mutation(), 1..12)) {
        let mut bytes = session();
        for m in mutations {
            match m {
                Mutation::Flip(i, bit) => {
                    let i = i % bytes.len();
                    bytes[i] ^= 1 << bit;
                }
                Mutation::Drop(i) => {
                    bytes.remove(i % bytes.len());
                }
                Mutation::Insert(i, b) => {
                    let i = i % (bytes.len() + 1);
                    bytes.insert(i, b);
                }
            }
        }
        let mut host = SmallHost::default();
        host.raw(&bytes);
        host.replies();
        hello_still_answered(&mut host)?;
    }

    #[test]
    fn arbitrary_configurations_and_samples_never_panic(
        config in wire_config(),
        values in vec((any_f64(), any::<u32>().prop_map(f32::from_bits)), 0..150),
    ) {
        let mut host = SmallHost::default();
        host.exchange(&HostMsg::Configure(config));
        let mut batch = lssi_proto::SampleBatch::new(0, lssi_proto::Channels::new(config.channels.velocity, config.channels.input));
        let mut seq = 0;
        for (t, x) in values {
            let sample = lssi_proto::WireSample {
                t,
                x,
                v: config.channels.velocity.then_some(x),
                u: config.channels.input.then_some(-x),
            };
            if let Err(sample) = batch.push(sample) {
                host.exchange(&HostMsg::Samples(batch));
                seq += 1;
                batch = lssi_proto::SampleBatch::new(seq, lssi_proto::Channels::of(&sample));
                let _ = batch.push(sample);
            }
        }
        host.exchange(&HostMsg::Samples(batch));
        host.exchange(&HostMsg::Query);
        host.exchange(&HostMsg::Reset);
        hello_still_answered(&mut host)?;
    }
}
