//! Every encoding fits its `MaxSize`, the hand-written `MaxSize`s are exact, and the frame
//! length constants cover the CRC, COBS's worst case and the delimiter.

use crate::common;

use common::*;
use lssi_proto::size::frame_len;
use lssi_proto::{
    CRC_LEN, DeviceMsg, HostMsg, MAX_DEVICE_FRAME_LEN, MAX_FRAME_LEN, MAX_HOST_FRAME_LEN, MaxSize,
    Message, ModelSnapshot, SampleBatch, WireConfig,
};
use postcard::ser_flavors::crc::CrcModifier;
use postcard::ser_flavors::{Cobs, Slice};
use proptest::prelude::*;
use serde::Serialize;
use serde::ser::SerializeTuple;

fn postcard_len<T: Serialize>(value: &T) -> usize {
    let mut buffer = [0u8; 2048];
    postcard::to_slice(value, &mut buffer)
        .expect("fits in 2 KiB")
        .len()
}

#[test]
fn hand_written_max_sizes_are_exact() {
    // Exact (not merely an upper bound) for the worst-case value: a missed field would show.
    assert_eq!(postcard_len(&worst_batch()), SampleBatch::POSTCARD_MAX_SIZE);
    assert_eq!(
        postcard_len(&worst_snapshot()),
        ModelSnapshot::POSTCARD_MAX_SIZE
    );
    assert_eq!(postcard_len(&worst_config()), WireConfig::POSTCARD_MAX_SIZE);
    let device = worst_device_msgs().iter().map(postcard_len).max();
    assert_eq!(device, Some(DeviceMsg::POSTCARD_MAX_SIZE));
    let host = worst_host_msgs().iter().map(postcard_len).max();
    assert_eq!(host, Some(HostMsg::POSTCARD_MAX_SIZE));
}

#[test]
fn worst_case_frames_fit_the_frame_constants() {
    for message in worst_host_msgs() {
        assert!(frame(&message).len() <= MAX_HOST_FRAME_LEN);
    }
    for message in worst_device_msgs() {
        assert!(frame(&message).len() <= MAX_DEVICE_FRAME_LEN);
    }
    // MAX_HOST_FRAME_LEN <= 512 is a compile-time assertion in the crate.
    assert_eq!(MAX_FRAME_LEN, MAX_HOST_FRAME_LEN.max(MAX_DEVICE_FRAME_LEN));
    assert_eq!(HostMsg::MAX_FRAME_LEN, MAX_HOST_FRAME_LEN);
    assert_eq!(DeviceMsg::MAX_FRAME_LEN, MAX_DEVICE_FRAME_LEN);
}

/// Exactly `bytes`, with no length prefix (postcard writes a tuple's elements only).
struct Raw<'a>(&'a [u8]);

impl Serialize for Raw<'_> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut tuple = serializer.serialize_tuple(self.0.len())?;
        for byte in self.0 {
            tuple.serialize_element(byte)?;
        }
        tuple.end()
    }
}

/// `frame_len` bounds the very flavour chain `encode` uses, at COBS's worst case (no zero
/// bytes, so every 254-byte run costs a code byte), for every payload length up to 2 KiB.
#[test]
fn frame_len_bounds_cobs_worst_case() {
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);
    let payload = [0xFFu8; 2048];
    let mut out = [0u8; 2200];
    let mut tight = 0;
    for len in 0..=payload.len() {
        let cobs = Cobs::try_new(Slice::new(&mut out)).expect("room");
        let flavor = CrcModifier::new(cobs, crc.digest());
        let framed = postcard::serialize_with_flavor(&Raw(&payload[..len]), flavor).expect("room");
        assert!(
            framed.len() <= frame_len(len),
            "payload {len}: {} > {}",
            framed.len(),
            frame_len(len)
        );
        assert_eq!(
            framed.iter().filter(|&&b| b == 0).count(),
            1,
            "one 0x00, at the end"
        );
        tight += usize::from(framed.len() == frame_len(len));
    }
    // The bound is reached (whenever the CRC has no zero byte), so it is not loose.
    assert!(tight > 1000, "{tight}");
    assert_eq!(frame_len(0), CRC_LEN + 2);
}

proptest! {
    #![proptest_config(cases(512))]

    #[test]
    fn host_encodings_fit_max_size(message in host_msg()) {
        prop_assert!(postcard_len(&message) <= HostMsg::POSTCARD_MAX_SIZE);
        prop_assert!(frame(&message).len() <= MAX_HOST_FRAME_LEN);
    }

    #[test]
    fn device_encodings_fit_max_size(message in device_msg()) {
        prop_assert!(postcard_len(&message) <= DeviceMsg::POSTCARD_MAX_SIZE);
        prop_assert!(frame(&message).len() <= MAX_DEVICE_FRAME_LEN);
        if let DeviceMsg::Model(snapshot) = &message {
            prop_assert!(postcard_len(snapshot) <= ModelSnapshot::POSTCARD_MAX_SIZE);
        }
    }

    #[test]
    fn parts_fit_max_size(batch in batch(), config in any_wire_config()) {
        prop_assert!(postcard_len(&batch) <= SampleBatch::POSTCARD_MAX_SIZE);
        prop_assert!(postcard_len(&config) <= WireConfig::POSTCARD_MAX_SIZE);
    }
}

#[test]
fn print_sizes() {
    println!("| type | MaxSize (postcard bytes) | longest frame (bytes) |");
    println!("|---|---:|---:|");
    println!(
        "| HostMsg | {} | {} |",
        HostMsg::POSTCARD_MAX_SIZE,
        MAX_HOST_FRAME_LEN
    );
    println!(
        "| DeviceMsg | {} | {} |",
        DeviceMsg::POSTCARD_MAX_SIZE,
        MAX_DEVICE_FRAME_LEN
    );
    println!("| WireConfig | {} | |", WireConfig::POSTCARD_MAX_SIZE);
    println!("| SampleBatch | {} | |", SampleBatch::POSTCARD_MAX_SIZE);
    println!("| ModelSnapshot | {} | |", ModelSnapshot::POSTCARD_MAX_SIZE);
    println!();
    println!("| variant (worst case) | postcard bytes | frame bytes |");
    println!("|---|---:|---:|");
    for message in worst_host_msgs() {
        let name = variant_name(&message);
        println!(
            "| HostMsg::{name} | {} | {} |",
            postcard_len(&message),
            frame(&message).len()
        );
    }
    for message in worst_device_msgs() {
        let name = variant_name(&message);
        println!(
            "| DeviceMsg::{name} | {} | {} |",
            postcard_len(&message),
            frame(&message).len()
        );
    }
}

fn variant_name<T: std::fmt::Debug>(message: &T) -> String {
    format!("{message:?}")
        .chars()
        .take_while(|c| c.is_alphanumeric())
        .collect()
}
