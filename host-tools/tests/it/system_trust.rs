//! Never a confident wrong system (issue 25), as a user meets it: `lssi gen` a harvester,
//! then `lssi identify --json` it. Exit 0 must be the truth (its terms and no others, each
//! coefficient within 10 %, x'''s damping within 25 %: `scripts/hostile-system.sh`'s "true
//! model"); anything else must be withheld (exit 3, the sentence saying why). Each record is
//! one of that script's hostile variants that main printed wrong with exit 0.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use serde_json::Value;

use crate::common::{generate, lssi, paired_equations, truth};

/// Generates `args`, identifies the record as a user does, and holds the outcome to the true
/// model or withheld; returns stderr of a withheld one (`None`: the true model).
fn true_or_withheld(args: &[&str]) -> Option<String> {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), "h.csv", args);
    let truth = truth(&path);
    let o = lssi(&["identify", "--json", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    match o.status.code().unwrap() {
        0 => {
            let printed = serde_json::from_slice(&o.stdout).unwrap();
            for (target, have, want) in paired_equations(&printed, &truth) {
                for (k, (w, _)) in &want {
                    let tolerance = if k == "v" && target.ends_with("''") {
                        0.25
                    } else {
                        0.10
                    };
                    assert!(
                        (have[k].0 / w - 1.0).abs() <= tolerance,
                        "exit 0 with {target}'s {k} {} (truth {w}): {have:?}",
                        have[k].0
                    );
                }
            }
            None
        }
        3 => {
            assert!(
                stderr.contains("no deterministic dynamics found in"),
                "{stderr}"
            );
            let v: Value = serde_json::from_slice(&o.stdout).unwrap();
            assert_eq!(v["withheld"], true, "{v}");
            assert!(v.get("equations").is_none(), "{v}");
            Some(stderr)
        }
        code => panic!("exit {code}: {stderr}"),
    }
}

/// Seed 9907 of `scripts/hostile-system.sh`: an electromagnetic harvester (inductive coil,
/// V), x at 1 % noise, one tone. Main printed V' = −9116 x + 41.3 v − 3.11 sin Ωt − 7.87 cos
/// Ωt (truth 500 v − 200 V) and x'''s coupling (0.15 ± 4.3) V (truth −0.25) with exit 0: an
/// electrical equation driven by the forcing, which a circuit is not.
#[test]
fn a_circuit_equation_driven_by_the_forcing_is_withheld() {
    let withheld = true_or_withheld(&[
        "electromagnetic",
        "--electrical",
        "V",
        "--coil",
        "inductive",
        "--wells",
        "monostable",
        "--amplitude",
        "3.98",
        "--omega",
        "78.41",
        "--rate",
        "1040",
        "--t-end",
        "4.75",
        "--delta",
        "0.01",
        "--observe",
        "x",
        "--seed",
        "9907",
    ]);
    if let Some(stderr) = withheld {
        assert!(
            stderr.contains("excitation") || stderr.contains("standard errors"),
            "{stderr}"
        );
    }
}

/// Seed 9915: the same harvester, v alone at 2 % noise, the base acceleration u measured.
/// Main printed x'' = … + (−1.08 ± 12) v + (−0.33 ± 5.3) V + (3.9 ± 0.78) v² … with exit 0
/// (truth −1.26 v − 0.25 V, no v²): the damping/coupling split under one tone, its ± wider
/// than the coefficients.
#[test]
fn an_undetermined_damping_and_coupling_split_is_withheld() {
    let withheld = true_or_withheld(&[
        "electromagnetic",
        "--electrical",
        "V",
        "--coil",
        "inductive",
        "--wells",
        "monostable",
        "--amplitude",
        "0.848",
        "--omega",
        "42.63",
        "--rate",
        "4130",
        "--t-end",
        "8.32",
        "--delta",
        "0.02",
        "--observe",
        "v",
        "--input",
        "--seed",
        "9915",
    ]);
    if let Some(stderr) = withheld {
        assert!(stderr.contains("x''"), "{stderr}");
    }
}

/// Seed 9910: a piezoelectric harvester, v alone without noise (x integrated from it). Main
/// printed x'' = … + 0.0128 V + 0.0218 sin Ωt − 0.860 cos Ωt (truth 0.0157 V, no sin) with
/// exit 0, refinement not taken.
#[test]
fn an_unconfirmed_model_of_integrated_velocity_is_withheld() {
    let withheld = true_or_withheld(&[
        "piezo",
        "--wells",
        "monostable",
        "--amplitude",
        "0.866",
        "--omega",
        "57.3",
        "--rate",
        "1170",
        "--t-end",
        "7.91",
        "--delta",
        "0",
        "--observe",
        "v",
        "--seed",
        "9910",
    ]);
    // Withheld as unconfirmed (x integrated), or, with Ω refined beside the coefficients,
    // for the sine the streaming model kept beside the forcing's cosine: 0.8 of its ± on the
    // whole record.
    if let Some(stderr) = withheld {
        assert!(
            stderr.contains("integrated") || stderr.contains("does not determine the terms"),
            "{stderr}"
        );
    }
}

/// Seed 10368 of `scripts/hostile-system.sh`: a bistable piezo harvester, x at 2 % noise
/// and u, 4.5 s. The streaming selection kept a spurious v³ beside the damping, which the
/// refinement could not fix the sign of, and the model was withheld ("the recording does not
/// determine the terms x'''s v^3"). Backward elimination over the refinement drops it (the
/// held-out prediction no worse without), and the truth's terms are printed.
#[test]
fn a_spurious_term_the_refinement_cannot_resolve_is_dropped() {
    let args = [
        "piezo",
        "--wells",
        "bistable",
        "--amplitude",
        "2.08",
        "--omega",
        "52.28",
        "--rate",
        "2150",
        "--t-end",
        "4.49",
        "--delta",
        "0.02",
        "--observe",
        "x",
        "--seed",
        "10368",
        "--input",
    ];
    assert_eq!(true_or_withheld(&args), None, "withheld");
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), "h.csv", &args);
    let o = lssi(&["identify", "--json", path.to_str().unwrap()]);
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["refinement"]["dropped"][0], "x'''s v^3", "{v}");
    let terms: Vec<&str> = v["equations"][0]["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["term"].as_str().unwrap())
        .collect();
    assert_eq!(terms, ["x", "v", "V", "x^3", "u"]);
}

