//! `lssi log`: a telemetry log printed as text, JSON lines and CSV; a log cut short read up to
//! its last whole record with a sentence on stderr; bad logs refused with one sentence.

#![allow(clippy::unwrap_used)]

use std::path::Path;

use crate::common::lssi;
use lssi_host::telemetry::{RecordKind, TelemetryLog, encode_record};
use lssi_proto::{
    CONTROL_SEQ, CostUnit, DeviceMsg, MAX_FRAME_LEN, ModelSnapshot, NakReason, PROTOCOL_VERSION,
    SnapshotCause, SolutionSummary, TermCode, TermKind, encode,
};

/// A frame as the link logs it: COBS bytes without the delimiter.
fn frame(message: &DeviceMsg) -> Vec<u8> {
    let mut buffer = [0u8; MAX_FRAME_LEN];
    let len = encode(message, &mut buffer).unwrap();
    buffer[..len - 1].to_vec()
}

fn snapshot(samples: u64, linear: f32) -> ModelSnapshot {
    let mut s = ModelSnapshot {
        omega: 2.0,
        samples,
        cause: SnapshotCause::Scheduled,
        ..ModelSnapshot::default()
    };
    for (kind, a, b, c) in [
        (TermKind::Monomial, 1, 0, linear),
        (TermKind::Monomial, 0, 1, -0.25),
        (TermKind::Cos, 1, 0, 5.0),
    ] {
        s.terms.push(TermCode { kind, a, b }).unwrap();
        s.coefficients.push(c).unwrap();
    }
    s.solutions
        .push(SolutionSummary {
            threshold: 0.1,
            mean_error: 0.01,
            support: 0b111,
        })
        .unwrap();
    s
}

fn health(samples: u64) -> DeviceMsg {
    DeviceMsg::Health {
        samples,
        rejected: 0,
        buffer_fill: 3,
        cost_mean: 10,
        cost_max: 20,
        cost_unit: CostUnit::Nanoseconds,
        watchdog: 7,
        crc_errors: 2,
        frames_ok: 40,
        screen_cost: 0,
        screen_cost_max: 0,
        screenings: 1,
        duplicates: 1,
        decode_errors: 0,
        overruns: 0,
        queue_high_water: 0,
        latency_max_ns: 0,
        screenings_skipped: 0,
        sample_rate_hz: 0.0,
        drift: None,
        reference: None,
    }
}

/// A log of one short session: hello, acks, a nak, two models, health, a note, a summary.
fn write_log(path: &Path) {
    let mut log = TelemetryLog::open(path).unwrap();
    let session = serde_json::json!({
        "tool": "lssi replay", "input": "run.csv", "port": "/dev/pts/9",
        "device": "firmware-sim", "baud": 921600, "samples": 48, "omega_estimated": false,
    });
    log.append(RecordKind::Session, session.to_string().as_bytes())
        .unwrap();
    let messages = [
        DeviceMsg::HelloReply {
            protocol_version: PROTOCOL_VERSION,
            max_terms: 16,
            window_capacity: 256,
            max_batch: 24,
        },
        DeviceMsg::Ack { seq: CONTROL_SEQ },
        DeviceMsg::Ack { seq: 0 },
        DeviceMsg::Nak {
            seq: 1,
            reason: NakReason::OutOfOrder,
        },
        DeviceMsg::Ack { seq: 1 },
        DeviceMsg::Model(snapshot(24, -1.5)),
        DeviceMsg::Model(ModelSnapshot {
            cause: SnapshotCause::Query,
            ..snapshot(48, -2.0)
        }),
        health(48),
    ];
    for message in &messages {
        log.append(RecordKind::Frame, &frame(message)).unwrap();
    }
    // A frame that arrived corrupt is logged too.
    let mut bad = frame(&DeviceMsg::Ack { seq: 2 });
    bad[2] ^= 0x40;
    log.append(RecordKind::Frame, &bad).unwrap();
    log.note("replay finished").unwrap();
    log.append(
        RecordKind::Summary,
        br#"{"frames_sent":12,"retransmits":1,"crc_errors":3,"samples_lost":0}"#,
    )
    .unwrap();
}

