//! Fresh hostile sets of the twenty-second session (issues 25 and 26): each record printed a
//! wrong model with exit 0, or was refused with advice that did not help, before its fix.
//! The outcome held to is the issue's: the true model, or withheld with its reason.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use crate::common::{equations, gen_eveh, generate, identify_json, terms, truth};

/// The printed single-equation model holds the truth's terms and no others, each coefficient
/// within 10 % (the damping within 25 %).
fn assert_true_model(printed: &serde_json::Value, truth: &serde_json::Value) {
    let mut got = terms(printed);
    let mut want = terms(truth);
    got.sort_by(|a, b| a.0.cmp(&b.0));
    want.sort_by(|a, b| a.0.cmp(&b.0));
    let names = |t: &[(String, f64)]| t.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&got), names(&want), "printed {got:?}, truth {want:?}");
    for ((name, c), (_, w)) in got.iter().zip(&want) {
        let bar = if name == "v" { 0.25 } else { 0.10 };
        assert!(
            ((c - w) / w).abs() <= bar,
            "{name}: printed {c}, truth {w} (printed {got:?})"
        );
    }
}

/// Hostile 22620: a double well driven in one well, 6 periods at 33 samples a period, 195
/// samples in all. Refused before with "too few samples to estimate the excitation frequency;
/// give --omega", though given Ω the identifier found the truth: Ω's scan took every fourth
/// window, 47 rows where it needs 64.
#[test]
fn a_record_of_a_few_hundred_samples_gets_its_frequency_and_its_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "short.csv",
        &[
            "--wells",
            "bistable",
            "--mass",
            "0.007804",
            "--k1",
            "1.242",
            "--k3",
            "26870000.0",
            "--zeta",
            "0.07592",
            "--omega",
            "17.39",
            "--amplitude",
            "0.1486",
            "--rate",
            "91.8",
            "--t-end",
            "2.12",
            "--x0",
            "0.0001661",
            "--seed",
            "22620",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    assert_true_model(&out.unwrap(), &truth(&path));
}

/// A record too short for any model is told so, not told to give --omega.
#[test]
fn a_record_too_short_for_any_model_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "tiny.csv",
        &["--wells", "monostable", "--rate", "40", "--t-end", "1.75"],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 2, "{out:?}");
    let err = out.unwrap_err();
    assert!(err.contains("only 71 samples, too few"), "{err}");
    assert!(!err.contains("give --omega"), "{err}");
}

/// Hostile 22684: a hardening single well, 432 periods at 20 samples a period, x and v at 2 %
/// noise. Printed `−0.448 v − 1.64e9 x³ − 6.19e6 x·v² + 0.0228 cos` (truth `−53.9 x − 0.589 v
/// − 1.31e9 x³ + 0.0277 cos`): on one steady orbit x·v² stands in for x, and the support with
/// x was never tried, barred as a term a v offset of 10⁻³ of v's RMS "makes" from x·v².
#[test]
fn a_steady_orbits_stand_in_for_the_stiffness_is_not_printed() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "orbit.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.002498",
            "--k1",
            "0.1347",
            "--k3",
            "3282000.0",
            "--zeta",
            "0.04009",
            "--omega",
            "7.601",
            "--amplitude",
            "0.0277",
            "--rate",
            "24.1",
            "--t-end",
            "357.5",
            "--x0",
            "0.0001283",
            "--observe",
            "xv",
            "--delta",
            "0.02",
            "--seed",
            "22684",
        ],
    );
    match identify_json(&path, &[]) {
        (0, Ok(printed)) => assert_true_model(&printed, &truth(&path)),
        (3, Err(err)) => assert!(err.contains("no deterministic dynamics found"), "{err}"),
        other => panic!("{other:?}"),
    }
}

