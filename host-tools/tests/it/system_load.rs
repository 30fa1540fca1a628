//! Issue 26, item 3 for electromagnetic harvesters: `--load-ohms R --coil-ohms R_c` gives the
//! coil's inductance, the transduction factor, the mass, the coupling factor, the electrical
//! time constant, the mean power R i² and the power against load and frequency, checked
//! against the truth of `lssi gen electromagnetic` (OUT.json), as a user runs it; without
//! `--coil-ohms` the report says what the load analysis needs.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::Path;

use crate::common::lssi;
use serde_json::Value;

/// `lssi gen electromagnetic ARGS OUT.csv` (a bistable beam, a slow coil: L = 100 H, so that
/// i is not a copy of v), and its truth.
fn generate(dir: &Path, name: &str, args: &[&str]) -> (String, Value) {
    let path = dir.join(format!("{name}.csv"));
    let mut all = vec![
        "gen",
        "electromagnetic",
        "--wells",
        "bistable",
        "--inductance",
        "100",
    ];
    all.extend(args);
    all.push(path.to_str().unwrap());
    let o = lssi(&all);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(path.with_extension("json")).unwrap())
            .unwrap();
    (path.to_str().unwrap().to_owned(), truth)
}

fn identify(path: &str, extra: &[&str]) -> Value {
    let mut args = vec!["identify", path, "--json"];
    args.extend(extra);
    let o = lssi(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn coil_ohms_gives_the_electromagnetic_harvester_in_physical_terms() {
    let dir = tempfile::tempdir().unwrap();
    // The current i, and the voltage V = R i across the load (read as a coil's with
    // --coil-ohms), at 1 % noise.
    for (name, electrical, seed) in [("i", "i", "5"), ("v", "V", "7")] {
        let (path, truth) = generate(
            dir.path(),
            name,
            &[
                "--electrical",
                electrical,
                "--delta",
                "0.01",
                "--seed",
                seed,
            ],
        );
        let p = &truth["params"];
        let tr = &p["transducer"];
        let f = |v: &Value| v.as_f64().unwrap();
        let (phi, rc, load, l) = (
            f(&tr["phi"]),
            f(&tr["coil_ohms"]),
            f(&tr["load_ohms"]),
            f(&tr["inductance"]),
        );
        let json = identify(
            &path,
            &[
                "--load-ohms",
                &load.to_string(),
                "--coil-ohms",
                &rc.to_string(),
            ],
        );
        let h = &json["harvester"];
        let get = |k: &str| h[k].as_f64().unwrap_or(f64::NAN);
        eprintln!("{name}: {h}");
        assert_eq!(h["transducer"], "electromagnetic", "{h}");
        assert_eq!(h["channel"], electrical, "{h}");
        // L = (R_c + R)/λ, Φ = −κ L: from i' alone.
        assert!(rel(get("inductance_h"), l) < 0.02, "{h}");
        assert!(rel(get("phi"), phi) < 0.02, "{h}");
        assert!(
            rel(get("time_constant_s"), f(&p["electrical_time_constant"])) < 0.02,
            "{h}"
        );
        // m = −Φ/χ and k² need x'''s coupling χ, the least certain coefficient here.
        assert!(rel(get("mass"), f(&p["mass"])) < 0.1, "{h}");
        // The truth's coupling_squared is Φ²/(k L); the report's k² = Φ²/(k L + Φ²).
        let k2 = get("coupling_k2");
        assert!(rel(k2 / (1.0 - k2), f(&p["coupling_squared"])) < 0.1, "{h}");
        // The mean power at the load, R i² or V²/R, over the record's second half.
        let text = std::fs::read_to_string(&path).unwrap();
        let e: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
            .collect();
        let half = &e[e.len() / 2..];
        let ms = half.iter().map(|q| q * q).sum::<f64>() / half.len() as f64;
        let measured = if electrical == "i" {
            ms * load
        } else {
            ms / load
        };
        assert!(rel(get("power_measured_w"), measured) < 1e-9, "{h}");
        assert!(
            rel(get("power_predicted_w"), get("power_measured_w")) < 0.25,
            "{h}"
        );
        // The load sweep: the recorded load's point is the prediction, and the optimum is
        // inside the sweep with no point above it.
        let sweep = h["load_sweep"].as_array().unwrap();
        assert!(sweep.len() > 10, "{h}");
        let at_load = sweep.iter().find(|q| f(&q["at"]) == load).unwrap();
        assert!(rel(f(&at_load["power_w"]), get("power_predicted_w")) < 1e-9);
        let best = get("optimal_load_ohms");
        assert!(f(&sweep[0]["at"]) < best && best < f(&sweep[sweep.len() - 1]["at"]));
        let most = get("optimal_power_w");
        for q in sweep {
            assert!(q["power_w"].as_f64().unwrap() <= most * (1.0 + 1e-9), "{h}");
        }
        assert!(!h["frequency_sweep"].as_array().unwrap().is_empty(), "{h}");
    }
}

#[test]
fn a_current_without_coil_ohms_says_what_the_load_analysis_needs() {
    let dir = tempfile::tempdir().unwrap();
    let (path, truth) = generate(
        dir.path(),
        "i",
        &["--electrical", "i", "--delta", "0.01", "--seed", "9"],
    );
    // The streaming model (the load analysis is the same on a refined one: CI's time).
    let json = identify(&path, &["--load-ohms", "1000", "--no-refine"]);
    let h = &json["harvester"];
    assert_eq!(h["transducer"], "electromagnetic", "{h}");
    // What needs only λ, κ and χ is there.
    let tau = truth["params"]["electrical_time_constant"]
        .as_f64()
        .unwrap();
    assert!(
        rel(h["time_constant_s"].as_f64().unwrap(), tau) < 0.02,
        "{h}"
    );
    assert!(h["coupling_k2"].as_f64().unwrap() > 0.0, "{h}");
    assert!(h["power_predicted_w"].as_f64().unwrap() > 0.0, "{h}");
    // What needs R_c is not, and one note says so.
    assert!(h.get("inductance_h").is_none(), "{h}");
    assert!(h["load_sweep"].as_array().unwrap().is_empty(), "{h}");
    let notes: Vec<&str> = h["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert!(
        notes
            .iter()
            .any(|n| n.contains("need the coil's resistance (--coil-ohms R_c)")),
        "{notes:?}"
    );
    // The text report says it too.
    let o = lssi(&["identify", &path, "--load-ohms", "1000", "--no-refine"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("--coil-ohms R_c"), "{text}");
    assert!(text.contains("mean power R i²"), "{text}");
}

#[test]
fn coil_ohms_is_refused_without_a_load_or_when_negative() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = generate(
        dir.path(),
        "i",
        &["--electrical", "i", "--t-end", "2", "--seed", "10"],
    );
    for (args, says) in [
        (vec!["--coil-ohms", "10"], "--coil-ohms needs the load"),
        (
            vec!["--load-ohms", "1000", "--coil-ohms", "-3"],
            "--coil-ohms",
        ),
    ] {
        let mut all = vec!["identify", path.as_str()];
        all.extend(&args);
        let o = lssi(&all);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
}

#[test]
fn plot_draws_an_electromagnetic_harvesters_power_against_load() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = generate(
        dir.path(),
        "i",
        &["--electrical", "i", "--delta", "0.01", "--seed", "11"],
    );
    let out = dir.path().join("figs");
    let o = lssi(&[
        "plot",
        &path,
        "--load-ohms",
        "1000",
        "--coil-ohms",
        "1000",
        "--no-refine",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for figure in ["i-current.png", "i-power-load.png", "i-power-frequency.png"] {
        let png = std::fs::read(out.join(figure)).unwrap();
        assert_eq!(&png[1..4], b"PNG", "{figure}");
    }
}
