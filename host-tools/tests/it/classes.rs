//! Issue 25, item 5: one property per class of recording, over many variants (amplitudes,
//! rates, lengths, noise, offsets, seeds): `lssi identify FILE` (as a user runs it, with
//! refinement) prints the true model — the truth's terms and no others, coefficients within
//! 10 % (the damping within 25 %) — or withholds it (exit 3, no model printed, one sentence
//! with its reason), never a model that is not the truth's with exit 0. Where the reason is
//! known (a sweep, a constant), the sentence must name it. The truth is `lssi gen`'s JSON
//! sidecar; records without one (a sine, noise) have no true model and must be withheld.
//!
//! The variants here are seeds 61–66 (gate-classes.sh reports 51–53; the thresholds were
//! set on 11–12).

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

/// `lssi gen eveh ARGS FILE`: the file and its truth (term → coefficient, the forcing as `cos`).
fn generate(dir: &Path, name: &str, args: &[&str]) -> (PathBuf, BTreeMap<String, f64>) {
    let path = dir.join(name);
    let out = Command::new(LSSI)
        .args(["gen", "eveh"])
        .args(args)
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "gen {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path.with_extension("json")).unwrap())
            .unwrap();
    let truth = json["terms"]
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
    (path, truth)
}

/// `cos(21.4t)` and `cos(21.3999t)` are the same term.
fn key(name: &str) -> String {
    if name.starts_with("cos(") {
        "cos".into()
    } else if name.starts_with("sin(") {
        "sin".into()
    } else {
        name.into()
    }
}

/// A `t,x` recording of `n` samples at `rate` Hz.
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

/// What `lssi identify FILE` did.
#[derive(Debug)]
enum Outcome {
    /// Exit 0 and the truth's terms within tolerance.
    True,
    /// Exit 3, no model printed, and the reason's sentence.
    Withheld(String),
    /// Anything else: what was printed.
    Wrong(String),
}

/// Runs `lssi identify --json FILE` and holds the outcome against `truth` (`None`: there is
/// no true model).
fn judge(path: &Path, truth: Option<&BTreeMap<String, f64>>) -> Outcome {
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .arg("--json")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    match out.status.code() {
        Some(0) => {
            let json: serde_json::Value = serde_json::from_str(&stdout).unwrap();
            let got: BTreeMap<String, f64> = json["terms"]
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
            let Some(truth) = truth else {
                return Outcome::Wrong(format!("a model where there is none: {got:?}"));
            };
            let keys = |m: &BTreeMap<String, f64>| m.keys().cloned().collect::<Vec<_>>();
            let close = keys(&got) == keys(truth)
                && truth.iter().all(|(k, w)| {
                    let tolerance = if k == "v" { 0.25 } else { 0.10 };
                    (got[k] / w - 1.0).abs() <= tolerance
                });
            if close {
                Outcome::True
            } else {
                Outcome::Wrong(format!("{got:?}, truth {truth:?}"))
            }
        }
        Some(3) => {
            let line = stderr.lines().last().unwrap_or("").to_owned();
            let json: serde_json::Value = serde_json::from_str(&stdout).unwrap_or_default();
            if json["withheld"] == true
                && json.get("terms").is_none()
                && line.contains("no deterministic dynamics found in")
                && line.ends_with('.')
            {
                Outcome::Withheld(line)
            } else {
                Outcome::Wrong(format!("withheld without its reason: {stdout} {stderr}"))
            }
        }
        code => Outcome::Wrong(format!("exit {code:?}: {stderr}")),
    }
}

/// Every outcome true or withheld (with `reason` in the sentence, when given); the spread
/// printed. Panics naming the wrong ones.
fn hold(class: &str, outcomes: &[(String, Outcome)], reason: Option<&str>) {
    let mut wrong = Vec::new();
    let (mut true_models, mut withheld) = (0, 0);
    for (variant, outcome) in outcomes {
        match outcome {
            Outcome::True => true_models += 1,
            Outcome::Withheld(line) => match reason {
                Some(r) if !line.contains(r) => {
                    wrong.push(format!("{variant}: withheld without naming {r:?}: {line}"))
                }
                _ => withheld += 1,
            },
            Outcome::Wrong(what) => wrong.push(format!("{variant}: {what}")),
        }
    }
    eprintln!(
        "{class}: {true_models} true, {withheld} withheld, {} wrong of {}",
        wrong.len(),
        outcomes.len()
    );
    assert!(wrong.is_empty(), "{class}:\n{}", wrong.join("\n"));
}

