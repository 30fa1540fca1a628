//! Never a confident wrong model (issue 25), from sets nobody tuned on: a printed term must be
//! resolved at two standard errors (`scripts/hostile-more.sh` seeds 20407 and 20431), a term
//! the selection picked out of the library must clear a bar that counts the library (seed
//! 20741), and a system's coupling must be a passive transducer's
//! (`scripts/hostile-system.sh` seed 10126). Each printed a wrong model with exit 0 before.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use crate::common::{gen_eveh, generate, identify_json, terms};

/// Exit 3 and the sentence, or the test fails with what was printed instead.
fn assert_withheld(path: &std::path::Path, says: &str) {
    let (code, out) = identify_json(path, &[]);
    assert_eq!(code, 3, "{}: {out:?}", path.display());
    let err = out.unwrap_err();
    assert!(err.contains(says), "{err}");
}

/// A bistable harvester with ζ 0.083 at 19 samples a forcing period, 2 % noise, 0.49 s: the
/// refined model carried x·v² at −1.76e4 ± 1.20e4 (1.5 standard errors, spurious) beside the
/// truth's terms, and was printed: one standard error was the bar.
#[test]
fn a_refined_term_within_two_standard_errors_withholds_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "a.csv",
        &[
            "--wells",
            "bistable",
            "--mass",
            "0.07919",
            "--k1",
            "3565",
            "--k3",
            "1.634e10",
            "--zeta",
            "0.0826",
            "--omega",
            "197.9",
            "--amplitude",
            "37.89",
            "--rate",
            "3714",
            "--t-end",
            "0.4915",
            "--x0",
            "0.0003345",
            "--observe",
            "x",
            "--delta",
            "0.02",
            "--seed",
            "20431",
        ],
    );
    assert_withheld(&path, "twice its ± covers 0");
}

/// The same harvester's kind at 14 samples a period, 353 samples in all: the streaming model
/// kept, its x²·v (spurious) 1.4 standard errors from 0 where its support was refined.
#[test]
fn a_kept_streaming_term_within_two_standard_errors_withholds_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "b.csv",
        &[
            "--wells",
            "bistable",
            "--mass",
            "0.06125",
            "--k1",
            "1167",
            "--k3",
            "8.071e9",
            "--zeta",
            "0.04828",
            "--omega",
            "360",
            "--amplitude",
            "12.03",
            "--rate",
            "823.2",
            "--t-end",
            "0.4281",
            "--x0",
            "0.0001194",
            "--observe",
            "x",
            "--delta",
            "0.01",
            "--seed",
            "20407",
        ],
    );
    assert_withheld(
        &path,
        "the printed model is the streaming identifier's, and its term",
    );
}

/// A bistable electromagnetic harvester with an inductive coil (i recorded, τ = 5 ms), 0 %
/// noise: printed x'' = … − 2.50 v + 243.5 i with i' = 0.5 v − 200 i (truth −1.26 v − 250 i):
/// the coupling's pair of one sign, a beam fed by its circuit. Withheld for it since; with Ω
/// refined beside the coefficients (twenty-second session) the refinement reaches the truth
/// itself (a negligible x·v² at 4·10⁻⁹ of x'' dropped), and that is what is printed.
#[test]
fn a_coupling_that_fed_the_beam_is_refined_to_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "c.csv",
        &[
            "electromagnetic",
            "--wells",
            "bistable",
            "--amplitude",
            "0.672",
            "--omega",
            "49.51",
            "--rate",
            "3720",
            "--t-end",
            "10.7",
            "--delta",
            "0",
            "--observe",
            "x",
            "--seed",
            "10126",
            "--electrical",
            "i",
            "--coil",
            "inductive",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let out = out.unwrap();
    let printed = crate::common::equations(&out);
    let want = crate::common::equations(&crate::common::truth(&path));
    for (target, terms) in &want {
        let got = &printed[target];
        let names = |t: &crate::common::Terms| t.keys().cloned().collect::<Vec<_>>();
        assert_eq!(names(got), names(terms), "{target}: {out}");
        for (name, (w, _)) in terms {
            let c = got[name].0;
            assert!(
                ((c - w) / w).abs() < 1e-3,
                "{target} {name}: {c} against {w}"
            );
        }
    }
}

