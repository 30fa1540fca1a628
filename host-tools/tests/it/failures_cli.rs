//! Issue 25, "every failure named, every exit code right", on the command side: each test
//! runs the `lssi` binary as a user would and holds the exit code and the sentence naming
//! what failed.
#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::Path;
use std::process::{Command, Output, Stdio};

fn lssi(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(args)
        .output()
        .unwrap()
}

fn arg(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A short synthetic recording (the paper's harvester, one well) written with `lssi gen`.
fn generate(dir: &Path, name: &str, seed: u64) -> String {
    let path = dir.join(name);
    let seed = seed.to_string();
    let out = lssi(&[
        "gen",
        "eveh",
        "--wells",
        "monostable",
        "--t-end",
        "6",
        "--seed",
        &seed,
        arg(&path),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    arg(&path).to_owned()
}

#[test]
fn a_batch_with_an_empty_folder_still_gives_the_good_files_rows_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let a = generate(dir.path(), "a.csv", 1);
    let b = generate(dir.path(), "b.csv", 2);
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    // A folder with files that are not recordings is as empty.
    let other = dir.path().join("other");
    std::fs::create_dir(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "not a recording").unwrap();
    for (format, rows) in [("--csv", 5), ("--json", 4)] {
        let out = lssi(&[
            "identify",
            &a,
            arg(&empty),
            &b,
            arg(&other),
            format,
            "--no-refine",
        ]);
        assert_eq!(out.status.code(), Some(2), "{format}: {}", stderr(&out));
        let stdout = String::from_utf8(out.stdout.clone()).unwrap();
        let lines: Vec<&str> = stdout.lines().collect();
        assert_eq!(lines.len(), rows, "{format}: {stdout}");
        let body = &lines[rows - 4..];
        // The good files' models, in order, and each folder's row naming it.
        assert!(
            body[0].contains(&a) && body[0].contains("x''"),
            "{}",
            body[0]
        );
        assert!(
            body[2].contains(&b) && body[2].contains("x''"),
            "{}",
            body[2]
        );
        for (line, folder) in [(body[1], &empty), (body[3], &other)] {
            assert!(
                line.contains(&format!(
                    "{}: the folder holds no .csv recording.",
                    folder.display()
                )),
                "{format}: {line}"
            );
            assert!(!line.contains("x''"), "{line}");
        }
        assert!(
            stderr(&out).contains("2 of 4 recordings could not be identified"),
            "{}",
            stderr(&out)
        );
    }
    // The empty folder alone: exit 2, and its sentence on stdout's row.
    let out = lssi(&["identify", arg(&empty), "--csv"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stdout).contains("holds no .csv recording"));
}

#[test]
fn a_log_without_a_record_says_so_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let magic = lssi_host::telemetry::MAGIC;
    let mut partial = magic.to_vec();
    partial.extend_from_slice(&[0x20, 0, 0, 0, b'a', b'b']);
    let cases: [(&str, Vec<u8>, &str); 4] = [
        ("empty.tlm", Vec::new(), "the file is empty"),
        (
            "magic.tlm",
            magic[..4].to_vec(),
            "holds only the first 4 of the log header's 8 bytes",
        ),
        ("header.tlm", magic.to_vec(), "holds only its header"),
        ("partial.tlm", partial, "one partial record (6 bytes"),
    ];
    for (name, bytes, says) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        for format in [&[][..], &["--json"], &["--csv"]] {
            let mut args = vec!["log", arg(&path)];
            args.extend_from_slice(format);
            let out = lssi(&args);
            assert_eq!(out.status.code(), Some(2), "{name} {format:?}");
            assert!(out.stdout.is_empty(), "{name}: printed something");
            let err = stderr(&out);
            assert!(
                err.starts_with(&format!("lssi: {}: ", path.display())) && err.contains(says),
                "{name}: {err}"
            );
            assert_eq!(err.lines().count(), 1, "{err}");
        }
    }
}

/// Runs `lssi ARGS` with standard output a pipe its reader closes at once (`| head` when
/// head has had enough): `lssi` must end quietly, without a panic.
fn closed_pipe(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    child.wait_with_output().unwrap()
}

fn assert_quiet(args: &[&str], out: &Output) {
    let err = stderr(out);
    assert!(err.is_empty(), "{args:?}: {err}");
    // Exit 0, or 1 for "the output could not be written" (crate::output); never a panic
    // (101) or a signal.
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{args:?}: {:?}",
        out.status
    );
}

#[test]
fn a_closed_pipe_ends_log_identify_and_info_quietly() {
    let dir = tempfile::tempdir().unwrap();
    // A log long enough to fill a pipe many times over.
    let log_path = dir.path().join("long.tlm");
    let mut log = lssi_host::telemetry::TelemetryLog::open(&log_path).unwrap();
    for i in 0..5000 {
        log.note(&format!("note {i}: the device said something long enough"))
            .unwrap();
    }
    drop(log);
    let log = arg(&log_path);
    let a = generate(dir.path(), "a.csv", 3);
    for args in [
        &["log", log][..],
        &["log", log, "--json"],
        &["log", log, "--csv"],
        &["identify", "--json", &a, "--no-refine"],
        &["identify", &a, &a, "--json"],
        &["info", &a],
    ] {
        assert_quiet(args, &closed_pipe(args));
    }
    // And as `| head -c 10` does it: read a little, then close.
    let mut child = Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(["log", log])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 10];
    std::io::Read::read_exact(child.stdout.as_mut().unwrap(), &mut first).unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert!(first.iter().any(|b| !b.is_ascii_whitespace()), "{first:?}");
    assert_quiet(&["log", log], &out);
}