#[test]
fn text_shows_models_health_and_counts() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.tlm");
    write_log(&path);
    let out = lssi(&["log", path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stderr.is_empty());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.starts_with(
            "session 1: run.csv on /dev/pts/9 (firmware-sim, 921600 baud), 48 samples"
        ),
        "{text}"
    );
    assert!(text.contains("hello: protocol"), "{text}");
    assert!(
        text.contains(
            "model (scheduled, 24 samples): x'' = -1.5000 x - 0.25000 v + 5.0000 cos(2t)"
        ),
        "{text}"
    );
    assert!(
        text.contains("model (query, 48 samples): x'' = -2.0000 x"),
        "{text}"
    );
    assert!(text.contains("health: 48 samples (0 rejected)"), "{text}");
    assert!(text.contains("note: replay finished"), "{text}");
    assert!(
        text.contains("summary: 12 frames sent, 1 retransmitted, 3 CRC errors, 0 samples lost"),
        "{text}"
    );
    assert!(text.contains("frames: 3 acks, 1 corrupt, 1 naks"), "{text}");
}

#[test]
fn json_is_one_object_per_record() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.tlm");
    write_log(&path);
    let out = lssi(&["log", "--json", path.to_str().unwrap()]);
    assert!(out.status.success());
    let values: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(values.len(), 1 + 8 + 1 + 1 + 1);
    let kinds: Vec<&str> = values.iter().map(|v| v["kind"].as_str().unwrap()).collect();
    assert_eq!(
        kinds,
        [
            "session",
            "hello",
            "ack",
            "ack",
            "nak",
            "ack",
            "model",
            "model",
            "health",
            "corrupt_frame",
            "note",
            "summary"
        ]
    );
    let model = &values[7];
    assert_eq!(model["cause"], "query");
    assert_eq!(model["report"]["terms"][0]["term"], "x");
    assert_eq!(model["report"]["terms"][0]["coef"], -2.0);
    assert_eq!(values[8]["crc_errors"], 2);
    assert_eq!(values[4]["reason"], "OutOfOrder");
}

