//! Issue 25's "every failure named", for what a hostile user found after the list: rows out
//! of time order, and an x in a unit that puts it beyond what the identifier computes with
//! (x in nm at 1e10, x scaled to 1e300 or 1e-303, x at 2e-13 in f32) were refused with a
//! sentence about something else ("only 1 usable samples", "x'' has no spectral peak … give
//! --omega", "x is constant", "40001 samples were accepted and 0 rejected, too few regression
//! rows"); a `;`-separated file with decimal commas was told to turn its `;` into commas.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};

use crate::common::{gen_eveh, lssi};

/// A 5 s bistable record's rows (t, x) rewritten by `edit` into `dir/name`.
fn edited(dir: &Path, name: &str, edit: impl Fn(&[(f64, f64)]) -> Vec<(f64, f64)>) -> PathBuf {
    let source = gen_eveh(dir, "source.csv", &["--t-end", "5"]);
    let text = std::fs::read_to_string(&source).unwrap();
    let rows: Vec<(f64, f64)> = text
        .lines()
        .skip(1)
        .map(|l| {
            let (t, x) = l.split_once(',').unwrap();
            (t.parse().unwrap(), x.parse().unwrap())
        })
        .collect();
    let mut out = String::from("t,x\n");
    for (t, x) in edit(&rows) {
        out.push_str(&format!("{t:e},{x:e}\n"));
    }
    let path = dir.join(name);
    std::fs::write(&path, out).unwrap();
    path
}

/// `lssi ARGS PATH`: exit code and stderr.
fn refused(args: &[&str], path: &Path) -> (Option<i32>, String) {
    let mut all = args.to_vec();
    all.push(path.to_str().unwrap());
    let out = lssi(&all);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn rows_in_reverse_time_order_are_named_so() {
    let dir = tempfile::tempdir().unwrap();
    let path = edited(dir.path(), "reversed.csv", |rows| {
        rows.iter().rev().copied().collect()
    });
    for command in [&["identify"][..], &["info"]] {
        let (code, err) = refused(command, &path);
        assert_eq!(code, Some(2), "{command:?}: {err}");
        assert!(
            err.contains("t does not increase") && err.contains("sort them by t"),
            "{command:?}: {err}"
        );
    }
}

#[test]
fn an_x_beyond_the_identifiers_range_names_the_unit() {
    let dir = tempfile::tempdir().unwrap();
    for (name, scale) in [("nm.csv", 1e13), ("huge.csv", 1e300)] {
        let path = edited(dir.path(), name, |rows| {
            rows.iter().map(|(t, x)| (*t, x * scale)).collect()
        });
        for command in [&["identify"][..], &["info"], &["identify", "--f64"]] {
            let (code, err) = refused(command, &path);
            assert_eq!(code, Some(2), "{name} {command:?}: {err}");
            assert!(
                err.contains("x reaches") && err.contains("larger unit"),
                "{name} {command:?}: {err}"
            );
        }
    }
}

/// x at 9e8 (under the intake's 1e9): x^3 fits in f32, x^5 does not (every row was lost:
/// "40001 samples were accepted and 0 rejected, too few regression rows").
#[test]
fn an_x_whose_library_overflows_f32_names_the_unit() {
    let dir = tempfile::tempdir().unwrap();
    let path = edited(dir.path(), "large.csv", |rows| {
        let largest = rows.iter().fold(0.0_f64, |m, r| m.max(r.1.abs()));
        rows.iter().map(|(t, x)| (*t, x * 9e8 / largest)).collect()
    });
    let (code, err) = refused(&["identify", "--no-refine", "--poly-order", "5"], &path);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("x^5") && err.contains("larger unit") && err.contains("--f64"),
        "{err}"
    );
    let (code, err) = refused(&["identify", "--no-refine"], &path);
    assert!(!err.contains("larger unit"), "exit {code:?}: {err}");
}

#[test]
fn an_x_too_small_to_compute_with_names_the_unit_not_a_constant() {
    let dir = tempfile::tempdir().unwrap();
    // Amplitude 2e-13: x^3 under f32's smallest normal number; f64 computes it.
    let largest = |rows: &[(f64, f64)]| rows.iter().fold(0.0_f64, |m, r| m.max(r.1.abs()));
    let path = edited(dir.path(), "small.csv", |rows| {
        let scale = 2e-13 / largest(rows);
        rows.iter().map(|(t, x)| (*t, x * scale)).collect()
    });
    let (code, err) = refused(&["identify", "--no-refine"], &path);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("smaller unit") && err.contains("--f64"),
        "{err}"
    );
    let (code, err) = refused(&["identify", "--no-refine", "--f64"], &path);
    assert!(!err.contains("smaller unit"), "exit {code:?}: {err}");
    // 2.5e-13: still computed in f32 (the limit is where x^3 underflows, not before it).
    let path = edited(dir.path(), "small_ok.csv", |rows| {
        let scale = 2.5e-13 / largest(rows);
        rows.iter().map(|(t, x)| (*t, x * scale)).collect()
    });
    let (code, err) = refused(&["identify", "--no-refine"], &path);
    assert!(!err.contains("smaller unit"), "exit {code:?}: {err}");
    // x^5 at 2.5e-13 is under it too.
    let (code, err) = refused(&["identify", "--no-refine", "--poly-order", "5"], &path);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("x^5") && err.contains("smaller unit"), "{err}");
    // 1e-303: its variance underflows f64, but it is not constant.
    let path = edited(dir.path(), "tiny.csv", |rows| {
        rows.iter().map(|(t, x)| (*t, x * 1e-300)).collect()
    });
    for command in [&["identify"][..], &["info"], &["identify", "--f64"]] {
        let (code, err) = refused(command, &path);
        assert_eq!(code, Some(2), "{command:?}: {err}");
        assert!(
            err.contains("smaller unit") && !err.contains("constant"),
            "{command:?}: {err}"
        );
    }
}

#[test]
fn a_semicolon_file_is_told_about_decimal_commas() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("euro.csv");
    std::fs::write(&path, "t;x\n0,0;0,0019\n0,0005;0,0018\n").unwrap();
    let (code, err) = refused(&["identify"], &path);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("semicolons") && err.contains("decimal commas"),
        "{err}"
    );
}

/// `--memory 0.05` on a 2 kHz record: every sample accepted, no model, and the sentence
/// named neither the memory nor what to do.
#[test]
fn a_memory_too_short_for_a_model_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = edited(dir.path(), "m.csv", <[(f64, f64)]>::to_vec);
    let (code, err) = refused(&["identify", "--no-refine", "--memory", "0.05"], &path);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--memory 0.05 s keeps about 100 samples") && err.contains("longer memory"),
        "{err}"
    );
}
