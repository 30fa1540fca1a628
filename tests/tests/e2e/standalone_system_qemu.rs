//! The standalone instrument with two ADC channels under QEMU (`-icount shift=4,sleep=off`):
//! the `system` build of lssi-standalone samples a piezoelectric harvester's displacement x
//! and the voltage V across its load by its timer, decimates both to rows (a CIC of order 3),
//! identifies x'' and V' on its own and reports by itself (issue 26 item 2, issue 27).
//!
//! The device's final model must equal, bit for bit, lssi-core's f32 `SystemIdentifier` run
//! on the host over the same rows (decimated here by the same `Decimator`) with the same
//! configuration (stored in the image as a host's `ConfigureSystem` frame); its scheduled
//! models must be the host's scheduled ones; no conversion may be lost; and V' = −λV − κv
//! must come out within 2 % (x'' is printed).
//!
//! `#[ignore]`d: it needs `qemu-system-arm` and the image
//! (`cd crates/lssi-firmware && cargo build --release --bin lssi-standalone --features system`,
//! copied to `lssi-standalone-system`; `scripts/ci-qemu.sh` does both, or
//! `LSSI_STANDALONE_SYSTEM_ELF` names it).

use lssi_core::identifier::system::{SystemIdentifier, Target};
use lssi_core::library::{Electrical, StateTerm};
use lssi_core::{Config, LibraryConfig, PolyFamily, SystemConfig, SystemSample};
use lssi_device::decimate::{Decimator, factor_for};
use lssi_device::system::{
    state_term_from_code, system_config_to_wire, system_snapshot, target_from_wire,
};
use lssi_proto::{
    DeviceFrameDecoder, DeviceMsg, HostMsg, MAX_HOST_FRAME_LEN, SnapshotCause, SystemSnapshot,
    encode,
};
use lssi_testkit::harvester::{Piezo, PiezoPoint};
use std::path::{Path, PathBuf};

/// The image's capacities (lssi-firmware: WINDOW, DEFAULT_TERMS, CHANNELS = x and V).
const W: usize = 256;
const P: usize = 16;
const C: usize = 2;
/// The ADC's conversions a second, and the firmware's CIC order (CIC_ORDER).
const ADC_HZ: f64 = 1_000.0;
const ORDER: u8 = 3;
/// Rows a second: the piezo rings at about 1 rad/s (0.8 rad/s forcing), 100 rows a second is
/// what lssi-core's system tests sample it at.
const ROW_HZ: f64 = 100.0;

fn image_elf() -> PathBuf {
    std::env::var_os("LSSI_STANDALONE_SYSTEM_ELF").map_or_else(
        || {
            Path::new(env!("CARGO_MANIFEST_DIR")).join(
                "../crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-standalone-system",
            )
        },
        PathBuf::from,
    )
}

fn config(period: f64, window: usize) -> SystemConfig {
    SystemConfig {
        base: Config {
            sample_period: period,
            window,
            derivative_degree: 5,
            library: LibraryConfig {
                poly_order: 3,
                family: PolyFamily::All,
                constant: true,
                harmonics: 1,
                input: false,
            },
            omega: 0.8,
            screening_period: 7_000,
            ..Config::default()
        },
        electrical: [Some(Electrical::Voltage), None],
        coupling_order: 1,
        displacements: 1,
    }
}

/// The PSRAM image (crates/lssi-firmware/src/mps2.rs): x and V interleaved, the electrical
/// channel flagged by bit 2, the configuration stored as a host's `ConfigureSystem` frame.
fn image(points: &[PiezoPoint], config: &SystemConfig) -> Vec<u8> {
    let mut frame = [0u8; MAX_HOST_FRAME_LEN];
    let wire = system_config_to_wire(config).expect("fits the wire");
    let len = encode(&HostMsg::ConfigureSystem(wire), &mut frame).expect("encodes");
    assert!(
        len <= 256 - 28,
        "a {len}-byte frame does not fit the header"
    );
    let mut out = Vec::with_capacity(256 + 8 * points.len());
    out.extend_from_slice(b"LSSIREC1");
    out.extend_from_slice(&4u32.to_le_bytes());
    out.extend_from_slice(&(points.len() as u32).to_le_bytes());
    out.extend_from_slice(&ADC_HZ.to_le_bytes());
    out.extend_from_slice(&(len as u32).to_le_bytes());
    out.extend_from_slice(&frame[..len]);
    out.resize(256, 0);
    for p in points {
        out.extend_from_slice(&(p.x as f32).to_le_bytes());
        out.extend_from_slice(&(p.e as f32).to_le_bytes());
    }
    out
}

