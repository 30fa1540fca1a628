//! "Never a confident wrong model": the excitation's fundamental, not a harmonic, is taken for
//! Ω; and the quality gate withholds (exit status 3, one sentence naming the check) a model of
//! a constant x, of a chirp or white noise (its simulation cannot follow the recording over
//! two periods), and of a pure sine (its terms are collinear), while the harvester and paper
//! recordings, at 0.5–10 % noise and several seeds, still pass. Every recording is written
//! here, into a temporary directory, or by `lssi gen`.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

use crate::common::generate;
use crate::quality::Gauss;

/// A recording of `n` samples at `rate` Hz, x(t) given (shortest round-trip decimals).
fn write(dir: &Path, name: &str, n: usize, rate: f64, mut x: impl FnMut(f64) -> f64) -> PathBuf {
    let path = dir.join(name);
    let mut text = String::from("t,x\n");
    for i in 0..n {
        let t = i as f64 / rate;
        text.push_str(&format!("{t:?},{:?}\n", x(t)));
    }
    std::fs::write(&path, text).unwrap();
    path
}

/// `lssi identify --no-refine --json FILE` (the gate runs before refinement).
fn identify(path: &Path) -> Output {
    Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .args(["--no-refine", "--json"])
        .output()
        .unwrap()
}

/// The estimated Ω of a recording that passes the gate.
fn omega(path: &Path) -> f64 {
    let out = identify(path);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{}: {stderr}", path.display());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["omega_estimated"], true);
    json["omega"].as_f64().unwrap()
}

/// `path` is withheld (exit 3) with one sentence that contains `reason`; no model printed.
fn assert_withheld(path: &Path, reason: &str) {
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}: {stdout}{stderr}",
        path.display()
    );
    assert!(!stdout.contains("x'' ="), "{stdout}");
    assert!(
        stderr.contains("no deterministic dynamics found in") && stderr.contains(reason),
        "expected {reason:?}: {stderr}"
    );
}

#[test]
fn omega_is_the_fundamental_not_its_third_harmonic() {
    // A strongly driven double well: x'' has stronger lines near 3Ω than at Ω (was 65.47).
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), "strong.csv", &["eveh", "--amplitude", "5"]);
    let w = omega(&path);
    assert!((w - 21.4).abs() < 0.01, "Ω = {w}");
}

#[test]
fn omega_below_the_natural_frequency_is_the_fundamental() {
    // A single well driven at 10 rad/s (its linear resonance is 18.3 rad/s): x'' is strongest
    // near 4Ω (was 39.86).
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "slow.csv",
        &["eveh", "--wells", "monostable", "--omega", "10"],
    );
    let w = omega(&path);
    assert!((w - 10.0).abs() < 0.01, "Ω = {w}");
}

#[test]
fn omega_on_a_short_finely_sampled_record() {
    // 3 s at 50 kHz: ten periods, and the spectral peak most of a resolution width off the
    // line (was 21.27).
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "short.csv",
        &[
            "eveh",
            "--wells",
            "monostable",
            "--rate",
            "50000",
            "--t-end",
            "3",
        ],
    );
    let w = omega(&path);
    assert!((w - 21.4).abs() < 0.02, "Ω = {w}");
}

#[test]
fn omega_on_three_periods() {
    // The first second of data/eveh-monostable.csv: x'' shows 2Ω and 3Ω, no peak at Ω (was
    // 63.55).
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/eveh-monostable.csv");
    let text = std::fs::read_to_string(data).unwrap();
    let mut head = String::new();
    for (i, line) in text.lines().enumerate() {
        if i > 0 && line.split(',').next().unwrap().parse::<f64>().unwrap() > 1.0 {
            break;
        }
        head.push_str(line);
        head.push('\n');
    }
    let path = dir.path().join("first-second.csv");
    std::fs::write(&path, head).unwrap();
    let w = omega(&path);
    assert!((w - 21.4).abs() < 0.1, "Ω = {w}");
}

#[test]
fn a_constant_x_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let flat = write(dir.path(), "flat.csv", 40_001, 2000.0, |_| 0.003);
    assert_withheld(&flat, "x is constant");
    let mut g = Gauss(7);
    let nearly = write(dir.path(), "nearly.csv", 40_001, 2000.0, |_| {
        0.003 + 1e-12 * g.next()
    });
    assert_withheld(&nearly, "x is nearly constant");
}

