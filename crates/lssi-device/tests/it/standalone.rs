//! The standalone instrument's parts on the host: a timer that queues readings, the
//! identify task, thread mode's screening on the snapshot, frames out and commands in.

use lssi_core::{Config, Identifier, Sample, Snapshot};
use lssi_device::Transport;
use lssi_device::standalone::{
    Clock, Engine, Event, EventQueue, IdentifyTask, Reading, Reporter, Sampler, Shared,
};
use lssi_proto::{DeviceFrameDecoder, DeviceMsg, HostMsg, SnapshotCause, encode};
use std::cell::Cell;

const W: usize = 64;
const P: usize = 16;
const C: usize = 1;

struct FakeClock(Cell<u32>);

impl Clock for FakeClock {
    const HZ: u32 = 1_000_000;
    fn now(&self) -> u32 {
        self.0.get()
    }
}

#[derive(Default)]
struct Wire(Vec<u8>);

impl Transport for Wire {
    type Error = std::convert::Infallible;
    fn read(&mut self, _: &mut [u8]) -> Result<usize, Self::Error> {
        Ok(0)
    }
    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.extend_from_slice(bytes);
        Ok(())
    }
}

fn config() -> Config {
    Config {
        sample_period: 0.01,
        window: 31,
        omega: 1.0,
        screening_period: 1500,
        ..Config::default()
    }
}

fn signal(i: u32) -> f32 {
    let t = f64::from(i) * 0.01;
    ((1.3 * t).sin() + 0.2 * (0.7 * t).cos()) as f32
}

fn decode(bytes: &[u8]) -> Vec<DeviceMsg> {
    let mut decoder = DeviceFrameDecoder::new();
    decoder
        .feed::<DeviceMsg>(bytes)
        .map(|m| m.expect("a valid frame"))
        .collect()
}

/// Runs `n` samples through the three parts, the identify task every `burst` ticks and
/// thread mode every `screen_every` ticks (a screening that lags the rows); returns the
/// frames sent and the shared state.
fn run(
    n: u32,
    burst: u32,
    screen_every: u32,
    reading: impl Fn(u32) -> f32,
) -> (Vec<DeviceMsg>, &'static Shared<P>) {
    let shared: &'static Shared<P> = Box::leak(Box::new(Shared::new()));
    shared.give_snapshot(Box::leak(Box::new(Snapshot::empty())));
    let queue: &'static mut EventQueue = Box::leak(Box::new(EventQueue::new()));
    let (producer, consumer) = queue.split();
    let mut sampler = Sampler::new(producer);
    let engine: &'static mut Engine<W, P, C> = Box::leak(Box::new(Engine::new()));
    engine.configure(config()).expect("valid");
    // As a board keeps them: the identify interrupt takes both out for each run.
    let identify: &'static IdentifyTask<W, P, C> = Box::leak(Box::new(IdentifyTask::new()));
    identify.give(engine, consumer);
    let mut reporter: Reporter<W, P, C> = Reporter::new(config(), 100.0, 100_000_000);
    let clock = FakeClock(Cell::new(0));
    let mut wire = Wire::default();
    for i in 0..n {
        clock.0.set(clock.0.get() + 10_000);
        sampler.tick(
            clock.now(),
            Reading {
                x: reading(i),
                v: None,
                u: None,
                e: None,
            },
            &shared.counters,
        );
        if i % burst == burst - 1 {
            identify.run(shared, &clock);
        }
        if i % screen_every == screen_every - 1 {
            let Ok(()) = reporter.poll(shared, &mut wire, &clock, || {});
        }
    }
    assert!(sampler.end());
    for _ in 0..4 {
        identify.run(shared, &clock);
        let Ok(()) = reporter.poll(shared, &mut wire, &clock, || {});
    }
    assert!(reporter.finished());
    (decode(&wire.0), shared)
}

/// The final model equals the identifier's own (every sample pushed, then a screening),
/// bit for bit, with screenings that lag the rows by up to 700 samples; no overruns with
/// the queue drained every 32 ticks; the final Health says so.
#[test]
fn the_final_model_is_the_identifiers_own() {
    let n = 5000;
    let (frames, shared) = run(n, 32, 700, signal);
    let mut id: Box<Identifier<f32, W, P, C>> = Box::new(Identifier::new(config()).expect("valid"));
    for i in 0..n {
        id.push(Sample {
            t: f64::from(i) * 0.01,
            x: signal(i),
            v: None,
            u: None,
        })
        .expect("finite");
    }
    assert!(id.screen());
    let model = id.model().expect("a model");
    let last_model = frames
        .iter()
        .rev()
        .find_map(|m| match m {
            DeviceMsg::Model(s) => Some(s.clone()),
            _ => None,
        })
        .expect("a model frame");
    assert_eq!(last_model.cause, SnapshotCause::Final);
    let expected: Vec<f32> = model.coefficients[..model.terms.len()].to_vec();
    assert_eq!(last_model.coefficients.to_vec(), expected);
    assert_eq!(last_model.samples, u64::from(n));
    match frames.last() {
        Some(DeviceMsg::Health {
            overruns,
            queue_high_water,
            samples,
            screenings_skipped,
            ..
        }) => {
            assert_eq!(*overruns, 0);
            assert_eq!(*queue_high_water, 32);
            assert_eq!(*samples, u64::from(n));
            assert_eq!(*screenings_skipped, 0);
        }
        other => panic!("the last frame is {other:?}"),
    }
    assert_eq!(shared.status().samples, u64::from(n));
}

