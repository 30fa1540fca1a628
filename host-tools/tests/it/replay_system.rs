//! `lssi replay` on a harvester's recording with an electrical column (V or i): the device
//! identifies the system (x'' and V' or i') over the link, and its equations are those of
//! `lssi identify --f32 --no-refine` on the same file, bit for bit: every term, coefficient
//! and standard error. The one difference is the solutions' list: the device sends each
//! equation's selected solution only (`solutions` holds that one, `selected` 0), not its
//! whole sweep.
//!
//! Recordings are made with `lssi gen` (piezo mono- and bistable, x or v alone, with and
//! without a measured u; electromagnetic with i or V). firmware-sim must be built (see
//! `replay_cli.rs`).

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::lssi;
use serde_json::Value;

fn ok(out: &Output, what: &str) -> Value {
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// identify's model: the printed one, or the one its gate withheld (exit status 3, under
/// `"withheld_model"`: replay reports the device's model with the gate's failures as warnings).
fn identified(out: &Output, what: &str) -> Value {
    if out.status.code() == Some(3) {
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["withheld"], true, "{what}: {json}");
        return json["withheld_model"].clone();
    }
    ok(out, what)
}

fn generate(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let file = dir.join(format!("{name}.csv"));
    let mut all = vec!["gen"];
    all.extend(args);
    all.push(file.to_str().unwrap());
    let out = lssi(&all);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    file
}

/// identify's JSON against replay's (its "link" taken out): the equations' targets and
/// terms equal (coefficients and standard errors bit for bit, as JSON numbers print every
/// digit), each equation's selected solution equal to identify's, and every other key equal.
fn assert_same_system(identify: &Value, mut replay: Value, label: &str) {
    let link = replay.as_object_mut().unwrap().remove("link").unwrap();
    assert_eq!(link["samples_lost"], 0, "{label}");
    assert!(link["samples_acked"].as_u64().unwrap() > 0, "{label}");
    let (a, b) = (identify.as_object().unwrap(), replay.as_object().unwrap());
    let keys = |o: &serde_json::Map<String, Value>| o.keys().cloned().collect::<Vec<_>>();
    assert_eq!(keys(a), keys(b), "{label}");
    for (key, value) in a {
        if key != "equations" {
            assert_eq!(value, &b[key], "{label}: {key}");
        }
    }
    let (ea, eb) = (
        a["equations"].as_array().unwrap(),
        b["equations"].as_array().unwrap(),
    );
    assert!(ea.len() >= 2, "{label}: {identify}");
    assert_eq!(ea.len(), eb.len(), "{label}");
    for (x, y) in ea.iter().zip(eb) {
        assert_eq!(x["target"], y["target"], "{label}");
        assert_eq!(x["terms"], y["terms"], "{label}: {}", x["target"]);
        assert!(!x["terms"].as_array().unwrap().is_empty(), "{label}");
        // The device's one solution is identify's selected one.
        let selected = &x["solutions"][x["selected"].as_u64().unwrap() as usize];
        assert_eq!(y["selected"], 0, "{label}");
        assert_eq!(y["solutions"].as_array().unwrap().len(), 1, "{label}");
        assert_eq!(y["solutions"][0]["terms"], selected["terms"], "{label}");
        assert_eq!(
            y["solutions"][0]["threshold"], selected["threshold"],
            "{label}"
        );
        assert_eq!(
            y["solutions"][0]["mean_error"], selected["mean_error"],
            "{label}"
        );
    }
}

