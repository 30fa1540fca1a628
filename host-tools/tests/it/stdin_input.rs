//! `lssi identify -` and `lssi identify /dev/stdin` on a pipe (issue 25, 3): the input is
//! spooled to a temporary file and read as a file is, so a pipe gives the file's model, and
//! its messages name the input as the user did.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

/// `lssi ARGS` with `input` written to its standard input through a pipe.
fn piped(args: &[&str], input: &[u8]) -> Output {
    let mut child = Command::new(LSSI)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let bytes = input.to_vec();
    // A writer thread: the child may answer before it has read everything.
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(&bytes);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    out
}

fn generate(dir: &Path, args: &[&str]) -> std::path::PathBuf {
    let path = dir.join("rec.csv");
    let out = Command::new(LSSI)
        .args(["gen", "eveh"])
        .args(args)
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success());
    path
}

/// A pipe gives what the file gives: the same stdout, byte for byte (the model and its
/// report; `--json` and text), for recordings of a few rates, lengths and seeds.
#[test]
fn a_pipe_gives_the_files_model() {
    let dir = tempfile::tempdir().unwrap();
    for (rate, t_end, seed) in [("2000", "6", "1"), ("500", "20", "2"), ("5000", "4", "3")] {
        let path = generate(
            dir.path(),
            &[
                "--wells",
                "monostable",
                "--rate",
                rate,
                "--t-end",
                t_end,
                "--seed",
                seed,
            ],
        );
        let bytes = std::fs::read(&path).unwrap();
        for format in [&[][..], &["--json"]] {
            let file = Command::new(LSSI)
                .args(["identify", path.to_str().unwrap(), "--no-refine"])
                .args(format)
                .output()
                .unwrap();
            assert_eq!(file.status.code(), Some(0));
            for name in ["-", "/dev/stdin"] {
                let mut args = vec!["identify", name, "--no-refine"];
                args.extend(format);
                let pipe = piped(&args, &bytes);
                assert_eq!(
                    pipe.status.code(),
                    Some(0),
                    "{name}: {}",
                    String::from_utf8_lossy(&pipe.stderr)
                );
                assert_eq!(
                    String::from_utf8_lossy(&pipe.stdout),
                    String::from_utf8_lossy(&file.stdout),
                    "{name} {format:?} (rate {rate}, {t_end} s)"
                );
            }
        }
    }
}

/// Bad input on a pipe: the file's sentence, exit status 2, naming `-` (not the temporary
/// file it was spooled to).
#[test]
fn a_bad_pipe_is_named_as_given() {
    for (input, says) in [
        (&b""[..], "-: the file is empty"),
        (b"t,x\n0,1\n1,x\n", "-: line 3, column 'x'"),
        (b"a,b\n0,1\n", "-: no column named 't'"),
        // A system's recording (a V column) cut short: its reader names the pipe too.
        (b"t,x,V\n0,1,2\n1,2\n", "-: line 3 has 2 fields"),
    ] {
        let out = piped(&["identify", "-"], input);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
        assert!(!stderr.contains("tmp"), "{stderr}");
    }
}

/// A pipe over `STREAM_BYTES` is streamed as the file is: the same model (stdout byte for
/// byte), and the warning names `-`. About 20 s in a debug build.
#[test]
#[ignore = "about 40 s: a 10 MB recording through the CLI twice"]
fn a_big_pipe_is_streamed_as_the_file_is() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(dir.path(), &["--rate", "50000", "--t-end", "10"]);
    assert!(std::fs::metadata(&path).unwrap().len() > lssi_host::identify::stream::STREAM_BYTES);
    let file = Command::new(LSSI)
        .args(["identify", path.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert_eq!(file.status.code(), Some(0));
    let pipe = piped(&["identify", "-", "--json"], &std::fs::read(&path).unwrap());
    let stderr = String::from_utf8_lossy(&pipe.stderr);
    assert_eq!(pipe.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("-: not refined"), "{stderr}");
    let model = |out: &[u8]| {
        let v: serde_json::Value = serde_json::from_slice(out).unwrap();
        (v["terms"].clone(), v["omega"].clone(), v["samples"].clone())
    };
    assert_eq!(model(&pipe.stdout), model(&file.stdout));
}