/// A queue drained too late overruns: the lost samples are counted, never silent, and
/// the samples that follow keep the timer's time.
#[test]
fn a_full_queue_counts_overruns() {
    let (frames, shared) = run(2000, 100, 100, signal);
    let overruns = shared
        .counters
        .overruns
        .load(std::sync::atomic::Ordering::Relaxed);
    // 100 ticks a drain, 64 places: 36 lost a drain.
    assert_eq!(overruns, 20 * 36);
    assert_eq!(shared.status().samples, 2000 - u64::from(overruns));
    assert!(
        frames
            .iter()
            .any(|m| matches!(m, DeviceMsg::Health { overruns: o, .. } if *o == overruns))
    );
}

/// NaN and saturated readings are counted and skipped; sampling goes on.
#[test]
fn bad_readings_are_counted_and_skipped() {
    let (_, shared) = run(3000, 16, 16, |i| match i % 500 {
        7 => f32::NAN,
        9 => 1.0e30,
        _ => signal(i),
    });
    let status = shared.status();
    assert_eq!(status.rejected, 12);
    assert_eq!(status.samples, 3000 - 12);
}

/// A stuck sensor (one reading repeated) is passed through for STUCK_RUN samples, then
/// counted and skipped until it moves again; sampling goes on.
#[test]
fn a_stuck_sensor_is_counted_and_skipped() {
    let stuck = 1000..1600;
    let (_, shared) = run(3000, 16, 16, |i| {
        if stuck.contains(&i) { 0.25 } else { signal(i) }
    });
    let skipped = 600 - lssi_device::standalone::STUCK_RUN;
    let status = shared.status();
    assert_eq!(
        shared
            .counters
            .stuck
            .load(std::sync::atomic::Ordering::Relaxed),
        skipped
    );
    assert_eq!(status.rejected, u64::from(skipped));
    assert_eq!(status.samples, 3000 - u64::from(skipped));
}

/// Commands from a host mid-run: Hello, Query (model + health), a refused Configure, and
/// a host's sample batch (Busy: this device samples itself); garbage is counted.
#[test]
fn a_host_can_connect_mid_run() {
    let shared: &'static Shared<P> = Box::leak(Box::new(Shared::new()));
    let mut reporter: Reporter<W, P, C> = Reporter::new(config(), 100.0, 0);
    let mut wire = Wire::default();
    let mut bytes = vec![0x13, 0x37, 0x00];
    let mut frame = [0u8; 512];
    for message in [
        HostMsg::Hello {
            protocol_version: lssi_proto::PROTOCOL_VERSION,
        },
        HostMsg::Query,
        HostMsg::Configure(
            lssi_device::wire::config_to_wire(&Config {
                window: 500,
                ..config()
            })
            .expect("encodable"),
        ),
    ] {
        let len = encode(&message, &mut frame).expect("fits");
        bytes.extend_from_slice(&frame[..len]);
    }
    let Ok(()) = reporter.receive::<_, FakeClock>(&bytes, shared, &mut wire);
    let frames = decode(&wire.0);
    assert!(matches!(
        frames[0],
        DeviceMsg::HelloReply {
            window_capacity: 64,
            ..
        }
    ));
    assert!(matches!(frames[1], DeviceMsg::Health { .. }));
    assert!(matches!(
        frames[2],
        DeviceMsg::Nak {
            reason: lssi_proto::NakReason::BadConfig,
            ..
        }
    ));
    assert_eq!(frames.len(), 3);
    // The refused configuration is not one to keep.
    assert_eq!(reporter.take_accepted(), None);
}

#[test]
fn an_accepted_configuration_is_handed_over_once_to_keep() {
    let shared: &'static Shared<P> = Box::leak(Box::new(Shared::new()));
    let mut reporter: Reporter<W, P, C> = Reporter::new(config(), 100.0, 0);
    let mut wire = Wire::default();
    let sent = lssi_device::wire::config_to_wire(&Config {
        window: 41,
        ..config()
    })
    .expect("encodable");
    let mut frame = [0u8; 512];
    let len = encode(&HostMsg::Configure(sent), &mut frame).expect("fits");
    let Ok(()) = reporter.receive::<_, FakeClock>(&frame[..len], shared, &mut wire);
    assert!(matches!(
        decode(&wire.0)[..],
        [DeviceMsg::Ack {
            seq: lssi_proto::CONTROL_SEQ
        }]
    ));
    assert_eq!(reporter.take_accepted(), Some(sent));
    assert_eq!(reporter.take_accepted(), None);
}

/// A decimating sampler: one row every D conversions (after the CIC's and its
/// compensator's warm-up), the row the decimator's own, queued with consecutive indices;
/// the identify task wakes for rows only (`tick` says when).
#[test]
fn a_decimating_sampler_queues_one_row_every_factor_conversions() {
    use lssi_device::decimate::Decimator;
    let counters = Shared::<P>::new();
    let queue: &'static mut EventQueue = Box::leak(Box::new(EventQueue::new()));
    let (producer, mut consumer) = queue.split();
    let mut sampler = Sampler::new(producer);
    let mut reference = Decimator::new(5, 3).expect("valid");
    sampler.set_decimator(reference);
    let mut rows = Vec::new();
    let mut woken = 0;
    for i in 0..300u32 {
        let x = signal(i);
        if sampler.tick(
            i,
            Reading {
                x,
                v: None,
                u: None,
                e: None,
            },
            &counters.counters,
        ) {
            woken += 1;
        }
        if let Some(row) = reference.push([x, 0.0, 0.0]) {
            rows.push(row[0]);
        }
        while let Some(event) = consumer.dequeue() {
            let Event::Sample { index, reading, .. } = event else {
                panic!("no end yet");
            };
            assert_eq!(reading.x, rows[index as usize], "row {index}");
        }
    }
    // 60 blocks of 5, the first two fill the order-3 kernel and two more the compensator
    // (it needs the CIC rows either side of the one it compensates).
    assert_eq!(reference.warm_up(), 5);
    assert_eq!(rows.len(), 56);
    assert_eq!(woken, 56);
    assert_eq!(sampler.taken(), 56);
    assert_eq!(sampler.conversions(), 300);
}

