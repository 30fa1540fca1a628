//! The device over an in-process loopback: the handshake, configuration, exactly-once
//! batches through duplicates, gaps and corrupt frames, queries, resets and logs.

use crate::common;

use common::*;
use lssi_device::wire::{config_from_wire, config_to_wire};
use lssi_device::{DEFAULT_TERMS, DEFAULT_WINDOW};
use lssi_proto::{
    CONTROL_SEQ, CostUnit, DeviceMsg, HostMsg, MAX_BATCH, MAX_LOG, NakReason, PROTOCOL_VERSION,
    SnapshotCause,
};

type DefaultHost = Host<DEFAULT_WINDOW, DEFAULT_TERMS>;

fn configure(host: &mut DefaultHost) {
    let wire = config_to_wire(&duffing_config()).expect("fits the wire");
    assert_eq!(
        host.exchange(&HostMsg::Configure(wire)),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
}

fn health_field(message: &DeviceMsg) -> (u64, u32, u32, u32) {
    match message {
        DeviceMsg::Health {
            samples,
            duplicates,
            crc_errors,
            decode_errors,
            ..
        } => (*samples, *duplicates, *crc_errors, *decode_errors),
        other => panic!("expected Health, got {other:?}"),
    }
}

#[test]
fn hello_reports_version_and_capacities() {
    let mut host = DefaultHost::default();
    let replies = host.exchange(&HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION,
    });
    assert_eq!(
        replies,
        [DeviceMsg::HelloReply {
            protocol_version: PROTOCOL_VERSION,
            max_terms: DEFAULT_TERMS as u8,
            window_capacity: DEFAULT_WINDOW as u16,
            max_batch: MAX_BATCH as u16,
        }]
    );
}

#[test]
fn a_hello_of_another_version_gets_our_version() {
    let mut host = DefaultHost::default();
    let replies = host.exchange(&HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION + 7,
    });
    assert!(matches!(
        replies[..],
        [DeviceMsg::HelloReply {
            protocol_version: PROTOCOL_VERSION,
            ..
        }]
    ));
}

#[test]
fn commands_before_configure_are_refused() {
    let mut host = DefaultHost::default();
    let batch = batches(&duffing(10, 1e-3), 3).remove(0);
    assert_eq!(
        host.exchange(&HostMsg::Samples(batch)),
        [DeviceMsg::Nak {
            seq: 3,
            reason: NakReason::NotConfigured
        }]
    );
    let nak = DeviceMsg::Nak {
        seq: CONTROL_SEQ,
        reason: NakReason::NotConfigured,
    };
    assert_eq!(host.exchange(&HostMsg::Query), std::slice::from_ref(&nak));
    assert_eq!(host.exchange(&HostMsg::Reset), [nak]);
}

#[test]
fn a_bad_configuration_is_naked_and_the_old_one_stays() {
    let mut host = DefaultHost::default();
    configure(&mut host);
    let mut wire = config_to_wire(&duffing_config()).expect("fits");
    wire.window = (DEFAULT_WINDOW + 1) as u16;
    assert_eq!(
        host.exchange(&HostMsg::Configure(wire)),
        [DeviceMsg::Nak {
            seq: CONTROL_SEQ,
            reason: NakReason::BadConfig
        }]
    );
    assert_eq!(host.device.config(), Some(&duffing_config()));
    wire.window = 63;
    wire.library.poly_order = 9; // 55 monomials: beyond 16 terms
    let asked = lssi_core::Library::<64>::count(&config_from_wire(&wire).library);
    assert!(asked > DEFAULT_TERMS);
    // A library over the capacity is refused naming the size asked for and the limit.
    assert_eq!(
        host.exchange(&HostMsg::Configure(wire)),
        [DeviceMsg::Nak {
            seq: CONTROL_SEQ,
            reason: NakReason::TooManyTerms {
                terms: asked as u8,
                capacity: DEFAULT_TERMS as u8
            }
        }]
    );
    // Poly order 5 and 5 harmonics (32 terms), the largest library the host identifies.
    wire.library.poly_order = 5;
    wire.library.harmonics = 5;
    let asked = lssi_core::Library::<64>::count(&config_from_wire(&wire).library);
    assert!(matches!(
        host.exchange(&HostMsg::Configure(wire))[..],
        [DeviceMsg::Nak {
            reason: NakReason::TooManyTerms { terms, capacity },
            ..
        }] if usize::from(terms) == asked && usize::from(capacity) == DEFAULT_TERMS
    ));
    assert_eq!(host.device.config(), Some(&duffing_config()));
}

