//! Issue 26, item 1: two displacements. `lssi gen twodof` (a primary mass and a secondary
//! piezo beam coupled by a spring, shaken broadband) identified with the commands a user runs:
//! x1'', x2'' and V', each with exactly the truth's terms; the text report prints each
//! equation on its own line with standard errors; `lssi simulate` writes every state; a bad
//! column spec is a one-sentence error.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lssi_host::synth::harvester::SystemTruth;
use serde_json::Value;

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

fn lssi(args: &[&str]) -> Output {
    Command::new(LSSI).args(args).output().unwrap()
}

/// `lssi gen twodof ARGS DIR/NAME.csv`: the CSV and its truth.
fn generate(dir: &Path, name: &str, args: &[&str]) -> (PathBuf, SystemTruth) {
    let csv = dir.join(format!("{name}.csv"));
    let mut all = vec!["gen", "twodof"];
    if !args.contains(&"--t-end") {
        all.extend(["--t-end", "20"]);
    }
    all.extend_from_slice(args);
    all.push(csv.to_str().unwrap());
    let out = lssi(&all);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth: SystemTruth =
        serde_json::from_str(&std::fs::read_to_string(csv.with_extension("json")).unwrap())
            .unwrap();
    (csv, truth)
}

fn identify_json(csv: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["identify", "--json", csv.to_str().unwrap()];
    args.extend_from_slice(extra);
    let out = lssi(&args);
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Each equation of `json` against the truth: the same targets in order, no term the truth
/// has not, every true coefficient within `tolerance` (relative). Returns the worst error.
fn check(json: &Value, truth: &SystemTruth, tolerance: f64, label: &str) -> f64 {
    let equations = json["equations"].as_array().unwrap();
    let targets: Vec<&str> = equations
        .iter()
        .map(|e| e["target"].as_str().unwrap())
        .collect();
    assert_eq!(targets, ["x1''", "x2''", "V'"], "{label}");
    let mut worst = 0.0f64;
    for (e, t) in equations.iter().zip(&truth.equations) {
        assert_eq!(e["target"].as_str(), Some(t.target.as_str()), "{label}");
        let found: Vec<(&str, f64)> = e["terms"]
            .as_array()
            .unwrap()
            .iter()
            .map(|q| (q["term"].as_str().unwrap(), q["coef"].as_f64().unwrap()))
            .collect();
        let mut names: Vec<&str> = found.iter().map(|f| f.0).collect();
        let mut true_names: Vec<&str> = t.terms.iter().map(|q| q.term.as_str()).collect();
        names.sort_unstable();
        true_names.sort_unstable();
        assert_eq!(names, true_names, "{label}: {}", t.target);
        for q in &t.terms {
            let c = found.iter().find(|f| f.0 == q.term).unwrap().1;
            let error = ((c - q.coef) / q.coef).abs();
            worst = worst.max(error);
            assert!(
                error < tolerance,
                "{label}: {} term {}: {c} against {}",
                t.target,
                q.term,
                q.coef
            );
        }
    }
    worst
}

/// Clean records, with x1, x2 and with v1, v2 recorded too: the truth's terms, every
/// coefficient within 0.5 %, in f32 (the default) and f64.
#[test]
fn a_clean_two_degree_of_freedom_harvester_gives_its_three_equations() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, truth) = generate(dir.path(), "clean", &[]);
    let worst = check(&identify_json(&csv, &[]), &truth, 0.005, "clean f32");
    eprintln!(
        "clean, x1 x2 V u, f32: worst coefficient error {:.4} %",
        100.0 * worst
    );
    check(&identify_json(&csv, &["--f64"]), &truth, 0.005, "clean f64");
    let (csv, truth) = generate(dir.path(), "xv", &["--observe", "xv"]);
    let worst = check(&identify_json(&csv, &[]), &truth, 0.005, "clean xv");
    eprintln!(
        "clean, x1 x2 v1 v2 V u: worst coefficient error {:.4} %",
        100.0 * worst
    );
}

/// 1 % sensor noise on every channel, three seeds: the truth's terms and no other, every
/// coefficient within 10 % (the reaction χ V in x2'' is the smallest part of x2'' and the
/// least determined: its standard error is printed beside it), refined on simulation error.
#[test]
fn a_noisy_two_degree_of_freedom_harvester_gives_its_three_equations() {
    let dir = tempfile::tempdir().unwrap();
    for seed in ["1", "2", "3"] {
        let (csv, truth) = generate(dir.path(), seed, &["--delta", "0.01", "--seed", seed]);
        let json = identify_json(&csv, &[]);
        let worst = check(&json, &truth, 0.10, seed);
        eprintln!(
            "1 % noise, seed {seed}: worst coefficient error {:.3} %",
            100.0 * worst
        );
        // Refined on simulation error, as one displacement's system is (it was declined).
        assert_eq!(json["refinement"]["taken"], true, "seed {seed}: {json}");
    }
}

