//! Golden frames: the README's worked examples, byte for byte, for implementers elsewhere.

use crate::common;

use common::frame;
use lssi_proto::{
    Channels, DeviceMsg, HostMsg, MAX_HOST_FRAME_LEN, NakReason, PROTOCOL_VERSION, PolyFamily,
    SampleBatch, SampleEncoding, WireChannels, WireConfig, WireDuty, WireLibrary, WireSample,
    decode_frame,
};

#[test]
fn crc_is_crc32c() {
    // The catalogue's check value of CRC-32C (iSCSI): "123456789" → 0xE3069283.
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);
    assert_eq!(crc.checksum(b"123456789"), 0xE306_9283);
    // The Hello frame's CRC, over its payload 00 03.
    assert_eq!(crc.checksum(&[0x00, 0x03]), 0xE231_8426);
}

#[test]
fn golden_host_frames() {
    assert_eq!(PROTOCOL_VERSION, 9, "update the README's worked examples");
    assert_eq!(
        frame(&HostMsg::Hello {
            protocol_version: 9
        }),
        [0x01, 0x06, 0x09, 0x1E, 0xAC, 0xD3, 0x89, 0x00]
    );
    // Version-8, -7, -6 and -5 hosts' Hellos still read as such (variant 0 is frozen).
    assert_eq!(
        frame(&HostMsg::Hello {
            protocol_version: 8
        }),
        [0x01, 0x06, 0x08, 0x1D, 0x2F, 0xB8, 0x7B, 0x00]
    );
    assert_eq!(
        frame(&HostMsg::Hello {
            protocol_version: 7
        }),
        [0x01, 0x06, 0x07, 0x39, 0x13, 0xAB, 0x25, 0x00]
    );
    assert_eq!(
        frame(&HostMsg::Hello {
            protocol_version: 6
        }),
        [0x01, 0x06, 0x06, 0x3A, 0x90, 0xC0, 0xD7, 0x00]
    );
    assert_eq!(
        frame(&HostMsg::Hello {
            protocol_version: 5
        }),
        [0x01, 0x06, 0x05, 0xCE, 0x63, 0x90, 0xC4, 0x00]
    );
    assert_eq!(
        frame(&HostMsg::Query),
        [0x06, 0x03, 0xA5, 0xA0, 0x2D, 0x41, 0x00]
    );

    let mut batch = SampleBatch::new(1, Channels::X);
    batch
        .push(WireSample {
            t: 0.5,
            x: 2.0,
            v: None,
            u: None,
        })
        .expect("room");
    let golden = [
        0x03, 0x02, 0x01, 0x02, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x03, 0xE0, 0x3F, 0x01, 0x01,
        0x06, 0x40, 0xDE, 0x04, 0xC0, 0xDB, 0x00,
    ];
    assert_eq!(frame(&HostMsg::Samples(batch.clone())), golden);
    let mut bytes = golden;
    assert_eq!(
        decode_frame::<HostMsg>(&mut bytes),
        Ok(HostMsg::Samples(batch))
    );
    // Decoded in place: the payload (02 01 00 01, t, x) and the CRC (DE 04 C0 DB).
    assert_eq!(
        bytes[..20],
        [
            0x02, 0x01, 0x00, 0x01, 0, 0, 0, 0, 0, 0, 0xE0, 0x3F, 0, 0, 0, 0x40, 0xDE, 0x04, 0xC0,
            0xDB
        ]
    );
    assert!(golden.len() <= MAX_HOST_FRAME_LEN);
}

#[test]
fn golden_device_frames() {
    // seq 300 is the varint AC 02.
    assert_eq!(
        frame(&DeviceMsg::Ack { seq: 300 }),
        [0x08, 0x01, 0xAC, 0x02, 0x6C, 0xFA, 0xC8, 0x73, 0x00]
    );
    assert_eq!(
        frame(&DeviceMsg::Nak {
            seq: 7,
            reason: NakReason::OutOfOrder
        }),
        [0x08, 0x02, 0x07, 0x03, 0xC6, 0xCB, 0x36, 0x46, 0x00]
    );
    // A struct variant: its index, then its fields (terms 55, capacity 16).
    let refused = frame(&DeviceMsg::Nak {
        seq: 7,
        reason: NakReason::TooManyTerms {
            terms: 55,
            capacity: 16,
        },
    });
    let mut bytes = refused.clone();
    assert_eq!(
        decode_frame::<DeviceMsg>(&mut bytes),
        Ok(DeviceMsg::Nak {
            seq: 7,
            reason: NakReason::TooManyTerms {
                terms: 55,
                capacity: 16
            }
        })
    );
    assert_eq!(bytes[..5], [0x02, 0x07, 0x08, 55, 16]);
}

