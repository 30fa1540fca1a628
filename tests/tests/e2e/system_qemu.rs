//! A simulated piezoelectric harvester (x and V recorded) through the Cortex-M4F firmware
//! under QEMU as a system (issue 26 item 2): the device's two equations, x'' and V', must
//! equal bit for bit the f32 `SystemIdentifier` run on the host over the same samples with
//! the same `SystemConfig` (a direct lssi-core call: the host's `lssi identify --f32
//! --no-refine` for systems runs that identifier with that configuration).
//!
//! `#[ignore]`d like `qemu.rs` (QEMU and the firmware ELF are needed); `scripts/ci-qemu.sh`
//! runs it with `--include-ignored`. The image is the replay firmware built with its `system`
//! feature (`cd crates/lssi-firmware && cargo build --release --features system`, copied to
//! `lssi-firmware-system` beside the default image), or the one `LSSI_SYSTEM_FIRMWARE_ELF`
//! names.

use crate::qemu::{Link, Qemu};
use lssi_core::identifier::system::{SystemIdentifier, Target};
use lssi_core::library::{Electrical, StateTerm};
use lssi_core::{Config, LibraryConfig, PolyFamily, SystemConfig, SystemSample};
use lssi_device::system::{system_config_to_wire, system_snapshot};
use lssi_proto::{
    CONTROL_SEQ, CostUnit, DeviceMsg, HostMsg, MAX_SYSTEM_BATCH, PROTOCOL_VERSION, SnapshotCause,
    SystemBatch, SystemSnapshot, SystemWireSample,
};
use lssi_testkit::harvester::{Piezo, PiezoPoint};
use std::time::Instant;

/// The firmware's capacities (lssi-firmware: WINDOW, DEFAULT_TERMS, CHANNELS = x and V).
const W: usize = 256;
const P: usize = 16;
const C: usize = 2;
const DT: f64 = 0.01;

fn config(window: usize) -> SystemConfig {
    SystemConfig {
        base: Config {
            sample_period: DT,
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
        coupling_order: 2,
        displacements: 1,
    }
}

/// The host's f32 system identifier over the same samples: every scheduled model, then the
/// one screened at the end (what a `Query` after the last batch gives).
fn host(config: SystemConfig, points: &[PiezoPoint]) -> (Vec<SystemSnapshot>, SystemSnapshot) {
    let mut id: Box<SystemIdentifier<f32, W, P, 2, C>> =
        Box::new(SystemIdentifier::new(config).expect("a valid configuration"));
    let mut scheduled = Vec::new();
    for p in points {
        let e = [p.e as f32];
        let sample = SystemSample {
            x2: None,
            v2: None,
            t: p.t,
            x: p.x as f32,
            v: None,
            u: None,
            electrical: &e,
        };
        if id.push(&sample) == Ok(true) {
            let model = id.model().expect("a screening made it");
            scheduled.push(system_snapshot(model, SnapshotCause::Scheduled).expect("fits"));
        }
    }
    id.screen();
    let model = id.model().expect("the host finds a model");
    (
        scheduled,
        system_snapshot(model, SnapshotCause::Query).expect("fits"),
    )
}

/// The same samples through the firmware: its scheduled models, its queried one and its
/// mean and worst instructions a sample.
fn device(
    config: SystemConfig,
    points: &[PiezoPoint],
) -> (Vec<SystemSnapshot>, SystemSnapshot, (u32, u32)) {
    let elf = system_firmware();
    let dir = tempfile::tempdir().expect("temp dir");
    let socket = dir.path().join("uart.sock");
    let qemu = Qemu::start(&elf, &socket, &dir.path().join("defmt.bin"));
    let mut link = Link::connect(&socket);
    link.send(&HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION,
    });
    match link.receive() {
        DeviceMsg::HelloReply {
            protocol_version, ..
        } => assert_eq!(protocol_version, PROTOCOL_VERSION),
        other => panic!("expected HelloReply, got {other:?}"),
    }
    let wire = system_config_to_wire(&config).expect("fits the wire");
    link.send(&HostMsg::ConfigureSystem(wire));
    match link.receive() {
        DeviceMsg::Ack { seq: CONTROL_SEQ } => {}
        other => panic!("expected the Ack of ConfigureSystem, got {other:?}"),
    }
    let mut scheduled = Vec::new();
    for (seq, chunk) in points.chunks(MAX_SYSTEM_BATCH).enumerate() {
        let seq = u32::try_from(seq).expect("few batches");
        let mut batch = SystemBatch::new(seq);
        for p in chunk {
            let sample = SystemWireSample {
                t: p.t,
                x: p.x as f32,
                v: None,
                u: None,
                electrical: heapless::Vec::from_slice(&[p.e as f32]).expect("one channel"),
            };
            batch.samples.push(sample).expect("room");
        }
        link.send(&HostMsg::SystemSamples(batch));
        loop {
            match link.receive() {
                DeviceMsg::Ack { seq: s } if s == seq => break,
                DeviceMsg::SystemModel(m) => scheduled.push(m),
                DeviceMsg::Log { .. } => {}
                other => panic!("batch {seq}: expected its Ack, got {other:?}"),
            }
        }
    }
    link.send(&HostMsg::Query);
    let last = loop {
        match link.receive() {
            DeviceMsg::SystemModel(m) if m.cause == SnapshotCause::Query => break m,
            DeviceMsg::SystemModel(m) => scheduled.push(m),
            DeviceMsg::Log { .. } => {}
            other => panic!("expected the queried SystemModel, got {other:?}"),
        }
    };
    let cost = loop {
        match link.receive() {
            DeviceMsg::Health {
                samples,
                cost_mean,
                cost_max,
                cost_unit,
                crc_errors,
                ..
            } => {
                assert_eq!(samples, points.len() as u64);
                assert_eq!(cost_unit, CostUnit::Instructions);
                assert_eq!(crc_errors, 0);
                assert!(cost_mean > 0 && cost_max >= cost_mean);
                break (cost_mean, cost_max);
            }
            DeviceMsg::Log { .. } => {}
            other => panic!("expected Health, got {other:?}"),
        }
    };
    drop(qemu);
    (scheduled, last, cost)
}