/// With an ADC rate set, a `Configure` whose row period is no whole number of conversions
/// is refused (`BadConfig`) and one that is gets the decimator to the sampling interrupt.
#[test]
fn a_configure_sets_the_decimation_by_its_row_period() {
    let shared: &'static Shared<P> = Box::leak(Box::new(Shared::new()));
    let mut reporter: Reporter<W, P, C> = Reporter::new(config(), 100.0, 0);
    reporter.set_adc(1000.0, 3, 0.0);
    let mut wire = Wire::default();
    for (period, accepted) in [
        (0.0035, false),
        (0.0031, false),
        (0.003, true),
        (0.01, true),
        (0.5, false),
    ] {
        wire.0.clear();
        let sent = lssi_device::wire::config_to_wire(&Config {
            sample_period: period,
            ..config()
        })
        .expect("encodable");
        let mut frame = [0u8; 512];
        let len = encode(&HostMsg::Configure(sent), &mut frame).expect("fits");
        let Ok(()) = reporter.receive::<_, FakeClock>(&frame[..len], shared, &mut wire);
        let reply = decode(&wire.0);
        if accepted {
            assert!(
                matches!(reply[..], [DeviceMsg::Ack { .. }]),
                "{period}: {reply:?}"
            );
        } else {
            assert!(
                matches!(
                    reply[..],
                    [DeviceMsg::Nak {
                        reason: lssi_proto::NakReason::BadConfig,
                        ..
                    }]
                ),
                "{period}: {reply:?}"
            );
        }
    }
}

/// The duty cycle: the device identifies for a window, reports Model then Health, sleeps
/// for the interval (no row pushed), wakes and goes on from the kept model; each window's
/// report says how the coefficients moved from the previous one.
///
/// Returns per window: (rows the model has seen, the drift), and the frames.
fn windows(
    n: u32,
    window_s: f32,
    interval_s: f32,
    reading: impl Fn(u32) -> f32,
) -> (Vec<(u64, lssi_device::standalone::Drift)>, Vec<DeviceMsg>) {
    windows_every(n, window_s, interval_s, 1, reading)
}

/// [`windows`] with a model every `model_every` windows (the others Health only): per
/// window that made a model, (rows, the drift), and the frames.
fn windows_every(
    n: u32,
    window_s: f32,
    interval_s: f32,
    model_every: u16,
    reading: impl Fn(u32) -> f32,
) -> (Vec<(u64, lssi_device::standalone::Drift)>, Vec<DeviceMsg>) {
    let shared: &'static Shared<P> = Box::leak(Box::new(Shared::new()));
    shared.give_snapshot(Box::leak(Box::new(Snapshot::empty())));
    let queue: &'static mut EventQueue = Box::leak(Box::new(EventQueue::new()));
    let (producer, consumer) = queue.split();
    let mut sampler = Sampler::new(producer);
    let engine: &'static mut Engine<W, P, C> = Box::leak(Box::new(Engine::new()));
    let config = Config {
        memory: Some(20.0),
        screening_period: 400,
        ..config()
    };
    engine.configure(config).expect("valid");
    let identify: &'static IdentifyTask<W, P, C> = Box::leak(Box::new(IdentifyTask::new()));
    identify.give(engine, consumer);
    let mut reporter: Reporter<W, P, C> = Reporter::new(config, 100.0, 1_000);
    reporter.set_duty(
        Some(lssi_proto::WireDuty {
            window: window_s,
            interval: interval_s,
            model_every,
        }),
        shared,
    );
    let clock = FakeClock(Cell::new(0));
    let mut wire = Wire::default();
    let mut out = Vec::new();
    for i in 0..n {
        clock.0.set(clock.0.get() + 10_000);
        let reading = Reading {
            x: reading(i),
            v: None,
            u: None,
            e: None,
        };
        if sampler.convert(clock.now(), reading, shared) {
            identify.run(shared, &clock);
            // Thread mode screens right away (a window's end) and reports.
            let before = reporter.drift();
            let Ok(()) = reporter.poll(shared, &mut wire, &clock, || {});
            identify.run(shared, &clock);
            if reporter.drift() != before
                && let Some(drift) = reporter.drift()
            {
                out.push((shared.status().samples, drift));
            }
        }
    }
    (out, decode(&wire.0))
}