/// A configuration whose fields all differ from their neighbours, so that a reordering shows.
fn golden_config() -> WireConfig {
    WireConfig {
        sample_period: 1e-3,
        window: 301,
        derivative_degree: 5,
        library: WireLibrary {
            poly_order: 7,
            family: PolyFamily::Families,
            constant: true,
            harmonics: 2,
            input: false,
        },
        omega: 21.4,
        channels: WireChannels {
            velocity: true,
            input: false,
        },
        memory: Some(2.5),
        screening_period: 10_000,
        thresholds: 24,
        smoothing: false,
        row_stride: 4,
        parsimony: 0.05,
        offsets: true,
        max_abs: 1e9,
        test_rows: 64,
        encoding: SampleEncoding::F32,
        duty: Some(WireDuty {
            window: 10.0,
            interval: 590.0,
            model_every: 4,
        }),
    }
}

/// `WireConfig`'s bytes are those of protocol version 5's flat record (taken from main
/// before the library and channel fields were nested and renamed after `Config`): nesting
/// adds no framing in postcard, so the rename did not change the wire. Version 6 appends
/// `duty` (`01`, then window 10.0 and interval 590.0 as f32); version 8 its `model_every`
/// (4, a vu16).
#[test]
fn golden_configure_frame() {
    let payload = [
        0xFC, 0xA9, 0xF1, 0xD2, 0x4D, 0x62, 0x50, 0x3F, 0xAD, 0x02, 0x05, 0x07, 0x01, 0x01, 0x02,
        0x00, 0x66, 0x66, 0x66, 0x66, 0x66, 0x66, 0x35, 0x40, 0x01, 0x00, 0x01, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x04, 0x40, 0x90, 0x4E, 0x18, 0x00, 0x04, 0x9A, 0x99, 0x99, 0x99, 0x99,
        0x99, 0xA9, 0x3F, 0x01, 0x00, 0x00, 0x00, 0x00, 0x65, 0xCD, 0xCD, 0x41, 0x40, 0x00,
        // Version 6: Some(WireDuty { window: 10.0, interval: 590.0 }).
        0x01, 0x00, 0x00, 0x20, 0x41, 0x00, 0x80, 0x13, 0x44,
        // Version 8: its model_every, 4 (a vu16).
        0x04,
    ];
    let mut buf = [0u8; 128];
    let bytes = postcard::to_slice(&golden_config(), &mut buf).expect("fits");
    assert_eq!(bytes, payload);
    assert_eq!(
        postcard::from_bytes::<WireConfig>(&payload),
        Ok(golden_config())
    );
    let golden = [
        0x11, 0x01, 0xFC, 0xA9, 0xF1, 0xD2, 0x4D, 0x62, 0x50, 0x3F, 0xAD, 0x02, 0x05, 0x07, 0x01,
        0x01, 0x02, 0x0A, 0x66, 0x66, 0x66, 0x66, 0x66, 0x66, 0x35, 0x40, 0x01, 0x02, 0x01, 0x01,
        0x01, 0x01, 0x01, 0x01, 0x06, 0x04, 0x40, 0x90, 0x4E, 0x18, 0x0B, 0x04, 0x9A, 0x99, 0x99,
        0x99, 0x99, 0x99, 0xA9, 0x3F, 0x01, 0x01, 0x01, 0x01, 0x06, 0x65, 0xCD, 0xCD, 0x41, 0x40,
        0x02, 0x01, 0x01, 0x03, 0x20, 0x41, 0x09, 0x80, 0x13, 0x44, 0x04, 0x1A, 0x81, 0x9B, 0x11,
        0x00,
    ];
    assert_eq!(frame(&HostMsg::Configure(golden_config())), golden);
    let mut bytes = golden;
    assert_eq!(
        decode_frame::<HostMsg>(&mut bytes),
        Ok(HostMsg::Configure(golden_config()))
    );
}
