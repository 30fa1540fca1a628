//! Issue 16, item 3: libraries of any size the issue names (poly order ≤ 5, harmonics ≤ 5,
//! with or without a measured input) are identified on the host; a larger one is refused
//! naming its size and the limit, and so is a device's library over its capacity.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

fn generate(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let out = Command::new(LSSI)
        .args(["gen", "eveh", "--t-end", "12"])
        .args(extra)
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    path
}

fn identify(path: &Path, flags: &[&str]) -> Output {
    Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .arg("--json")
        .arg("--no-refine")
        .args(flags)
        .output()
        .unwrap()
}

fn terms(out: &Output) -> (BTreeMap<String, f64>, serde_json::Value) {
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let terms = json["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                name(t["term"].as_str().unwrap()),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    (terms, json)
}

/// A term's name with the forcing's frequency left out (its estimate differs in the last
/// digits between libraries): `cos(21.4001t)` → `cos(Ωt)`.
fn name(term: &str) -> String {
    match term.split_once('(') {
        Some((f @ ("sin" | "cos"), _)) => format!("{f}(Ωt)"),
        _ => term.to_owned(),
    }
}

/// The library's size: the dense solution (threshold 0) holds every term.
fn library_size(json: &serde_json::Value) -> usize {
    json["solutions"][0]["terms"].as_array().unwrap().len()
}

#[test]
fn larger_libraries_find_the_same_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), "eveh.csv", &[]);
    let out = identify(&path, &[]);
    assert!(out.status.success());
    let (reference, json) = terms(&out);
    assert_eq!(library_size(&json), 12);
    for (flags, size) in [
        (&["--poly-order", "4"][..], 17),
        (&["--harmonics", "4"][..], 18),
        (&["--poly-order", "5", "--harmonics", "5"][..], 31),
    ] {
        let out = identify(&path, flags);
        assert!(
            out.status.success(),
            "{flags:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (found, json) = terms(&out);
        assert_eq!(library_size(&json), size, "{flags:?}");
        let omega = json["omega"].as_f64().unwrap();
        assert!((omega - 21.4).abs() < 1e-3, "{flags:?}: Ω = {omega}");
        assert_eq!(
            found.keys().collect::<Vec<_>>(),
            reference.keys().collect::<Vec<_>>(),
            "{flags:?}"
        );
        for (term, c) in &reference {
            let e = (found[term] / c - 1.0).abs();
            assert!(e < 0.02, "{flags:?}: {term} off by {:.2} %", 100.0 * e);
        }
    }
}

/// With a measured input u the largest library is 32 terms (21 monomials with the constant,
/// 10 harmonics, u): it runs, and is never refused for "too few regression rows".
#[test]
fn the_largest_library_with_an_input_runs() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), "input.csv", &["--input"]);
    for flags in [
        &["--poly-order", "5", "--harmonics", "5"][..],
        &["--poly-order", "5", "--harmonics", "0"][..],
    ] {
        let out = identify(&path, flags);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{flags:?}: {stderr}");
        let (found, json) = terms(&out);
        assert!(library_size(&json) <= 32);
        assert!(
            found.contains_key("u") && found.contains_key("x^3"),
            "{found:?}"
        );
    }
    let (_, json) = terms(&identify(&path, &["--poly-order", "5", "--harmonics", "5"]));
    assert_eq!(library_size(&json), 32);
}

#[test]
fn a_library_over_the_capacity_is_refused_naming_size_and_limit() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), "eveh.csv", &[]);
    let out = identify(&path, &["--poly-order", "7"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("36 terms") && stderr.contains("at most 32"),
        "{stderr}"
    );
    assert!(!stderr.contains("regression rows"), "{stderr}");
}

/// The device's refusal of a library over its capacity, as the host words it.
#[test]
fn a_device_refusal_names_size_and_limit() {
    let text = lssi_host::serial::link::nak_text(lssi_proto::NakReason::TooManyTerms {
        terms: 31,
        capacity: 16,
    });
    assert!(
        text.contains("at most 16 terms") && text.contains("31"),
        "{text}"
    );
}