#[test]
fn a_chirp_and_white_noise_are_withheld_for_their_simulation() {
    let dir = tempfile::tempdir().unwrap();
    // 1 → 10 Hz over 20 s, no dynamics.
    let chirp = write(dir.path(), "chirp.csv", 40_001, 2000.0, |t| {
        1e-3 * (2.0 * std::f64::consts::PI * (t + 0.5 * 9.0 / 20.0 * t * t)).sin()
    });
    // A chirp is a swept forcing with no u column: named as such (tests/it/sweep.rs).
    assert_withheld(&chirp, "the forcing sweeps in frequency (a chirp)");
    let mut g = Gauss(11);
    let noise = write(dir.path(), "noise.csv", 40_001, 2000.0, |_| 1e-3 * g.next());
    assert_withheld(&noise, "the model's simulation cannot follow the recording");
}

#[test]
fn a_pure_sine_is_not_given_collinear_terms() {
    // x'' = −ω² x and x'' = −ω²A sin(ωt) explain it equally: was
    // (−2581 ± 32) x + (1.949 ± 0.032) sin(25.13t).
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gauss(3);
    let sine = write(dir.path(), "sine.csv", 20_001, 2000.0, |t| {
        1e-3 * (2.0 * std::f64::consts::PI * 4.0 * t).sin() + 1e-5 * g.next()
    });
    // Ω estimated: the noise decides whether sin(Ωt) is taken beside x; both are never
    // printed (x alone, the free oscillation, is a model of it).
    let out = identify(&sine);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() == Some(3) {
        assert!(
            stderr.contains("are collinear on this recording"),
            "{stderr}"
        );
    } else {
        assert_eq!(out.status.code(), Some(0), "{stderr}");
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let names: Vec<&str> = json["terms"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["term"].as_str().unwrap())
            .collect();
        let wave = names
            .iter()
            .any(|n| n.starts_with("sin(") || n.starts_with("cos("));
        assert!(!(names.contains(&"x") && wave), "{names:?}");
    }
    // Ω given: x and sin(Ωt) both taken, and withheld.
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(&sine)
        .args(["--omega", "25.132741228718345"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains("x, sin(25.1327t) are collinear"),
        "{stderr}"
    );
}

#[test]
fn collinear_excitation_terms_alone_are_not_withheld() {
    // A measured u that is the forcing 0.98 cos(21.4t): cos(21.4t) and u may share the
    // excitation, the dynamics are as they are.
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), "input.csv", &["eveh", "--input"]);
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(&path)
        .args(["--no-refine", "--poly-order", "5", "--harmonics", "5"])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn harvester_and_paper_recordings_still_pass() {
    let dir = tempfile::tempdir().unwrap();
    let mut paths = Vec::new();
    for seed in ["1", "2", "3"] {
        for delta in ["0.005", "0.1"] {
            for wells in ["bistable", "monostable"] {
                let name = format!("eveh-{wells}-{delta}-{seed}.csv");
                paths.push(generate(
                    dir.path(),
                    &name,
                    &["eveh", "--wells", wells, "--delta", delta, "--seed", seed],
                ));
            }
            let name = format!("paper-{delta}-{seed}.csv");
            paths.push(generate(
                dir.path(),
                &name,
                &["paper", "--delta", delta, "--seed", seed],
            ));
        }
    }
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data");
    for name in [
        "eveh-bistable",
        "eveh-drift",
        "eveh-monostable",
        "paper-eq17",
    ] {
        paths.push(data.join(format!("{name}.csv")));
    }
    for path in &paths {
        let mut out = identify(path);
        // At 10 % noise the streaming selection can lose the damping: --no-refine withholds
        // that driven model without damping (issue 25), and refinement brings it back, so
        // the recording passes as `lssi identify` runs by default.
        if out.status.code() == Some(3)
            && String::from_utf8_lossy(&out.stderr).contains("no term odd in v, no damping")
        {
            out = Command::new(LSSI)
                .arg("identify")
                .arg(path)
                .arg("--json")
                .output()
                .unwrap();
        }
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// A refined model printed with a term its ± does not resolve from 0 is withheld, naming the
/// term (issue 25: a bistable harvester hopping between its wells at 5 % noise, 483 Hz, 16 s,
/// printed `x*v^2 = 1662 ± 2190` beside the true terms; scripts/hostile-eveh.sh seed 9116):
/// since held-out windows stuck in a local minimum are fitted again, backward elimination
/// drops that x·v² and the true model is printed, which is the other right outcome.
#[test]
fn a_printed_term_its_standard_error_does_not_resolve_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "hop.csv",
        &[
            "eveh",
            "--wells",
            "bistable",
            "--amplitude",
            "2.3",
            "--rate",
            "483",
            "--t-end",
            "16",
            "--delta",
            "0.05",
            "--seed",
            "9116",
        ],
    );
    let (code, terms, stderr) = identify_terms(&path);
    if code == Some(0) {
        assert_true_model(&path);
    } else {
        assert!(terms.is_empty(), "{terms:?}");
        assert_withheld(&path, "is not resolved by the record: twice its ± covers 0");
        assert!(stderr.contains("x*v^2"), "{stderr}");
    }
}

