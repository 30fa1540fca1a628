//! What many of these tests share: the command, run as a user runs it.

#![allow(clippy::unwrap_used)] // a test fails by panicking

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
