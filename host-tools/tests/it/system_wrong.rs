//! Never a confident wrong system (issue 25): a harvester's model printed with exit 0 has the
//! truth's terms with ± that cover the truth's coefficients; else it is withheld (exit 3). The record is one of that script's
//! hostile variants (seed 9706), where a model with a wrong damping/coupling split was
//! printed with a tight ±.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::Path;

use crate::common::{generate, lssi, paired_equations, truth};

/// Generates `args` into `dir`, identifies it (with `extra` flags) and checks the outcome:
/// the truth's terms with x'''s damping and coupling within 2.5 of their ± of the truth's
/// (the ± cover it), or withheld naming why. Returns the exit status and stderr.
fn true_or_withheld(dir: &Path, args: &[&str], extra: &[&str]) -> (i32, String) {
    let path = generate(dir, "h.csv", args);
    let truth = truth(&path);
    let mut id_args = vec!["identify", "--json"];
    id_args.extend(extra);
    id_args.push(path.to_str().unwrap());
    let o = lssi(&id_args);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let code = o.status.code().unwrap();
    match code {
        0 => {
            let printed = serde_json::from_slice(&o.stdout).unwrap();
            for (target, have, want) in paired_equations(&printed, &truth) {
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
