//! Every message survives encode → decode, bit for bit, and the batch API keeps its promises.

use crate::common;

use common::*;
use lssi_proto::{
    Channels, DeviceMsg, Error, HostMsg, MAX_BATCH, MAX_DEVICE_FRAME_LEN, MAX_HOST_FRAME_LEN,
    NakReason, PROTOCOL_VERSION, SampleBatch, WireSample, decode_frame, encode_device, encode_host,
};
use proptest::prelude::*;

fn round_trip_host(message: &HostMsg) -> HostMsg {
    let mut frame = [0u8; MAX_HOST_FRAME_LEN];
    let len = encode_host(message, &mut frame).expect("fits");
    decode_frame(&mut frame[..len]).expect("decodes")
}

fn round_trip_device(message: &DeviceMsg) -> DeviceMsg {
    let mut frame = [0u8; MAX_DEVICE_FRAME_LEN];
    let len = encode_device(message, &mut frame).expect("fits");
    decode_frame(&mut frame[..len]).expect("decodes")
}

fn small_batch(channels: Channels) -> SampleBatch {
    let mut batch = SampleBatch::new(300, channels);
    for i in 0..5u32 {
        let t = f64::from(i) * 1e-3 + 0.1;
        let sample = WireSample {
            t,
            x: (t * 7.0).sin() as f32,
            v: channels.has_v().then_some(-f64::from(i) as f32),
            u: channels.has_u().then_some(0.25),
        };
        batch.push(sample).expect("room");
    }
    batch
}

#[test]
fn every_host_message_round_trips() {
    let mut messages = worst_host_msgs();
    for channels in [Channels::X, Channels::XV, Channels::XU, Channels::XVU] {
        messages.push(HostMsg::Samples(small_batch(channels)));
        messages.push(HostMsg::Samples(SampleBatch::new(0, channels)));
    }
    let mut config = worst_config();
    config.memory = None;
    messages.push(HostMsg::Configure(config));
    for message in &messages {
        assert_eq!(&round_trip_host(message), message);
    }
}

#[test]
fn every_device_message_round_trips() {
    let mut messages = worst_device_msgs();
    let mut snapshot = worst_snapshot();
    snapshot.resonance_hz = None;
    snapshot.wells = None;
    snapshot.solutions.clear();
    messages.push(DeviceMsg::Model(snapshot));
    messages.push(DeviceMsg::Model(Default::default()));
    messages.push(DeviceMsg::Log {
        bytes: heapless::Vec::new(),
    });
    for message in &messages {
        assert_eq!(&round_trip_device(message), message);
    }
}

#[test]
fn the_handshake_bytes_are_frozen() {
    // Variant 0, then the version as a varint: what every protocol version can read.
    let mut payload = [0u8; 8];
    let hello = HostMsg::Hello {
        protocol_version: 0x1234,
    };
    assert_eq!(
        postcard::to_slice(&hello, &mut payload).expect("fits"),
        &[0x00, 0xB4, 0x24]
    );
    let reply = DeviceMsg::HelloReply {
        protocol_version: 1,
        max_terms: 2,
        window_capacity: 3,
        max_batch: 4,
    };
    assert_eq!(
        postcard::to_slice(&reply, &mut payload).expect("fits"),
        &[0x00, 1, 2, 3, 4]
    );
}

#[test]
fn a_different_protocol_version_is_reported_as_such() {
    let theirs = PROTOCOL_VERSION + 1;
    let mut frame = frame(&HostMsg::Hello {
        protocol_version: theirs,
    });
    assert_eq!(
        decode_frame::<HostMsg>(&mut frame),
        Err(Error::VersionMismatch {
            ours: PROTOCOL_VERSION,
            theirs
        })
    );
    // A newer device's reply may have more fields; the version is still read.
    let version = u8::try_from(theirs).expect("a one-byte varint");
    let mut frame = frame_payload(&[0x00, version, 9, 9, 9, 9, 9, 9, 9]);
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut frame),
        Err(Error::VersionMismatch {
            ours: PROTOCOL_VERSION,
            theirs
        })
    );
}

