//! Issue 26, item 7: `lssi gen piezo` and `lssi gen electromagnetic`. Each recording, made with
//! the command a user runs, satisfies its own truth's equations (fourth-order finite
//! differences of a clean record against the truth's terms), its truth file parses with both
//! equations and the load, and its columns are the ones asked for.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use lssi_host::synth::harvester::{Equation, SystemTruth};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

/// Runs `lssi gen ARGS OUT.csv`; returns the header, the columns by name and the truth.
fn generated(dir: &Path, args: &[&str]) -> (Vec<String>, BTreeMap<String, Vec<f64>>, SystemTruth) {
    let csv = dir.join("h.csv");
    let out = Command::new(LSSI)
        .arg("gen")
        .args(args)
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let mut columns: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for line in lines {
        for (name, field) in header.iter().zip(line.split(',')) {
            columns
                .entry(name.clone())
                .or_default()
                .push(field.parse().unwrap());
        }
    }
    let truth: SystemTruth =
        serde_json::from_str(&std::fs::read_to_string(dir.join("h.json")).unwrap()).unwrap();
    (header, columns, truth)
}

/// Fourth-order central first and second differences at sample k.
fn d1(s: &[f64], k: usize, dt: f64) -> f64 {
    (s[k - 2] - 8.0 * s[k - 1] + 8.0 * s[k + 1] - s[k + 2]) / (12.0 * dt)
}
fn d2(s: &[f64], k: usize, dt: f64) -> f64 {
    (-s[k - 2] + 16.0 * s[k - 1] - 30.0 * s[k] + 16.0 * s[k + 1] - s[k + 2]) / (12.0 * dt * dt)
}

/// The value of a truth term at sample k.
fn term(name: &str, c: &BTreeMap<String, Vec<f64>>, omega: f64, k: usize) -> f64 {
    let t = c["t"][k];
    match name {
        "x" => c["x"][k],
        "v" => c["v"][k],
        "x^3" => c["x"][k].powi(3),
        "V" | "i" | "u" => c[name][k],
        cos if cos.starts_with("cos(") => (omega * t).cos(),
        other => panic!("no such term in a harvester's truth: {other}"),
    }
}

/// RMS over the interior of (lhs − Σ coef · term) relative to the RMS of lhs, with the
/// truth's coefficients scaled by `scale` per term name (1 when absent).
fn residual(
    eq: &Equation,
    lhs: &dyn Fn(usize) -> f64,
    c: &BTreeMap<String, Vec<f64>>,
    omega: f64,
    scale: &BTreeMap<&str, f64>,
) -> f64 {
    let n = c["t"].len();
    let (mut r2, mut l2) = (0.0, 0.0);
    for k in 2..n - 2 {
        let l = lhs(k);
        let rhs: f64 = eq
            .terms
            .iter()
            .map(|tt| {
                tt.coef
                    * scale.get(tt.term.as_str()).copied().unwrap_or(1.0)
                    * term(&tt.term, c, omega, k)
            })
            .sum();
        r2 += (l - rhs).powi(2);
        l2 += l * l;
    }
    (r2 / l2).sqrt()
}

/// Each variant, clean, with x, v, the electrical channel and u written: both equations hold
/// to 1e-6 of their left-hand side's RMS (the finite differences' own error is ~1e-8; the
/// electrical channel's coefficient 10 % off makes it 10⁻³ and more, so the check can fail).
#[test]
fn each_harvester_satisfies_its_own_truth() {
    let dir = tempfile::tempdir().unwrap();
    let variants: [&[&str]; 6] = [
        &["piezo"],
        &["piezo", "--wells", "bistable"],
        &["piezo", "--wells", "bistable", "--amplitude", "1"],
        &["electromagnetic"],
        &["em", "--electrical", "i", "--wells", "bistable"],
        &["em", "--coil", "negligible"],
    ];
    for variant in variants {
        let mut args = variant.to_vec();
        args.extend(["--observe", "xv", "--input", "--t-end", "5", "--delta", "0"]);
        let (_, c, truth) = generated(dir.path(), &args);
        let dt = c["t"][1] - c["t"][0];
        let e = if c.contains_key("i") { "i" } else { "V" };
        let none = BTreeMap::new();
        let mech = truth.equation("x''").unwrap();
        let x = &c["x"];
        let lhs_x = |k: usize| d2(x, k, dt);
        let r = residual(mech, &lhs_x, &c, truth.omega, &none);
        assert!(r < 1e-6, "{variant:?}: x'' residual {r:.2e}");
        // The velocity column is the displacement's derivative.
        let lhs_v = |k: usize| d1(x, k, dt);
        let v_eq = Equation {
            target: "x'".into(),
            terms: vec![lssi_host::synth::truth::TruthTerm {
                term: "v".into(),
                coef: 1.0,
            }],
        };
        let r = residual(&v_eq, &lhs_v, &c, truth.omega, &none);
        assert!(r < 1e-6, "{variant:?}: v against x' {r:.2e}");
        if let Some(elec) = truth.equation(&format!("{e}'")) {
            let s = &c[e];
            let lhs_e = |k: usize| d1(s, k, dt);
            let r = residual(elec, &lhs_e, &c, truth.omega, &none);
            assert!(r < 1e-6, "{variant:?}: {e}' residual {r:.2e}");
            // The coupling in x'' is checked, not only the beam: 10 % off shows.
            let off = BTreeMap::from([(e, 1.1)]);
            let r = residual(mech, &lhs_x, &c, truth.omega, &off);
            assert!(r > 1e-3, "{variant:?}: x'' insensitive to {e} ({r:.2e})");
        } else {
            let alg = truth.equation(e).unwrap();
            let s = &c[e];
            let lhs = |k: usize| s[k];
            let r = residual(alg, &lhs, &c, truth.omega, &none);
            assert!(r < 1e-12, "{variant:?}: {e} = g v residual {r:.2e}");
            assert!(mech.coefficient(e).is_none(), "{variant:?}");
        }
        // u is the base acceleration, with coefficient −1 in x''.
        assert_eq!(mech.coefficient("u"), Some(-1.0), "{variant:?}");
    }
}

