//! The shipped harvester recordings (`data/eveh-*`): reproducible from their documented
//! commands, and identified to the accuracy.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

use lssi_host::synth::truth::Truth;

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(name)
}

/// Each shipped recording and the `lssi gen` arguments that make it (the README's commands).
const SHIPPED: [(&str, &[&str]); 3] = [
    ("eveh-bistable", &["gen", "eveh"]),
    ("eveh-monostable", &["gen", "eveh", "--wells", "monostable"]),
    (
        "eveh-drift",
        &[
            "gen",
            "eveh",
            "--wells",
            "monostable",
            "--drift",
            "stiffness",
            "--drift-at",
            "6",
            "--drift-by",
            "-0.2",
        ],
    ),
];

#[test]
fn shipped_recordings_are_reproducible_and_small() {
    let dir = tempfile::tempdir().unwrap();
    for (name, args) in SHIPPED {
        let out = dir.path().join(format!("{name}.csv"));
        let status = Command::new(LSSI).args(args).arg(&out).output().unwrap();
        assert!(status.status.success(), "{name}: {status:?}");
        for ext in ["csv", "json"] {
            let fresh = std::fs::read(out.with_extension(ext)).unwrap();
            let shipped = std::fs::read(data(&format!("{name}.{ext}"))).unwrap();
            assert!(
                fresh == shipped,
                "data/{name}.{ext} differs from what `lssi {}` writes now",
                args.join(" ")
            );
            assert!(shipped.len() < 850_000, "data/{name}.{ext} is too big");
        }
    }
}

/// What the "must show" measures, for one recording and one set of flags.
struct Score {
    missing: Vec<String>,
    spurious: Vec<String>,
    mean_error: f64,
    resonance_error: f64,
}

/// The harmonic's name without its (estimated) frequency: `cos(21.4001t)` → `cos`.
fn kind(name: &str) -> String {
    match name.split_once('(') {
        Some((f, _)) if f == "sin" || f == "cos" => f.to_owned(),
        _ => name.to_owned(),
    }
}

fn score(name: &str, flags: &[&str]) -> Score {
    let csv = data(&format!("{name}.csv"));
    let truth: Truth =
        serde_json::from_str(&std::fs::read_to_string(csv.with_extension("json")).unwrap())
            .unwrap();
    let out = Command::new(LSSI)
        .args(["identify", "--json"])
        .args(flags)
        .arg(&csv)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let found: Vec<(String, f64)> = report["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                kind(t["term"].as_str().unwrap()),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    let true_terms: Vec<(String, f64)> = truth
        .terms
        .iter()
        .map(|t| (kind(&t.term), t.coef))
        .collect();
    let get = |list: &[(String, f64)], k: &str| list.iter().find(|(n, _)| n == k).map(|p| p.1);
    let missing = true_terms
        .iter()
        .filter(|(n, _)| get(&found, n).is_none())
        .map(|p| p.0.clone())
        .collect();
    let spurious = found
        .iter()
        .filter(|(n, _)| get(&true_terms, n).is_none())
        .map(|p| p.0.clone())
        .collect();
    let errors: Vec<f64> = true_terms
        .iter()
        .map(|(n, c)| (get(&found, n).unwrap_or(0.0) - c).abs() / c.abs())
        .collect();
    let mean_error = errors.iter().sum::<f64>() / errors.len() as f64;
    let (truth_key, report_key) = if truth.params["resonance_hz"].is_null() {
        ("well_resonance_hz", "well_resonance_hz")
    } else {
        ("resonance_hz", "resonance_hz")
    };
    let true_f = truth.params[truth_key].as_f64().unwrap();
    let found_f = report[report_key].as_f64().unwrap_or(0.0);
    Score {
        missing,
        spurious,
        mean_error,
        resonance_error: (found_f - true_f).abs() / true_f,
    }
}

fn must_show(flags: &[&str]) {
    for name in ["eveh-bistable", "eveh-monostable"] {
        let s = score(name, flags);
        let label = format!("{name} with {flags:?}");
        assert!(s.missing.is_empty(), "{label}: missed {:?}", s.missing);
        assert!(s.spurious.is_empty(), "{label}: spurious {:?}", s.spurious);
        assert!(
            s.mean_error <= 0.02,
            "{label}: mean coefficient error {:.2} %",
            100.0 * s.mean_error
        );
        assert!(
            s.resonance_error <= 0.01,
            "{label}: resonance off by {:.2} %",
            100.0 * s.resonance_error
        );
    }
}

/// The documented command: the paper's odd library, everything else from the data (the
/// k-neighbour smoothing decides per channel whether it helps; on these recordings it does not),
/// the streaming identifier's model (a device's).
#[test]
fn shipped_recordings_meet_the_accuracy_criteria() {
    must_show(&["--family", "odd", "--no-refine"]);
}

/// The ablation: with the smoothing off by flag the criteria hold too.
#[test]
fn shipped_recordings_meet_the_accuracy_criteria_without_smoothing() {
    must_show(&["--family", "odd", "--no-smoothing", "--no-refine"]);
}

/// The model `lssi identify` reports by default (refined on simulation error when that
/// predicts the held-out half better) meets them too.
#[test]
fn shipped_recordings_meet_the_accuracy_criteria_refined_by_default() {
    must_show(&["--family", "odd"]);
}
