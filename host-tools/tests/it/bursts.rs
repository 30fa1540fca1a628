//! Bursts of 2 and 3 consecutive bad samples (a hostile check, session 13): rows of x set to
//! 10× the amplitude, or to a constant glitch value, at the first, middle and last rows of
//! `lssi gen eveh`'s recording. Before, `lssi info` named nothing and `lssi identify` exited 3
//! with "damping lost", "forcing not held" or "diverges"; now each is named with its rows,
//! and the model is printed (repaired inside the record, left out at its ends).

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};
use std::process::Output;

use lssi_host::identify::blemish::{Kind, Scan};
use lssi_host::recording::{ColumnNames, Recording};

use crate::common::{gen_eveh, lssi};

/// `lssi gen eveh` with `args`: the file's header and data lines.
fn generated(dir: &Path, args: &[&str]) -> (String, Vec<String>) {
    let path = gen_eveh(dir, "clean.csv", args);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines().map(str::to_owned);
    let header = lines.next().unwrap();
    (header, lines.collect())
}

/// A copy with x of rows `first..first + len` set to `value`.
fn with_burst(
    dir: &Path,
    header: &str,
    rows: &[String],
    first: usize,
    len: usize,
    value: f64,
) -> PathBuf {
    let path = dir.join(format!("burst-{first}-{len}.csv"));
    let mut text = format!("{header}\n");
    for (i, r) in rows.iter().enumerate() {
        if (first..first + len).contains(&i) {
            let t = r.split(',').next().unwrap();
            text.push_str(&format!("{t},{value:e}\n"));
        } else {
            text.push_str(r);
            text.push('\n');
        }
    }
    std::fs::write(&path, text).unwrap();
    path
}

fn run(args: &[&str], path: &Path) -> Output {
    let mut all = args.to_vec();
    let path = path.to_str().unwrap();
    all.push(path);
    lssi(&all)
}

/// The largest |x| of the rows.
fn amplitude(rows: &[String]) -> f64 {
    rows.iter()
        .map(|r| r.split(',').nth(1).unwrap().parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max)
}

/// Each burst is named with its data rows by `info` and `identify`, and `identify` prints
/// the model (exit 0) with the clean file's terms.
#[test]
fn bursts_at_the_first_middle_and_last_rows_are_named_and_a_model_printed() {
    let dir = tempfile::tempdir().unwrap();
    let (header, rows) = generated(dir.path(), &["--seed", "1"]);
    let n = rows.len();
    let high = 10.0 * amplitude(&rows);
    for len in [2, 3] {
        for (first, value) in [(0, high), (20_000, high), (n - len, high), (20_000, 0.0123)] {
            let path = with_burst(dir.path(), &header, &rows, first, len, value);
            let named = format!(
                "data rows {}–{}: a burst of {len} bad samples in x",
                first + 1,
                first + len
            );
            let info = run(&["info"], &path);
            let text = String::from_utf8_lossy(&info.stdout);
            assert!(info.status.success(), "{info:?}");
            assert!(
                text.contains(&format!(
                    "a burst of {len} bad samples in x at data rows {}–{}",
                    first + 1,
                    first + len
                )),
                "rows {first}+{len} = {value}: {text}"
            );
            let out = run(&["identify", "--json", "--no-refine"], &path);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(
                out.status.success(),
                "rows {first}+{len} = {value}: {stderr}"
            );
            let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
            let warnings: Vec<String> = json["warnings"]
                .as_array()
                .unwrap()
                .iter()
                .map(|w| w.as_str().unwrap().to_owned())
                .collect();
            let sentence = warnings
                .iter()
                .find(|w| {
                    w.contains(&format!("data rows {}–{}", first + 1, first + len))
                        && w.contains(&format!("a burst of {len} bad samples in x"))
                })
                .unwrap_or_else(|| panic!("{named}: not in {warnings:?}"));
            // Repaired inside the record; left out at its ends.
            let inside = first > 0 && first + len < n;
            assert_eq!(
                sentence.contains("replaced by the cubic"),
                inside,
                "{sentence}"
            );
            assert!(
                !warnings.iter().any(|w| w.contains("isolated spike")),
                "{warnings:?}"
            );
            let terms: Vec<&str> = json["terms"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| t["term"].as_str().unwrap())
                .collect();
            assert!(terms.contains(&"v"), "the damping lost: {terms:?}");
        }
    }
}

/// The burst rule names nothing on clean noisy records, finds a burst of 2 to 5 samples a
/// as high as 4 RMS (80 noise σ: its residual is h/2 to h/3, against a spike's h) where it is (not its clean neighbours), and leaves a single spike to the
/// spike rule.
#[test]
fn the_burst_rule_finds_bursts_only() {
    let dir = tempfile::tempdir().unwrap();
    for seed in ["1", "2", "3"] {
        let path = gen_eveh(
            dir.path(),
            &format!("noisy-{seed}.csv"),
            &["--delta", "0.05", "--seed", seed],
        );
        let r = Recording::read(&path, &ColumnNames::default()).unwrap();
        assert!(Scan::of(&r).is_clean(), "{:?}", Scan::of(&r).summary());
    }
    let path = dir.path().join("noisy-1.csv");
    let clean = Recording::read(&path, &ColumnNames::default()).unwrap();
    let rms = (clean.x.iter().map(|x| x * x).sum::<f64>() / clean.x.len() as f64).sqrt();
    for len in 2..=5 {
        let mut r = clean.clone();
        for x in &mut r.x[9_000..9_000 + len] {
            *x += 4.0 * rms;
        }
        let scan = Scan::of(&r);
        let found: Vec<(Kind, usize, usize)> = scan
            .blemishes
            .iter()
            .map(|b| (b.kind, b.index, b.rows))
            .collect();
        assert_eq!(found, vec![(Kind::Burst, 9_000, len)], "a burst of {len}");
        // Repaired within a few noise σ of the clean samples.
        for i in 9_000..9_000 + len {
            let repaired = scan.repairs[&i].x;
            assert!(
                (repaired - clean.x[i]).abs() < 0.2 * rms,
                "{i}: {repaired} for {}",
                clean.x[i]
            );
        }
    }
    let mut r = clean.clone();
    r.x[9_000] += 2.0 * rms;
    let found: Vec<(Kind, usize)> = Scan::of(&r)
        .blemishes
        .iter()
        .map(|b| (b.kind, b.index))
        .collect();
    assert_eq!(found, vec![(Kind::Spike, 9_000)]);
}
