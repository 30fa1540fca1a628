//! The `lssi` binary: exit codes and the messages a person sees.
#![allow(clippy::unwrap_used)] // a test fails by panicking

use crate::common::lssi;
use std::path::Path;

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn arg(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn malformed_recording_exits_2_with_one_sentence() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("data.csv");
    std::fs::write(&path, "t,x,v\n0,1,0\n0.001,1.2.3,0\n").unwrap();
    let out = lssi(&["info", arg(&path)]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        text(&out.stderr),
        format!(
            "lssi: {}: line 3, column 'x': \"1.2.3\" is not a number.\n",
            path.display()
        )
    );
    assert!(out.stdout.is_empty());
}

#[test]
fn gen_writes_a_recording_that_info_reads() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let out = lssi(&[
        "gen",
        "paper",
        "--t-end",
        "1",
        "--noise",
        "gauss",
        arg(&csv),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(dir.path().join("run.json").exists());
    let first = std::fs::read(&csv).unwrap();
    assert!(first.starts_with(b"t,x,v\n0.0,"));

    let out = lssi(&["info", arg(&csv)]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains(": 1001 samples, t from 0 to 1 s"));

    // The same seed writes the same bytes.
    lssi(&[
        "gen",
        "paper",
        "--t-end",
        "1",
        "--noise",
        "gauss",
        arg(&csv),
    ]);
    assert_eq!(std::fs::read(&csv).unwrap(), first);
}

#[test]
fn bad_flag_values_exit_2_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let out = lssi(&["gen", "paper", "--dt", "0", arg(&csv)]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        text(&out.stderr),
        "lssi: --dt 0 cannot be used: it must be positive and finite.\n"
    );
    assert!(!csv.exists());

    let out = lssi(&["gen", "paper", "--eps", "-1", "--t-end", "5", arg(&csv)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).starts_with("lssi: the paper-eq17 simulation diverged at t = "));

    // Flags clap cannot parse exit 2 too, with clap's own message.
    let out = lssi(&["gen", "paper", "--noise", "pink", arg(&csv)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("pink"));
}

#[test]
fn unwritable_output_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("missing-dir").join("run.csv");
    let out = lssi(&["gen", "paper", "--t-end", "0.01", arg(&csv)]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).starts_with(&format!("lssi: {}: cannot write the file: ", csv.display())),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn rejected_samples_are_named_on_stderr_and_the_rest_identifies() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("eq17.csv");
    let made = lssi(&[
        "gen",
        "paper",
        "--t-end",
        "20",
        "--dt",
        "0.002",
        "--observe",
        "xv",
        arg(&path),
    ]);
    assert!(made.status.success(), "{}", text(&made.stderr));
    // Row 100 gets a NaN displacement, row 200 an absurd one.
    let csv = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = csv.lines().map(str::to_string).collect();
    for (row, value) in [(100usize, "NaN"), (200, "1e30")] {
        let mut fields: Vec<&str> = lines[row].split(',').collect();
        fields[1] = value;
        lines[row] = fields.join(",");
    }
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let out = lssi(&[
        "identify",
        arg(&path),
        "--omega",
        "2",
        "--json",
        "--no-refine",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    let warnings: Vec<&str> = stderr.lines().collect();
    assert_eq!(warnings.len(), 2, "{stderr}");
    assert!(
        warnings[0].contains("data row 100") && warnings[0].contains("NaN"),
        "{stderr}"
    );
    assert!(warnings[1].contains("data row 200"), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["rejected"], 2);
    let terms = report["terms"].as_array().unwrap();
    assert!(terms.iter().any(|t| t["term"] == "x^3"), "{report}");
}

/// `lssi identify --help` reads in the order of the work: where the data comes from, the
/// library, the identifier's tunables, then what is printed; each flag under its heading.
#[test]
fn identify_help_groups_its_flags_input_library_identifier_output() {
    let out = lssi(&["identify", "--help"]);
    assert_eq!(out.status.code(), Some(0));
    let help = text(&out.stdout);
    // The heading each flag is listed under, in the order they appear.
    let mut heading = "";
    let mut listed = Vec::new();
    for line in help.lines() {
        if !line.starts_with(' ') && line.ends_with(':') {
            heading = line.trim_end_matches(':');
        } else if let Some(flag) = line
            .trim_start()
            .trim_start_matches("-h, ")
            .strip_prefix("--")
        {
            let flag = flag.split([' ', ',']).next().unwrap();
            listed.push((heading.to_owned(), flag.to_owned()));
        }
    }
    let headings: Vec<&str> =
        listed
            .iter()
            .map(|(h, _)| h.as_str())
            .fold(Vec::new(), |mut seen, h| {
                if seen.last() != Some(&h) {
                    seen.push(h);
                }
                seen
            });
    assert_eq!(
        headings,
        [
            "Options",
            "Input",
            "System (a harvester's electrical channels)",
            "Library",
            "Identifier",
            "Output"
        ],
        "{help}"
    );
    let under = |flag: &str| {
        listed
            .iter()
            .find(|(_, f)| f == flag)
            .map(|(h, _)| h.as_str())
    };
    for (flag, expected) in [
        ("t-col", "Input"),
        ("u-col", "Input"),
        ("quantise", "Input"),
        ("omega", "Library"),
        ("poly-order", "Library"),
        ("family", "Library"),
        ("memory", "Identifier"),
        ("f64", "Identifier"),
        ("refine", "Identifier"),
        ("json", "Output"),
        ("csv", "Output"),
        ("track", "Output"),
        ("settle-tol", "Output"),
    ] {
        assert_eq!(under(flag), Some(expected), "--{flag} in {help}");
    }
}
