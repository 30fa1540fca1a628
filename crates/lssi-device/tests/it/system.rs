//! A simulated piezoelectric harvester (x and V) through the device as a system: every
//! snapshot, scheduled and queried, equals bit for bit the f32 `SystemIdentifier` driven
//! directly with the same configuration; and the protocol's system rules (naks).

use crate::common;

use common::*;
use lssi_core::identifier::system::{SystemIdentifier, Target};
use lssi_core::library::{Electrical, StateTerm};
use lssi_core::{Config, LibraryConfig, PolyFamily, SystemConfig, SystemSample};
use lssi_device::system::{system_config_to_wire, system_model_from_snapshot, system_snapshot};
use lssi_device::{DEFAULT_TERMS, DEFAULT_WINDOW};
use lssi_proto::{
    CONTROL_SEQ, Channels, DeviceMsg, HostMsg, MAX_SYSTEM_BATCH, NakReason, SampleBatch,
    SnapshotCause, SystemBatch, SystemSnapshot, SystemWireSample, WireSample,
};
use lssi_testkit::harvester::{Piezo, PiezoPoint};

const DT: f64 = 0.01;

fn config(window: usize, screening_period: u32) -> SystemConfig {
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
            screening_period,
            ..Config::default()
        },
        electrical: [Some(Electrical::Voltage), None],
        coupling_order: 2,
        displacements: 1,
    }
}

fn direct(config: SystemConfig, points: &[PiezoPoint]) -> (Vec<SystemSnapshot>, SystemSnapshot) {
    let mut id: Box<SystemIdentifier<f32, DEFAULT_WINDOW, DEFAULT_TERMS, 2, 3>> =
        Box::new(SystemIdentifier::new(config).expect("valid"));
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
    let last = system_snapshot(id.model().expect("a model"), SnapshotCause::Query).expect("fits");
    (scheduled, last)
}

fn batches(points: &[PiezoPoint]) -> Vec<SystemBatch> {
    points
        .chunks(MAX_SYSTEM_BATCH)
        .enumerate()
        .map(|(seq, chunk)| {
            let mut batch = SystemBatch::new(seq as u32);
            for p in chunk {
                let sample = SystemWireSample {
                    t: p.t,
                    x: p.x as f32,
                    v: None,
                    u: None,
                    electrical: heapless::Vec::from_slice(&[p.e as f32]).expect("one"),
                };
                batch.samples.push(sample).expect("room");
            }
            batch
        })
        .collect()
}