/// Without --input the forcing is the cosine at Ω, coefficient −A; the bistable truth puts
/// the wells where asked.
#[test]
fn forcing_and_wells_in_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (header, c, truth) = generated(
        dir.path(),
        &[
            "piezo",
            "--wells",
            "bistable",
            "--amplitude",
            "1.5",
            "--omega",
            "40",
            "--well",
            "0.004",
            "--t-end",
            "2",
        ],
    );
    assert_eq!(header, ["t", "x", "V"]);
    let mech = truth.equation("x''").unwrap();
    assert_eq!(mech.coefficient("cos(40t)"), Some(-1.5));
    assert_eq!(mech.coefficient("u"), None);
    let k1 = mech.coefficient("x").unwrap();
    let k3 = mech.coefficient("x^3").unwrap();
    assert!(k1 > 0.0 && k3 < 0.0);
    assert!(((-k1 / k3).sqrt() - 0.004).abs() < 1e-12);
    // x'' with the cosine, on the file's own columns.
    let dt = c["t"][1] - c["t"][0];
    let x = &c["x"];
    // v is not written: the damping term needs x' from the displacement.
    let mut with_v = c.clone();
    let n = x.len();
    let mut v = vec![0.0; n];
    for (k, vk) in v.iter_mut().enumerate().take(n - 2).skip(2) {
        *vk = (x[k - 2] - 8.0 * x[k - 1] + 8.0 * x[k + 1] - x[k + 2]) / (12.0 * dt);
    }
    with_v.insert("v".into(), v);
    let r = residual(
        mech,
        &|k| d2(x, k, dt),
        &with_v,
        truth.omega,
        &BTreeMap::new(),
    );
    assert!(r < 1e-6, "x'' residual {r:.2e}");
    let params = &truth.params;
    assert_eq!(params["transducer"]["load_ohms"], 1e6);
    assert_eq!(params["load_ohms"], 1e6);
    assert!(params["coupling_squared"].as_f64().unwrap() > 0.0);
    assert!(params["mean_power_w"].as_f64().unwrap() > 0.0);
}

/// The columns asked for, in order, and the noise: each written channel's noise RMS is δ
/// times its RMS, recorded in the truth.
#[test]
fn columns_and_noise_as_asked() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &[&str]); 5] = [
        (&["piezo"], &["t", "x", "V"]),
        (
            &["piezo", "--observe", "v", "--input"],
            &["t", "v", "V", "u"],
        ),
        (&["em", "--electrical", "i"], &["t", "x", "i"]),
        (
            &["em", "--observe", "xv", "--coil", "negligible"],
            &["t", "x", "v", "V"],
        ),
        (
            &[
                "electromagnetic",
                "--observe",
                "v",
                "--electrical",
                "i",
                "--input",
            ],
            &["t", "v", "i", "u"],
        ),
    ];
    for (args, expected) in cases {
        let mut a = args.to_vec();
        a.extend(["--t-end", "2", "--delta", "0.05", "--seed", "4"]);
        let (header, c, truth) = generated(dir.path(), &a);
        assert_eq!(header, expected, "{args:?}");
        assert_eq!(truth.noise.delta, 0.05);
        let names: Vec<&String> = truth.noise.channels.keys().collect();
        let mut want: Vec<String> = expected[1..].iter().map(|s| (*s).to_owned()).collect();
        want.sort();
        assert_eq!(names, want.iter().collect::<Vec<_>>(), "{args:?}");
        for name in &expected[1..] {
            let s = &c[*name];
            let rms = (s.iter().map(|v| v * v).sum::<f64>() / s.len() as f64).sqrt();
            let noise = truth.noise.channels[*name].rms;
            // The noise is 5 % of the clean channel's RMS, so about 5 % of the noisy one's.
            assert!(
                (noise / rms - 0.05).abs() < 0.005,
                "{args:?} {name}: noise {noise} against RMS {rms}"
            );
        }
    }
}

/// A value that cannot be used is refused with a sentence naming the flag, exit status 2.
#[test]
fn bad_values_name_their_flag() {
    let dir = tempfile::tempdir().unwrap();
    for (args, flag) in [
        (&["piezo", "--load-ohms", "0"][..], "--load-ohms"),
        (&["piezo", "--capacitance=-1e-9"][..], "--capacitance"),
        (&["em", "--inductance", "0"][..], "--inductance"),
        (&["em", "--freq", "nan"][..], "--freq"),
        (&["piezo", "--rate", "0"][..], "--rate"),
    ] {
        let out = Command::new(LSSI)
            .arg("gen")
            .args(args)
            .arg(dir.path().join("bad.csv"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(!dir.path().join("bad.csv").exists(), "{args:?}");
    }
}