/// The replay image with systems; a missing QEMU or image fails the (asked-for) test.
fn system_firmware() -> std::path::PathBuf {
    let elf = std::env::var_os("LSSI_SYSTEM_FIRMWARE_ELF").map_or_else(
        || {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(
                "../crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-firmware-system",
            )
        },
        std::path::PathBuf::from,
    );
    let qemu = std::process::Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        qemu,
        "qemu-system-arm is not installed (bash scripts/ci-qemu.sh installs it)"
    );
    assert!(
        elf.is_file(),
        "no system firmware at {} (cd crates/lssi-firmware && cargo build --release --features system, \
         then copy the ELF to lssi-firmware-system; bash scripts/ci-qemu.sh does both)",
        elf.display()
    );
    elf
}

fn describe(s: &SystemSnapshot) -> String {
    s.equations
        .iter()
        .map(|e| {
            let terms: Vec<String> = s
                .terms
                .iter()
                .zip(&e.coefficients)
                .filter(|(_, c)| **c != 0.0)
                .map(|(t, c)| format!("{:?}{:?} {c:e}", t.kind, t.powers))
                .collect();
            format!("{:?}: {}", e.target, terms.join(", "))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF: bash scripts/ci-qemu.sh runs it"]
fn piezo_harvester_through_qemu_firmware_equals_host_f32_system() {
    for (name, piezo, n, window) in [
        ("monostable", Piezo::monostable(), 20_000, 63),
        ("bistable", Piezo::bistable(), 16_000, 41),
    ] {
        let points = piezo.simulate(n, DT);
        let config = config(window);
        let started = Instant::now();
        let (got_scheduled, got, (mean, worst)) = device(config, &points);
        let (want_scheduled, want) = host(config, &points);
        eprintln!(
            "{name}: {n} samples (x, V) through QEMU in {:.1} s, {} scheduled models; \
             instructions a sample: mean {mean}, worst {worst}\n{}",
            started.elapsed().as_secs_f64(),
            got_scheduled.len(),
            describe(&got)
        );
        assert_eq!(got_scheduled.len(), n / 7_000, "{name}: scheduled models");
        assert_eq!(got_scheduled, want_scheduled, "{name}: scheduled models");
        // Bit for bit: f32 `==` would let 0.0 equal −0.0.
        let bits = |s: &SystemSnapshot| -> Vec<Vec<u32>> {
            s.equations
                .iter()
                .map(|e| e.coefficients.iter().map(|c| c.to_bits()).collect())
                .collect()
        };
        assert_eq!(
            bits(&got),
            bits(&want),
            "{name}: coefficients differ\ndevice:\n{}\nhost:\n{}",
            describe(&got),
            describe(&want)
        );
        assert_eq!(got, want, "{name}: the queried model");
        // Both equations, and V' = −λV − κv recovered.
        assert_eq!(got.equations.len(), 2);
        let terms: Vec<StateTerm> = got
            .terms
            .iter()
            .map(|&t| lssi_device::system::state_term_from_code(t).expect("a term"))
            .collect();
        let v_eq = &got.equations[1];
        assert_eq!(
            lssi_device::system::target_from_wire(v_eq.target),
            Target::Rate(Electrical::Voltage)
        );
        let coef = |term: StateTerm| {
            let j = terms
                .iter()
                .position(|&t| t == term)
                .expect("in the library");
            f64::from(v_eq.coefficients[j])
        };
        let kappa = coef(StateTerm::Monomial([0, 1, 0, 0, 0, 0]));
        let lambda = coef(StateTerm::Monomial([0, 0, 1, 0, 0, 0]));
        assert!(
            (kappa + piezo.kappa).abs() < 0.02 * piezo.kappa,
            "{name}: κ {kappa}"
        );
        assert!(
            (lambda + piezo.lambda).abs() < 0.02 * piezo.lambda,
            "{name}: λ {lambda}"
        );
    }
}