/// A hard-driven single well (x and u each at 5 % noise, 79 samples a forcing period, 105
/// s): the refined support with a spurious x² and v² (at an origin 5·10⁻⁴ off) predicted the
/// held-out half 0.33 % better than the truth's support and was printed, each term 4 and 2.7
/// standard errors from 0 (`scripts/hostile-more.sh` seed 20448). Two terms must buy more
/// than that (0.5 %): the truth's terms are printed.
#[test]
fn two_terms_for_a_third_of_a_percent_are_not_taken() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "p.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.1184",
            "--k1",
            "212.7",
            "--k3",
            "141000000",
            "--zeta",
            "0.02287",
            "--omega",
            "55.2",
            "--amplitude",
            "15.3",
            "--rate",
            "691.5",
            "--t-end",
            "104.7",
            "--x0",
            "0.002285",
            "--observe",
            "x",
            "--delta",
            "0.05",
            "--seed",
            "20448",
            "--full-scale",
            "0.005",
            "--input",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let json = out.unwrap();
    let names: Vec<String> = terms(&json).into_iter().map(|(n, _)| n).collect();
    assert_eq!(names, ["x", "v", "x^3", "u"], "{json}");
}

/// A light single well ringing down at its own frequency under a weak forcing, 30 periods at 20
/// samples a period (12-bit, 1 %): Ω came out at the ringing's 24.8 rad/s (the forcing's is
/// 31.8) and `−5.65e7 x³ − 9966 x·v² + 0.05 cos(24.8t)` was printed: x·v² counted as damping.
/// Dissipation is odd in v; the model is withheld as driven and undamped
/// (`scripts/hostile-more.sh` seed 20500).
#[test]
fn a_term_even_in_v_is_not_a_damping() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "r.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.00525",
            "--k1",
            "2.208",
            "--k3",
            "241600",
            "--zeta",
            "0.01984",
            "--omega",
            "31.83",
            "--amplitude",
            "0.8386",
            "--rate",
            "103.1",
            "--t-end",
            "6.05",
            "--x0",
            "0.004662",
            "--observe",
            "x",
            "--delta",
            "0.01",
            "--adc-bits",
            "12",
            "--full-scale",
            "0.008847783704878901",
            "--seed",
            "20500",
        ],
    );
    assert_withheld(&path, "no term odd in v, no damping");
}

/// A monostable harvester driven through a measured u, 5 % noise, 12 bits, 9.3 forcing
/// periods (2,089 samples): the streaming support had v and v³, refined together at 0.2 and
/// 0.3 standard errors; backward elimination dropped v, and v³ was printed in place of the
/// truth's v (`scripts/hostile-more.sh` seed 20179). Which of the two damps the record cannot
/// tell.
#[test]
fn a_cubic_damping_kept_where_v_was_dropped_beside_it_withholds_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "e.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.01873",
            "--k1",
            "185.5",
            "--k3",
            "3.205e8",
            "--zeta",
            "0.006638",
            "--omega",
            "42.91",
            "--amplitude",
            "44.74",
            "--rate",
            "1529",
            "--t-end",
            "1.366",
            "--x0",
            "0.001418",
            "--observe",
            "x",
            "--delta",
            "0.05",
            "--adc-bits",
            "12",
            "--full-scale",
            "0.003642633386536894",
            "--input",
            "--seed",
            "20179",
        ],
    );
    // Refined with u's tone (its noise left out), both dampings drop: withheld as lost.
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 3, "{out:?}");
    let err = out.unwrap_err();
    assert!(
        err.contains("cannot tell the model's damping from a linear one")
            || err.contains("no term odd in v, no damping"),
        "{err}"
    );
}