/// Hostile 22738: a double well's one well, 10 periods at 80 samples a period, 2 % noise.
/// Printed the truth written about the well (`−3356 x − 7.51 v − 2.42e6 x² − 3.88e8 x³ + 3.85
/// cos`) where the model about the wells' midpoint, with two terms fewer, predicted the
/// held-out half within 1.1 % of it (z = −1.5).
#[test]
fn a_double_well_seen_in_one_well_is_written_about_its_middle() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "well.csv",
        &[
            "--wells",
            "bistable",
            "--mass",
            "0.02314",
            "--k1",
            "39.25",
            "--k3",
            "8988000.0",
            "--zeta",
            "0.09515",
            "--omega",
            "44.61",
            "--amplitude",
            "3.816",
            "--rate",
            "565.6",
            "--t-end",
            "1.45",
            "--x0",
            "0.0002312",
            "--observe",
            "xv",
            "--delta",
            "0.02",
            "--seed",
            "22738",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    assert_true_model(&out.unwrap(), &truth(&path));
}

/// Hostile-system 10558: a piezo harvester forced by a tone (no u), x, v and V at 2 % noise,
/// 4.8 s. Printed χ = 0.0203 ± 0.0012 (truth 0.0157, 3.7 of its ± off): Ω estimated 2·10⁻⁵
/// off, and the forcing's phase drift, far larger than the coupling's reaction on the
/// motion, was taken up by χ. Ω is now refined with the coefficients.
#[test]
fn a_harvesters_coupling_is_not_moved_by_the_forcings_phase_drift() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "piezo.csv",
        &[
            "piezo",
            "--wells",
            "monostable",
            "--amplitude",
            "4.34",
            "--omega",
            "47.55",
            "--rate",
            "1040",
            "--t-end",
            "4.79",
            "--delta",
            "0.02",
            "--observe",
            "xv",
            "--seed",
            "10558",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let printed = equations(&out.unwrap());
    let want = equations(&truth(&path));
    let (chi, se) = printed["x''"]["V"];
    let truth_chi = want["x''"]["V"].0;
    assert!(
        (chi - truth_chi).abs() <= (2.0 * se).max(0.1 * truth_chi.abs()),
        "χ printed {chi} ± {se}, truth {truth_chi}"
    );
}

/// `lssi gen electromagnetic --electrical i --coil inductive --wells bistable --delta 0.01
/// --seed 1` (twenty-third session): a coil's current in a chaotic double well. Withheld
/// before: the streaming i' kept six terms of the equation error (x, x³, x²·v, x·v², sin,
/// cos), backward elimination dropped one at a time and at most three, and x in i' counted
/// as a harvester's linear term; the refined model, near the truth, lost to the streaming one
/// on the held-out half because one of 39 segments started near the saddle and was fitted
/// into the other well (73.8 % against 1.07 % on the others). Now every term under one
/// standard error goes at once, x in an electrical equation can go, and such an outlier
/// segment is left out of the held-out measure.
#[test]
fn a_coils_current_in_a_chaotic_double_well_gives_its_two_equations() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "coil.csv",
        &[
            "electromagnetic",
            "--electrical",
            "i",
            "--coil",
            "inductive",
            "--wells",
            "bistable",
            "--delta",
            "0.01",
            "--seed",
            "1",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let printed = equations(&out.unwrap());
    let want = equations(&truth(&path));
    assert_eq!(
        printed.keys().collect::<Vec<_>>(),
        want.keys().collect::<Vec<_>>()
    );
    for (target, terms) in &want {
        let got = &printed[target];
        assert_eq!(
            got.keys().collect::<Vec<_>>(),
            terms.keys().collect::<Vec<_>>(),
            "{target}: printed {got:?}, truth {terms:?}"
        );
        for (name, (w, _)) in terms {
            let bar = if name == "v" && target == "x''" {
                0.25
            } else {
                0.10
            };
            let (c, _) = got[name];
            assert!(
                ((c - w) / w).abs() <= bar,
                "{target}'s {name}: printed {c}, truth {w}"
            );
        }
    }
}
