//! What many of these tests share: the command, run as a user runs it.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `lssi ARGS`: its exit status, stdout and stderr.
pub fn lssi(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(args)
        .output()
        .unwrap()
}

/// `lssi gen ARGS DIR/NAME` (ARGS start with the kind: `eveh`, `piezo`, …): the recording's
/// path; the truth is beside it (`truth`). Fails the test with gen's stderr if gen fails.
pub fn generate(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let out = Command::new(env!("CARGO_BIN_EXE_lssi"))
        .arg("gen")
        .args(args)
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "gen {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    path
}

/// `lssi gen eveh ARGS DIR/NAME`.
pub fn gen_eveh(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let mut all = vec!["eveh"];
    all.extend_from_slice(args);
    generate(dir, name, &all)
}

/// The truth `lssi gen` wrote beside `path` (its `.json`).
pub fn truth(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path.with_extension("json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// `lssi identify --json ARGS PATH`: the exit code and the JSON (exit 0) or stderr, trimmed.
pub fn identify_json(path: &Path, args: &[&str]) -> (i32, Result<serde_json::Value, String>) {
    let out = Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(["identify", "--json"])
        .args(args)
        .arg(path)
        .output()
        .unwrap();
    let code = out.status.code().unwrap();
    if code == 0 {
        (code, Ok(serde_json::from_slice(&out.stdout).unwrap()))
    } else {
        let err = String::from_utf8_lossy(&out.stderr).trim().to_owned();
        (code, Err(err))
    }
}

/// A model JSON's term name by kind: harmonics as `sin`/`cos` (what precedes the `(`).
fn kind(name: &str) -> String {
    name.split('(').next().unwrap().to_owned()
}

/// The terms of a single-equation model JSON (`lssi identify --json` or `lssi gen`'s truth)
/// by kind, with their coefficients, in the JSON's order.
pub fn terms(json: &serde_json::Value) -> Vec<(String, f64)> {
    json["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                kind(t["term"].as_str().unwrap()),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// One equation of a system's JSON (an element of `"equations"`): its terms by kind, with
/// their coefficients and standard errors (0 where absent).
pub fn equation_terms(equation: &serde_json::Value) -> Terms {
    equation["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let se = t
                .get("se")
                .and_then(serde_json::Value::as_f64)
                .unwrap_or(0.0);
            (
                kind(t["term"].as_str().unwrap()),
                (t["coef"].as_f64().unwrap(), se),
            )
        })
        .collect()
}

/// Each equation of a system's JSON by target: [`equation_terms`].
pub fn equations(v: &serde_json::Value) -> BTreeMap<String, Terms> {
    v["equations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| (e["target"].as_str().unwrap().to_owned(), equation_terms(e)))
        .collect()
}

/// A small deterministic generator (an LCG, Box–Muller): standard normal draws.
pub struct Normal(pub u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    /// The next standard normal draw.
    pub fn next(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// One classical Runge–Kutta step of x'' = acc(x, v, t) from (x, v) at t by h: the new (x, v).
pub fn rk4_step(acc: impl Fn(f64, f64, f64) -> f64, x: f64, v: f64, t: f64, h: f64) -> (f64, f64) {
    let (k1x, k1v) = (v, acc(x, v, t));
    let (k2x, k2v) = (
        v + h / 2.0 * k1v,
        acc(x + h / 2.0 * k1x, v + h / 2.0 * k1v, t + h / 2.0),
    );
    let (k3x, k3v) = (
        v + h / 2.0 * k2v,
        acc(x + h / 2.0 * k2x, v + h / 2.0 * k2v, t + h / 2.0),
    );
    let (k4x, k4v) = (v + h * k3v, acc(x + h * k3x, v + h * k3v, t + h));
    (
        x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
        v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
    )
}

/// An equation's terms by kind: (coefficient, standard error).
pub type Terms = BTreeMap<String, (f64, f64)>;

/// A system's equations (`lssi identify --json`'s) paired with the truth's by target, each
/// asserted to hold the truth's terms by kind and no others: (target, printed, truth).
pub fn paired_equations(
    printed: &serde_json::Value,
    truth: &serde_json::Value,
) -> Vec<(String, Terms, Terms)> {
    let mut got = equations(printed);
    equations(truth)
        .into_iter()
        .map(|(target, want)| {
            let have = got.remove(&target).unwrap();
            assert_eq!(
                have.keys().collect::<Vec<_>>(),
                want.keys().collect::<Vec<_>>(),
                "exit 0 with {target} = {have:?} (truth {want:?})"
            );
            (target, have, want)
        })
        .collect()
}
