//! Broken time axes and unreadable headers are named as such (issue 25 item 4): samples
//! dropped (steps of 2× the median and more), a jittered t, a t rounded to fewer decimals than
//! the sample period needs; a `;`- or tab-separated header, and an upper-case one (the options
//! to give). Each through the CLI, exit status 2, one sentence; never "give --omega".

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};
use std::process::Command;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

/// A signal with a fundamental and a harmonic (no need to be a solution: the time axis is
/// refused before anything is fitted).
fn signal(t: f64) -> f64 {
    1e-3 * (21.4 * t).cos() + 2e-4 * (64.2 * t).sin()
}

fn write(dir: &Path, name: &str, header: &str, rows: impl Iterator<Item = String>) -> PathBuf {
    let path = dir.join(name);
    let mut text = format!("{header}\n");
    for r in rows {
        text.push_str(&r);
        text.push('\n');
    }
    std::fs::write(&path, text).unwrap();
    path
}

fn refusal(path: &Path) -> String {
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .arg("--no-refine")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{}: {stderr}", path.display());
    assert!(!stderr.contains("give --omega"), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    stderr
}

#[test]
fn broken_time_axes_are_named() {
    let dir = tempfile::tempdir().unwrap();
    for (seed, rate, drop) in [(41u64, 2000.0, 0.1), (42, 1000.0, 0.05), (43, 5000.0, 0.2)] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = (20.0 * rate) as usize;
        let dropped: Vec<usize> = (0..n).filter(|_| rng.random::<f64>() >= drop).collect();
        let path = write(
            dir.path(),
            "dropped.csv",
            "t,x",
            dropped.iter().map(|&i| {
                let t = i as f64 / rate;
                format!("{t:?},{:?}", signal(t))
            }),
        );
        let why = refusal(&path);
        assert!(why.contains("the time column has gaps"), "{why}");
        assert!(why.contains("× the median step"), "{why}");

        let path = write(
            dir.path(),
            "jittered.csv",
            "t,x",
            (0..n).map(|i| {
                let t = i as f64 / rate + 0.8 / rate * (rng.random::<f64>() - 0.5);
                format!("{t:?},{:?}", signal(t))
            }),
        );
        let why = refusal(&path);
        assert!(why.contains("the time column is jittered"), "{why}");

        // t to one decimal fewer than the period needs.
        let decimals = (rate.log10().ceil() as usize).saturating_sub(1);
        let path = write(
            dir.path(),
            "rounded.csv",
            "t,x",
            (0..n).map(|i| {
                let t = i as f64 / rate;
                format!("{t:.decimals$},{:?}", signal(t))
            }),
        );
        let why = refusal(&path);
        assert!(
            why.contains(&format!(
                "the time column is rounded to {decimals} decimals"
            )),
            "{why}"
        );
    }
}

#[test]
fn other_delimiters_and_cases_get_a_hint() {
    let dir = tempfile::tempdir().unwrap();
    let rows = |sep: &'static str| {
        (0..500).map(move |i| {
            let t = i as f64 / 1000.0;
            format!("{t:?}{sep}{:?}", signal(t))
        })
    };
    let why = refusal(&write(dir.path(), "semi.csv", "t;x", rows(";")));
    assert!(why.contains("separated by semicolons (';')"), "{why}");
    let why = refusal(&write(dir.path(), "tab.csv", "t\tx", rows("\t")));
    assert!(why.contains("separated by tabs"), "{why}");
    let why = refusal(&write(dir.path(), "upper.csv", "T,X", rows(",")));
    assert!(why.contains("give --t-col T --x-col X"), "{why}");
    let why = refusal(&write(dir.path(), "mixed.csv", "t,X", rows(",")));
    assert!(why.contains("give --x-col X"), "{why}");
}