/// `gen eveh` harmonic variants (wells, F, rate, noise, seed) through [`judge`].
fn harmonic(variants: &[(&str, &str, &str, &str, &str)]) -> Vec<(String, Outcome)> {
    let dir = tempfile::tempdir().unwrap();
    variants
        .iter()
        .enumerate()
        .map(|(i, &(wells, amplitude, rate, delta, seed))| {
            let (path, truth) = generate(
                dir.path(),
                &format!("h{i}.csv"),
                &[
                    "--wells",
                    wells,
                    "--amplitude",
                    amplitude,
                    "--rate",
                    rate,
                    "--delta",
                    delta,
                    "--seed",
                    seed,
                ],
            );
            (
                format!("{wells} F={amplitude} {rate} Hz noise {delta} seed {seed}"),
                judge(&path, Some(&truth)),
            )
        })
        .collect()
}

#[test]
fn harmonic_and_strong_forcing_give_the_truth_or_are_withheld() {
    let outcomes = harmonic(&[
        ("monostable", "0.98", "2000", "0.005", "61"),
        ("monostable", "5", "5000", "0.005", "63"),
        ("monostable", "0.5", "1000", "0.05", "64"),
        ("bistable", "0.98", "2000", "0.02", "65"),
        ("bistable", "3", "2000", "0.02", "66"),
        ("bistable", "5", "2000", "0.005", "61"),
        ("bistable", "3", "1000", "0.05", "62"),
    ]);
    hold("harmonic", &outcomes, None);
}

/// A single well driven hard (F = 3) at 2 % noise: seeds 62 and 63 kept an x·v² of 6–7
/// standard errors while the refinement held x's origin where the streaming model put it
/// (1.5 × 10⁻⁶ off the centre, 0.1 % of the amplitude; the offset is now fitted), and seed 67
/// took x·v + v³ for the damping v (a candidate with v added is now pruned back).
#[test]
fn a_hard_driven_single_well_at_two_percent_noise() {
    let outcomes = harmonic(&[
        ("monostable", "3", "2000", "0.02", "62"),
        ("monostable", "3", "2000", "0.02", "63"),
        ("monostable", "3", "2000", "0.02", "67"),
    ]);
    hold("harmonic, F = 3 at 2 %", &outcomes, None);
}

#[test]
fn short_records_high_rates_and_ringdowns_give_the_truth_or_are_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let mut outcomes = Vec::new();
    let variants: [&[&str]; 8] = [
        // A few periods of the forcing.
        &["--t-end", "1", "--seed", "61"],
        &["--t-end", "2", "--rate", "500", "--seed", "62"],
        // Very high rates.
        &["--t-end", "3", "--rate", "50000", "--seed", "63"],
        &[
            "--t-end", "2", "--rate", "20000", "--delta", "0.02", "--seed", "64",
        ],
        // Ringdowns of 5 s: the damping found, or the model withheld for want of it.
        &[
            "--amplitude",
            "0",
            "--x0",
            "0.004",
            "--t-end",
            "5",
            "--seed",
            "65",
        ],
        &[
            "--amplitude",
            "0",
            "--x0",
            "0.004",
            "--t-end",
            "5",
            "--rate",
            "5000",
            "--delta",
            "0.05",
            "--seed",
            "66",
        ],
        &[
            "--amplitude",
            "0",
            "--x0",
            "0.004",
            "--t-end",
            "5",
            "--rate",
            "1000",
            "--delta",
            "0.05",
            "--seed",
            "61",
        ],
        &[
            "--amplitude",
            "0",
            "--x0",
            "0.004",
            "--t-end",
            "5",
            "--rate",
            "5000",
            "--delta",
            "0.02",
            "--seed",
            "62",
        ],
    ];
    for (i, args) in variants.into_iter().enumerate() {
        let mut all = vec!["--wells", "monostable"];
        all.extend_from_slice(args);
        let (path, truth) = generate(dir.path(), &format!("s{i}.csv"), &all);
        outcomes.push((args.join(" "), judge(&path, Some(&truth))));
    }
    hold("short, fast, ringdown", &outcomes, None);
}

