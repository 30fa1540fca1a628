//! A whole recording through the device equals the identifier driven directly: every
//! snapshot, scheduled and queried, bit for bit, and independent of the capacities W and P
//! (the host's `lssi identify` runs W = 1023, P = 32).

use crate::common;

use common::*;
use lssi_core::{Identifier, Sample};
use lssi_device::wire::{config_to_wire, model_from_snapshot, snapshot};
use lssi_device::{DEFAULT_TERMS, DEFAULT_WINDOW};
use lssi_proto::{CONTROL_SEQ, DeviceMsg, HostMsg, ModelSnapshot, SnapshotCause};

/// What `lssi identify --f32` does: push every sample, keep each scheduled model, screen.
fn direct<const W: usize, const P: usize>(
    samples: &[(f64, f64)],
) -> (Vec<ModelSnapshot>, ModelSnapshot) {
    let mut id: Identifier<f32, W, P> = Identifier::new(duffing_config()).expect("valid");
    let mut scheduled = Vec::new();
    for &(t, x) in samples {
        let sample = Sample {
            t,
            x: x as f32,
            v: None,
            u: None,
        };
        if id.push(sample) == Ok(true) {
            let model = id.model().expect("a screening made it");
            scheduled.push(snapshot(model, SnapshotCause::Scheduled).expect("fits"));
        }
    }
    id.screen();
    let last = snapshot(id.model().expect("a model"), SnapshotCause::Query).expect("fits");
    (scheduled, last)
}

/// The same recording through the device over the loopback, batches resent and duplicated.
fn through_device(samples: &[(f64, f64)]) -> (Vec<ModelSnapshot>, ModelSnapshot) {
    let mut host: Host<DEFAULT_WINDOW, DEFAULT_TERMS> = Host::default();
    let wire = config_to_wire(&duffing_config()).expect("fits");
    assert_eq!(
        host.exchange(&HostMsg::Configure(wire)),
        [DeviceMsg::Ack { seq: CONTROL_SEQ }]
    );
    let mut scheduled = Vec::new();
    let all = batches(samples, 0);
    for (i, batch) in all.iter().enumerate() {
        // Every 7th batch is sent twice; every 11th is preceded by the next one (a gap).
        if i % 11 == 5
            && let Some(next) = all.get(i + 1)
        {
            host.exchange(&HostMsg::Samples(next.clone()));
        }
        for reply in host.exchange(&HostMsg::Samples(batch.clone())) {
            if let DeviceMsg::Model(m) = reply {
                scheduled.push(m);
            }
        }
        if i % 7 == 3 {
            host.exchange(&HostMsg::Samples(batch.clone()));
        }
    }
    let replies = host.exchange(&HostMsg::Query);
    let [DeviceMsg::Model(last), DeviceMsg::Health { .. }] = &replies[..] else {
        panic!("expected Model and Health, got {replies:?}");
    };
    // A resent query (no samples since) screens nothing and gives the same snapshot.
    let again = host.exchange(&HostMsg::Query);
    assert!(matches!(&again[..], [DeviceMsg::Model(m), DeviceMsg::Health { .. }] if m == last));
    (scheduled, last.clone())
}

fn check(samples: &[(f64, f64)]) {
    let (device_scheduled, device_last) = through_device(samples);
    let (scheduled, last) = direct::<DEFAULT_WINDOW, DEFAULT_TERMS>(samples);
    let (host_scheduled, host_last) = direct::<1023, 32>(samples);
    assert!(!scheduled.is_empty());
    assert_eq!(device_scheduled, scheduled);
    assert_eq!(device_last, last);
    // Capacities do not matter when the window fits both.
    assert_eq!(host_scheduled, scheduled);
    assert_eq!(host_last, last);
    // Bit for bit (== on f32 would let 0.0 equal -0.0).
    let bits = |s: &ModelSnapshot| {
        s.coefficients
            .iter()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&device_last), bits(&last));
    // The model is the Duffing oscillator's: x'' ≈ -400 x - 2 x' - 4e4 x³ + 60 cos(15 t).
    let model = model_from_snapshot::<32>(&device_last).expect("valid snapshot");
    let k = model
        .coefficient(lssi_core::Term::Monomial { px: 1, pv: 0 })
        .expect("x");
    assert!((k + 400.0).abs() < 20.0, "stiffness {k}");
    assert_eq!(
        snapshot(&model, SnapshotCause::Query).expect("fits"),
        device_last
    );
}

#[test]
fn device_equals_direct_identifier() {
    // Ends between screenings: the query screens.
    check(&duffing(23_456, 1e-3));
}

#[test]
fn device_equals_direct_identifier_ending_on_a_screening() {
    // 20 016 = 834 full batches: the run ends 16 samples after the screening at 20 000.
    check(&duffing(20_016, 1e-3));
    // 15 000 = 625 × 24: the last sample runs the scheduled screening; the query does not
    // screen again, and still equals identify's extra screen().
    check(&duffing(15_000, 1e-3));
}
