//! Memory figures of the firmware's device: `cargo test -p lssi-device --test it sizes:: -- --nocapture`.

use lssi_core::Identifier;
use lssi_device::{DEFAULT_TERMS, DEFAULT_WINDOW, Device};

#[test]
fn print_sizes() {
    let device = size_of::<Device>();
    let identifier = size_of::<Identifier<f32, DEFAULT_WINDOW, DEFAULT_TERMS>>();
    println!("Device<{DEFAULT_WINDOW}, {DEFAULT_TERMS}>: {device} bytes");
    println!("  of which Identifier<f32, {DEFAULT_WINDOW}, {DEFAULT_TERMS}>: {identifier} bytes");
    for (name, size) in [
        ("Device<256, 24>", size_of::<Device<256, 24>>()),
        ("Device<128, 16>", size_of::<Device<128, 16>>()),
        ("Device<256, 16>", size_of::<Device<256, 16>>()),
        (
            "Device<256, 16, 2> (the firmware's)",
            size_of::<Device<256, 16, 2>>(),
        ),
        ("Device<512, 16>", size_of::<Device<512, 16>>()),
    ] {
        println!("{name}: {size} bytes");
    }
    // The static part (11 KiB on x86_64; the screening's stack comes on top, see the
    // crate README). Grows with W (C ring buffers and the folded taps: (C + 2) × 4 bytes a
    // sample) and P (3 factors of 4·P² bytes); one channel fewer saves a ring of 4·W bytes.
    // With the `system` feature (default) a SystemSlot (x'' and V', 10 KiB) comes on top;
    // the firmware's default image leaves it out.
    let system = if cfg!(feature = "system") {
        11 * 1024
    } else {
        0
    };
    assert!(device <= 14 * 1024 + system, "{device}");
    let two = size_of::<Device<DEFAULT_WINDOW, DEFAULT_TERMS, 2>>();
    assert!(two + 4 * DEFAULT_WINDOW <= device, "{two} {device}");
}