#[test]
fn a_device_with_two_channel_rings_refuses_three_channels() {
    let mut host: Host<DEFAULT_WINDOW, DEFAULT_TERMS, 2> = Host::default();
    let mut config = duffing_config();
    config.channels.velocity = true;
    let wire = config_to_wire(&config).expect("fits");
    assert_eq!(
        host.exchange(&HostMsg::Configure(wire)),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    config.channels.input = true;
    let wire = config_to_wire(&config).expect("fits");
    assert_eq!(
        host.exchange(&HostMsg::Configure(wire)),
        [DeviceMsg::Nak {
            seq: CONTROL_SEQ,
            reason: NakReason::BadConfig
        }]
    );
    // The x + v configuration stays.
    assert!(host.device.config().is_some_and(|c| !c.channels.input));
}

#[test]
fn the_device_rebuilds_exactly_the_hosts_config() {
    let mut host = DefaultHost::default();
    let mut config = duffing_config();
    config.memory = Some(12.5);
    config.parsimony = 0.03;
    config.row_stride = 3;
    config.max_abs = 1e6;
    config.offsets = false;
    config.derivative_degree = 4;
    config.omega = core::f64::consts::PI * 7.000_000_1;
    let wire = config_to_wire(&config).expect("fits");
    assert_eq!(config_from_wire(&wire), config);
    assert_eq!(
        host.exchange(&HostMsg::Configure(wire)),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    assert_eq!(host.device.config(), Some(&config));
}

#[test]
fn batches_apply_exactly_once_in_order() {
    let mut host = DefaultHost::default();
    configure(&mut host);
    let b = batches(&duffing(5 * MAX_BATCH, 1e-3), 0);
    assert_eq!(
        host.exchange(&HostMsg::Samples(b[0].clone())),
        [DeviceMsg::Ack { seq: 0 }]
    );
    // A gap: batch 2 before 1 is refused, with the seq to resend from.
    assert_eq!(
        host.exchange(&HostMsg::Samples(b[2].clone())),
        [DeviceMsg::Nak {
            seq: 1,
            reason: NakReason::OutOfOrder
        }]
    );
    assert_eq!(
        host.exchange(&HostMsg::Samples(b[1].clone())),
        [DeviceMsg::Ack { seq: 1 }]
    );
    // Duplicates are acked, not applied.
    assert_eq!(
        host.exchange(&HostMsg::Samples(b[0].clone())),
        [DeviceMsg::Ack { seq: 0 }]
    );
    assert_eq!(
        host.exchange(&HostMsg::Samples(b[1].clone())),
        [DeviceMsg::Ack { seq: 1 }]
    );
    // A corrupt frame is dropped silently and counted; the resend goes through.
    let mut bad = frame(&HostMsg::Samples(b[2].clone()));
    bad[10] ^= 0x10;
    host.raw(&bad);
    assert_eq!(host.replies(), []);
    assert_eq!(
        host.exchange(&HostMsg::Samples(b[2].clone())),
        [DeviceMsg::Ack { seq: 2 }]
    );
    let replies = host.exchange(&HostMsg::Query);
    let (samples, duplicates, crc_errors, _) = health_field(replies.last().expect("health"));
    assert_eq!(samples, 3 * MAX_BATCH as u64);
    assert_eq!(duplicates, 2);
    assert!(crc_errors >= 1);
    assert_eq!(host.device.next_seq(), 3);
    assert_eq!(
        host.device.identifier().map(|id| id.counters().accepted),
        Some(3 * MAX_BATCH as u64)
    );
}

#[test]
fn a_decodable_frame_of_no_message_is_naked() {
    let mut host = DefaultHost::default();
    configure(&mut host);
    // Discriminant 9 is no HostMsg; the frame's CRC is right.
    let crc = crc32c(&[9]);
    let mut raw = vec![9u8];
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut framed = cobs_frame(&raw);
    framed.push(0);
    host.raw(&framed);
    assert_eq!(
        host.replies(),
        [DeviceMsg::Nak {
            seq: 0,
            reason: NakReason::Decode
        }]
    );
    let replies = host.exchange(&HostMsg::Query);
    assert_eq!(health_field(replies.last().expect("health")).3, 1);
}

fn crc32c(bytes: &[u8]) -> u32 {
    // Bitwise CRC-32C (Castagnoli, reflected), independent of the crate under test.
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0x82F6_3B78
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn cobs_frame(raw: &[u8]) -> Vec<u8> {
    // Payloads under 254 bytes: one code byte per run of non-zero bytes.
    let mut out = Vec::new();
    for run in raw.split(|&b| b == 0) {
        out.push(run.len() as u8 + 1);
        out.extend_from_slice(run);
    }
    out
}

#[test]
fn frames_split_and_merged_arbitrarily_still_decode() {
    let mut host = DefaultHost::default();
    host.link.chunk = 3;
    configure(&mut host);
    let b = batches(&duffing(3 * MAX_BATCH, 1e-3), 0);
    // Garbage, a flush, then three batches back to back.
    host.raw(&[0x13, 0x77, 0xFF, 0x00]);
    for batch in &b {
        host.send(&HostMsg::Samples(batch.clone()));
    }
    assert_eq!(
        host.replies(),
        [
            DeviceMsg::Ack { seq: 0 },
            DeviceMsg::Ack { seq: 1 },
            DeviceMsg::Ack { seq: 2 }
        ]
    );
}

#[test]
fn reset_keeps_the_config_and_restarts_the_sequence() {
    let mut host = DefaultHost::default();
    configure(&mut host);
    let b = batches(&duffing(2 * MAX_BATCH, 1e-3), 0);
    host.exchange(&HostMsg::Samples(b[0].clone()));
    host.exchange(&HostMsg::Samples(b[1].clone()));
    assert_eq!(
        host.exchange(&HostMsg::Reset),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    assert_eq!(host.device.next_seq(), 0);
    assert_eq!(host.device.config(), Some(&duffing_config()));
    assert_eq!(
        host.device.identifier().map(|id| id.counters().accepted),
        Some(0)
    );
    assert_eq!(
        host.exchange(&HostMsg::Samples(b[0].clone())),
        [DeviceMsg::Ack { seq: 0 }]
    );
}

#[test]
fn query_before_a_model_answers_health_only_with_costs() {
    let mut host = DefaultHost::default();
    configure(&mut host);
    let b = batches(&duffing(MAX_BATCH, 1e-3), 0);
    host.exchange(&HostMsg::Samples(b[0].clone()));
    let replies = host.exchange(&HostMsg::Query);
    match &replies[..] {
        [
            DeviceMsg::Health {
                samples,
                cost_mean,
                cost_max,
                cost_unit,
                watchdog,
                frames_ok,
                ..
            },
        ] => {
            assert_eq!(*samples, MAX_BATCH as u64);
            assert_eq!(
                (*cost_mean, *cost_max, *cost_unit),
                (7, 7, CostUnit::Cycles)
            );
            assert!(*watchdog > 0);
            assert_eq!(*frames_ok, 3);
        }
        other => panic!("expected Health alone, got {other:?}"),
    }
}

#[test]
fn log_bytes_travel_in_order_in_bounded_frames() {
    let mut host = DefaultHost::default();
    let bytes: Vec<u8> = (0..=255u8).cycle().take(3 * MAX_LOG + 5).collect();
    host.device
        .send_log(&mut host.link, &bytes)
        .expect("infallible");
    let replies = host.replies();
    assert_eq!(replies.len(), 4);
    let mut joined = Vec::new();
    for reply in replies {
        match reply {
            DeviceMsg::Log { bytes } => joined.extend_from_slice(&bytes),
            other => panic!("expected Log, got {other:?}"),
        }
    }
    assert_eq!(joined, bytes);
}

#[test]
fn scheduled_screenings_send_snapshots() {
    let mut host = DefaultHost::default();
    configure(&mut host);
    let samples = duffing(12_000, 1e-3);
    let mut scheduled = 0;
    for batch in batches(&samples, 0) {
        let seq = batch.seq;
        let replies = host.exchange(&HostMsg::Samples(batch));
        assert_eq!(replies.first(), Some(&DeviceMsg::Ack { seq }));
        for reply in &replies[1..] {
            match reply {
                DeviceMsg::Model(m) => {
                    assert_eq!(m.cause, SnapshotCause::Scheduled);
                    scheduled += 1;
                }
                other => panic!("unexpected {other:?}"),
            }
        }
    }
    // Screenings at 5 000 and 10 000 samples (both have enough rows).
    assert_eq!(scheduled, 2);
}