#[test]
fn trailing_bytes_and_unknown_variants_are_decode_errors() {
    // Ack { seq: 5 } and one byte too many.
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut frame_payload(&[1, 5])),
        Ok(DeviceMsg::Ack { seq: 5 })
    );
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut frame_payload(&[1, 5, 0])),
        Err(Error::Decode)
    );
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut frame_payload(&[6])),
        Err(Error::Decode)
    );
    assert_eq!(
        decode_frame::<HostMsg>(&mut frame_payload(&[5])),
        Err(Error::Decode)
    );
    assert_eq!(
        decode_frame::<HostMsg>(&mut frame_payload(&[])),
        Err(Error::Decode)
    );
    // Nak with reason 8 (no such reason).
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut frame_payload(&[2, 1, 8])),
        Err(Error::Decode)
    );
}

#[test]
fn a_batch_refuses_unknown_channels_and_too_many_samples() {
    // Samples { seq: 1, channels: 0b100, no samples }.
    assert_eq!(
        decode_frame::<HostMsg>(&mut frame_payload(&[2, 1, 0b100, 0])),
        Err(Error::Decode)
    );
    // A count above MAX_BATCH, before any sample bytes.
    let count = u8::try_from(MAX_BATCH + 1).expect("small");
    assert_eq!(
        decode_frame::<HostMsg>(&mut frame_payload(&[2, 1, 0, count])),
        Err(Error::Decode)
    );
    // A count the bytes do not back.
    assert_eq!(
        decode_frame::<HostMsg>(&mut frame_payload(&[2, 1, 0, 1, 0, 0])),
        Err(Error::Decode)
    );
    // An x-only sample is exactly t then x, little endian.
    let mut payload = vec![2, 1, 0, 1];
    payload.extend_from_slice(&0.5f64.to_le_bytes());
    payload.extend_from_slice(&2.0f32.to_le_bytes());
    let Ok(HostMsg::Samples(batch)) = decode_frame::<HostMsg>(&mut frame_payload(&payload)) else {
        panic!("a valid x-only batch");
    };
    assert_eq!(
        batch.iter().collect::<Vec<_>>(),
        [WireSample {
            t: 0.5,
            x: 2.0,
            v: None,
            u: None
        }]
    );
}

#[test]
fn push_hands_the_sample_back_when_full_or_of_other_channels() {
    let mut batch = SampleBatch::new(1, Channels::XV);
    let with_v = WireSample {
        t: 0.0,
        x: 1.0,
        v: Some(2.0),
        u: None,
    };
    let without_v = WireSample { v: None, ..with_v };
    let with_u = WireSample {
        u: Some(3.0),
        ..with_v
    };
    assert_eq!(batch.push(without_v), Err(without_v));
    assert_eq!(batch.push(with_u), Err(with_u));
    for i in 0..MAX_BATCH {
        assert!(!batch.is_full());
        let sample = WireSample {
            t: i as f64,
            ..with_v
        };
        assert_eq!(batch.push(sample), Ok(()));
    }
    assert!(batch.is_full());
    assert_eq!(batch.push(with_v), Err(with_v));
    assert_eq!(batch.len(), MAX_BATCH);
    assert_eq!(batch.iter().len(), MAX_BATCH);
    assert_eq!(batch.get(3).map(|s| s.t), Some(3.0));
    assert_eq!(batch.get(MAX_BATCH), None);
    assert_eq!(
        batch.iter().next_back().map(|s| s.t),
        Some((MAX_BATCH - 1) as f64)
    );
    assert!(batch.iter().all(|s| s.v == Some(2.0) && s.u.is_none()));
    batch.clear();
    assert!(batch.is_empty());
    assert_eq!(batch.channels(), Channels::XV);
}

