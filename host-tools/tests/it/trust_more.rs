//! The single equation's last confident wrong models on `scripts/hostile-more.sh` (issue 25),
//! each as a user meets it (`lssi identify --json FILE`): the true model, or withheld (exit 3)
//! with the check that failed named; and a random excitation without u named as such, not as
//! a chirp.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::Path;

use crate::common::{Normal, gen_eveh, identify_json, rk4_step, terms, truth};

/// Exit 0 with the truth's terms (coefficients within 10 %, the damping within 25 %, or
/// within two of their printed standard errors: "true" and "true within ±" as
/// `scripts/hostile-more.sh` judges), or exit 3 whose sentence holds `reason`.
fn true_or_withheld(path: &Path, reason: &str) -> bool {
    let (code, out) = identify_json(path, &[]);
    match out {
        Ok(json) => {
            let want = terms(&truth(path));
            let got = terms(&json);
            let se: Vec<f64> = json["terms"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| t["se"].as_f64().unwrap_or(0.0))
                .collect();
            assert!(
                got.len() == want.len()
                    && want
                        .iter()
                        .all(|(k, w)| got.iter().zip(&se).any(|((g, c), se)| g == k
                            && (c - w).abs()
                                <= (2.0 * se).max(if k == "v" { 0.25 } else { 0.10 } * w.abs()))),
                "{}: printed {got:?}, truth {want:?}",
                path.display()
            );
            false
        }
        Err(err) => {
            assert_eq!(code, 3, "{err}");
            assert!(err.contains(reason), "{err}");
            true
        }
    }
}

/// hostile-more seed 20212: a stiff single well (ζ 0.086) driven at 0.6 of its linear
/// resonance, 10 samples a forcing period, 62 periods, x and v at 0.2 % noise. Its steady
/// orbit was printed as a linear oscillator (stiffness 3.4 times k₁, no x³) with tight ±,
/// predicting the held-out half 18 times worse than the harmonics of Ω fit it.
#[test]
fn a_steady_orbit_the_model_misses_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let mut withheld = 0;
    for seed in ["20212", "1", "2"] {
        let path = gen_eveh(
            dir.path(),
            &format!("orbit{seed}.csv"),
            &[
                "--wells",
                "monostable",
                "--mass",
                "0.003481",
                "--k1",
                "91.89",
                "--k3",
                "5425000000",
                "--zeta",
                "0.08609",
                "--omega",
                "101.5",
                "--amplitude",
                "1.912",
                "--rate",
                "167.2",
                "--t-end",
                "3.866",
                "--x0",
                "0.0002402",
                "--observe",
                "xv",
                "--delta",
                "0.002",
                "--seed",
                seed,
            ],
        );
        let (code, out) = identify_json(&path, &[]);
        let periodic = out
            .as_ref()
            .is_err_and(|e| e.contains("repeats the forcing's period"));
        withheld += usize::from(periodic);
        true_or_withheld(
            &path,
            if code == 0 {
                ""
            } else {
                "no deterministic dynamics found"
            },
        );
    }
    assert!(withheld >= 1, "no draw was withheld by the periodic floor");
}

/// hostile-more seed 20024: a single well driven by a measured u at 2.4 times its resonance,
/// 10 samples a period, x at 5 % noise. Its steady orbit was printed without x³ and with the
/// stiffness 1.8 times k₁ and a forcing gain 0.88 (tight ±), predicting the held-out half
/// 1.9 times worse than the harmonics of u's tone fit it; seed 1's draw was printed with a
/// positive x³ of 5.2e10 at ± 8 %, which the ± widened to the move from the first half's
/// refinement shows unresolved.
#[test]
fn a_steady_orbit_driven_by_a_measured_tone_is_true_or_withheld() {
    let dir = tempfile::tempdir().unwrap();
    for seed in ["20024", "1"] {
        let path = gen_eveh(
            dir.path(),
            &format!("tone{seed}.csv"),
            &[
                "--wells",
                "monostable",
                "--mass",
                "0.002785",
                "--k1",
                "14.15",
                "--k3",
                "7843000",
                "--zeta",
                "0.02391",
                "--omega",
                "170.9",
                "--amplitude",
                "18.85",
                "--rate",
                "275.5",
                "--t-end",
                "16",
                "--x0",
                "0.0006759",
                "--observe",
                "x",
                "--delta",
                "0.05",
                "--input",
                "--seed",
                seed,
            ],
        );
        true_or_withheld(&path, "no deterministic dynamics found");
    }
}