/// A weak damping the streaming selection took as v³ (a steady oscillation's v³ is ¾ A² v: the
/// held-out half cannot tell them apart) is printed as v, the support of lower degree reached by
/// backward elimination from the model with v added (issue 25: scripts/hostile-eveh.sh seed
/// 9239, a single well at F = 2.53, 979 Hz, 26.6 s, 3 % noise, printed `- 97.801 v^3`).
#[test]
fn a_damping_the_record_cannot_tell_from_v_cubed_is_printed_as_v() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "weak.csv",
        &[
            "eveh",
            "--wells",
            "monostable",
            "--amplitude",
            "2.53",
            "--rate",
            "979",
            "--t-end",
            "26.6",
            "--delta",
            "0.03",
            "--seed",
            "9239",
        ],
    );
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(&path)
        .arg("--json")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let terms: Vec<(String, f64)> = json["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["term"].as_str().unwrap().to_owned(),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    let names: Vec<&str> = terms.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names[..3], ["x", "v", "x^3"], "{terms:?}");
    assert_eq!(names.len(), 4, "{terms:?}");
    let v = terms[1].1;
    assert!((v / -0.4036 - 1.0).abs() < 0.25, "damping {v}");
}

/// `lssi identify --json FILE`: the exit status and the printed terms (name, coefficient).
fn identify_terms(path: &Path) -> (Option<i32>, Vec<(String, f64)>, String) {
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .arg("--json")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let terms = serde_json::from_slice::<serde_json::Value>(&out.stdout)
        .ok()
        .and_then(|json| json["terms"].as_array().cloned())
        .unwrap_or_default()
        .iter()
        .map(|t| {
            (
                t["term"].as_str().unwrap().to_owned(),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    (out.status.code(), terms, stderr)
}

/// The printed model is the truth of `lssi gen eveh` at `path` (its JSON beside): its terms
/// and no others, coefficients within 10 %, the damping within 25 %.
fn assert_true_model(path: &Path) {
    let (code, terms, stderr) = identify_terms(path);
    assert_eq!(code, Some(0), "{stderr}");
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path.with_extension("json")).unwrap())
            .unwrap();
    let key = |name: &str| name.split('(').next().unwrap().to_owned();
    let want: Vec<(String, f64)> = truth["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                key(t["term"].as_str().unwrap()),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(terms.len(), want.len(), "{terms:?} against {want:?}");
    for (name, w) in &want {
        let (_, got) = terms
            .iter()
            .find(|(n, _)| key(n) == *name)
            .unwrap_or_else(|| panic!("{name} missing from {terms:?}"));
        let allowed = if name == "v" { 0.25 } else { 0.10 };
        assert!(
            (got / w - 1.0).abs() <= allowed,
            "{name}: {got} against {w} ({terms:?})"
        );
    }
}

/// Refinement's held-out windows, each from its fitted state: a state fitted from the samples'
/// guess landed in a local minimum in 7 of 12 windows for the near-true refined models of a
/// single well driven hard (none for the streaming model), which then "predicted better" and
/// was printed with x 36 % off and a spurious x², v², x·v² (issue 25: scripts/hostile-eveh.sh
/// seed 9330, F = 2.91 at 238 Hz, 14.4 s, 1 % noise). Such windows are fitted again from the
/// previous window carried on and from their first quarter: the true model.
#[test]
fn held_out_windows_in_a_local_minimum_do_not_pick_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "hard.csv",
        &[
            "eveh",
            "--wells",
            "monostable",
            "--amplitude",
            "2.91",
            "--rate",
            "238",
            "--t-end",
            "14.4",
            "--delta",
            "0.01",
            "--seed",
            "9330",
        ],
    );
    assert_true_model(&path);
}

