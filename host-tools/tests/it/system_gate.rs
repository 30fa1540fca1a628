//! The quality gate for systems (issue 26): harvesters made by `lssi gen` pass it, and a
//! recording whose electrical channel is noise, unrelated to the motion, or constant is
//! withheld (exit status 3, one sentence naming the check; `--json` gives `"withheld":
//! true`, the reason and the model under `"withheld_model"`), as a user runs it.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::Path;

use crate::common::lssi;
use serde_json::Value;

fn generate(args: &[&str], out: &Path) {
    let mut all = vec!["gen"];
    all.extend(args);
    all.push(out.to_str().unwrap());
    let o = lssi(&all);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The columns of a CSV (header, rows).
fn read(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|q| q.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

fn write(path: &Path, header: &[String], rows: &[Vec<f64>]) {
    let mut text = header.join(",");
    text.push('\n');
    for r in rows {
        let fields: Vec<String> = r.iter().map(|q| format!("{q}")).collect();
        text.push_str(&fields.join(","));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn generated_harvesters_pass_the_gate() {
    let dir = tempfile::tempdir().unwrap();
    // Seeds and noise levels the gate's thresholds were not set on (those were seed 1).
    for (k, args) in [
        &[
            "piezo",
            "--observe",
            "xv",
            "--delta",
            "0.01",
            "--seed",
            "21",
        ][..],
        &[
            "piezo", "--wells", "bistable", "--delta", "0.01", "--seed", "22",
        ],
        &[
            "piezo", "--wells", "bistable", "--delta", "0.05", "--seed", "24",
        ],
    ]
    .iter()
    .enumerate()
    {
        let path = dir.path().join(format!("g{k}.csv"));
        generate(args, &path);
        let out = lssi(&["identify", path.to_str().unwrap(), "--json"]);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        let q = &json["quality"];
        assert_eq!(q["stable"], true, "{args:?}: {q}");
        for s in q["short_horizon"].as_array().unwrap() {
            let e = s["nrmse_percent"].as_f64().unwrap();
            eprintln!("{args:?}: {} {e:.2} %", s["state"]);
            assert!(e <= 50.0, "{args:?}: {q}");
        }
        assert_eq!(q["conditioning"].as_array().unwrap().len(), 2, "{q}");
    }
}

/// A harvester's coupling acts both ways: a model whose V' depends on the motion but whose x''
/// has no V is withheld, with the refitted coupling in the sentence. Single-tone monostable
/// piezo harvesters from x at 1–5 % noise (V, x, v and cos Ωt move as one sinusoid, so χV
/// went into the damping: 35 % off); an electromagnetic one whose selection dropped V gets it
/// back.
#[test]
fn a_coupling_lost_from_x_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    for (k, args) in [
        &["piezo", "--delta", "0.01", "--seed", "41"][..],
        &["piezo", "--input", "--delta", "0.01", "--seed", "42"],
        &["piezo", "--delta", "0.05", "--seed", "43"],
    ]
    .iter()
    .enumerate()
    {
        let path = dir.path().join(format!("c{k}.csv"));
        generate(args, &path);
        let out = lssi(&["identify", path.to_str().unwrap(), "--json"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{args:?}: {stderr}");
        assert!(
            stderr.contains("x'' has no term in V although V' depends on the motion"),
            "{args:?}: {stderr}"
        );
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["withheld"], true, "{json}");
        assert!(json.get("equations").is_none(), "{json}");
        let model = &json["withheld_model"]["equations"];
        let v_prime: Vec<&str> = model[1]["terms"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["term"].as_str().unwrap())
            .collect();
        assert!(v_prime.contains(&"v"), "{args:?}: {model}");
    }
    // A clean electromagnetic harvester whose selection dropped V: V is added back and the
    // model refined with it, Ω too (before Ω was refined, the forcing's phase drift kept the
    // refined model from predicting better, and the model was withheld).
    let path = dir.path().join("em.csv");
    generate(&["electromagnetic", "--seed", "44"], &path);
    let out = lssi(&["identify", path.to_str().unwrap(), "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(
        json["warnings"].as_array().unwrap().iter().any(|w| w
            .as_str()
            .unwrap()
            .contains("V was added and the model refined with it")),
        "{json}"
    );
    let x = &json["equations"][0]["terms"];
    let chi = x
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["term"] == "V")
        .and_then(|t| t["coef"].as_f64())
        .unwrap();
    assert!((chi + 0.25).abs() < 1e-3, "{json}");
}

/// Gaussian noise (xorshift and Box–Muller).
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn gauss(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// A broken recording: its label, its V at each row, and the check that withholds it.
type Case<'a> = (&'a str, Box<dyn Fn(usize) -> f64 + 'a>, &'a str);

#[test]
fn broken_voltage_channels_are_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let base = dir.path().join("base.csv");
    generate(
        &["piezo", "--delta", "0.01", "--t-end", "8", "--seed", "25"],
        &base,
    );
    let other = dir.path().join("other.csv");
    generate(
        &[
            "piezo",
            "--omega",
            "31",
            "--amplitude",
            "3",
            "--delta",
            "0.01",
            "--t-end",
            "8",
            "--seed",
            "26",
        ],
        &other,
    );
    let (header, rows) = read(&base);
    let k = header.iter().position(|h| h == "V").unwrap();
    let (other_header, other_rows) = read(&other);
    let ko = other_header.iter().position(|h| h == "V").unwrap();
    let rms = (rows.iter().map(|r| r[k] * r[k]).sum::<f64>() / rows.len() as f64).sqrt();
    let mut noise = Noise(0x9E37_79B9_7F4A_7C15);
    let cases: [Case<'_>; 3] = [
        ("noise", Box::new(|_| 0.0), "cannot follow the recorded V"),
        (
            "unrelated",
            Box::new(|i| other_rows[i % other_rows.len()][ko]),
            "cannot follow the recorded V",
        ),
        ("constant", Box::new(|_| 0.4 * rms), "V is constant"),
    ];
    for (label, value, check) in &cases {
        let mut broken = rows.clone();
        for (i, r) in broken.iter_mut().enumerate() {
            r[k] = if *label == "noise" {
                rms * noise.gauss()
            } else {
                value(i)
            };
        }
        let path = dir.path().join(format!("{label}.csv"));
        write(&path, &header, &broken);
        // The sentence on standard error and the JSON on standard output, from one run.
        let out = lssi(&["identify", path.to_str().unwrap(), "--json"]);
        assert_eq!(out.status.code(), Some(3), "{label}");
        let err = String::from_utf8(out.stderr.clone()).unwrap();
        let last = err.lines().last().unwrap();
        assert!(
            last.starts_with("lssi: no deterministic dynamics found in") && last.contains(check),
            "{label}: {err}"
        );
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["withheld"], true, "{label}");
        assert!(json["reason"].as_str().unwrap().contains(check), "{json}");
        assert!(json.get("equations").is_none(), "{label}");
        let model = &json["withheld_model"]["equations"];
        assert_eq!(model.as_array().map(Vec::len), Some(2), "{json}");
        // A withheld model is not drawn.
        let figs = dir.path().join(format!("figs-{label}"));
        let out = lssi(&[
            "plot",
            path.to_str().unwrap(),
            "--out",
            figs.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(3), "{label}");
        assert!(!figs.join(format!("{label}-voltage.png")).exists());
    }
}

/// A harvester's x'' with the coupling but without its own damping (the selection traded −c v
/// for an inflated χV under a single forcing tone: V lags v by a few degrees) is withheld with
/// v's refitted coefficient; the same harvester on a seed where the selection keeps v passes.
#[test]
fn a_coupling_without_the_beam_s_damping_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    for seed in ["41", "42", "43", "44"] {
        let path = dir.path().join(format!("t{seed}.csv"));
        generate(
            &[
                "piezo",
                "--amplitude",
                "5.8",
                "--rate",
                "925",
                "--t-end",
                "6.24",
                "--delta",
                "0.02",
                "--observe",
                "v",
                "--input",
                "--seed",
                seed,
            ],
            &path,
        );
        let out = lssi(&["identify", path.to_str().unwrap(), "--json"]);
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        if seed == "44" {
            assert_eq!(out.status.code(), Some(0), "{json}");
            let x = &json["equations"][0];
            let names: Vec<&str> = x["terms"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| t["term"].as_str().unwrap())
                .collect();
            assert_eq!(names, ["x", "v", "V", "u"], "{x}");
            continue;
        }
        assert_eq!(out.status.code(), Some(3), "{seed}: {json}");
        let reason = json["reason"].as_str().unwrap();
        assert!(
            reason.contains("x'' has the coupling V but no damping term in v"),
            "{seed}: {reason}"
        );
    }
}