#[test]
fn sweeps_without_u_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut outcomes = Vec::new();
    for (i, (from, to, delta, seed)) in [
        ("21.4", "50.27", "0.005", "61"),
        ("10", "30", "0.02", "62"),
        ("35", "15", "0.005", "63"),
    ]
    .into_iter()
    .enumerate()
    {
        let (path, truth) = generate(
            dir.path(),
            &format!("w{i}.csv"),
            &[
                "--wells",
                "monostable",
                "--excitation",
                "sweep",
                "--omega",
                from,
                "--sweep-to",
                to,
                "--delta",
                delta,
                "--seed",
                seed,
            ],
        );
        // A sweep is not cos(Ωt): no true model without its u column.
        let _ = truth;
        outcomes.push((
            format!("{from} -> {to} rad/s seed {seed}"),
            judge(&path, None),
        ));
    }
    hold("sweep, no u", &outcomes, Some("sweeps in frequency"));
}

#[test]
fn offsets_give_the_same_true_model() {
    let dir = tempfile::tempdir().unwrap();
    let mut outcomes = Vec::new();
    for (i, (k, seed)) in [(100.0, "61"), (1e4, "62")].into_iter().enumerate() {
        let (path, truth) = generate(
            dir.path(),
            &format!("o{i}.csv"),
            &["--wells", "monostable", "--seed", seed],
        );
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        let head = lines.next().unwrap();
        let ix = head.split(',').position(|c| c == "x").unwrap();
        let rows: Vec<Vec<String>> = lines
            .map(|l| l.split(',').map(str::to_owned).collect())
            .collect();
        let amplitude = rows
            .iter()
            .map(|r| r[ix].parse::<f64>().unwrap().abs())
            .fold(0.0, f64::max);
        let mut out = format!("{head}\n");
        for r in &rows {
            let mut r = r.clone();
            r[ix] = format!("{:?}", r[ix].parse::<f64>().unwrap() + k * amplitude);
            out.push_str(&r.join(","));
            out.push('\n');
        }
        let shifted = dir.path().join(format!("o{i}-shifted.csv"));
        std::fs::write(&shifted, out).unwrap();
        outcomes.push((
            format!("offset {k:e} x amplitude seed {seed}"),
            judge(&shifted, Some(&truth)),
        ));
    }
    hold("offset", &outcomes, None);
}

#[test]
fn no_dynamics_and_a_collinear_sine_are_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let mut outcomes = Vec::new();
    let constant = write(dir.path(), "c.csv", 20_001, 2000.0, |_| 0.003);
    outcomes.push(("constant x".into(), judge(&constant, None)));
    for seed in [61u64, 62] {
        let mut gauss = crate::quality::Gauss(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
        let noise = write(dir.path(), &format!("n{seed}.csv"), 20_001, 2000.0, |_| {
            1e-3 * gauss.next()
        });
        outcomes.push((format!("white noise seed {seed}"), judge(&noise, None)));
        let mut gauss = crate::quality::Gauss(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
        let hz = 3.0 + seed as f64 % 3.0;
        let sine = write(dir.path(), &format!("s{seed}.csv"), 20_001, 1000.0, |t| {
            1e-3 * (2.0 * std::f64::consts::PI * hz * t).sin() + 1e-5 * gauss.next()
        });
        outcomes.push((format!("{hz} Hz sine + 1 % noise"), judge(&sine, None)));
    }
    let chirp = write(dir.path(), "chirp.csv", 20_001, 2000.0, |t| {
        1e-3 * (2.0 * std::f64::consts::PI * (t + 0.45 * t * t / 2.0)).cos()
    });
    outcomes.push(("chirp 1 -> 10 Hz".into(), judge(&chirp, None)));
    hold("no dynamics", &outcomes, None);
}
