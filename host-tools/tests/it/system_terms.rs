//! Issue 26: an electromagnetic harvester's electrical equation does not pass with spurious
//! terms. On a single tone's steady state x, sin Ωt and cos Ωt are one sinusoid, so V' (or i')
//! can gain a combination of them nearly 0 on the record whose free run still follows it;
//! the gate's term check (each electrical term refitted at least 2 standard errors from 0)
//! withholds it, as a user runs `lssi identify`. Seeds the check was not set on (those were
//! 101–106).

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::process::Command;

use serde_json::Value;

#[test]
fn electromagnetic_records_pass_only_with_their_electrical_terms() {
    let dir = tempfile::tempdir().unwrap();
    let lssi = env!("CARGO_BIN_EXE_lssi");
    let mut by_the_check = 0;
    for (electrical, seed) in [("V", "201"), ("V", "202"), ("i", "203")] {
        let path = dir.path().join(format!("em{seed}.csv"));
        let path = path.to_str().unwrap();
        let o = Command::new(lssi)
            .args(["gen", "electromagnetic", "--electrical", electrical])
            .args(["--delta", "0.05", "--t-end", "10", "--seed", seed, path])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let o = Command::new(lssi)
            .args(["identify", path, "--json"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        let json: Value = serde_json::from_slice(&o.stdout).unwrap();
        let model = json.get("withheld_model").unwrap_or(&json);
        let terms: Vec<&str> = model["equations"][1]["terms"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["term"].as_str().unwrap())
            .collect();
        let spurious = terms.iter().any(|t| *t != "v" && *t != electrical);
        eprintln!(
            "{electrical} seed {seed}: exit {:?}, {terms:?}",
            o.status.code()
        );
        match o.status.code() {
            Some(0) => assert!(!spurious, "{seed}: passed with {terms:?}"),
            Some(3) => {
                if stderr.contains("standard errors of 0 (refitted on the record") {
                    by_the_check += 1;
                    assert!(spurious, "{seed}: {stderr}");
                }
            }
            code => panic!("{seed}: exit {code:?}: {stderr}"),
        }
    }
    // The records hold spurious fits the other checks pass.
    assert!(by_the_check >= 1);
}

/// A bistable piezo harvester recorded as v and V (clean, one well, u recorded: fresh
/// `scripts/hostile-system.sh` seed 10466): x is v integrated, about its mean, and x'' came
/// out as the truth written about that mean, `2.50 − 2170 x − 9.9e5 x² − 7.94e7 x³ …` for
/// `1974 x − 7.90e7 x³ …`. Recentred on the centre of symmetry of its restoring force, the
/// truth's terms.
#[test]
fn a_double_well_from_an_integrated_velocity_is_recentred() {
    let dir = tempfile::tempdir().unwrap();
    let path = crate::common::generate(
        dir.path(),
        "p.csv",
        &[
            "piezo",
            "--wells",
            "bistable",
            "--amplitude",
            "0.77",
            "--omega",
            "55.79",
            "--rate",
            "512",
            "--t-end",
            "15.2",
            "--delta",
            "0",
            "--observe",
            "v",
            "--seed",
            "10466",
            "--input",
        ],
    );
    let (code, out) = crate::common::identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let json = out.unwrap();
    let got = crate::common::equations(&json);
    let want = crate::common::equations(&crate::common::truth(&path));
    for (target, terms) in &want {
        let have = &got[target];
        let names = |t: &crate::common::Terms| t.keys().cloned().collect::<Vec<_>>();
        assert_eq!(names(have), names(terms), "{target}: {json}");
        for (name, (w, _)) in terms {
            let (c, _) = have[name];
            let bar = if name == "v" && target == "x''" {
                0.25
            } else {
                0.1
            };
            assert!(
                (c / w - 1.0).abs() <= bar,
                "{target} {name}: {c} against {w}"
            );
        }
    }
}
