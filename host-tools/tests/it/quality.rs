//! Issue 16, item 2: the quality gate. Recordings without deterministic dynamics (white
//! noise, a step, an impulse followed by silence), generated here, get no model: exit status
//! 3 and "no deterministic dynamics found in …", and with `--json` the reason in "warnings".
//! A generated harvester recording passes with an empty "warnings".

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");
const SAMPLES: usize = 20_000;
const DT: f64 = 0.0005;

/// Standard normal numbers from a fixed seed (xorshift64* and Box–Muller).
pub(crate) struct Gauss(pub(crate) u64);

impl Gauss {
    pub(crate) fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    pub(crate) fn next(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

fn write(dir: &Path, name: &str, x: impl Fn(usize) -> f64) -> PathBuf {
    let path = dir.join(name);
    let mut text = String::from("t,x\n");
    for i in 0..SAMPLES {
        text.push_str(&format!("{},{:e}\n", i as f64 * DT, x(i)));
    }
    std::fs::write(&path, text).unwrap();
    path
}

fn identify(path: &Path, json: bool) -> Output {
    let mut command = Command::new(LSSI);
    command.arg("identify").arg(path);
    if json {
        command.arg("--json");
    }
    command.output().unwrap()
}

/// `path` gets no model: exit 3 and the sentence, in text and in JSON.
fn assert_refused(path: &Path) {
    let name = path.file_name().unwrap().to_str().unwrap();
    let out = identify(path, false);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{name}: {stderr}");
    assert!(
        stderr.contains("no deterministic dynamics found in") && stderr.contains(name),
        "{stderr}"
    );
    assert!(out.stdout.is_empty(), "{name}: a model was printed");
    let out = identify(path, true);
    assert_eq!(out.status.code(), Some(3), "{name}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let warnings = json["warnings"].as_array().unwrap();
    assert!(!warnings.is_empty(), "{name}: {json}");
    // A withheld model says so, and is not given as the answer.
    assert_eq!(json["withheld"], true, "{name}: {json}");
    assert!(json.get("terms").is_none(), "{name}: {json}");
    assert!(json["withheld_model"]["terms"].is_array(), "{name}: {json}");
    assert!(
        json["reason"]
            .as_str()
            .unwrap()
            .contains("no deterministic dynamics found"),
        "{name}: {json}"
    );
    // "warnings" is the last key.
    let text = String::from_utf8_lossy(&out.stdout);
    let at = text.find("\"warnings\"").unwrap();
    assert!(text[at..].trim_end().ends_with("]}"), "{text}");
}

#[test]
fn white_noise_gets_no_model() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gauss(0x9E37_79B9_7F4A_7C15);
    let noise: Vec<f64> = (0..SAMPLES).map(|_| 1e-3 * g.next()).collect();
    assert_refused(&write(dir.path(), "noise.csv", |i| noise[i]));
}

#[test]
fn a_step_gets_no_model() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gauss(7);
    let noise: Vec<f64> = (0..SAMPLES).map(|_| 1e-6 * g.next()).collect();
    assert_refused(&write(dir.path(), "step.csv", |i| {
        (if i < SAMPLES / 2 { 0.0 } else { 1e-3 }) + noise[i]
    }));
}

#[test]
fn an_impulse_followed_by_silence_gets_no_model() {
    let dir = tempfile::tempdir().unwrap();
    assert_refused(&write(dir.path(), "impulse.csv", |i| {
        if i == 1000 { 1e-3 } else { 0.0 }
    }));
    let mut g = Gauss(11);
    let noise: Vec<f64> = (0..SAMPLES).map(|_| 1e-6 * g.next()).collect();
    assert_refused(&write(dir.path(), "impulse-noisy.csv", |i| {
        (if i == 1000 { 1e-3 } else { 0.0 }) + noise[i]
    }));
}

#[test]
fn a_harvester_recording_passes_the_gate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("eveh.csv");
    let out = Command::new(LSSI)
        .args(["gen", "eveh", "--wells", "monostable", "--t-end", "8"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    for json in [false, true] {
        let out = identify(&path, json);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        if json {
            let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
            assert_eq!(v["warnings"], serde_json::json!([]));
        }
    }
    // The library view: the checks measured what they say.
    let recording =
        lssi_host::recording::Recording::read(&path, &lssi_host::recording::ColumnNames::default())
            .unwrap();
    let (_, quality) =
        lssi_host::identify::quality::identify_checked(&recording, &Default::default()).unwrap();
    assert!(quality.passed(), "{:?}", quality.failures);
    assert!(quality.unexplained.unwrap() < 0.01, "{quality:?}");
    assert_eq!(quality.stable, Some(true));
    assert_eq!(quality.precisions_agree, Some(true));
}

/// The gate's checks fail on their own: a model with the wrong sign of the cubic diverges in
/// its free run; a held-out error as large as the variance of x'' fails the fit; a
/// precision that selects other terms fails the agreement.
#[test]
fn each_check_can_fail() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("eveh.csv");
    let out = Command::new(LSSI)
        .args(["gen", "eveh", "--t-end", "8"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let recording =
        lssi_host::recording::Recording::read(&path, &lssi_host::recording::ColumnNames::default())
            .unwrap();
    let options = lssi_host::identify::Options::default();
    let (config, estimated) = lssi_host::identify::configure(&recording, &options).unwrap();
    let report = lssi_host::identify::run::<f32>(&recording, config, estimated).unwrap();
    let q = lssi_host::identify::quality::assess(&recording, &config, &report, None);
    assert!(q.passed(), "{:?}", q.failures);
    // The cubic's sign flipped: x'' = … + |h| x³ runs away.
    let mut flipped = report.clone();
    for (term, c) in &mut flipped.model {
        if *term == (lssi_core::Term::Monomial { px: 3, pv: 0 }) {
            *c = -*c;
        }
    }
    let q = lssi_host::identify::quality::assess(&recording, &config, &flipped, None);
    assert_eq!(q.stable, Some(false), "{q:?}");
    assert!(!q.passed());
    // A held-out error as large as the target's variance.
    let mut poor = report.clone();
    let variance = lssi_host::identify::quality::target_variance(&recording, &config).unwrap();
    poor.solutions[poor.selected].mean_error = variance;
    let q = lssi_host::identify::quality::assess(&recording, &config, &poor, None);
    assert!(q.unexplained.unwrap() > 0.99, "{q:?}");
    assert!(!q.passed());
    // Precisions that disagree.
    let mut other = report.clone();
    other.terms.pop();
    let q = lssi_host::identify::quality::assess(&recording, &config, &report, Some(&other));
    assert_eq!(q.precisions_agree, Some(false));
    assert!(!q.passed());
}