fn through_device(
    config: SystemConfig,
    points: &[PiezoPoint],
) -> (Vec<SystemSnapshot>, SystemSnapshot) {
    let mut host: Host<DEFAULT_WINDOW, DEFAULT_TERMS> = Host::default();
    let wire = system_config_to_wire(&config).expect("fits");
    assert_eq!(
        host.exchange(&HostMsg::ConfigureSystem(wire)),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    let mut scheduled = Vec::new();
    for (i, batch) in batches(points).into_iter().enumerate() {
        let message = HostMsg::SystemSamples(batch.clone());
        let mut replies = host.exchange(&message);
        // Every 13th batch is sent twice: acked again, not applied again.
        if i % 13 == 3 {
            assert_eq!(host.exchange(&message), [DeviceMsg::Ack { seq: batch.seq }]);
        }
        assert_eq!(replies.remove(0), DeviceMsg::Ack { seq: batch.seq });
        for reply in replies {
            match reply {
                DeviceMsg::SystemModel(s) => scheduled.push(s),
                other => panic!("unexpected {other:?}"),
            }
        }
    }
    let replies = host.exchange(&HostMsg::Query);
    let [
        DeviceMsg::SystemModel(last),
        DeviceMsg::Health { samples, .. },
    ] = &replies[..]
    else {
        panic!("{replies:?}");
    };
    assert_eq!(*samples, points.len() as u64);
    (scheduled, last.clone())
}

#[test]
fn a_piezo_harvester_through_the_device_equals_the_system_identifier_bit_for_bit() {
    for (piezo, n, window) in [
        (Piezo::monostable(), 30_000, 63),
        (Piezo::bistable(), 24_000, 41),
    ] {
        let points = piezo.simulate(n, DT);
        let config = config(window, 9_000);
        let (want_scheduled, want) = direct(config, &points);
        let (got_scheduled, got) = through_device(config, &points);
        assert_eq!(got_scheduled.len(), n / 9_000);
        assert_eq!(got_scheduled, want_scheduled);
        assert_eq!(got, want);
        // Two equations, and the electrical one is the harvester's.
        let model = system_model_from_snapshot::<DEFAULT_TERMS>(&got).expect("valid");
        assert_eq!(model.equations.len(), 2);
        assert_eq!(model.equations[0].target, Target::Acceleration);
        let voltage = Target::Rate(Electrical::Voltage);
        assert_eq!(model.equations[1].target, voltage);
        let coef = |m: [u8; 4]| {
            f64::from(
                model
                    .coefficient(voltage, StateTerm::Monomial([m[0], m[1], m[2], m[3], 0, 0]))
                    .expect("in the library"),
            )
        };
        let (kappa, lambda) = (coef([0, 1, 0, 0]), coef([0, 0, 1, 0]));
        // Each equation on its own line, as lssi-core writes it.
        let mut text = String::new();
        model.write_equation(1, 3, &mut text).expect("a String");
        assert!(text.starts_with("V' ="), "{text}");
        assert!(
            (kappa + piezo.kappa).abs() < 0.02 * piezo.kappa,
            "κ {kappa}"
        );
        assert!(
            (lambda + piezo.lambda).abs() < 0.02 * piezo.lambda,
            "λ {lambda}"
        );
    }
}

#[test]
fn system_and_single_equation_messages_do_not_mix() {
    let mut host: Host<DEFAULT_WINDOW, DEFAULT_TERMS> = Host::default();
    let points = Piezo::monostable().simulate(24, DT);
    let batch = batches(&points).remove(0);
    // System samples before any system configuration.
    assert_eq!(
        host.exchange(&HostMsg::SystemSamples(batch.clone())),
        [DeviceMsg::Nak {
            seq: 0,
            reason: NakReason::NotConfigured
        }]
    );
    // Too many terms: coupling order 3 adds V³, x²V, … beyond 16.
    let mut too_big = system_config_to_wire(&config(63, 1000)).expect("fits");
    too_big.coupling_order = 3;
    let replies = host.exchange(&HostMsg::ConfigureSystem(too_big));
    assert!(
        matches!(
            replies[..],
            [DeviceMsg::Nak {
                seq: CONTROL_SEQ,
                reason: NakReason::TooManyTerms { .. } | NakReason::BadConfig
            }]
        ),
        "{replies:?}"
    );
    let wire = system_config_to_wire(&config(63, 1000)).expect("fits");
    assert_eq!(
        host.exchange(&HostMsg::ConfigureSystem(wire)),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    // One equation's samples while a system is configured.
    let mut single = SampleBatch::new(0, Channels::X);
    single
        .push(WireSample {
            t: 0.0,
            x: 0.0,
            v: None,
            u: None,
        })
        .expect("room");
    assert_eq!(
        host.exchange(&HostMsg::Samples(single)),
        [DeviceMsg::Nak {
            seq: 0,
            reason: NakReason::NotConfigured
        }]
    );
    assert_eq!(
        host.exchange(&HostMsg::SystemSamples(batch.clone())),
        [DeviceMsg::Ack { seq: 0 }]
    );
    // Reset keeps the system; numbering starts again.
    assert_eq!(
        host.exchange(&HostMsg::Reset),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    assert_eq!(
        host.device.system().expect("a system").counters().accepted,
        0
    );
    // Back to one equation: system samples are refused again.
    let single = lssi_device::wire::config_to_wire(&duffing_config()).expect("fits");
    assert_eq!(
        host.exchange(&HostMsg::Configure(single)),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    assert!(host.device.system().is_none());
    assert_eq!(
        host.exchange(&HostMsg::SystemSamples(batch)),
        [DeviceMsg::Nak {
            seq: 0,
            reason: NakReason::NotConfigured
        }]
    );
}
