//! Issue 25 on sets nobody tuned on (scripts/hostile-more.sh, scripts/lowest-rate.sh): the
//! true model at a field device's rate, a damping the streaming selection lost brought back,
//! and a streaming model that cannot predict its record withheld. Each as a user meets it:
//! `lssi gen eveh`, then `lssi identify --json FILE`.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use crate::common::{gen_eveh, identify_json, truth};

/// sin/cos named by their function alone.
fn kind(name: &str) -> &str {
    if name.starts_with("cos(") {
        "cos"
    } else if name.starts_with("sin(") {
        "sin"
    } else {
        name
    }
}

/// The printed model has the truth's terms and no others, each coefficient within 10 % of
/// the truth's, the damping v within 25 % or within two of its standard errors (a weak
/// damping at a coarse rate: the ± the model prints covers the truth).
fn assert_true_model(model: &serde_json::Value, truth: &serde_json::Value, what: &str) {
    let got: Vec<(String, f64, f64)> = model["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                kind(t["term"].as_str().unwrap()).to_owned(),
                t["coef"].as_f64().unwrap(),
                t["se"].as_f64().unwrap_or(0.0),
            )
        })
        .collect();
    let want: Vec<(String, f64)> = truth["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                kind(t["term"].as_str().unwrap()).to_owned(),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    let mut names: Vec<&str> = got.iter().map(|g| g.0.as_str()).collect();
    let mut truth_names: Vec<&str> = want.iter().map(|w| w.0.as_str()).collect();
    names.sort_unstable();
    truth_names.sort_unstable();
    assert_eq!(names, truth_names, "{what}: terms {got:?}, truth {want:?}");
    for (name, w) in &want {
        let (_, c, se) = got.iter().find(|g| &g.0 == name).unwrap();
        let rel = (c / w - 1.0).abs();
        let ok = if name == "v" {
            rel <= 0.25 || (c - w).abs() <= 2.0 * se
        } else {
            rel <= 0.10
        };
        assert!(ok, "{what}: {name} = {c} ± {se}, truth {w}");
    }
}

/// Table 5's double well sampled at 80 Hz (23 samples a forcing period, as a field device
/// samples), 20 s, 0.5 % noise: the true model (it was withheld: the streaming model, from
/// derivatives biased at this rate, kept x³, x·v², cos(Ωt) and failed the gate's simulation
/// checks; the model refined on simulation error, with the lost v and x brought back, follows
/// the record).
#[test]
fn the_double_well_at_a_field_devices_rate_is_identified() {
    let dir = tempfile::tempdir().unwrap();
    for seed in ["2", "3"] {
        let path = gen_eveh(dir.path(), "field.csv", &["--rate", "80", "--seed", seed]);
        let truth = truth(&path);
        let (code, out) = identify_json(&path, &[]);
        assert_eq!(code, 0, "seed {seed}: {out:?}");
        assert_true_model(&out.unwrap(), &truth, &format!("80 Hz seed {seed}"));
    }
}

/// A heavy single well (187 g, 2.85 Hz) driven gently at 10.25 rad/s, x and v at 63 Hz, 2 %
/// noise, 8.5 s: the true model. The streaming selection took x·v² for the damping (even in v:
/// no dissipation), and the refinement, which added v only beside a term odd in v, printed x·v²
/// beside v.
#[test]
fn a_driven_model_without_a_damping_gets_v_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "heavy.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.1871",
            "--k1",
            "60.06",
            "--k3",
            "4.863e9",
            "--zeta",
            "0.004629",
            "--omega",
            "10.25",
            "--amplitude",
            "0.02302",
            "--rate",
            "63.35",
            "--t-end",
            "8.476",
            "--x0",
            "0.0001785",
            "--observe",
            "xv",
            "--delta",
            "0.02",
            "--adc-bits",
            "0",
            "--seed",
            "20059",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    assert_true_model(&out.unwrap(), &truth(&path), "heavy single well");
}

/// A light single well driven hard (4.9 m/s²) at 0.45 of its resonance, 45 samples a period,
/// 0.5 % noise, x only: withheld (exit 3, naming the prediction), not the streaming model
/// with half the cubic stiffness and x²·v, x·v² for a damping printed with exit 0. Refinement
/// found the streaming model unable to predict even half a forcing period, and the gate's
/// noise estimate took the record's harmonics for 28 % of noise.
#[test]
fn a_streaming_model_that_cannot_predict_its_record_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "hard.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.01524",
            "--k1",
            "2.977",
            "--k3",
            "1.587e6",
            "--zeta",
            "0.01805",
            "--omega",
            "6.34",
            "--amplitude",
            "4.881",
            "--rate",
            "45.09",
            "--t-end",
            "94.43",
            "--x0",
            "0.002204",
            "--delta",
            "0.005",
            "--adc-bits",
            "0",
            "--seed",
            "20094",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 3, "{out:?}");
    let reason = out.unwrap_err();
    assert!(
        reason.contains("no deterministic dynamics found") && reason.contains("held-out half"),
        "{reason}"
    );
}

/// A light single well driven through a measured u at 1.3 of its resonance, 472 Hz, 1 % noise,
/// 8.4 s: withheld (exit 3) naming the unresolved terms, not the streaming model with a
/// constant and v² beside the truth's terms printed with exit 0. Refinement kept the streaming
/// model (the model without them predicted the held-out half 0.9 % worse, z = −1.3), and the
/// terms no refined model has were judged nowhere: refined, they lie 0.2 and 0.3 standard
/// errors from 0.
#[test]
fn a_kept_streaming_model_with_unresolved_terms_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "input.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.004564",
            "--k1",
            "9.755",
            "--k3",
            "6.574e7",
            "--zeta",
            "0.003622",
            "--omega",
            "37.59",
            "--amplitude",
            "1.46",
            "--rate",
            "472.3",
            "--t-end",
            "8.443",
            "--x0",
            "0.0006",
            "--input",
            "--delta",
            "0.01",
            "--adc-bits",
            "0",
            "--seed",
            "20119",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    // Refined with u's tone (its noise left out: `periodic::steady_input`) the record gives
    // the truth's terms (hostile 20119: worst coefficient 3.3 %); withheld, it must say why.
    if code == 0 {
        let json = out.unwrap();
        let mut names: Vec<String> = json["terms"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["term"].as_str().unwrap().to_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["u", "v", "x", "x^3"], "{json}");
        return;
    }
    assert_eq!(code, 3, "{out:?}");
    let reason = out.unwrap_err();
    assert!(
        reason.contains("streaming identifier's") && reason.contains("standard error"),
        "{reason}"
    );
}