#[test]
fn channel_masks() {
    assert_eq!(Channels::from_bits(0b11), Some(Channels::XVU));
    assert_eq!(Channels::from_bits(0b100), None);
    assert_eq!(Channels::new(true, false), Channels::XV);
    assert_eq!(Channels::new(false, true).bits(), Channels::U_BIT);
    let widths: Vec<_> = [Channels::X, Channels::XV, Channels::XU, Channels::XVU]
        .map(Channels::bytes_per_sample)
        .into();
    assert_eq!(widths, [12, 16, 16, 20]);
}

#[test]
fn errors_read_as_sentences_and_map_to_nak_reasons() {
    let errors = [
        Error::BufferTooSmall,
        Error::Encode,
        Error::Overflow,
        Error::Cobs,
        Error::Crc,
        Error::Decode,
        Error::VersionMismatch { ours: 1, theirs: 2 },
    ];
    for error in errors {
        let text = error.to_string();
        assert!(text.starts_with(|c: char| c.is_lowercase()), "{text}");
        assert!(!text.ends_with('.'), "{text}");
    }
    assert_eq!(
        Error::VersionMismatch { ours: 1, theirs: 2 }.to_string(),
        "the peer speaks lssi protocol version 2, but this build speaks version 1"
    );
    assert_eq!(Error::Crc.nak_reason(), Some(NakReason::Crc));
    assert_eq!(Error::BufferTooSmall.nak_reason(), None);
}

#[test]
fn encode_reports_a_short_buffer() {
    let message = HostMsg::Samples(worst_batch());
    let full = frame(&message).len();
    let mut out = vec![0u8; full - 1];
    assert_eq!(encode_host(&message, &mut out), Err(Error::BufferTooSmall));
    assert_eq!(encode_host(&message, &mut []), Err(Error::BufferTooSmall));
}

#[cfg(feature = "std")]
#[test]
fn write_frame_writes_one_frame() {
    let message = DeviceMsg::Nak {
        seq: 9,
        reason: NakReason::Busy,
    };
    let mut out = Vec::new();
    let len = lssi_proto::write_frame(&mut out, &message).expect("a Vec takes it");
    assert_eq!(out, frame(&message));
    assert_eq!(len, out.len());
    let error: std::io::Error = Error::Crc.into();
    assert_eq!(error.kind(), std::io::ErrorKind::InvalidData);
}

proptest! {
    #![proptest_config(cases(512))]

    /// Re-encoding the decoded message gives the same bytes: every f64/f32 (NaN payloads
    /// included) crossed the link bit for bit.
    #[test]
    fn host_messages_round_trip_bit_for_bit(message in host_msg()) {
        let bytes = frame(&message);
        let decoded = decode_chunks::<HostMsg, MAX_HOST_FRAME_LEN>(&[&bytes]);
        prop_assert_eq!(decoded.len(), 1);
        let decoded = decoded.into_iter().next().expect("one").expect("valid");
        prop_assert_eq!(frame(&decoded), bytes);
        if let (HostMsg::Samples(sent), HostMsg::Samples(got)) = (&message, &decoded) {
            prop_assert_eq!(sent.len(), got.len());
            for (a, b) in sent.iter().zip(got) {
                prop_assert_eq!(a.t.to_bits(), b.t.to_bits());
                prop_assert_eq!(a.x.to_bits(), b.x.to_bits());
                prop_assert_eq!(a.v.map(f32::to_bits), b.v.map(f32::to_bits));
                prop_assert_eq!(a.u.map(f32::to_bits), b.u.map(f32::to_bits));
            }
        }
    }

    #[test]
    fn device_messages_round_trip_bit_for_bit(message in device_msg()) {
        let bytes = frame(&message);
        let decoded = decode_chunks::<DeviceMsg, MAX_DEVICE_FRAME_LEN>(&[&bytes]);
        prop_assert_eq!(decoded.len(), 1);
        let decoded = decoded.into_iter().next().expect("one").expect("valid");
        prop_assert_eq!(frame(&decoded), bytes);
    }
}

