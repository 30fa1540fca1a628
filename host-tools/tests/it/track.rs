//! `lssi identify --track` on the shipped drift recording, and its flag errors.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

fn drift(ext: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../data/eveh-drift.{ext}"))
}

#[test]
fn the_stiffness_drift_is_followed_and_settles() {
    let out = Command::new(LSSI)
        .args([
            "identify", "--track", "--json", "--family", "odd", "--memory", "2",
        ])
        .args(["--settle-tol", "0.1", "--truth"])
        .arg(drift("json"))
        .arg(drift("csv"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // A snapshot every 0.25 s over 20 s.
    assert!(lines.len() > 70, "{} lines", lines.len());
    let x_at = |t: f64| {
        lines
            .iter()
            .find(|l| l["t"].as_f64().is_some_and(|s| s >= t))
            .and_then(|l| l["terms"]["x"].as_f64())
            .unwrap()
    };
    // Before the change (D = 336.6) and well after it (0.8 D = 269.3).
    assert!((x_at(5.5) + 336.6).abs() < 0.03 * 336.6, "{}", x_at(5.5));
    assert!((x_at(19.5) + 269.3).abs() < 0.03 * 269.3, "{}", x_at(19.5));
    let settle = &lines.last().unwrap()["settle"];
    assert_eq!(settle["change_at"].as_f64(), Some(6.0));
    let time = settle["settle_time"].as_f64().unwrap();
    assert!(time > 0.0 && time < 8.0, "settle time {time} s");
}

#[test]
fn track_csv_has_a_column_per_term() {
    let out = Command::new(LSSI)
        .args(["identify", "--track", "--family", "odd", "--every", "5"])
        .arg(drift("csv"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    let header = text.lines().next().unwrap();
    assert!(header.starts_with("t,1,x,v,x^3,x^2*v,"), "{header}");
    assert!(header.ends_with(",resonance_hz,wells"), "{header}");
    assert_eq!(text.lines().count(), 1 + 4);
}

#[test]
fn track_flags_are_checked() {
    let run = |args: &[&str]| {
        let out = Command::new(LSSI)
            .arg("identify")
            .args(args)
            .arg(drift("csv"))
            .output()
            .unwrap();
        (out.status.code(), String::from_utf8(out.stderr).unwrap())
    };
    let (code, err) = run(&["--track", "--every", "0"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--every"), "{err}");
    let (code, err) = run(&["--change-at", "3"]);
    assert_eq!(code, Some(2));
    assert!(
        err.contains("--change-at") && err.contains("--track"),
        "{err}"
    );
    let (code, err) = run(&["--track", "--truth", "/nonexistent/truth.json"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--truth"), "{err}");
}