/// A lightly damped bistable harvester (ζ 0.0026) driven through a measured u, x and v
/// recorded at 1 % noise and 10 bits, 47 samples a forcing period: the noise on u drives the
/// simulation the refinement fits, and moved the damping 3 times as far as a ± from x's
/// residual alone allowed; the streaming model was kept, its damping 25 % off the truth at
/// ± 3.3 % (`scripts/hostile-more.sh` seed 20108). Printed now, every coefficient lies within
/// two of its ± of the truth, or within the hostile sets' bars (10 %, the damping 25 %): the
/// refinement drives the model by u's tone without its noise (`periodic::steady_input`), and
/// the damping moved from 25 % off (± 13 %) to 8 % off (± 3.3 %).
#[test]
fn noise_on_the_excitation_is_in_the_standard_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "f.csv",
        &[
            "--wells",
            "bistable",
            "--mass",
            "0.03751",
            "--k1",
            "24.41",
            "--k3",
            "7.755e6",
            "--zeta",
            "0.00257",
            "--omega",
            "78.34",
            "--amplitude",
            "3.229",
            "--rate",
            "582.8",
            "--t-end",
            "6.784",
            "--x0",
            "0.0009982",
            "--observe",
            "xv",
            "--delta",
            "0.01",
            "--adc-bits",
            "10",
            "--full-scale",
            "0.009584824880842472",
            "--input",
            "--seed",
            "20108",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    if code == 3 {
        return; // withheld is no wrong model
    }
    assert_eq!(code, 0, "{out:?}");
    let model = out.unwrap();
    let truth = crate::common::truth(&path);
    let want: std::collections::HashMap<String, f64> = terms(&truth).into_iter().collect();
    let got = model["terms"].as_array().unwrap();
    assert_eq!(got.len(), want.len(), "{model}");
    for t in got {
        let name = t["term"].as_str().unwrap();
        let coef = t["coef"].as_f64().unwrap();
        let se = t["se"].as_f64().unwrap_or(0.0);
        let w = *want.get(name).unwrap_or(&0.0);
        let bar = if name == "v" { 0.25 } else { 0.10 };
        assert!(
            (coef - w).abs() <= (2.0 * se).max(bar * w.abs()),
            "{name}: {coef} ± {se}, truth {w}"
        );
    }
}

/// Fresh hostile seed 20610 (a hardening single well forced at 10.83 rad/s, x and v at 5 %
/// noise, 787 s at 381 Hz): Ω was taken at the third harmonic and `0.060 v − 1.41e9 x³ −
/// 0.0069 cos(32.49t)` (a negative damping) was printed with exit 0, its free run 1032 % off
/// a record whose cycles are steady to 0.5 %. Withheld, naming the orbit and the free run.
#[test]
fn a_steady_orbit_the_free_run_misses_withholds_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "o.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.02061",
            "--k1",
            "3.791",
            "--k3",
            "33890000",
            "--zeta",
            "0.05211",
            "--omega",
            "10.83",
            "--amplitude",
            "0.06526",
            "--rate",
            "381",
            "--t-end",
            "787.4",
            "--x0",
            "0.0002329",
            "--observe",
            "xv",
            "--delta",
            "0.05",
            "--adc-bits",
            "16",
            "--full-scale",
            "0.001224398700224701",
            "--seed",
            "20610",
        ],
    );
    assert_withheld(
        &path,
        "steady to 0.48 %) but the model's free run over the held-out half misses it",
    );
}

/// Hostile seed 20741 (a light single well forced below resonance, x at 5 % noise through a
/// 10-bit ADC, u given, 24 periods): `… − (143 ± 35) v² …` was printed beside the truth's x,
/// v, x³ and u. The streaming selection had picked v² out of the library's 11 terms, and
/// refined it stood 3.3 of its standard errors from 0, over the 3σ bar of a term fixed in
/// advance, so backward elimination never tried the truth's support. A term the selection
/// picked must clear the bar Bonferroni gives for 11 candidates (3.67σ): v² is dropped, and
/// the sparser support predicts the held-out half as well.
#[test]
fn a_term_picked_from_the_library_clears_a_bar_that_counts_the_library() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "s.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.005137",
            "--k1",
            "3.604",
            "--k3",
            "116200000.0",
            "--zeta",
            "0.008555",
            "--omega",
            "11.32",
            "--amplitude",
            "0.08041",
            "--rate",
            "481.4",
            "--t-end",
            "13.27",
            "--x0",
            "0.0001913",
            "--observe",
            "x",
            "--delta",
            "0.05",
            "--adc-bits",
            "10",
            "--seed",
            "20741",
            "--full-scale",
            "0.0005478174254042974",
            "--input",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let json = out.unwrap();
    let names: Vec<String> = terms(&json).into_iter().map(|(n, _)| n).collect();
    assert_eq!(names, ["x", "v", "x^3", "u"], "{json}");
}

