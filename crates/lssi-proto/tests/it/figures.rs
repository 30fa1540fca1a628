//! The README's bytes-per-sample table: `cargo test -p lssi-proto --test it figures:: -- --nocapture`.

use crate::common;

use common::frame;
use lssi_proto::size::frame_len;
use lssi_proto::{Channels, HostMsg, MAX_BATCH, SampleBatch, WireSample};

/// A full batch from a recording-like signal: 1 kHz samples some minutes in, millimetre
/// displacements, a sequence number past 2^14 (a three-byte varint).
fn recorded_batch(channels: Channels) -> SampleBatch {
    let mut batch = SampleBatch::new(20_000, channels);
    for i in 0..MAX_BATCH {
        let t = 123.456 + i as f64 * 1e-3;
        let sample = WireSample {
            t,
            x: (2.1e-3 * (21.4 * t).cos()) as f32,
            v: channels
                .has_v()
                .then_some((-4.5e-2 * (21.4 * t).sin()) as f32),
            u: channels
                .has_u()
                .then_some((0.398 * (21.4 * t).cos()) as f32),
        };
        batch.push(sample).expect("room");
    }
    batch
}

/// Worst-case frame of a full batch: largest `seq` varint, no zero byte to absorb a COBS code.
fn worst_frame(channels: Channels) -> usize {
    frame_len(1 + 5 + 1 + 1 + MAX_BATCH * channels.bytes_per_sample())
}

/// Samples per second a UART carries at `baud`, 8N1 (10 bit times per byte).
fn rate(baud: f64, bytes_per_sample: f64) -> f64 {
    baud / 10.0 / bytes_per_sample
}

#[test]
fn bytes_per_sample_at_max_batch() {
    println!(
        "| channels | per sample (postcard) | full-batch frame, recorded / worst (bytes) | bytes per sample, recorded / worst | samples/s at 115200 / 921600 baud (worst) |"
    );
    println!("|---|---:|---:|---:|---:|");
    let mut worst = Vec::new();
    for (name, channels) in [
        ("x", Channels::X),
        ("x+v", Channels::XV),
        ("x+v+u", Channels::XVU),
    ] {
        let recorded = frame(&HostMsg::Samples(recorded_batch(channels))).len();
        let worst_len = worst_frame(channels);
        assert!(recorded <= worst_len);
        let per_recorded = recorded as f64 / MAX_BATCH as f64;
        let per_worst = worst_len as f64 / MAX_BATCH as f64;
        println!(
            "| {name} | {} | {recorded} / {worst_len} | {per_recorded:.3} / {per_worst:.3} | {:.0} / {:.0} |",
            channels.bytes_per_sample(),
            rate(115_200.0, per_worst),
            rate(921_600.0, per_worst),
        );
        worst.push(worst_len);
    }
    // The README quotes these.
    assert_eq!(worst, [303, 399, 495]);
}