/// A forced Duffing oscillator, x'' = −k x − 0.1 v − 0.5 x³ + 2 cos t (the library's
/// terms at Ω = 1), sampled at 100 Hz (RK4, 4 steps a sample); `k` from `stiffness(i)`.
fn duffing(n: u32, stiffness: impl Fn(u32) -> f64) -> Vec<f32> {
    let (mut x, mut v) = (1.0f64, 0.0f64);
    let h = 0.01 / 4.0;
    let f = |t: f64, x: f64, v: f64, k: f64| -k * x - 0.1 * v - 0.5 * x * x * x + 2.0 * t.cos();
    let mut out = Vec::with_capacity(n as usize);
    for i in 0..n {
        out.push(x as f32);
        let k = stiffness(i);
        for j in 0..4 {
            let t = f64::from(i) * 0.01 + f64::from(j) * h;
            let (k1x, k1v) = (v, f(t, x, v, k));
            let (k2x, k2v) = (
                v + 0.5 * h * k1v,
                f(t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v, k),
            );
            let (k3x, k3v) = (
                v + 0.5 * h * k2v,
                f(t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v, k),
            );
            let (k4x, k4v) = (v + h * k3v, f(t + h, x + h * k3x, v + h * k3v, k));
            x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
    }
    out
}

#[test]
fn duty_cycled_windows_report_once_each_and_go_on_from_the_kept_model() {
    // 100 rows a second: windows of 10 s (1000 rows) every 30 s, 9 windows in 270 s.
    let x = duffing(27_000, |_| 4.0);
    let (reports, frames) = windows(27_000, 10.0, 20.0, |i| x[i as usize]);
    assert_eq!(reports.len(), 9, "{reports:?}");
    for (k, (samples, drift)) in reports.iter().enumerate() {
        // Only the windows' rows went in, and the model kept them all.
        assert_eq!(*samples, 1000 * (k as u64 + 1), "window {k}");
        assert_eq!(drift.windows, k as u32 + 1);
    }
    // Nothing but the windows' reports went out: a Model and a Health each.
    let models = frames
        .iter()
        .filter(|m| matches!(m, DeviceMsg::Model(_)))
        .count();
    let healths = frames
        .iter()
        .filter(|m| matches!(m, DeviceMsg::Health { .. }))
        .count();
    assert_eq!((models, healths), (9, 9));
    // The first window has nothing to compare with.
    assert_eq!(reports[0].1.relative, 0.0);
    // Each window's Health carries its drift (protocol version 7), as the reporter has it.
    let carried: Vec<_> = frames
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::Health { drift, .. } => Some(*drift),
            _ => None,
        })
        .collect();
    let expected: Vec<_> = reports
        .iter()
        .map(|(_, d)| Some(lssi_device::wire::drift_to_wire(d)))
        .collect();
    assert_eq!(carried, expected);
}

/// A model every third window: the windows between end with a Health alone (no screening),
/// their rows still go in, and the models made are those of a model every window at the
/// same windows, bit for bit; the drift is measured between consecutive models.
#[test]
fn a_model_every_third_window_is_the_every_window_model_and_the_others_send_health_alone() {
    use lssi_device::standalone::Drift;
    let x = duffing(27_000, |i| if i < 12_000 { 4.0 } else { 5.0 });
    let (every, every_frames) = windows(27_000, 10.0, 20.0, |i| x[i as usize]);
    let (third, frames) = windows_every(27_000, 10.0, 20.0, 3, |i| x[i as usize]);
    let kinds: String = frames
        .iter()
        .map(|m| match m {
            DeviceMsg::Model(_) => 'M',
            DeviceMsg::Health { .. } => 'H',
            _ => '?',
        })
        .collect();
    assert_eq!(kinds, "HHMHHHMHHHMH");
    // Every window's Health counts its rows: the Health-only windows' rows went in.
    let samples: Vec<u64> = frames
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::Health { samples, .. } => Some(*samples),
            _ => None,
        })
        .collect();
    assert_eq!(samples, (1..=9).map(|k| 1000 * k).collect::<Vec<u64>>());
    let models = |frames: &[DeviceMsg]| -> Vec<lssi_proto::ModelSnapshot> {
        frames
            .iter()
            .filter_map(|m| match m {
                DeviceMsg::Model(s) => Some(s.clone()),
                _ => None,
            })
            .collect()
    };
    let (all, made) = (models(&every_frames), models(&frames));
    assert_eq!(all.len(), 9);
    assert_eq!(made.len(), 3);
    for (k, model) in made.iter().enumerate() {
        assert_eq!(model, &all[3 * k + 2], "window {}", 3 * k + 3);
    }
    // So with every 2nd and 4th window, and on the unchanged harvester and a softer one
    // (k 3.2) with other windows (8 s every 25 s).
    let steady = duffing(27_000, |_| 4.0);
    let soft = duffing(27_000, |_| 3.2);
    for (name, x, window, interval) in [
        ("changed", &x, 10.0, 20.0),
        ("steady", &steady, 10.0, 20.0),
        ("soft", &soft, 8.0, 17.0),
    ] {
        let (_, all_frames) = windows(27_000, window, interval, |i| x[i as usize]);
        let all = models(&all_frames);
        for n in [2u16, 4] {
            let (_, frames) = windows_every(27_000, window, interval, n, |i| x[i as usize]);
            let made = models(&frames);
            let n = usize::from(n);
            assert_eq!(made.len(), all.len() / n, "{name}, every {n}");
            for (k, model) in made.iter().enumerate() {
                assert_eq!(model, &all[n * k + n - 1], "{name}, every {n}, model {k}");
            }
        }
    }
    // The drift at windows 3, 6 and 9, each from the model before.
    assert_eq!(every.len(), 9);
    let windows: Vec<u32> = third.iter().map(|(_, d)| d.windows).collect();
    assert_eq!(windows, [3, 6, 9]);
    assert_eq!(third[0].1.relative, 0.0);
    for k in 1..3 {
        let expected = Drift::between(&made[k - 1], &made[k], 3 * k as u32 + 3);
        assert_eq!(third[k].1, expected, "window {}", 3 * k + 3);
    }
    // The stiffer harvester (from 120 s, window 5) shows at window 6's model.
    assert!(
        third[1].1.relative > third[2].1.relative,
        "drift {:?}",
        third.iter().map(|(_, d)| d.relative).collect::<Vec<_>>()
    );
    // Each Health carries the drift of the last model made (none before the first).
    let carried: Vec<Option<u32>> = frames
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::Health { drift, .. } => Some(drift.map(|d| d.windows)),
            _ => None,
        })
        .collect();
    let expected: Vec<Option<u32>> = (1..=9u32).map(|k| (k >= 3).then_some(k - k % 3)).collect();
    assert_eq!(carried, expected);
}