#[test]
fn csv_has_the_coefficients_and_health_over_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.tlm");
    write_log(&path);
    let out = lssi(&["log", "--csv", path.to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    assert_eq!(
        reader.headers().unwrap(),
        vec!["session", "time_s", "kind", "field", "value"]
    );
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    let x: Vec<&str> = rows
        .iter()
        .filter(|r| &r[2] == "model" && &r[3] == "x")
        .map(|r| r.get(4).unwrap())
        .collect();
    assert_eq!(x, ["-1.5", "-2"]);
    assert!(
        rows.iter()
            .any(|r| &r[2] == "health" && &r[3] == "duplicates" && &r[4] == "1")
    );
    assert!(
        rows.iter()
            .any(|r| &r[2] == "note" && &r[4] == "replay finished")
    );
}

#[test]
fn a_log_cut_anywhere_in_its_last_record_prints_the_rest_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.tlm");
    write_log(&path);
    let whole = std::fs::read(&path).unwrap();
    let last = encode_record(
        RecordKind::Summary,
        0,
        br#"{"frames_sent":12,"retransmits":1,"crc_errors":3,"samples_lost":0}"#,
    )
    .len();
    let full_text = String::from_utf8(lssi(&["log", path.to_str().unwrap()]).stdout).unwrap();
    for cut in [1, last / 2, last - 1] {
        let cut_path = dir.path().join(format!("cut-{cut}.tlm"));
        std::fs::write(&cut_path, &whole[..whole.len() - cut]).unwrap();
        let out = lssi(&["log", cut_path.to_str().unwrap()]);
        assert!(out.status.success());
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert!(stderr.contains("is partial"), "{stderr}");
        assert!(stderr.contains("was skipped"), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(!text.contains("summary:"));
        assert!(text.contains("note: replay finished"));
        assert_eq!(
            text.lines().filter(|l| l.contains("model")).count(),
            full_text.lines().filter(|l| l.contains("model")).count()
        );
    }
}

#[test]
fn bad_logs_are_one_sentence_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.tlm");
    let out = lssi(&["log", missing.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with(&format!(
            "lssi: {}: cannot read the telemetry log",
            missing.display()
        )),
        "{stderr}"
    );

    let csv = dir.path().join("data.csv");
    std::fs::write(&csv, "t,x\n0,1\n").unwrap();
    let out = lssi(&["log", csv.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("is not an lssi telemetry log"), "{stderr}");

    let path = dir.path().join("run.tlm");
    write_log(&path);
    let mut bytes = std::fs::read(&path).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x01;
    let corrupt = dir.path().join("corrupt.tlm");
    std::fs::write(&corrupt, &bytes).unwrap();
    let out = lssi(&["log", corrupt.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("damaged bytes at byte"), "{stderr}");
    assert!(stderr.contains("the log is damaged"), "{stderr}");
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.starts_with("session 1"));
    // Resynchronised: the records after the damaged one are printed too (one record lost).
    let intact = lssi(&["log", path.to_str().unwrap(), "--json"]);
    let damaged = lssi(&["log", corrupt.to_str().unwrap(), "--json"]);
    let lines = |o: &std::process::Output| String::from_utf8_lossy(&o.stdout).lines().count();
    assert_eq!(
        lines(&damaged) + 1,
        lines(&intact),
        "one record lost, the rest kept"
    );
    let last = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .last()
            .map(str::to_owned)
    };
    assert_eq!(last(&damaged), last(&intact));
}

/// A duty-cycled device's Health carries the drift between its windows (protocol 7):
/// `lssi log` prints it in words, `--json` as an object, `--csv` a row per figure; a
/// Health without one (a host-fed device) prints none.
#[test]
fn the_drift_of_a_duty_cycle_is_printed_in_text_json_and_csv() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("duty.tlm");
    let mut log = TelemetryLog::open(&path).unwrap();
    let session = serde_json::json!({"tool": "lssi monitor", "source": "/dev/ttyACM0"});
    log.append(RecordKind::Session, session.to_string().as_bytes())
        .unwrap();
    let drifts = [
        (1, 0.0, 0.0, 0, 0),
        (2, 0.0125, 0.031, 2, 0),
        (3, 0.2, 1.0, 4, 1),
    ];
    log.append(RecordKind::Frame, &frame(&health(10))).unwrap();
    for (k, &(windows, relative, largest, largest_term, support_changes)) in
        drifts.iter().enumerate()
    {
        let mut h = health(1000 * (k as u64 + 1));
        if let DeviceMsg::Health { drift, .. } = &mut h {
            *drift = Some(lssi_proto::WireDrift {
                windows,
                relative,
                largest,
                largest_term,
                support_changes,
            });
        }
        log.append(RecordKind::Frame, &frame(&h)).unwrap();
    }
    drop(log);
    let file = path.to_str().unwrap();

    let out = lssi(&["log", file]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let health_lines: Vec<&str> = text.lines().filter(|l| l.contains("health:")).collect();
    assert_eq!(health_lines.len(), 4, "{text}");
    assert!(!health_lines[0].contains("drift"), "{text}");
    assert!(
        health_lines[2].contains(
            "drift over window 2: coefficients moved 1.25 % (RMS), at most 3.10 % (term 2), 0 terms in or out"
        ),
        "{text}"
    );
    assert!(
        health_lines[3].contains("at most 100.00 % (term 4), 1 term in or out"),
        "{text}"
    );

    let out = lssi(&["log", "--json", file]);
    assert!(out.status.success());
    let healths: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["kind"] == "health")
        .collect();
    assert_eq!(healths.len(), 4);
    assert!(healths[0]["drift"].is_null());
    for (h, &(windows, relative, largest, term, changes)) in healths[1..].iter().zip(&drifts) {
        assert_eq!(h["drift"]["windows"], windows);
        assert_eq!(h["drift"]["relative"].as_f64().unwrap() as f32, relative);
        assert_eq!(h["drift"]["largest"].as_f64().unwrap() as f32, largest);
        assert_eq!(h["drift"]["largest_term"], term);
        assert_eq!(h["drift"]["support_changes"], changes);
    }

    let out = lssi(&["log", "--csv", file]);
    assert!(out.status.success());
    let csv = String::from_utf8(out.stdout).unwrap();
    let windows: Vec<&str> = csv
        .lines()
        .filter(|l| l.contains(",health,drift_windows,"))
        .collect();
    assert_eq!(windows.len(), 3, "{csv}");
    assert!(windows[2].ends_with(",3"), "{csv}");
    assert!(!csv.contains(",health,drift,"), "{csv}");
}

/// `lssi defmt -e ELF` (defmt-print's stand-in in scripts/ci-qemu.sh; its decoding is checked
/// there, on the firmware's own log under QEMU): an ELF it cannot read, or one without defmt
/// tables, is one sentence naming the file, exit 2, before reading any input.
#[test]
fn defmt_names_an_elf_it_cannot_use() {
    let out = lssi(&["defmt", "-e", "/nonexistent/fw.elf"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.starts_with("lssi: /nonexistent/fw.elf: cannot read the firmware ELF"),
        "{stderr}"
    );
    let host = env!("CARGO_BIN_EXE_lssi");
    let out = lssi(&["defmt", "--elf", host]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("the ELF has no defmt tables") && stderr.contains(host),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
}
