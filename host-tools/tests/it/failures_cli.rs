//! Issue 25, "every failure named, every exit code right", on the command side: each test
//! runs the `lssi` binary as a user would and holds the exit code and the sentence naming
//! what failed.
#![allow(clippy::unwrap_used)] // a test fails by panicking

use crate::common::lssi;
use std::path::Path;
use std::process::{Command, Output, Stdio};

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
        // The folders named, not counted as recordings (issue 25).
        assert!(
            stderr(&out).contains(&format!(
                "the folders {} and {} hold no .csv recording",
                empty.display(),
                other.display()
            )) && !stderr(&out).contains("recordings could not be identified"),
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
    // Exit 0 (crate::output: the reader had all it wanted); never 1, a panic (101) or a
    // signal.
    assert_eq!(out.status.code(), Some(0), "{args:?}: {:?}", out.status);
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

/// A recording whose x never moves: `lssi identify` withholds its model (exit 3).
fn constant(dir: &Path, name: &str) -> String {
    let path = dir.join(name);
    let mut text = String::from("t,x\n");
    for i in 0..4001 {
        text.push_str(&format!("{},0.003\n", f64::from(i) / 1000.0));
    }
    std::fs::write(&path, text).unwrap();
    arg(&path).to_owned()
}

/// Gaussian white noise (no dynamics at all).
fn white_noise(dir: &Path, name: &str) -> String {
    let path = dir.join(name);
    let mut text = String::from("t,x\n");
    // A small xorshift and Box-Muller: no dependency for a test's noise.
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut unit = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    for i in 0..8001 {
        let (a, b) = (unit(), unit());
        let g = (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos();
        text.push_str(&format!("{},{g}\n", f64::from(i) / 1000.0));
    }
    std::fs::write(&path, text).unwrap();
    arg(&path).to_owned()
}

/// A recording whose model `lssi identify` withholds (exit 3): a constant x or white noise,
/// the first it withholds (the issue asks both to be).
fn withheld(dir: &Path) -> String {
    let candidates = [constant(dir, "flat.csv"), white_noise(dir, "noise.csv")];
    for file in &candidates {
        if lssi(&["identify", file, "--no-refine"]).status.code() == Some(3) {
            return file.clone();
        }
    }
    panic!("lssi identify withholds neither a constant x nor white noise");
}

const FIGURES: [&str; 5] = [
    "model",
    "screening",
    "k-neighbours",
    "coefficients",
    "phase",
];

fn figures_of(out: &Path, stem: &str) -> usize {
    FIGURES
        .iter()
        .flat_map(|f| ["png", "svg"].map(|ext| out.join(format!("{stem}-{f}.{ext}"))))
        .filter(|p| std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.len() > 1000))
        .count()
}

#[test]
fn plot_draws_every_recording_named_or_names_each_that_failed() {
    let dir = tempfile::tempdir().unwrap();
    let a = generate(dir.path(), "a.csv", 4);
    let b = generate(dir.path(), "b.csv", 5);
    let flat = withheld(dir.path());
    let flat_stem = Path::new(&flat).file_stem().unwrap().to_str().unwrap();
    let missing = dir.path().join("missing.csv");
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let out = dir.path().join("figures");
    let run = lssi(&[
        "plot",
        &a,
        arg(&missing),
        &b,
        &flat,
        arg(&empty),
        "--no-refine",
        "--out",
        arg(&out),
    ]);
    let err = stderr(&run);
    assert_eq!(run.status.code(), Some(2), "{err}");
    // Both good recordings drawn, every figure, and their paths printed.
    let printed = String::from_utf8_lossy(&run.stdout);
    for stem in ["a", "b"] {
        assert_eq!(figures_of(&out, stem), 10, "{stem}: {err}");
        assert!(printed.contains(&format!("{stem}-model.png")), "{printed}");
    }
    // The withheld model not drawn at all, and said so.
    assert_eq!(figures_of(&out, flat_stem), 0);
    assert!(err.contains(&format!("found in {flat}: ")), "{err}");
    assert!(err.contains("No figure of it was drawn"), "{err}");
    assert!(err.contains(&format!("{}: cannot read the file", missing.display())));
    assert!(err.contains(&format!("{}: the folder holds no .csv", empty.display())));
    let last = err.lines().last().unwrap();
    assert!(
        last.starts_with("lssi: 3 of 5 recordings could not be plotted: ")
            && [arg(&missing), &flat, arg(&empty)]
                .iter()
                .all(|f| last.contains(f)),
        "{last}"
    );

    // Good and withheld only: exit 3, the good one still drawn.
    let out3 = dir.path().join("three");
    let run = lssi(&["plot", &flat, &a, "--no-refine", "--out", arg(&out3)]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert_eq!(figures_of(&out3, "a"), 10);
    assert_eq!(figures_of(&out3, flat_stem), 0);
    // The withheld one alone: exit 3, nothing written.
    let run = lssi(&["plot", &flat, "--out", arg(&out3)]);
    assert_eq!(run.status.code(), Some(3));
    assert!(run.stdout.is_empty());

    // Two recordings of one name would overwrite each other's figures: refused up front.
    let other = dir.path().join("other");
    std::fs::create_dir(&other).unwrap();
    std::fs::copy(&a, other.join("a.csv")).unwrap();
    let out4 = dir.path().join("four");
    let run = lssi(&["plot", &a, arg(&other.join("a.csv")), "--out", arg(&out4)]);
    assert_eq!(run.status.code(), Some(2));
    assert!(
        stderr(&run).contains("have the same name"),
        "{}",
        stderr(&run)
    );
    assert!(!out4.exists());

    // What a withheld model gets is in the help.
    let help = lssi(&["plot", "--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("withholds") && help.contains("not drawn at all"),
        "{help}"
    );
}

#[test]
fn a_figure_that_cannot_be_written_is_an_error_naming_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let a = generate(dir.path(), "a.csv", 6);
    // A folder where the model figure should go (a read-only folder does not stop root).
    let out = dir.path().join("figures");
    std::fs::create_dir_all(out.join("a-model.png")).unwrap();
    let run = lssi(&["plot", &a, "--no-refine", "--out", arg(&out)]);
    let err = stderr(&run);
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with(&format!(
            "lssi: {}: cannot write the file: ",
            out.join("a-model.png").display()
        )),
        "{err}"
    );
    // The figures that could be written were.
    assert_eq!(figures_of(&out, "a"), 8, "{err}");
    // An output folder that cannot be made (its parent is a file).
    let below_a_file = Path::new(&a).join("figures");
    let run = lssi(&["plot", &a, "--no-refine", "--out", arg(&below_a_file)]);
    assert_eq!(run.status.code(), Some(1));
    assert!(
        stderr(&run).contains(&format!(
            "{}: cannot create the folder",
            below_a_file.display()
        )),
        "{}",
        stderr(&run)
    );
}

/// The data rows of a CSV file, without its header.
fn rows(path: &str) -> (String, Vec<String>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().map(str::to_owned);
    let header = lines.next().unwrap();
    (header, lines.collect())
}

fn write_rows(path: &Path, header: &str, rows: &[String]) -> String {
    std::fs::write(path, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
    arg(path).to_owned()
}

fn last_line(text: &str) -> &str {
    text.lines().last().unwrap_or_default()
}

#[test]
fn info_names_gaps_short_files_and_constant_signals_as_identify_does() {
    let dir = tempfile::tempdir().unwrap();
    let good = generate(dir.path(), "good.csv", 7);
    let (header, all) = rows(&good);
    // Every 50th sample dropped after the first 1000: gaps everywhere, too broken.
    let dropped: Vec<String> = all
        .iter()
        .enumerate()
        .filter(|(i, _)| *i <= 1000 || i % 50 != 0)
        .map(|(_, r)| r.clone())
        .collect();
    let dropped = write_rows(&dir.path().join("dropped.csv"), &header, &dropped);
    // One gap of 2000 samples (1 s): named, still usable.
    let one_gap: Vec<String> = all
        .iter()
        .enumerate()
        .filter(|(i, _)| !(4000..6000).contains(i))
        .map(|(_, r)| r.clone())
        .collect();
    let one_gap = write_rows(&dir.path().join("one-gap.csv"), &header, &one_gap);
    let short = write_rows(&dir.path().join("short.csv"), &header, &all[..30]);
    let flat = constant(dir.path(), "flat.csv");

    let info = |file: &str| {
        let out = lssi(&["info", file]);
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr(&out),
        )
    };
    // A clean recording: no warning, the configuration identify would use, exit 0.
    let (code, text, err) = info(&good);
    assert_eq!(code, Some(0), "{err}");
    assert!(!text.contains("warning"), "{text}");
    assert!(
        text.contains("identifier (default flags): sample period"),
        "{text}"
    );

    let (code, text, _) = info(&one_gap);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("warning: 1 time gap"), "{text}");
    assert!(text.contains("data row 4001"), "{text}");

    // Refused as identify refuses them: the same sentence, the same exit code.
    for (file, code, says) in [
        (&dropped, 2, "too broken to identify"),
        (&short, 2, "only 30 usable samples"),
        (&flat, 3, "x is constant"),
    ] {
        let (info_code, text, err) = info(file);
        assert_eq!(info_code, Some(code), "{file}: {err}");
        // The summary is still printed.
        assert!(text.starts_with(&format!("{file}: ")), "{text}");
        let sentence = last_line(&err);
        assert!(sentence.contains(says), "{file}: {err}");
        assert!(sentence.contains(file.as_str()), "{sentence}");
        // The configuration's refusals are identify's own sentences. (A constant x is the
        // quality gate's first check, withheld with exit 3: issue 25.)
        if code == 2 {
            let identify = lssi(&["identify", file, "--no-refine"]);
            assert_eq!(identify.status.code(), Some(code), "{file}");
            assert_eq!(last_line(&stderr(&identify)), sentence, "{file}");
        }
    }
    let (_, text, _) = info(&dropped);
    assert!(
        text.contains("warning: 2") && text.contains("time gaps"),
        "{text}"
    );
}