#[test]
fn a_changed_harvester_shows_as_drift_between_windows() {
    // The same oscillator, then from 120 s on (window 5 of 9) 25 % stiffer: the windows
    // after the change move more than any window of the unchanged run after its first two.
    let steady_x = duffing(27_000, |_| 4.0);
    let moved_x = duffing(27_000, |i| if i < 12_000 { 4.0 } else { 5.0 });
    let (steady, _) = windows(27_000, 10.0, 20.0, |i| steady_x[i as usize]);
    let (moved, _) = windows(27_000, 10.0, 20.0, |i| moved_x[i as usize]);
    assert_eq!((steady.len(), moved.len()), (9, 9));
    println!(
        "drift, unchanged: {:?}; changed: {:?}",
        steady.iter().map(|(_, d)| d.relative).collect::<Vec<_>>(),
        moved.iter().map(|(_, d)| d.relative).collect::<Vec<_>>()
    );
    let steady_max = steady[2..]
        .iter()
        .map(|(_, d)| d.relative)
        .fold(0.0f32, f32::max);
    let after = moved[4].1.relative;
    assert!(
        after > steady_max,
        "after the change {after}, unchanged at most {steady_max}"
    );
}

/// The two-channel instrument on the host: x and V through the sampler (decimated together
/// by 4, a CIC of order 3), the system's identify task, thread mode's screening on a
/// `SystemShot` with screenings lagging the rows: every scheduled model and the final one
/// are, bit for bit, lssi-core's `SystemIdentifier` pushed the same rows; a host's
/// `Configure` (one equation) is refused by this instrument, a `ConfigureSystem` accepted.
#[test]
fn the_two_channel_instrument_reports_the_systems_own_models() {
    use lssi_core::library::Electrical;
    use lssi_core::{LibraryConfig, PolyFamily, SystemConfig, SystemIdentifier, SystemSample};
    use lssi_device::decimate::Decimator;
    use lssi_device::standalone::{SystemEngine, SystemShot};
    use lssi_device::system::{system_config_to_wire, system_snapshot};
    use lssi_proto::{CONTROL_SEQ, NakReason};
    use lssi_testkit::harvester::Piezo;

    const C2: usize = 2;
    let factor = 4;
    let adc_dt = 0.0025;
    let config = SystemConfig {
        base: Config {
            sample_period: adc_dt * f64::from(factor),
            window: 41,
            derivative_degree: 5,
            library: LibraryConfig {
                poly_order: 3,
                family: PolyFamily::All,
                constant: true,
                harmonics: 1,
                input: false,
            },
            omega: 0.8,
            screening_period: 3_000,
            ..Config::default()
        },
        electrical: [Some(Electrical::Voltage), None],
        coupling_order: 1,
        displacements: 1,
    };
    let points = Piezo::bistable().simulate(40_000, adc_dt);

    type Shared2 = Shared<P, SystemShot<P>>;
    let shared: &'static Shared2 = Box::leak(Box::new(Shared::new()));
    shared.give_snapshot(Box::leak(Box::new(SystemShot::snapshot())));
    let queue: &'static mut EventQueue = Box::leak(Box::new(EventQueue::new()));
    let (producer, consumer) = queue.split();
    let mut sampler = Sampler::new(producer);
    let mut decimator = Decimator::new(factor, 3).expect("a decimator");
    sampler.set_decimator(decimator);
    let offset = decimator.time_offset(1.0 / adc_dt);
    let engine: &'static mut SystemEngine<W, P, C2> = Box::leak(Box::new(SystemEngine::new()));
    engine.configure_at(config, offset).expect("valid");
    let identify: &'static IdentifyTask<W, P, C2, SystemEngine<W, P, C2>> =
        Box::leak(Box::new(IdentifyTask::new()));
    identify.give(engine, consumer);
    let mut reporter: Reporter<W, P, C2, SystemShot<P>> = Reporter::new(config, 100.0, 0);
    let clock = FakeClock(Cell::new(0));
    let mut wire = Wire::default();
    // The models thread mode made, as it keeps them (it sends them every period; 0 here).
    let mut made: Vec<lssi_proto::SystemSnapshot> = Vec::new();
    let mut keep = |reporter: &Reporter<W, P, C2, SystemShot<P>>| {
        if let Some(DeviceMsg::SystemModel(s)) = reporter.latest_message()
            && made.last() != Some(s)
        {
            made.push(s.clone());
        }
    };
    for (i, p) in points.iter().enumerate() {
        clock.0.set(clock.0.get() + 2_500);
        let reading = Reading {
            x: p.x as f32,
            v: None,
            u: None,
            e: Some(p.e as f32),
        };
        sampler.tick(clock.now(), reading, &shared.counters);
        if i % 64 == 63 {
            identify.run(shared, &clock);
        }
        if i % 2_000 == 1_999 {
            let Ok(()) = reporter.poll(shared, &mut wire, &clock, || {});
            keep(&reporter);
        }
    }
    assert!(sampler.end());
    for _ in 0..4 {
        identify.run(shared, &clock);
        let Ok(()) = reporter.poll(shared, &mut wire, &clock, || {});
        keep(&reporter);
    }
    assert!(reporter.finished());
    let frames = decode(&wire.0);

    // The host: the same rows (decimated by the same decimator) through SystemIdentifier.
    let mut id: Box<SystemIdentifier<f32, W, P, 2, C2>> =
        Box::new(SystemIdentifier::new(config).expect("valid"));
    let mut scheduled = Vec::new();
    let mut rows = 0u64;
    for p in &points {
        let Some(row) = decimator.push_channels([p.x as f32, p.e as f32, 0.0], 2) else {
            continue;
        };
        let e = [row[1]];
        let sample = SystemSample {
            x2: None,
            v2: None,
            t: rows as f64 * config.base.sample_period + offset,
            x: row[0],
            v: None,
            u: None,
            electrical: &e,
        };
        rows += 1;
        if id.push(&sample) == Ok(true) {
            let model = id.model().expect("a model");
            scheduled.push(system_snapshot(model, SnapshotCause::Scheduled).expect("fits"));
        }
    }
    assert!(id.screen());
    let want = system_snapshot(id.model().expect("a model"), SnapshotCause::Final).expect("fits");
    let sent: Vec<_> = frames
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::SystemModel(s) => Some(s.clone()),
            DeviceMsg::Model(_) => panic!("a single-equation Model from the system's instrument"),
            _ => None,
        })
        .collect();
    assert_eq!(
        sent.len(),
        1,
        "the final model alone is sent (no report period)"
    );
    assert_eq!(sent.last(), made.last());
    let got = made;
    assert_eq!(
        shared
            .counters
            .screenings_skipped
            .load(std::sync::atomic::Ordering::Relaxed),
        0
    );
    let (last, earlier) = got.split_last().expect("model frames");
    assert_eq!(last, &want, "the final model");
    assert!(
        scheduled.len() >= 2,
        "{} scheduled screenings",
        scheduled.len()
    );
    assert_eq!(earlier, &scheduled[..], "the scheduled models, in order");
    let bits = |s: &lssi_proto::SystemSnapshot| -> Vec<u32> {
        s.equations
            .iter()
            .flat_map(|e| e.coefficients.iter().map(|c| c.to_bits()))
            .collect()
    };
    assert_eq!(bits(last), bits(&want));

    // Commands: one equation's Configure is refused, a system's accepted.
    let mut out = Wire::default();
    let mut frame = [0u8; lssi_proto::MAX_HOST_FRAME_LEN];
    let single = lssi_device::wire::config_to_wire(&config.base).expect("encodable");
    let len = encode(&HostMsg::Configure(single), &mut frame).expect("encodes");
    let Ok(()) = reporter.receive::<_, FakeClock>(&frame[..len], shared, &mut out);
    let wire_system = system_config_to_wire(&config).expect("encodable");
    let len = encode(&HostMsg::ConfigureSystem(wire_system), &mut frame).expect("encodes");
    let Ok(()) = reporter.receive::<_, FakeClock>(&frame[..len], shared, &mut out);
    assert_eq!(
        decode(&out.0),
        [
            DeviceMsg::Nak {
                seq: CONTROL_SEQ,
                reason: NakReason::BadConfig
            },
            DeviceMsg::Ack { seq: CONTROL_SEQ }
        ]
    );
}