/// A version-6 Health: every field of version 7's but `drift`.
fn version_6_health_payload() -> Vec<u8> {
    let mut payload = vec![0x04];
    // samples, rejected, buffer_fill, cost_mean, cost_max, cost_unit (Cycles = 1), watchdog,
    // crc_errors, frames_ok, screen_cost, screen_cost_max, screenings, duplicates,
    // decode_errors, overruns, queue_high_water, latency_max_ns, screenings_skipped.
    payload.extend_from_slice(&[100, 0, 33, 40, 50, 1, 7, 0, 9, 60, 70, 2, 0, 0, 0, 3, 80, 0]);
    payload.extend_from_slice(&200.0f32.to_le_bytes());
    payload
}

#[test]
fn health_carries_the_drift_since_version_7_and_a_version_6_peer_is_refused() {
    let drift = lssi_proto::WireDrift {
        windows: 12,
        relative: 0.031,
        largest: 0.12,
        largest_term: 3,
        support_changes: 1,
    };
    let DeviceMsg::Health { .. } = &worst_device_msgs()[4] else {
        panic!("the worst messages' fifth is Health");
    };
    let mut health = worst_device_msgs()[4].clone();
    if let DeviceMsg::Health { drift: d, .. } = &mut health {
        *d = Some(drift);
    }
    assert_eq!(round_trip_device(&health), health);
    if let DeviceMsg::Health { drift: d, .. } = &mut health {
        *d = None;
    }
    assert_eq!(round_trip_device(&health), health);

    // Version 7's Health is version 6's and the drift: a version-6 Health does not decode
    // (one byte short), and with `None` appended it does.
    let old = version_6_health_payload();
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut frame_payload(&old)),
        Err(Error::Decode)
    );
    let mut new = old.clone();
    new.push(0x00);
    // (and version 9's reference, `None`)
    new.push(0x00);
    let decoded = decode_frame::<DeviceMsg>(&mut frame_payload(&new)).expect("decodes");
    assert!(matches!(
        decoded,
        DeviceMsg::Health {
            samples: 100,
            sample_rate_hz: 200.0,
            drift: None,
            ..
        }
    ));
    // So a version-6 device is refused at its HelloReply, with a sentence naming both
    // versions, before any Health of it is read.
    assert_eq!(PROTOCOL_VERSION, 9);
    let mut reply = frame_payload(&[0x00, 6, 16, 0x80, 0x02, 24]);
    let error = decode_frame::<DeviceMsg>(&mut reply).expect_err("refused");
    assert_eq!(error, Error::VersionMismatch { ours: 9, theirs: 6 });
    assert_eq!(
        error.to_string(),
        "the peer speaks lssi protocol version 6, but this build speaks version 9"
    );
}

#[test]
fn health_carries_the_references_since_version_9_in_f64() {
    // A version-8 Health (version 7's with `drift: None`) lacks the reference's byte.
    let mut old = version_6_health_payload();
    old.push(0x00);
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut frame_payload(&old)),
        Err(Error::Decode)
    );
    // With `Some` and three f64 appended it decodes, every bit of each reference kept (an
    // ADC's mid-scale and a motion 10⁻⁴ of it).
    let (x, v, e) = (2_048.000_123_456_789_f64, -1.0e4 - 1.0e-9, 1.65);
    let mut new = old.clone();
    new.push(0x01);
    for r in [x, v, e] {
        new.extend_from_slice(&r.to_le_bytes());
    }
    let decoded = decode_frame::<DeviceMsg>(&mut frame_payload(&new)).expect("decodes");
    let DeviceMsg::Health { reference, .. } = decoded else {
        panic!("a Health: {decoded:?}");
    };
    assert_eq!(reference, Some(lssi_proto::WireReference { x, v, e }));
}