/// Hostile seed 20925 (a hardening single well forced hard through u, 5 % noise, a 10-bit
/// ADC, 9.3 samples a period at the top of its band): `+1491 x − 4.16e8 x³ − 2.18e4 x²·v −
/// 9.07e4 x·v² + 0.0169 u` was printed with exit 0 (truth −1029 x − 4.0 v − 2.6e8 x³ + u), a
/// double well entrained by a weak forcing. It followed the held-out half from a state fitted
/// there, but run from the state x shows at the record's start it falls into a well: the
/// harvester reached its orbit from there, so its equation does.
#[test]
fn a_model_that_does_not_reach_the_recorded_orbit_from_its_start_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "w.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.01601",
            "--k1",
            "16.47",
            "--k3",
            "4191000.0",
            "--zeta",
            "0.0625",
            "--omega",
            "25.08",
            "--amplitude",
            "3.813",
            "--rate",
            "111.0",
            "--t-end",
            "133.0",
            "--x0",
            "0.001915",
            "--observe",
            "x",
            "--delta",
            "0.05",
            "--adc-bits",
            "10",
            "--seed",
            "20925",
            "--full-scale",
            "0.005870467908575771",
            "--input",
        ],
    );
    // Refined with u's tone (its noise left out) the model reaches the orbit, but the record's
    // first half resolves v and x·v², which move its x³: withheld either way.
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 3, "{out:?}");
    let err = out.unwrap_err();
    assert!(
        err.contains("but the model's free run over the record from the state x shows at its start settles on an oscillation of RMS")
            || err.contains("the record cannot settle the model"),
        "{err}"
    );
}

/// Fresh hostile seed 21120 (a single well forced at 2.5 times its resonance, x and v at 1 %
/// noise through a 10-bit ADC, 57 periods): `(−13,431 ± 46) x − 22.4 v + 3.12 cos(284.3t)` was
/// printed with exit 0 (truth −12,930 x − 22.4 v − 7.87e10 x³ + 3.133 cos). x³ refined at
/// 13.4 standard errors on the first half (its transient), and with it x is −12,947; the
/// steady held-out half did not take it. The printed ± did not cover that, so the record
/// cannot settle the model: withheld, naming the term.
#[test]
fn a_resolved_term_that_moves_a_printed_coefficient_beyond_its_error_withholds_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "c.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.01116",
            "--k1",
            "144.3",
            "--k3",
            "877900000.0",
            "--zeta",
            "0.0987",
            "--omega",
            "284.3",
            "--amplitude",
            "3.133",
            "--rate",
            "1452.0",
            "--t-end",
            "1.268",
            "--x0",
            "4.397e-05",
            "--observe",
            "xv",
            "--delta",
            "0.01",
            "--adc-bits",
            "10",
            "--seed",
            "21120",
            "--full-scale",
            "0.0001461182290937946",
        ],
    );
    assert_withheld(&path, "the record resolves x^3 (");
}

/// A bistable beam forced hard through a measured u (52 m/s², 1 % noise on x and u, 16-bit x,
/// 15 samples a period at the top of its band), hostile 22011's harvester over 16 s (noise
/// seed 2): refined with u as recorded, its sensor noise drove the simulated beam like a
/// random force at its resonance and the fit printed
/// `1798 x − 0.72 v − 2.61e8 x³ + 4260 x·v² + 1.07 u` (truth `3240 x − 0.61 v − 2.73e8 x³ +
/// u`; x·v² at 5.8 standard errors). u is one steady tone: the refinement now drives the
/// model by its tone and harmonics.
#[test]
fn a_steady_forcings_noise_does_not_bend_the_refined_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "u.csv",
        &[
            "--wells",
            "bistable",
            "--mass",
            "0.008163",
            "--k1",
            "26.45",
            "--k3",
            "2.229e6",
            "--zeta",
            "0.005375",
            "--omega",
            "37.14",
            "--amplitude",
            "51.98",
            "--x0",
            "0.003669",
            "--observe",
            "x",
            "--input",
            "--rate",
            "441.9",
            "--delta",
            "0.01",
            "--adc-bits",
            "16",
            "--full-scale",
            "0.0148",
            "--t-end",
            "16",
            "--seed",
            "2",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let got = terms(&out.unwrap());
    let names: Vec<&str> = got.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["x", "v", "x^3", "u"]);
    for ((_, c), (t, bar)) in got.iter().zip([
        (3240.23, 0.05),
        (-0.611922, 0.25),
        (-2.73061e8, 0.05),
        (1.0, 0.05),
    ]) {
        assert!((c - t).abs() <= bar * f64::abs(t), "{got:?}");
    }
}