/// Amplitudes of `signal` (about 1.2) a recording far from zero is offset by.
const FAR: f64 = 1.0e4 * 1.2;

/// The model lssi-core's f32 identifier makes of rows `from..n` of `reading`, each less
/// `reference` as the device takes it off (`(reading as f64 − reference) as f32`), with the
/// rows' own times: what the device's identifier, restarted at row `from`, must report.
fn model_from(n: u32, from: u32, reference: f64, reading: impl Fn(u32) -> f32) -> (Vec<f32>, u64) {
    let mut id: Box<Identifier<f32, W, P, C>> = Box::new(Identifier::new(config()).expect("valid"));
    for i in from..n {
        let _ = id.push(Sample {
            t: f64::from(i) * 0.01,
            x: (f64::from(reading(i)) - reference) as f32,
            v: None,
            u: None,
        });
    }
    assert!(id.screen());
    let model = id.model().expect("a model");
    (
        model.coefficients[..model.terms.len()].to_vec(),
        id.counters().accepted,
    )
}

/// The device's final model and the references its last Health carries.
fn final_model(
    frames: &[DeviceMsg],
) -> (lssi_proto::ModelSnapshot, Option<lssi_proto::WireReference>) {
    let model = frames
        .iter()
        .rev()
        .find_map(|m| match m {
            DeviceMsg::Model(s) if s.cause == SnapshotCause::Final => Some(s.clone()),
            _ => None,
        })
        .expect("a final model");
    let reference = match frames.last() {
        Some(DeviceMsg::Health { reference, .. }) => *reference,
        other => panic!("the last frame is {other:?}"),
    };
    (model, reference)
}