/// A damping the streaming selection took as v³ at 5 % noise on a slow double well: v is
/// printed when the prediction does not separate it from v³ (scripts/hostile-eveh.sh seed
/// 9213, F = 0.51 at 186 Hz, 19.4 s: printed `- 251.67 v^3`), and the model is withheld, naming
/// both, when v and v³ refined together resolve neither and v predicts a little worse (seed
/// 9325, F = 0.632 at 222 Hz, 6.39 s: printed `- 200.38 v^3`).
#[test]
fn a_damping_the_record_cannot_tell_from_v_cubed_is_not_printed_as_v_cubed() {
    let dir = tempfile::tempdir().unwrap();
    let args = |f: &'static str, rate: &'static str, t: &'static str, seed: &'static str| {
        [
            "eveh",
            "--wells",
            "bistable",
            "--amplitude",
            f,
            "--rate",
            rate,
            "--t-end",
            t,
            "--delta",
            "0.05",
            "--seed",
            seed,
        ]
    };
    let slow = generate(dir.path(), "slow.csv", &args("0.51", "186", "19.4", "9213"));
    assert_true_model(&slow);
    let short = generate(
        dir.path(),
        "short.csv",
        &args("0.632", "222", "6.39", "9325"),
    );
    let (code, terms, stderr) = identify_terms(&short);
    assert!(
        !terms.iter().any(|(n, _)| n == "v^3"),
        "exit {code:?}: {terms:?}"
    );
    if code == Some(3) {
        assert!(
            stderr.contains("cannot tell the model's damping from a linear one")
                && stderr.contains("v^3 at"),
            "{stderr}"
        );
    } else {
        // Or the truth's terms with a damping the record resolves poorly, said by its ±
        // (since the 0.5 % parsimony margin: v −0.256 ± 0.117, truth −0.404): each
        // coefficient within the bars or within two of its printed standard errors.
        let out = Command::new(LSSI)
            .arg("identify")
            .arg(&short)
            .arg("--json")
            .output()
            .unwrap();
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let truth: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(short.with_extension("json")).unwrap())
                .unwrap();
        let key = |t: &serde_json::Value| {
            let name = t["term"].as_str().unwrap();
            name.split('(').next().unwrap().to_owned()
        };
        let got = json["terms"].as_array().unwrap();
        let want = truth["terms"].as_array().unwrap();
        assert_eq!(got.len(), want.len(), "{json}");
        for w in want {
            let g = got.iter().find(|g| key(g) == key(w)).unwrap();
            let (c, t) = (g["coef"].as_f64().unwrap(), w["coef"].as_f64().unwrap());
            let se = g["se"].as_f64().unwrap_or(0.0);
            let bar = if key(w) == "v" { 0.25 } else { 0.10 };
            assert!(
                (c / t - 1.0).abs() <= bar || (c - t).abs() <= 2.0 * se,
                "{}: {c} ± {se} against {t}",
                key(w)
            );
        }
    }
}

/// The printed model's held-out prediction over all refinement's windows is judged against
/// the noise in x: a near-true refined model of a single well at 1 % noise passes, and the
/// same check with its prediction at 47 % (what the streaming model printed in issue 25
/// had) withholds it with one sentence naming the NRMSE.
#[test]
fn a_printed_model_that_misses_the_held_out_half_is_withheld() {
    use lssi_host::identify::{self, Options, quality, refine};
    use lssi_host::synth::eveh::{EvehOptions, Wells, generate_eveh};
    let options = EvehOptions {
        wells: Wells::Monostable,
        amplitude: 2.91,
        rate: 238.0,
        t_end: 14.4,
        delta: 0.01,
        seed: 9330,
        ..EvehOptions::default()
    };
    let recording = generate_eveh(&options).to_recording("hard".to_owned());
    let id_options = Options {
        f32: true,
        ..Options::default()
    };
    let report = identify::identify_recording(&recording, &id_options).unwrap();
    let check = refine::refine_recording(&recording, &report);
    let fit = check.prediction.unwrap();
    assert!(fit.nrmse_percent < 5.0, "{}", check.reason);
    assert_eq!(quality::prediction_misses(&recording, &check), None);
    let missing = refine::Check {
        prediction: Some(refine::Fit {
            nrmse_percent: 47.0,
            rms: fit.rms * 47.0 / fit.nrmse_percent,
        }),
        ..check
    };
    let why = quality::prediction_misses(&recording, &missing).unwrap();
    assert!(why.contains("NRMSE of 47 %"), "{why}");
}

/// A driven model without damping (no term in v) is withheld, naming the lost damping: a
/// harvester dissipates, and the selection lost the damping at 5 % noise on a short record
/// at 278 Hz (issue 25: scripts/hostile-eveh.sh seed 9728, printed
/// `x'' = 334.1 x − 7.916e8 x^3 + 2.061 cos(21.4t)`). Or the true model, with its damping.
#[test]
fn a_driven_model_without_damping_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "lost.csv",
        &[
            "eveh",
            "--wells",
            "bistable",
            "--amplitude",
            "2.07",
            "--rate",
            "278",
            "--t-end",
            "8.11",
            "--delta",
            "0.05",
            "--seed",
            "9728",
        ],
    );
    let (code, terms, _) = identify_terms(&path);
    if code == Some(0) {
        assert_true_model(&path);
    } else {
        assert!(terms.is_empty(), "{terms:?}");
        assert_withheld(
            &path,
            "the model is driven but has no term odd in v, no damping",
        );
    }
}
