//! No input makes the device panic, and after any input it answers a valid `Hello`.

use crate::common;

use common::*;
use lssi_device::wire::config_to_wire;
use lssi_proto::{DeviceMsg, HostMsg, PROTOCOL_VERSION};
use lssi_testkit::wire::{edge_f64, valid_wire_config};
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
        config in valid_wire_config(),
        values in vec((edge_f64(), any::<u32>().prop_map(f32::from_bits)), 0..150),
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