/// A recording 10⁴ amplitudes from zero: the device learns its reference from the first
/// 1,024 rows (their mean, summed in f64), restarts its identifier at the 1,024th and
/// pushes every row from there less it; its final model is, bit for bit, the identifier's
/// on rows 1023.. less that reference, and its Health names the reference. Fed as they
/// come (no reference), the same rows give another model: f32 keeps ≈ 10 bits of the
/// motion at 1.2 · 10⁴.
#[test]
fn a_recording_far_from_zero_is_identified_less_its_first_rows_mean_from_its_1024th_row() {
    let n = 5000;
    let raw = |i: u32| (f64::from(signal(i)) + FAR) as f32;
    let (frames, shared) = run(n, 32, 700, raw);
    let reference = (0..1024).map(|i| f64::from(raw(i))).sum::<f64>() / 1024.0;
    let (got, health_reference) = final_model(&frames);
    assert_eq!(
        health_reference,
        Some(lssi_proto::WireReference {
            x: reference,
            v: 0.0,
            e: 0.0
        })
    );
    assert_eq!(shared.reference(), health_reference);
    let (want, accepted) = model_from(n, 1023, reference, raw);
    assert_eq!(
        got.coefficients.to_vec(),
        want,
        "the model of rows 1023.. less the reference"
    );
    assert_eq!(got.samples, accepted);
    assert_eq!(accepted, u64::from(n - 1023));
    // Not the model of the raw rows, nor of every row less the reference.
    assert_ne!(got.coefficients.to_vec(), model_from(n, 0, 0.0, raw).0);
    assert_ne!(
        got.coefficients.to_vec(),
        model_from(n, 0, reference, raw).0
    );
}

/// A recording about zero by the rule (an offset under 3 ranges of its first rows) never
/// restarts: its final model is, bit for bit, the identifier's on every row as it came, and
/// its Health names no reference.
#[test]
fn a_recording_about_zero_is_identified_as_it_comes() {
    let n = 5000;
    for offset in [0.0, 2.0] {
        let reading = |i: u32| (f64::from(signal(i)) + offset) as f32;
        let (frames, shared) = run(n, 32, 700, reading);
        let (got, reference) = final_model(&frames);
        assert_eq!(reference, None, "offset {offset}");
        assert_eq!(shared.reference(), None);
        let (want, accepted) = model_from(n, 0, 0.0, reading);
        assert_eq!(got.coefficients.to_vec(), want, "offset {offset}");
        assert_eq!(got.samples, u64::from(n));
        assert_eq!(accepted, u64::from(n));
    }
}

/// NaN rows before the 1,024th finite one are not counted: the reference is the mean of
/// the first 1,024 finite rows, and the identifier restarts at the row that completes them.
#[test]
fn nan_rows_are_not_counted_among_the_first_rows() {
    let n = 5000;
    let raw = |i: u32| {
        if i % 100 == 5 && i < 2000 {
            f32::NAN
        } else {
            (f64::from(signal(i)) + FAR) as f32
        }
    };
    let (frames, shared) = run(n, 32, 700, raw);
    let finite: Vec<u32> = (0..n).filter(|&i| raw(i).is_finite()).take(1024).collect();
    let from = *finite.last().expect("1,024 finite rows");
    // 11 NaN rows (5, 105, …, 1005) before the 1,024th finite one.
    assert_eq!(from, 1023 + 11);
    let reference = finite.iter().map(|&i| f64::from(raw(i))).sum::<f64>() / 1024.0;
    let (got, health_reference) = final_model(&frames);
    assert_eq!(health_reference.map(|r| r.x), Some(reference));
    let (want, accepted) = model_from(n, from, reference, raw);
    assert_eq!(got.coefficients.to_vec(), want);
    assert_eq!(got.samples, accepted);
    // The NaN rows after the restart are rejected, as before.
    assert_eq!(shared.status().rejected, 20 - 11);
}