/// The text report: each equation on its own line, with ± standard errors, the states
/// named; `lssi simulate` writes t and every state and follows the recording.
#[test]
fn the_report_and_the_simulation_cover_every_state() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, _) = generate(dir.path(), "h", &[]);
    let out = lssi(&["identify", csv.to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    for (line, target) in lines.iter().zip(["x1'' = ", "x2'' = ", "V' = "]) {
        assert!(line.starts_with(target), "{text}");
        assert!(line.contains(" ± "), "{line}");
    }
    assert!(text.contains("states: x1, v1, x2, v2, V"), "{text}");
    let json = identify_json(&csv, &[]);
    let model = dir.path().join("model.json");
    std::fs::write(&model, json.to_string()).unwrap();
    let sim = dir.path().join("sim.csv");
    let out = lssi(&[
        "simulate",
        model.to_str().unwrap(),
        csv.to_str().unwrap(),
        "--out",
        sim.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let written = std::fs::read_to_string(&sim).unwrap();
    assert_eq!(written.lines().next(), Some("t,x1,v1,x2,v2,V"));
    let report = String::from_utf8(out.stdout).unwrap();
    // Each recorded state's NRMSE over the whole record, from the first row and u alone.
    for state in ["x1", "x2", "V"] {
        let line = report
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{state} ")))
            .unwrap_or_else(|| panic!("{report}"));
        let nrmse: f64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
        eprintln!("simulated {state}: NRMSE {:.4}", nrmse);
        assert!(nrmse < 0.05, "{report}");
    }
}

/// Bad column specs and flags that do not apply: each a one-sentence error, exit 2.
#[test]
fn bad_column_specs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, _) = generate(dir.path(), "h", &["--t-end", "2"]);
    let path = csv.to_str().unwrap();
    let cases: [(&[&str], &str); 3] = [
        (
            &["--x-col", "x1,x2,x3"],
            "--x-col x1,x2,x3 names 3 columns, but it takes one name, or two",
        ),
        (&["--x-col", "x1,y"], "there is no column 'y'"),
        (
            &["--v-col", "v1"],
            "2 displacement column(s) (x1,x2) but 1 velocity column(s)",
        ),
    ];
    for (flags, expected) in cases {
        let mut args = vec!["identify", path];
        args.extend_from_slice(flags);
        let out = lssi(&args);
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(2), "{flags:?}: {err}");
        assert!(err.contains(expected), "{flags:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
    // Two displacements without an electrical column.
    let text = std::fs::read_to_string(&csv).unwrap();
    let plain: String = text
        .lines()
        .map(|l| l.split(',').collect::<Vec<_>>())
        .map(|f| format!("{},{},{},{}", f[0], f[1], f[2], f[4]))
        .collect::<Vec<_>>()
        .join("\n");
    let plain_path = dir.path().join("plain.csv");
    std::fs::write(&plain_path, plain + "\n").unwrap();
    let out = lssi(&["identify", plain_path.to_str().unwrap()]);
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("needs an electrical column"), "{err}");
}

/// `--load-ohms` on a two-degree-of-freedom harvester: the secondary beam the piezo sits on
/// (x2, its velocity drives V') in physical terms, and the power against the load, checked
/// against the generator's truth at the recorded load and at the optimum it predicts (1 %
/// noise).
#[test]
fn load_ohms_gives_the_secondary_beams_harvester_and_its_optimal_load() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, truth) = generate(dir.path(), "h", &["--delta", "0.01", "--seed", "3"]);
    let json = identify_json(&csv, &["--load-ohms", "1e6"]);
    let h = &json["harvester"];
    let rel = |a: &Value, b: f64| (a.as_f64().unwrap() / b - 1.0).abs();
    assert_eq!(h["displacement"], "x2", "{h}");
    let p = &truth.params;
    for (key, want) in [
        ("capacitance_f", p["capacitance"].as_f64().unwrap()),
        ("mass", p["mass2"].as_f64().unwrap()),
        ("theta", p["theta"].as_f64().unwrap()),
        (
            "time_constant_s",
            p["electrical_time_constant"].as_f64().unwrap(),
        ),
    ] {
        assert!(
            rel(&h[key], want) < 0.05,
            "{key}: {} against {want}",
            h[key]
        );
    }
    let measured = h["power_measured_w"].as_f64().unwrap();
    assert!(rel(&h["power_predicted_w"], measured) < 0.05, "{h}");
    // The optimum it predicts, generated: the truth's power there within 5 % of the
    // prediction, and more than at the recorded load.
    let optimum = h["optimal_load_ohms"].as_f64().unwrap();
    assert!(optimum < 0.8e6, "{optimum}");
    let (_, at_optimum) = generate(
        dir.path(),
        "opt",
        &[
            "--delta",
            "0.01",
            "--seed",
            "3",
            "--load-ohms",
            &format!("{optimum}"),
        ],
    );
    let truth_power = at_optimum.params["mean_power_w"].as_f64().unwrap();
    assert!(
        rel(&h["optimal_power_w"], truth_power) < 0.05,
        "{truth_power}: {h}"
    );
    assert!(
        truth_power > 1.2 * measured,
        "{truth_power} against {measured}"
    );
    // The text report names the beam.
    let out = lssi(&["identify", csv.to_str().unwrap(), "--load-ohms", "1e6"]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("x2'' ∋ χ V, V' = −λ V − κ v2"), "{text}");
}