/// The host's f32 system identifier over the rows the device makes: its scheduled models and
/// the final one.
fn host(config: SystemConfig, rows: &[(f64, f32, f32)]) -> (Vec<SystemSnapshot>, SystemSnapshot) {
    let mut id: Box<SystemIdentifier<f32, W, P, 2, C>> =
        Box::new(SystemIdentifier::new(config).expect("a valid configuration"));
    let mut scheduled = Vec::new();
    for &(t, x, e) in rows {
        let e = [e];
        let sample = SystemSample {
            t,
            x2: None,
            v2: None,
            x,
            v: None,
            u: None,
            electrical: &e,
        };
        if id.push(&sample) == Ok(true) {
            let model = id.model().expect("a screening made it");
            scheduled.push(system_snapshot(model, SnapshotCause::Scheduled).expect("fits"));
        }
    }
    assert!(id.screen(), "a model from {} rows", rows.len());
    let model = id.model().expect("a model");
    (
        scheduled,
        system_snapshot(model, SnapshotCause::Final).expect("fits"),
    )
}

fn bits(s: &SystemSnapshot) -> Vec<Vec<u32>> {
    s.equations
        .iter()
        .map(|e| e.coefficients.iter().map(|c| c.to_bits()).collect())
        .collect()
}

#[test]
#[ignore = "needs qemu-system-arm and the standalone system image: bash scripts/ci-qemu.sh runs it"]
fn standalone_two_channel_device_identifies_the_harvesters_system_as_the_host_does() {
    let piezo = Piezo::monostable();
    // 200 s of conversions at 1 kHz: 20,000 rows.
    let points = piezo.simulate(200_000, 1.0 / ADC_HZ);
    let factor = factor_for(ADC_HZ, 1.0 / ROW_HZ).expect("a whole factor");
    assert_eq!(factor, 10);
    let period = f64::from(factor) / ADC_HZ;
    let config = config(period, 63);

    // The rows the device makes: x and V as the image holds them (f32), decimated together
    // (x first, then the electrical channel: lssi-device's Sampler packs them so).
    let mut decimator = Decimator::new(factor, ORDER).expect("a decimator");
    let offset = decimator.time_offset(ADC_HZ);
    let rows: Vec<(f64, f32, f32)> = points
        .iter()
        .filter_map(|p| decimator.push_channels([p.x as f32, p.e as f32, 0.0], 2))
        .enumerate()
        .map(|(i, r)| (i as f64 * period + offset, r[0], r[1]))
        .collect();
    let (want_scheduled, want) = host(config, &rows);

    let elf = image_elf();
    assert!(
        elf.is_file(),
        "{}: cd crates/lssi-firmware && cargo build --release --bin lssi-standalone --features system, \
         then copy the ELF to lssi-standalone-system (bash scripts/ci-qemu.sh does both)",
        elf.display()
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let recording = dir.path().join("recording.bin");
    std::fs::write(&recording, image(&points, &config)).expect("write the image");
    let uart = dir.path().join("uart.bin");
    let qemu = lssi_host::serial::qemu::find().expect("qemu-system-arm on the PATH");
    let status = lssi_host::serial::qemu::command(&qemu)
        .args(["-icount", "shift=4,sleep=off", "-kernel"])
        .arg(&elf)
        .arg("-device")
        .arg(format!(
            "loader,file={},addr=0x21000000",
            recording.display()
        ))
        .arg("-serial")
        .arg(format!("file:{}", uart.display()))
        .output()
        .expect("QEMU runs");
    assert_eq!(status.status.code(), Some(0), "the firmware's exit status");
    // Its log: wake-ups, the deepest stack, the time awake.
    crate::standalone_qemu::print_log(&elf, &status.stdout, dir.path());
    let frames = std::fs::read(&uart).expect("the UART's bytes");
    let mut decoder = DeviceFrameDecoder::new();
    let messages: Vec<DeviceMsg> = decoder
        .feed::<DeviceMsg>(&frames)
        .map(|m| m.expect("a valid frame"))
        .collect();

    let Some((samples, overruns, skipped, rate)) = messages.iter().rev().find_map(|m| match m {
        DeviceMsg::Health {
            samples,
            overruns,
            screenings_skipped,
            sample_rate_hz,
            ..
        } => Some((*samples, *overruns, *screenings_skipped, *sample_rate_hz)),
        _ => None,
    }) else {
        panic!("no Health in {} frames", messages.len());
    };
    println!(
        "device: {samples} rows at {rate} Hz, {overruns} overruns, {skipped} screenings skipped"
    );
    assert_eq!(overruns, 0, "conversions lost");
    assert_eq!(samples, rows.len() as u64, "rows");
    assert!((f64::from(rate) - ROW_HZ).abs() < 1e-3, "row rate {rate}");
    // Every model it reported is a SystemModel; the scheduled ones (each sent once a second
    // until the next comes) are the host's scheduled models, in order.
    assert!(
        !messages.iter().any(|m| matches!(m, DeviceMsg::Model(_))),
        "a single-equation Model from the system's instrument"
    );
    let mut got_scheduled: Vec<&SystemSnapshot> = Vec::new();
    for m in &messages {
        if let DeviceMsg::SystemModel(s) = m
            && s.cause == SnapshotCause::Scheduled
            && got_scheduled.last() != Some(&s)
        {
            got_scheduled.push(s);
        }
    }
    if skipped == 0 {
        assert_eq!(
            got_scheduled.len(),
            want_scheduled.len(),
            "scheduled models"
        );
        for (g, w) in got_scheduled.iter().zip(&want_scheduled) {
            assert_eq!(bits(g), bits(w), "a scheduled model");
        }
    }
    let Some(got) = messages.iter().rev().find_map(|m| match m {
        DeviceMsg::SystemModel(s) if s.cause == SnapshotCause::Final => Some(s),
        _ => None,
    }) else {
        panic!("no final SystemModel in {} frames", messages.len());
    };
    assert_eq!(got.terms, want.terms);
    assert_eq!(bits(got), bits(&want), "device {got:?}\nhost {want:?}");
    assert_eq!(got, &want, "the final model");

    // The harvester's coupling, from two channels sampled and decimated on the device.
    let terms: Vec<StateTerm> = got
        .terms
        .iter()
        .map(|&t| state_term_from_code(t).expect("a term"))
        .collect();
    let coefficient = |k: usize, term: StateTerm| {
        let j = terms
            .iter()
            .position(|&t| t == term)
            .expect("in the library");
        f64::from(got.equations[k].coefficients[j])
    };
    assert_eq!(
        target_from_wire(got.equations[0].target),
        Target::Acceleration
    );
    assert_eq!(
        target_from_wire(got.equations[1].target),
        Target::Rate(Electrical::Voltage)
    );
    let v = StateTerm::Monomial([0, 1, 0, 0, 0, 0]);
    let e = StateTerm::Monomial([0, 0, 1, 0, 0, 0]);
    for (what, got, truth) in [
        ("κ (V' on v)", coefficient(1, v), -piezo.kappa),
        ("λ (V' on V)", coefficient(1, e), -piezo.lambda),
    ] {
        println!("{what}: {got:.5} on the device, {truth} true");
        assert!(
            (got - truth).abs() <= 0.02 * truth.abs(),
            "{what}: {got} against {truth}"
        );
    }
    // x'' as identified (printed: lssi-core's system tests say what it recovers of x'';
    // here the point is the device's equality with the host).
    for (what, term, truth) in [
        ("χ (x'' on V)", e, piezo.chi),
        ("c (x'' on v)", v, piezo.c),
        (
            "k1 (x'' on x)",
            StateTerm::Monomial([1, 0, 0, 0, 0, 0]),
            piezo.k1,
        ),
        (
            "k3 (x'' on x^3)",
            StateTerm::Monomial([3, 0, 0, 0, 0, 0]),
            piezo.k3,
        ),
    ] {
        println!(
            "{what}: {:.5} on the device, {truth} true",
            coefficient(0, term)
        );
    }
}