/// Seed 10409 of `scripts/hostile-system.sh`: a monostable piezo harvester recorded as v
/// alone with u, one tone, clean, 4.9 s. x is v integrated (its drift removal an estimate),
/// and at one tone the coupling trades with the stiffness: x'''s χ was printed 0.0219 ±
/// 0.0019 against the truth's 0.0157 with exit 0. Its ± now covers the distance to the model
/// refined without x followed, and the truth lies within two of them.
#[test]
fn a_coupling_from_an_integrated_x_carries_the_integrations_uncertainty() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "h.csv",
        &[
            "piezo",
            "--wells",
            "monostable",
            "--amplitude",
            "2.8",
            "--omega",
            "70.37",
            "--rate",
            "6220",
            "--t-end",
            "4.91",
            "--delta",
            "0",
            "--observe",
            "v",
            "--seed",
            "10409",
            "--input",
        ],
    );
    let truth = truth(&path);
    let o = lssi(&["identify", "--json", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    match o.status.code().unwrap() {
        0 => {
            let printed: Value = serde_json::from_slice(&o.stdout).unwrap();
            assert!(
                printed["standard_errors"]
                    .as_str()
                    .unwrap()
                    .contains("refined without x"),
                "{printed}"
            );
            for (target, have, want) in paired_equations(&printed, &truth) {
                for (k, (w, _)) in &want {
                    let (c, se) = have[k];
                    assert!(
                        (c - w).abs() <= 0.10 * w.abs() || (c - w).abs() <= 2.0 * se,
                        "{target}'s {k} {c} ± {se} against {w}"
                    );
                }
            }
        }
        3 => assert!(
            stderr.contains("no deterministic dynamics found in"),
            "{stderr}"
        ),
        code => panic!("exit {code}: {stderr}"),
    }
}