#[test]
fn a_replayed_system_is_identify_f32_bit_for_bit() {
    crate::replay_cli::require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str]); 6] = [
        ("mono-x", &["piezo", "--t-end", "6", "--seed", "3"]),
        (
            "bi-x",
            &[
                "piezo", "--wells", "bistable", "--t-end", "6", "--seed", "5",
            ],
        ),
        (
            "bi-v",
            &[
                "piezo",
                "--wells",
                "bistable",
                "--observe",
                "v",
                "--t-end",
                "8",
            ],
        ),
        (
            "mono-xu",
            &["piezo", "--input", "--t-end", "6", "--amplitude", "1.5"],
        ),
        ("em-i", &["electromagnetic", "--t-end", "6", "--seed", "7"]),
        (
            "em-V",
            &["electromagnetic", "--electrical", "V", "--t-end", "6"],
        ),
    ];
    for (name, args) in cases {
        let file = generate(dir.path(), name, args);
        let f = file.to_str().unwrap();
        let identify = identified(
            &lssi(&["identify", "--f32", "--no-refine", "--json", f]),
            name,
        );
        let replay = ok(&lssi(&["replay", "--json", "--baud", "4000000", f]), name);
        assert_same_system(&identify, replay, name);
    }
}

/// A piezo harvester's x half a metre from zero and V 3 V off: replay sends the channels
/// less the references `lssi identify` takes off them, and its report names them: the
/// equations are `identify --f32 --no-refine`'s bit for bit (sent as they were, the device
/// had x'' with a constant collinear with x).
#[test]
fn channels_off_zero_replay_as_identify_takes_them() {
    crate::replay_cli::require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    let file = generate(
        dir.path(),
        "p",
        &["piezo", "--input", "--t-end", "6", "--seed", "3"],
    );
    let text = std::fs::read_to_string(&file).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let names: Vec<&str> = header.split(',').collect();
    let mut out = format!("{header}\n");
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let row: Vec<String> = line
            .split(',')
            .zip(&names)
            .map(|(v, name)| {
                let v: f64 = v.trim().parse().unwrap();
                match *name {
                    "x" => format!("{}", v + 0.5),
                    "V" => format!("{}", v + 3.0),
                    _ => format!("{v}"),
                }
            })
            .collect();
        out.push_str(&row.join(","));
        out.push('\n');
    }
    let shifted = dir.path().join("shifted.csv");
    std::fs::write(&shifted, out).unwrap();
    let f = shifted.to_str().unwrap();
    let identify = identified(
        &lssi(&["identify", "--f32", "--no-refine", "--json", f]),
        "shifted",
    );
    let reference = &identify["reference"];
    assert!(
        (reference["x"].as_f64().unwrap() - 0.5).abs() < 0.01,
        "{identify}"
    );
    assert!(
        (reference["V"].as_f64().unwrap() - 3.0).abs() < 0.5,
        "{identify}"
    );
    let replay = ok(
        &lssi(&["replay", "--json", "--baud", "4000000", f]),
        "shifted",
    );
    assert_same_system(&identify, replay, "shifted");
}

/// Every column averaged `k` rows at a time, then through the droop compensator
/// `(1 + 2a)·y_r − a·(y_{r−1} + y_{r+1})`, a = 1/24 (t: the middle row's mean; the first and
/// last rows dropped), written as the shortest decimal that reads back the same f64: what
/// `lssi replay --row-rate` sends.
fn average_csv(from: &Path, to: &Path, k: usize) {
    let text = std::fs::read_to_string(from).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let t_column = header.split(',').position(|h| h.trim() == "t").unwrap();
    let rows: Vec<Vec<f64>> = lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split(',').map(|v| v.trim().parse().unwrap()).collect())
        .collect();
    let means: Vec<Vec<f64>> = rows
        .chunks_exact(k)
        .map(|group| {
            (0..group[0].len())
                .map(|j| group.iter().map(|r| r[j]).sum::<f64>() / k as f64)
                .collect()
        })
        .collect();
    let a = 1.0 / 24.0;
    let mut out = format!("{header}\n");
    for w in means.windows(3) {
        let row: Vec<String> = (0..w[1].len())
            .map(|j| {
                let value = if j == t_column {
                    w[1][j]
                } else {
                    (1.0 + 2.0 * a) * w[1][j] - a * (w[0][j] + w[2][j])
                };
                format!("{value}")
            })
            .collect();
        out.push_str(&row.join(","));
        out.push('\n');
    }
    std::fs::write(to, out).unwrap();
}