/// The two-channel instrument on x and V each 10⁴ amplitudes from zero (a piezo harvester):
/// the system's engine learns both references from the first 1,024 rows, restarts at the
/// 1,024th, and its final model is, bit for bit, lssi-core's `SystemIdentifier` on rows
/// 1023.. less them; the Health names both. (An x'' or V' of raw rows would lose most of
/// f32's bits.)
#[test]
fn the_two_channel_instrument_takes_its_first_rows_means_off_x_and_v() {
    use lssi_core::library::Electrical;
    use lssi_core::{LibraryConfig, PolyFamily, SystemConfig, SystemIdentifier, SystemSample};
    use lssi_device::standalone::{SystemEngine, SystemShot};
    use lssi_device::system::system_snapshot;
    use lssi_testkit::harvester::Piezo;

    const C2: usize = 2;
    let period = 0.01;
    let config = SystemConfig {
        base: Config {
            sample_period: period,
            window: 41,
            derivative_degree: 5,
            library: LibraryConfig {
                poly_order: 3,
                family: PolyFamily::All,
                constant: true,
                harmonics: 1,
                input: false,
            },
            omega: 0.8,
            screening_period: 3_000,
            ..Config::default()
        },
        electrical: [Some(Electrical::Voltage), None],
        coupling_order: 1,
        displacements: 1,
    };
    let points = Piezo::bistable().simulate(10_000, period);
    let far =
        |values: &mut dyn Iterator<Item = f64>| 1.0e4 * values.fold(0.0f64, |m, q| m.max(q.abs()));
    let (dx, de) = (
        far(&mut points.iter().map(|p| p.x)),
        far(&mut points.iter().map(|p| p.e)),
    );
    let readings: Vec<(f32, f32)> = points
        .iter()
        .map(|p| ((p.x + dx) as f32, (p.e + de) as f32))
        .collect();

    type Shared2 = Shared<P, SystemShot<P>>;
    let shared: &'static Shared2 = Box::leak(Box::new(Shared::new()));
    shared.give_snapshot(Box::leak(Box::new(SystemShot::snapshot())));
    let queue: &'static mut EventQueue = Box::leak(Box::new(EventQueue::new()));
    let (producer, consumer) = queue.split();
    let mut sampler = Sampler::new(producer);
    let engine: &'static mut SystemEngine<W, P, C2> = Box::leak(Box::new(SystemEngine::new()));
    engine.configure_at(config, 0.0).expect("valid");
    let identify: &'static IdentifyTask<W, P, C2, SystemEngine<W, P, C2>> =
        Box::leak(Box::new(IdentifyTask::new()));
    identify.give(engine, consumer);
    let mut reporter: Reporter<W, P, C2, SystemShot<P>> = Reporter::new(config, 100.0, 0);
    let clock = FakeClock(Cell::new(0));
    let mut wire = Wire::default();
    for (i, &(x, e)) in readings.iter().enumerate() {
        clock.0.set(clock.0.get() + 10_000);
        let reading = Reading {
            x,
            v: None,
            u: None,
            e: Some(e),
        };
        sampler.tick(clock.now(), reading, &shared.counters);
        if i % 32 == 31 {
            identify.run(shared, &clock);
        }
        if i % 500 == 499 {
            let Ok(()) = reporter.poll(shared, &mut wire, &clock, || {});
        }
    }
    assert!(sampler.end());
    for _ in 0..4 {
        identify.run(shared, &clock);
        let Ok(()) = reporter.poll(shared, &mut wire, &clock, || {});
    }
    assert!(reporter.finished());
    let frames = decode(&wire.0);

    let mean = |f: fn(&(f32, f32)) -> f32| {
        readings[..1024]
            .iter()
            .map(|r| f64::from(f(r)))
            .sum::<f64>()
            / 1024.0
    };
    let (rx, re) = (mean(|r| r.0), mean(|r| r.1));
    let reference = match frames.last() {
        Some(DeviceMsg::Health { reference, .. }) => *reference,
        other => panic!("the last frame is {other:?}"),
    };
    assert_eq!(
        reference,
        Some(lssi_proto::WireReference {
            x: rx,
            v: 0.0,
            e: re
        })
    );

    let mut id: Box<SystemIdentifier<f32, W, P, 2, C2>> =
        Box::new(SystemIdentifier::new(config).expect("valid"));
    for (i, &(x, e)) in readings.iter().enumerate().skip(1023) {
        let e = [(f64::from(e) - re) as f32];
        let _ = id.push(&SystemSample {
            x2: None,
            v2: None,
            t: i as f64 * period,
            x: (f64::from(x) - rx) as f32,
            v: None,
            u: None,
            electrical: &e,
        });
    }
    assert!(id.screen());
    let want = system_snapshot(id.model().expect("a model"), SnapshotCause::Final).expect("fits");
    let got = frames
        .iter()
        .rev()
        .find_map(|m| match m {
            DeviceMsg::SystemModel(s) if s.cause == SnapshotCause::Final => Some(s.clone()),
            _ => None,
        })
        .expect("a final model");
    assert_eq!(got.samples, (readings.len() - 1023) as u64);
    assert_eq!(got, want, "the model of rows 1023.. less the references");
}

/// Duty-cycled windows on a displacement 10⁴ amplitudes from zero: the first window's model
/// is of the raw rows (no reference yet, none reported); the references are learnt at row
/// 1,023, in the second window, which restarts the identifier: its model is about x less
/// the reference, the Health says so from then on, and the drift starts again there (a
/// model in other coordinates has nothing to compare with), then measures the windows
/// after as before.
#[test]
fn duty_cycled_windows_start_the_drift_again_at_the_restart() {
    let x = duffing(9_000, |_| 4.0);
    let far = |i: u32| (f64::from(x[i as usize]) + 1.0e4) as f32;
    let (reports, frames) = windows(9_000, 10.0, 20.0, far);
    assert_eq!(reports.len(), 3, "{reports:?}");
    let samples: Vec<u64> = reports.iter().map(|(s, _)| *s).collect();
    assert_eq!(samples, [1000, 2000 - 1023, 3000 - 1023]);
    let references: Vec<Option<f64>> = frames
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::Health { reference, .. } => Some(reference.map(|r| r.x)),
            _ => None,
        })
        .collect();
    // The first 1,024 rows: window 1's 1,000 (conversions 0..1000) and window 2's first 24
    // (from conversion 3,000: windows every 30 s).
    let first = (0..1000).chain(3000..3024);
    let mean = first.map(|i| f64::from(far(i))).sum::<f64>() / 1024.0;
    assert_eq!(references, [None, Some(mean), Some(mean)]);
    // The drift starts again at the second window, and the third moves little from it.
    assert_eq!(reports[0].1.relative, 0.0);
    assert_eq!(reports[1].1.relative, 0.0, "{reports:?}");
    assert!(
        reports[2].1.relative > 0.0 && reports[2].1.relative < 0.05,
        "{reports:?}"
    );
}