/// At 125 Hz (data/eveh-bistable.csv, every 16th sample: 37 samples a forcing period) the
/// refined damping's ± was a third of its error (± 0.10 % for 0.35 %): refinement's ± is
/// the noise's alone. Widened to the move from the first half's refinement, every printed
/// coefficient lies within two of its ± of the truth.
#[test]
fn a_refined_coefficient_lies_within_two_of_its_standard_errors_at_125_hz() {
    let dir = tempfile::tempdir().unwrap();
    let root = format!("{}/../data/eveh-bistable", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}.csv")).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for line in lines.step_by(16) {
        out.push_str(line);
        out.push('\n');
    }
    let path = dir.path().join("d16.csv");
    std::fs::write(&path, out).unwrap();
    let (code, json) = identify_json(&path, &[]);
    let json = json.unwrap_or_else(|e| panic!("exit {code}: {e}"));
    let want = terms(
        &serde_json::from_str(&std::fs::read_to_string(format!("{root}.json")).unwrap()).unwrap(),
    );
    for t in json["terms"].as_array().unwrap() {
        let name = t["term"].as_str().unwrap();
        let kind = name.split('(').next().unwrap();
        let (c, se) = (t["coef"].as_f64().unwrap(), t["se"].as_f64().unwrap());
        let w = want.iter().find(|(k, _)| k == kind).unwrap().1;
        assert!((c - w).abs() <= 2.0 * se, "{name}: {c} ± {se}, truth {w}");
    }
}

/// A bistable beam (336.6 x − 0.4 v − 7.955e8 x³) under white base acceleration of RMS 20
/// m/s² held over each 1 ms row, 10 s at 1 kHz from x = 6.5e-4, x with 0.5 % noise: the CSV
/// (t, x), no u.
fn random_beam(path: &Path, seed: u64) {
    let mut rng = Normal(seed);
    let n = 10_001;
    let force: Vec<f64> = (0..n).map(|_| 20.0 * rng.next()).collect();
    let acc = |x: f64, v: f64, f: f64| 336.6 * x - 0.4 * v - 7.955e8 * x.powi(3) + f;
    let h = 2.5e-4;
    let (mut x, mut v) = (6.5e-4, 0.0);
    let mut xs = Vec::with_capacity(n);
    for &f in &force {
        xs.push(x);
        for _ in 0..4 {
            (x, v) = rk4_step(|x, v, _| acc(x, v, f), x, v, 0.0, h);
        }
    }
    let mean = xs.iter().sum::<f64>() / n as f64;
    let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    let mut text = String::from("t,x\n");
    for (i, x) in xs.iter().enumerate() {
        text.push_str(&format!(
            "{},{}\n",
            i as f64 / 1000.0,
            x + 0.005 * sd * rng.next()
        ));
    }
    std::fs::write(path, text).unwrap();
}

/// A random excitation without u is withheld and not named a sweep: the sweep detector's
/// dechirping found, on 7 of 8 draws of such a beam (numpy's generator), a line 1.2–2.2
/// times stronger than the record's own and called the record a chirp; that line held
/// 0.06–0.18 of x's variance, a sweep's 0.47–0.96. One draw, no longer called a chirp, was
/// then printed as `x'' = −7.88e8 x^3` with exit 0.
#[test]
fn a_random_excitation_without_u_is_not_named_a_chirp() {
    let dir = tempfile::tempdir().unwrap();
    for seed in 2..6 {
        let path = dir.path().join(format!("random{seed}.csv"));
        random_beam(&path, seed);
        let (code, out) = identify_json(&path, &[]);
        let err = out
            .err()
            .unwrap_or_else(|| panic!("seed {seed}: a model, exit {code}"));
        assert_eq!(code, 3, "seed {seed}: {err}");
        assert!(
            !err.contains("chirp") && err.contains("random or broadband"),
            "seed {seed}: {err}"
        );
    }
}
