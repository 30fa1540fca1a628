//! `lssi monitor --port` with `--row-rate` and a duty cycle configures the board before it
//! listens (the configuration's row period and duty cycle as asked), and prints the drift the
//! board's Health carries; a refusal is one sentence. The board is a thread on a pseudo
//! terminal's other end.

#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::common::lssi;
use lssi_proto::{
    CONTROL_SEQ, CostUnit, DeviceMsg, HostFrameDecoder, HostMsg, MAX_FRAME_LEN, NakReason,
    WireConfig, WireDrift, WireReference, encode,
};
use serialport::SerialPort;

/// The reference a standalone device learnt for x (raw counts at mid-scale, with a motion
/// of 10⁻⁷ of it: every digit must reach the host).
const REFERENCE_X: f64 = 2_048.000_123_456_789;

fn health(drift: Option<WireDrift>, reference: Option<WireReference>) -> DeviceMsg {
    DeviceMsg::Health {
        samples: 2000,
        rejected: 0,
        buffer_fill: 25,
        cost_mean: 100,
        cost_max: 200,
        cost_unit: CostUnit::Ticks,
        watchdog: 9,
        crc_errors: 0,
        frames_ok: 1,
        screen_cost: 0,
        screen_cost_max: 0,
        screenings: 2,
        duplicates: 0,
        decode_errors: 0,
        overruns: 0,
        queue_high_water: 3,
        latency_max_ns: 1000,
        screenings_skipped: 0,
        sample_rate_hz: 250.0,
        drift,
        reference,
    }
}

/// A board on the pty's master end: waits for a Configure, answers `answer`, then (if it
/// acked) sends a Health with a drift every 100 ms for `for_s`; returns the configuration.
fn board(
    mut master: serialport::TTYPort,
    answer: DeviceMsg,
    for_s: f64,
) -> mpsc::Receiver<WireConfig> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut decoder = HostFrameDecoder::new();
        let mut buffer = [0u8; 256];
        let started = Instant::now();
        let mut frame = [0u8; MAX_FRAME_LEN];
        let config = loop {
            if started.elapsed() > Duration::from_secs(20) {
                return;
            }
            let n = match master.read(&mut buffer) {
                Ok(n) => n,
                Err(_) => continue,
            };
            let found = decoder.feed::<HostMsg>(&buffer[..n]).find_map(|m| match m {
                Ok(HostMsg::Configure(c)) => Some(c),
                _ => None,
            });
            if let Some(c) = found {
                break c;
            }
        };
        let acked = matches!(answer, DeviceMsg::Ack { .. });
        let len = encode(&answer, &mut frame).unwrap();
        master.write_all(&frame[..len]).unwrap();
        tx.send(config).unwrap();
        let sent = Instant::now();
        let mut window = 0;
        while acked && sent.elapsed().as_secs_f64() < for_s {
            window += 1;
            let drift = WireDrift {
                windows: window,
                relative: 0.02,
                largest: 0.05,
                largest_term: 1,
                support_changes: 0,
            };
            // The first window's rows were still being learnt from: no reference.
            let reference = (window > 1).then_some(WireReference {
                x: REFERENCE_X,
                v: 0.0,
                e: 0.0,
            });
            let len = encode(&health(Some(drift), reference), &mut frame).unwrap();
            if master.write_all(&frame[..len]).is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    });
    rx
}

#[test]
fn a_row_rate_and_a_duty_cycle_are_sent_and_the_drift_is_shown() {
    let (mut master, slave) = serialport::TTYPort::pair().unwrap();
    master.set_timeout(Duration::from_millis(50)).unwrap();
    let name = slave.name().unwrap();
    let configs = board(master, DeviceMsg::Ack { seq: CONTROL_SEQ }, 30.0);
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("m.tlm");
    let out = lssi(&[
        "monitor",
        "--port",
        &name,
        "--row-rate",
        "250",
        "--duty-window",
        "10",
        "--duty-interval",
        "600",
        "--seconds",
        "2",
        "--json",
        "--log",
        log.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let config = configs.recv_timeout(Duration::from_secs(5)).unwrap();
    assert!(
        (config.sample_period - 1.0 / 250.0).abs() < 1e-15,
        "{config:?}"
    );
    assert_eq!(config.window, 25, "a tenth of a second of rows, odd");
    let duty = config.duty.unwrap();
    // A model about every 40 minutes by default: every 3 windows of 610 s.
    assert_eq!(
        (duty.window, duty.interval, duty.model_every),
        (10.0, 600.0, 3)
    );
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let healths: Vec<_> = lines.iter().filter(|v| v["kind"] == "health").collect();
    assert!(healths.len() >= 3, "{lines:?}");
    for (k, h) in healths.iter().enumerate() {
        assert_eq!(h["drift"]["windows"], k as u64 + 1, "{h}");
        assert_eq!(h["drift"]["largest_term"], 1, "{h}");
        // The device's references, as it has them (null before it learnt any).
        if k == 0 {
            assert!(h["reference"].is_null(), "{h}");
        } else {
            assert_eq!(h["reference"]["x"].as_f64(), Some(REFERENCE_X), "{h}");
            assert_eq!(h["reference"]["v"].as_f64(), Some(0.0), "{h}");
        }
    }
    // lssi log names them in words.
    let text = lssi(&["log", log.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains(&format!(
            "references x {REFERENCE_X} (the model is about the channels less them)"
        )),
        "{text}"
    );
    drop(slave);
}

#[test]
fn a_refused_configuration_and_bad_flags_are_one_sentence() {
    let (mut master, slave) = serialport::TTYPort::pair().unwrap();
    master.set_timeout(Duration::from_millis(50)).unwrap();
    let name = slave.name().unwrap();
    let nak = DeviceMsg::Nak {
        seq: CONTROL_SEQ,
        reason: NakReason::BadConfig,
    };
    let _configs = board(master, nak, 0.0);
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("m.tlm");
    let out = lssi(&[
        "monitor",
        "--port",
        &name,
        "--row-rate",
        "333",
        "--seconds",
        "5",
        "--log",
        log.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{name}: the device refused the configuration (rows at 333 Hz): it cannot run this configuration"
        )),
        "{stderr}"
    );
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    drop(slave);

    for (args, says) in [
        (
            &["--duty-window", "5"][..],
            "must be given with --duty-interval",
        ),
        (
            &["--duty-interval", "5"][..],
            "must be given with --duty-window",
        ),
        (
            &["--duty-window", "5", "--duty-interval", "0"][..],
            "at most 30 days",
        ),
        (
            &[
                "--duty-window",
                "5",
                "--duty-interval",
                "5",
                "--duty-model-every",
                "0",
            ][..],
            "a whole number of windows from 1 to 65535",
        ),
        (
            &["--duty-model-every", "2"][..],
            "must be given with --duty-window and --duty-interval",
        ),
        (
            &["--row-rate", "0"][..],
            "a positive number of rows a second",
        ),
        (&["--row-rate", "2e6"][..], "at most 1 MHz"),
    ] {
        let mut all = vec!["monitor", "--port", "/dev/null-no-such-port", "--log"];
        let log = dir.path().join("bad.tlm");
        all.push(log.to_str().unwrap());
        all.extend(args);
        let out = lssi(&all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
    }
}
