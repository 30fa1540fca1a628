//! Issue 25: a sensor stuck partway through a record (x frozen, exactly constant, for a run
//! of rows in the middle) is named where it is (data rows and times) and left out: the model
//! comes from the rest of the record, as for a gap. Variants: share of the record stuck
//! (5–30 %), where, the wells, seeds, the noise; and quantised data (ADC counts, whose turning
//! points repeat a value) is not taken for a stuck sensor.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use serde_json::Value;

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

/// `lssi gen eveh ARGS`: the header, the data rows (t, x) and the truth's terms.
fn generated(dir: &Path, args: &[&str]) -> (String, Vec<(String, f64)>, BTreeMap<String, f64>) {
    let path = dir.join("g.csv");
    let out = Command::new(LSSI)
        .args(["gen", "eveh"])
        .args(args)
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_owned();
    let rows = lines
        .map(|l| {
            let (t, x) = l.split_once(',').unwrap();
            (t.to_owned(), x.parse().unwrap())
        })
        .collect();
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("g.json")).unwrap()).unwrap();
    let terms = truth["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                key(t["term"].as_str().unwrap()),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    (header, rows, terms)
}

/// cos(21.4t) and cos(21.3999t) are the same term.
fn key(term: &str) -> String {
    if term.starts_with("cos(") {
        "cos".into()
    } else if term.starts_with("sin(") {
        "sin".into()
    } else {
        term.into()
    }
}

fn write(path: &Path, header: &str, rows: &[(String, f64)]) {
    let mut text = format!("{header}\n");
    for (t, x) in rows {
        text.push_str(&format!("{t},{x:?}\n"));
    }
    std::fs::write(path, text).unwrap();
}

fn identify(path: &Path) -> (Option<i32>, Value, String) {
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .arg("--json")
        .output()
        .unwrap();
    let json = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    (
        out.status.code(),
        json,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_stuck_sensor_is_named_and_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("stuck.csv");
    // (wells, seed, noise, first stuck row as a share of the record, share stuck)
    let cases = [
        ("bistable", "71", "0.005", 0.40, 0.05),
        ("bistable", "72", "0.02", 0.20, 0.15),
        ("monostable", "73", "0.005", 0.55, 0.30),
        ("monostable", "74", "0.02", 0.30, 0.10),
    ];
    for (wells, seed, delta, at, share) in cases {
        let (header, mut rows, truth) = generated(
            dir.path(),
            &[
                "--wells", wells, "--seed", seed, "--delta", delta, "--t-end", "10",
            ],
        );
        let n = rows.len();
        let (a, b) = ((at * n as f64) as usize, ((at + share) * n as f64) as usize);
        let value = rows[a].1;
        for row in &mut rows[a..b] {
            row.1 = value;
        }
        write(&path, &header, &rows);
        let label = format!("{wells} seed {seed} noise {delta} rows {}–{b}", a + 1);
        let (code, json, stderr) = identify(&path);
        // Named where it is: its first and last data rows.
        let rows_named = format!("data rows {}–{b}", a + 1);
        assert!(
            stderr.contains(&rows_named) && stderr.contains("stuck at"),
            "{label}: {stderr}"
        );
        assert_eq!(code, Some(0), "{label}: {stderr}");
        assert!(
            json["warnings"].to_string().contains(&rows_named),
            "{label}: {}",
            json["warnings"]
        );
        // The model from the rest: the truth's terms, coefficients within 10 % (the
        // damping within 25 %).
        let got: BTreeMap<String, f64> = json["terms"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| {
                (
                    key(t["term"].as_str().unwrap()),
                    t["coef"].as_f64().unwrap(),
                )
            })
            .collect();
        assert_eq!(
            got.keys().collect::<Vec<_>>(),
            truth.keys().collect::<Vec<_>>(),
            "{label}: {got:?}"
        );
        for (k, w) in &truth {
            let tolerance = if k == "v" { 0.25 } else { 0.10 };
            assert!(
                (got[k] / w - 1.0).abs() <= tolerance,
                "{label}: {k} {got:?}"
            );
        }
    }
}

#[test]
fn quantised_counts_are_not_a_stuck_sensor() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("adc.csv");
    for (bits, rate) in [(8, "2000"), (8, "20000"), (12, "2000")] {
        let (header, rows, _) = generated(
            dir.path(),
            &["--wells", "monostable", "--rate", rate, "--t-end", "4"],
        );
        let amplitude = rows.iter().map(|r| r.1.abs()).fold(0.0, f64::max);
        let per = f64::from(1 << (bits - 1)) / (1.2 * amplitude);
        let counts: Vec<(String, f64)> = rows
            .iter()
            .map(|(t, x)| (t.clone(), (x * per).round() + f64::from(1 << (bits - 1))))
            .collect();
        write(&path, &header, &counts);
        let (_, _, stderr) = identify(&path);
        assert!(
            !stderr.contains("stuck at"),
            "{bits} bits at {rate} Hz: {stderr}"
        );
    }
}