#[test]
fn a_row_rate_averages_the_rows_and_the_duty_cycle_is_sent() {
    crate::replay_cli::require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    // 2000 Hz recordings replayed at 500 and 400 rows a second (k = 4, 5).
    for (name, args, rate, k) in [
        (
            "p",
            &["piezo", "--t-end", "8", "--seed", "11"][..],
            "500",
            4,
        ),
        (
            "b",
            &["piezo", "--wells", "bistable", "--t-end", "8"][..],
            "400",
            5,
        ),
    ] {
        let file = generate(dir.path(), name, args);
        let averaged = dir.path().join(format!("{name}-avg.csv"));
        average_csv(&file, &averaged, k);
        let identify = ok(
            &lssi(&[
                "identify",
                "--f32",
                "--no-refine",
                "--json",
                averaged.to_str().unwrap(),
            ]),
            name,
        );
        let log = dir.path().join(format!("{name}.tlm"));
        let mut replay_args = vec![
            "replay",
            "--json",
            "--baud",
            "4000000",
            "--row-rate",
            rate,
            "--duty-window",
            "10",
            "--duty-interval",
            "600",
            "--log",
            log.to_str().unwrap(),
            file.to_str().unwrap(),
        ];
        // A model every 3 windows of 610 s by default (about 40 minutes), or as asked.
        let model_every = if name == "b" {
            replay_args.extend(["--duty-model-every", "2"]);
            2
        } else {
            3
        };
        let replay = ok(&lssi(&replay_args), name);
        let sample_period = identify["sample_period"].as_f64().unwrap();
        let hz: f64 = rate.parse().unwrap();
        assert!(
            (1.0 / sample_period - hz).abs() < 1e-6 * hz,
            "{sample_period}"
        );
        assert_same_system(&identify, replay, name);
        // The configuration sent (the log's session record) carries the duty cycle.
        let session = lssi_host::telemetry::read_log(&std::fs::read(&log).unwrap())
            .unwrap()
            .records
            .into_iter()
            .find(|r| r.kind == lssi_host::telemetry::RecordKind::Session)
            .unwrap();
        let session: Value = serde_json::from_slice(&session.data).unwrap();
        assert_eq!(session["config"]["duty"]["window"], 10.0, "{session}");
        assert_eq!(session["config"]["duty"]["interval"], 600.0, "{session}");
        assert_eq!(
            session["config"]["duty"]["model_every"], model_every,
            "{session}"
        );
        assert!((session["row_rate_hz"].as_f64().unwrap() - hz).abs() < 1e-6 * hz);
    }
}

#[test]
fn a_system_replay_s_bad_flags_are_one_sentence() {
    let dir = tempfile::tempdir().unwrap();
    let file = generate(dir.path(), "p", &["piezo", "--t-end", "2"]);
    let f = file.to_str().unwrap();
    for (args, says) in [
        (
            vec!["--row-rate", "700"],
            "is not the recording's 2000 Hz divided by a whole number",
        ),
        (
            vec!["--row-rate", "4000"],
            "faster than the recording's 2000 samples a second",
        ),
        (vec!["--row-rate", "-3"], "--row-rate -3 cannot be used"),
        (
            vec!["--duty-window", "5"],
            "must be given with --duty-interval",
        ),
        (
            vec!["--duty-interval", "5"],
            "must be given with --duty-window",
        ),
        (
            vec!["--duty-window", "0", "--duty-interval", "5"],
            "a positive number of seconds, at most a day",
        ),
        (
            vec!["--duty-window", "5", "--duty-interval", "nan"],
            "at most 30 days",
        ),
        (
            vec![
                "--duty-window",
                "5",
                "--duty-interval",
                "5",
                "--duty-model-every",
                "70000",
            ],
            "a whole number of windows from 1 to 65535",
        ),
        (
            vec!["--duty-model-every", "4"],
            "must be given with --duty-window and --duty-interval",
        ),
        (vec!["--encoding", "i16"], "travel as f32"),
        (vec!["--load-ohms=-1"], "a positive resistance in ohms"),
    ] {
        let mut all = vec!["replay", f];
        all.extend(&args);
        let out = lssi(&all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
    }
}