#[test]
fn replay_refuses_bad_fault_options_with_its_own_sentence() {
    let dir = tempfile::tempdir().unwrap();
    let file = generate(dir.path(), "r.csv", 8);
    let log = dir.path().join("r.tlm");
    for (flag, value) in [
        ("--flip-rate", "-0.1"),
        ("--flip-rate", "1.5"),
        ("--flip-rate", "NaN"),
        ("--drop-rate", "-1"),
        ("--drop-rate", "inf"),
        ("--drop-rate", "1"),
        ("--flip-rate", "1"),
    ] {
        let out = lssi(&["replay", &file, flag, value, "--log", arg(&log)]);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}");
        let err = stderr(&out);
        assert!(
            err.starts_with(&format!("lssi: {flag} "))
                && err
                    .contains("cannot be used: it must be a probability per byte between 0 and 1, less than 1 (at 1 no frame gets through)."),
            "{flag} {value}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    let out = lssi(&["replay", &file, "--burst", "70000", "--log", arg(&log)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).starts_with("lssi: --burst 70000 cannot be used: it must be at most 65535")
    );
    // Not a number, or a negative count: clap's error, naming the flag and what is wrong.
    for (flag, value, says) in [
        ("--flip-rate", "x", "is not a number"),
        ("--burst", "-1", "is negative"),
        ("--window", "-3", "is negative"),
    ] {
        let out = lssi(&["replay", &file, flag, value]);
        assert_eq!(out.status.code(), Some(2));
        let err = stderr(&out);
        assert!(
            err.contains(flag) && err.contains(says),
            "{flag} {value}: {err}"
        );
        assert!(!err.contains("unexpected argument"), "{err}");
    }
    // Nothing was started or logged.
    assert!(!log.exists());
    let help = lssi(&["replay", "--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in ["--flip-rate", "--drop-rate"] {
        let text = help.split(flag).nth(1).unwrap();
        assert!(text[..200].contains("per byte"), "{flag}: {text}");
    }
}

fn require_firmware_sim() {
    let next_to_lssi = Path::new(env!("CARGO_BIN_EXE_lssi")).with_file_name("firmware-sim");
    assert!(
        next_to_lssi.is_file() || std::env::var_os("LSSI_FIRMWARE_SIM").is_some(),
        "{} is not built: run `cargo build -p firmware-sim`",
        next_to_lssi.display()
    );
}

#[test]
fn replay_measures_the_byte_error_rate_firmware_sim_injects() {
    require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    let file = generate(dir.path(), "r.csv", 9);
    for (flip, drop, seed) in [
        ("0.002", "0", "1"),
        ("0", "0.002", "2"),
        ("0.001", "0.001", "3"),
    ] {
        let log = dir.path().join(format!("r{seed}.tlm"));
        let out = lssi(&[
            "replay",
            &file,
            "--flip-rate",
            flip,
            "--drop-rate",
            drop,
            "--seed",
            seed,
            "--log",
            arg(&log),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        let text = String::from_utf8_lossy(&out.stdout);
        let faults = text
            .lines()
            .find(|l| l.starts_with("faults: "))
            .unwrap_or_else(|| panic!("no faults line in {text}"));
        // "… damaged about A % of the bytes … measured on the line to the device: B %"
        let percents: Vec<f64> = faults
            .split_whitespace()
            .filter_map(|w| w.parse::<f64>().ok())
            .collect();
        let (injected, measured) = (percents[0], *percents.last().unwrap());
        let expected = 100.0
            * (1.0 - (1.0 - flip.parse::<f64>().unwrap()) * (1.0 - drop.parse::<f64>().unwrap()));
        assert!((injected - expected).abs() < 1e-3, "{faults}");
        // Hundreds of damaged frames: within a third of the injected rate (the adaptive
        // estimate the link sizes its batches by was 3 to 6 times it).
        assert!(
            (measured / injected - 1.0).abs() < 0.35,
            "flip {flip} drop {drop}: {faults}"
        );
    }
}

#[test]
fn a_replay_that_gives_up_on_firmware_sim_does_not_advise_resuming_its_dead_pty() {
    require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    let file = generate(dir.path(), "r.csv", 10);
    let log = dir.path().join("r.tlm");
    let out = lssi(&[
        "replay",
        &file,
        "--drop-rate",
        "0.3",
        "--deadline",
        "1",
        "--log",
        arg(&log),
    ]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let last = last_line(&err);
    assert!(last.contains("no progress for"), "{err}");
    assert!(!last.contains("--resume"), "{last}");
    assert!(
        last.contains("firmware-sim ran on that pty for this replay only"),
        "{last}"
    );
}

/// A figures folder that cannot be created is named as a folder (it said "cannot write the
/// file"), exit status 1, nothing drawn.
#[test]
fn plot_names_a_folder_it_cannot_create() {
    let dir = tempfile::tempdir().unwrap();
    let file = generate(dir.path(), "p.csv", 4);
    let out = lssi(&["plot", &file, "--out", "/proc/lssi-no-such-folder"]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(
        err.starts_with("lssi: /proc/lssi-no-such-folder: cannot create the folder:"),
        "{err}"
    );
    assert!(out.stdout.is_empty());
}