/// Fresh hostile seed 22110's harvester (a single well forced at 84 rad/s, 10 samples a
/// period, x and v at 0.5 %, 12 bits): the streaming model `−14391 x − 9.56 v + 2.07e9 x³ +
/// 3.39e5 x·v² − 0.69 sin + 4.19 cos(84.45t)` (truth `−1923 x − 3.43 v − 5.34e9 x³ + 5.51 cos`)
/// was printed with exit 0 although its prediction of the held-out half diverged (refinement
/// said so and left it): no prediction, no judgement. It is withheld now.
#[test]
fn a_model_whose_prediction_diverges_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "p.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.05704",
            "--k1",
            "109.7",
            "--k3",
            "304500000.0",
            "--zeta",
            "0.03916",
            "--omega",
            "84.45",
            "--amplitude",
            "5.514",
            "--rate",
            "138.7",
            "--t-end",
            "25.72",
            "--x0",
            "0.001072",
            "--observe",
            "xv",
            "--delta",
            "0.005",
            "--adc-bits",
            "12",
            "--full-scale",
            "0.00426279097000051",
            "--seed",
            "22110",
        ],
    );
    assert_withheld(
        &path,
        "the printed model's simulation diverges over the held-out half",
    );
}

/// A single well swept from 38.9 to 48.9 rad/s over 2 s, 2 % noise, no u
/// (`scripts/sweep-sets.sh random 2 60`, its first draw): the streaming model was kept and
/// printed with exit 0 as `1045 x + 0.93 v − 8.9e8 x³ − 4.9e5 x²·v − 2.7e4 x·v² − (0.056 ±
/// 0.054) cos(136.2t)`, its forcing at 1.0 of its printed standard errors: a kept model's
/// printed ± is judged as a refined model's is.
#[test]
fn a_kept_streaming_terms_printed_error_covering_zero_withholds_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "s.csv",
        &[
            "--wells",
            "monostable",
            "--excitation",
            "sweep",
            "--omega",
            "38.91",
            "--sweep-to",
            "48.91",
            "--t-end",
            "2.01",
            "--rate",
            "1000",
            "--delta",
            "0.02",
            "--amplitude",
            "2",
            "--seed",
            "1",
        ],
    );
    assert_withheld(&path, "within two of their printed standard errors");
}

/// Hostile 20925's harvester without its u column, noise seed 1: 133 s of one steady orbit
/// after half a second of transient, on which x, x³, x·v² (and v, x²·v) are nearly collinear.
/// `−1.04 v − 3.29e8 x³ − 5.2e5 x²·v − 5.6e4 x·v² + 2.40 cos(25.08t)` (truth `−1029 x − 4.0 v −
/// 2.6e8 x³ + 3.81 cos`) predicted the held-out half at the noise's level and was printed with
/// exit 0, its free run parting from the orbit by 55 %: an orbit locked to the forcing cannot
/// drift in phase, and the model that holds another is withheld.
#[test]
fn a_forced_orbit_the_free_run_parts_from_withholds_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "l.csv",
        &[
            "--wells",
            "monostable",
            "--mass",
            "0.01601",
            "--k1",
            "16.47",
            "--k3",
            "4191000.0",
            "--zeta",
            "0.0625",
            "--omega",
            "25.08",
            "--amplitude",
            "3.813",
            "--rate",
            "111.0",
            "--t-end",
            "133.0",
            "--x0",
            "0.001915",
            "--observe",
            "x",
            "--delta",
            "0.05",
            "--adc-bits",
            "10",
            "--full-scale",
            "0.005870467908575771",
            "--seed",
            "1",
        ],
    );
    assert_withheld(
        &path,
        "locked to the forcing so that its phase cannot drift",
    );
}
