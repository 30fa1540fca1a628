//! Clean failures: a full standard output and an Ω above Nyquist end `lssi` with one line
//! and the documented exit code, never a panic.
#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::fs::File;
use std::process::{Command, Stdio};

fn repository_file(name: &str) -> String {
    format!("{}/../{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `lssi identify … > /dev/full`: exit 1, one line naming the error (was: a panic, exit 101).
#[test]
fn a_full_standard_output_exits_1_with_one_line() {
    let Ok(full) = File::create("/dev/full") else {
        eprintln!("no /dev/full on this system: nothing to test");
        return;
    };
    for args in [
        vec!["identify", "data/eveh-bistable.csv", "--no-refine"],
        vec!["identify", "data/eveh-bistable.csv", "--json"],
        vec!["info", "data/eveh-bistable.csv"],
    ] {
        let args: Vec<String> = args
            .iter()
            .map(|a| {
                if a.starts_with("data/") {
                    repository_file(a)
                } else {
                    (*a).to_string()
                }
            })
            .collect();
        let out = Command::new(env!("CARGO_BIN_EXE_lssi"))
            .args(&args)
            .stdout(Stdio::from(full.try_clone().unwrap()))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains("cannot write the output"), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

/// `--omega` at or above π / Δt is refused: exit 2, a sentence naming the flag and the limit.
#[test]
fn omega_above_nyquist_is_refused() {
    let out = Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args([
            "identify",
            &repository_file("data/eveh-bistable.csv"),
            "--omega",
            "7000",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--omega 7000") && stderr.contains("Nyquist"),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    // Just below it is accepted.
    let out = Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args([
            "identify",
            &repository_file("data/eveh-bistable.csv"),
            "--omega",
            "21.4",
            "--no-refine",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `--log` naming something that is not a regular file (a device, a directory) is refused
/// before anything starts: exit 2 and one sentence (was: `--log /dev/zero` spun forever).
#[test]
fn a_log_that_is_not_a_regular_file_is_refused() {
    let dir = std::env::temp_dir();
    for log in ["/dev/zero", dir.to_str().unwrap()] {
        if !std::path::Path::new(log).exists() {
            continue;
        }
        let out = Command::new(env!("CARGO_BIN_EXE_lssi"))
            .args([
                "replay",
                &repository_file("data/paper-eq17.csv"),
                "--log",
                log,
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{log}: {stderr}");
        assert!(stderr.contains("not a regular file"), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
    }
}

/// A line longer than 1 MiB is an error naming the file and the line; `lssi info /dev/zero`
/// ends at once (was: it grew without bound).
#[test]
fn an_endless_line_is_refused_promptly() {
    let dir = tempfile::tempdir().unwrap();
    let long = dir.path().join("long.csv");
    let mut text = String::from("t,x\n0,1\n");
    text.push_str(&"9".repeat((1 << 20) + 10));
    text.push('\n');
    std::fs::write(&long, text).unwrap();
    let mut files = vec![long.to_str().unwrap().to_owned()];
    if std::path::Path::new("/dev/zero").exists() {
        files.push("/dev/zero".into());
    }
    for file in files {
        let started = std::time::Instant::now();
        let out = Command::new(env!("CARGO_BIN_EXE_lssi"))
            .args(["info", &file])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{file}: {stderr}");
        assert!(stderr.contains("is longer than 1048576 bytes"), "{stderr}");
        assert!(
            started.elapsed().as_secs() < 10,
            "{file} took {:?}",
            started.elapsed()
        );
        assert!(stderr.len() < 300, "{stderr}");
    }
    assert!(
        String::from_utf8_lossy(
            &Command::new(env!("CARGO_BIN_EXE_lssi"))
                .args(["info", long.to_str().unwrap()])
                .output()
                .unwrap()
                .stderr
        )
        .contains("line 3")
    );
}
