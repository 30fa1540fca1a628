//! `lssi identify FILE...` (many recordings in parallel) and `lssi identify --refine`.
#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::Path;
use std::process::{Command, Output};

fn lssi(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(args)
        .output()
        .unwrap()
}

fn arg(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn generate(dir: &Path, name: &str, extra: &[&str]) -> String {
    let path = dir.join(name);
    let mut args = vec!["gen", "eveh", "--wells", "monostable", "--t-end", "8"];
    args.extend_from_slice(extra);
    args.push(arg(&path));
    let out = lssi(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    path.to_str().unwrap().to_owned()
}

#[test]
fn many_recordings_give_one_line_each_in_order_with_errors_in_their_rows() {
    let dir = tempfile::tempdir().unwrap();
    let a = generate(dir.path(), "a.csv", &["--seed", "1"]);
    let b = generate(dir.path(), "b.csv", &["--seed", "2"]);
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "t,x\n0,1\n").unwrap();
    let out = lssi(&["identify", &a, arg(&bad), &b, "--json", "--family", "odd"]);
    assert_eq!(out.status.code(), Some(2));
    let stdout = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 3);
    for (line, file) in lines.iter().zip([&a, &arg(&bad).to_owned(), &b]) {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(v["file"], file.as_str());
    }
    // Each good line is the single-file output (which ends with its "warnings") with
    // "file" in front.
    for (line, file) in [(lines[0], &a), (lines[2], &b)] {
        let single = lssi(&["identify", file, "--json", "--family", "odd"]);
        let single = String::from_utf8(single.stdout).unwrap();
        let single = single.trim();
        assert!(single.ends_with(",\"warnings\":[]}"), "{single}");
        let expected = format!(
            "{{\"file\":{},{}}}",
            serde_json::Value::from(file.as_str()),
            &single[1..single.len() - 1]
        );
        assert_eq!(line, expected);
    }
    let error: serde_json::Value = serde_json::from_str(lines[1]).unwrap();
    assert!(error["error"].as_str().unwrap().contains("bad.csv"));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("1 of 3 recordings could not be identified")
    );
    // A folder means its .csv files; --csv gives a table.
    let out = lssi(&["identify", arg(dir.path()), "--csv", "--family", "odd"]);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.starts_with(
        "file,equation,terms,coefficients,held_out_error,samples,rejected,warnings,error\n"
    ));
    assert_eq!(table.lines().count(), 4);
    assert!(table.contains("x v x^3 cos(21.4t)"));
}

#[test]
fn refine_reports_the_refined_model_with_standard_errors_and_its_fit() {
    let dir = tempfile::tempdir().unwrap();
    let a = generate(dir.path(), "a.csv", &["--seed", "3", "--delta", "0.02"]);
    let out = lssi(&["identify", &a, "--family", "odd", "--refine", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let refined = &v["refined"];
    assert_eq!(refined["chosen"], "refined", "{refined}");
    let terms = refined["terms"].as_array().unwrap();
    assert_eq!(terms.len(), 4);
    for t in terms {
        assert!(t["se"].as_f64().unwrap() > 0.0);
    }
    assert!(
        refined["free_run"]["nrmse_percent"].as_f64().unwrap() < 10.0,
        "{refined}"
    );
    // The streaming model above stays the device's: the same as without --refine.
    let plain = lssi(&["identify", &a, "--family", "odd", "--json"]);
    let plain: serde_json::Value = serde_json::from_slice(&plain.stdout).unwrap();
    assert_eq!(plain["terms"], v["terms"]);
    let text = lssi(&["identify", &a, "--family", "odd", "--refine", "--unit", "m"]);
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(
        text.contains("refined on simulation error: x'' = ("),
        "{text}"
    );
    assert!(text.contains(" m\n"), "{text}");
}
