//! Never a confident wrong system (issue 25): a harvester's model printed with exit 0 has the
//! truth's terms with ± that cover the truth's coefficients; else it is withheld (exit 3). The record is one of that script's
//! hostile variants (seed 9706), where a model with a wrong damping/coupling split was
//! printed with a tight ±.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

fn lssi(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(args)
        .output()
        .unwrap()
}

/// Each equation's terms (sin/cos by kind) and coefficients, with standard errors (0 where
/// absent).
fn equations(v: &Value) -> BTreeMap<String, BTreeMap<String, (f64, f64)>> {
    v["equations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            let terms = e["terms"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| {
                    let name = t["term"].as_str().unwrap();
                    let key = name.split('(').next().unwrap().to_owned();
                    let se = t.get("se").and_then(Value::as_f64).unwrap_or(0.0);
                    (key, (t["coef"].as_f64().unwrap(), se))
                })
                .collect();
            (e["target"].as_str().unwrap().to_owned(), terms)
        })
        .collect()
}

/// Generates `args` into `dir`, identifies it (with `extra` flags) and checks the outcome:
/// the truth's terms with x'''s damping and coupling within 2.5 of their ± of the truth's
/// (the ± cover it), or withheld naming why. Returns the exit status and stderr.
fn true_or_withheld(dir: &Path, args: &[&str], extra: &[&str]) -> (i32, String) {
    let path = dir.join("h.csv");
    let mut gen_args = vec!["gen"];
    gen_args.extend(args);
    gen_args.push(path.to_str().unwrap());
    let g = lssi(&gen_args);
    assert!(g.status.success(), "{}", String::from_utf8_lossy(&g.stderr));
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("h.json")).unwrap()).unwrap();
    let mut id_args = vec!["identify", "--json"];
    id_args.extend(extra);
    id_args.push(path.to_str().unwrap());
    let o = lssi(&id_args);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let code = o.status.code().unwrap();
    match code {
        0 => {
            let got = equations(&serde_json::from_slice(&o.stdout).unwrap());
            for (target, want) in equations(&truth) {
                let have = &got[&target];
                assert_eq!(
                    have.keys().collect::<Vec<_>>(),
                    want.keys().collect::<Vec<_>>(),
                    "{target}: printed {have:?}, truth {want:?}"
                );
                // The damping/coupling split (v and the electrical state in x''): the other
                // refined ± are not widened, and the refinement's are tight (x 3 of them off).
                let split = ["v", "V", "i"];
                for (k, (w, _)) in want
                    .iter()
                    .filter(|(k, _)| target.ends_with("''") && split.contains(&k.as_str()))
                {
                    let (c, se) = have[k];
                    assert!(
                        (c - w).abs() <= 2.5 * se,
                        "{target}'s {k}: printed {c} ± {se} (truth {w}) with exit 0"
                    );
                }
            }
        }
        3 => assert!(
            stderr.contains("no deterministic dynamics found in"),
            "{stderr}"
        ),
        _ => panic!("exit {code}: {stderr}"),
    }
    (code, stderr)
}

/// Seed 9706's record: a bistable electromagnetic harvester with an inductive coil (V lags v
/// by 11°), x only, 0.5 % noise, one tone. Refinement moved V from −0.346 to −0.310 (truth
/// −0.25) predicting the held-out half no better, and printed ± 0.005: now its ± is at least
/// the distance between the two fits, and the split is withheld or right.
#[test]
fn an_unbacked_refinement_does_not_print_a_tight_wrong_split() {
    let dir = tempfile::tempdir().unwrap();
    let (code, stderr) = true_or_withheld(
        dir.path(),
        &[
            "electromagnetic",
            "--electrical",
            "V",
            "--coil",
            "inductive",
            "--wells",
            "bistable",
            "--amplitude",
            "2.6",
            "--omega",
            "39.61",
            "--rate",
            "5030",
            "--t-end",
            "4.47",
            "--delta",
            "0.005",
            "--observe",
            "x",
            "--seed",
            "9706",
        ],
        &[],
    );
    assert!(
        code == 0 || stderr.contains("no deterministic dynamics found in"),
        "{stderr}"
    );
}
