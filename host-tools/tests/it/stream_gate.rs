//! A file read in chunks (over `STREAM_BYTES`) whose model the gate withholds: exit status 3,
//! and its `--json` is the in-memory file's shape ("withheld": true, the reason, the model
//! only under "withheld_model", no top-level "terms").

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::io::Write;
use std::process::Command;

use lssi_host::identify::stream::{STREAM_BYTES, STREAM_ROWS};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

#[test]
fn a_withheld_streamed_model_has_no_top_level_terms() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("noise.csv");
    let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    writeln!(file, "t,x").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(61);
    let mut i = 0u64;
    while std::fs::metadata(&path).map_or(0, |m| m.len()) <= STREAM_BYTES + (1 << 20)
        || i <= STREAM_ROWS + 50_000
    {
        for _ in 0..10_000 {
            let x: f64 = StandardNormal.sample(&mut rng);
            writeln!(file, "{:?},{:?}", i as f64 / 50_000.0, 1e-3 * x).unwrap();
            i += 1;
        }
        file.flush().unwrap();
    }
    drop(file);
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(&path)
        .arg("--json")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains("no deterministic dynamics found in"),
        "{stderr}"
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["withheld"], true);
    assert!(
        json["reason"]
            .as_str()
            .unwrap()
            .contains("no deterministic dynamics")
    );
    assert!(json.get("terms").is_none(), "{json}");
    assert!(json["withheld_model"]["terms"].is_array(), "{json}");
}

// The gate over the whole streamed file (issue 25, 3): a file whose dynamics break after the
// excerpt is withheld; the clean file is not. Small blocks (the `StreamOptions` knob) so the
// default suite stays fast; `a_big_file_that_breaks_after_the_excerpt_is_withheld` runs the
// CLI on files over `STREAM_BYTES` (ignored: about 20 s).

use lssi_host::identify::Options;
use lssi_host::identify::stream::{StreamOptions, identify_file};
use lssi_host::recording::{ColumnNames, Recording};
use lssi_host::synth::eveh::{EvehOptions, Wells, generate_eveh};
use lssi_host::synth::files::write_eveh;
use std::path::{Path, PathBuf};

/// How the recording goes on after the break.
#[derive(Clone, Copy, Debug)]
enum Break {
    /// x stuck at its last value (a sensor that died).
    Flat,
    /// Gaussian noise of x's RMS (a loose wire).
    Noise,
    /// Another harvester (the monostable one): the dynamics changed.
    Other,
}

/// The lines of a generated eveh recording (header first).
fn eveh_lines(dir: &Path, name: &str, options: &EvehOptions) -> Vec<String> {
    let csv = dir.join(format!("{name}.csv"));
    write_eveh(
        &csv,
        &dir.join(format!("{name}.json")),
        &generate_eveh(options),
    )
    .unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    text.lines().map(str::to_owned).collect()
}

/// `lines` (t,x) with the data rows from `after` on replaced as `kind` says.
fn broken(
    dir: &Path,
    name: &str,
    lines: &[String],
    other: &[String],
    after: usize,
    kind: Break,
    seed: u64,
) -> PathBuf {
    let x = |line: &str| line.split(',').nth(1).unwrap().parse::<f64>().unwrap();
    let rms = (lines[1..=after].iter().map(|l| x(l).powi(2)).sum::<f64>() / after as f64).sqrt();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let stuck = x(&lines[after]);
    let mut text = String::with_capacity(lines.len() * 24);
    text.push_str(&lines[0]);
    text.push('\n');
    for (row, line) in lines.iter().enumerate().skip(1) {
        let t = line.split(',').next().unwrap();
        let value = if row <= after {
            x(line)
        } else {
            match kind {
                Break::Flat => stuck,
                Break::Noise => {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    rms * z
                }
                Break::Other => x(&other[row]),
            }
        };
        text.push_str(&format!("{t},{value:?}\n"));
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn small_blocks() -> StreamOptions {
    StreamOptions {
        excerpt_rows: 1 << 13,
        probe_rows: 1 << 11,
        gate_blocks: 4,
    }
}

/// A 24 s bistable harvester at 2 kHz (48,001 rows, 5 blocks of 8,192 and the tail) read in
/// chunks: the
/// clean file passes the gate over the whole file; broken after 3 blocks (flat, noise,
/// another harvester) it is withheld, where the gate on the first block alone (the excerpt,
/// what the gate saw before) passes it.
#[test]
fn a_file_that_breaks_after_the_excerpt_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let columns = ColumnNames::default();
    let options = Options::default();
    let stream = small_blocks();
    let base = EvehOptions {
        rate: 2000.0,
        t_end: 24.0,
        seed: 21,
        ..EvehOptions::default()
    };
    let lines = eveh_lines(dir.path(), "clean", &base);
    let other = eveh_lines(
        dir.path(),
        "mono",
        &EvehOptions {
            wells: Wells::Monostable,
            seed: 22,
            ..base.clone()
        },
    );
    let (_, clean) = identify_file(
        dir.path().join("clean.csv"),
        &columns,
        &options,
        &stream,
        |_, _| {},
    )
    .unwrap();
    assert!(clean.streamed, "{clean:?}");
    assert!(clean.quality.passed(), "{:?}", clean.quality.failures);
    // The gate saw blocks spread over the whole file: at least gate_blocks of them, and the
    // file's last rows.
    assert!(clean.gated_blocks > stream.gate_blocks, "{clean:?}");
    assert_eq!(clean.quality.precisions_agree, Some(true));
    let after = 3 * stream.excerpt_rows;
    for (k, kind) in [Break::Flat, Break::Noise, Break::Other]
        .into_iter()
        .enumerate()
    {
        let path = broken(
            dir.path(),
            &format!("{kind:?}.csv"),
            &lines,
            &other,
            after,
            kind,
            k as u64,
        );
        // What the gate saw before: the excerpt alone passes.
        let mut excerpt = Recording::read(&path, &columns).unwrap();
        excerpt.t.truncate(stream.excerpt_rows);
        excerpt.x.truncate(stream.excerpt_rows);
        let (_, old) = lssi_host::identify::quality::identify_checked(&excerpt, &options).unwrap();
        assert!(
            old.passed(),
            "{kind:?}: the excerpt fails: {:?}",
            old.failures
        );
        match identify_file(&path, &columns, &options, &stream, |_, _| {}) {
            // The identifier itself may refuse the file: also no model.
            Err(e) => println!("{kind:?}: refused: {e}"),
            Ok((_, summary)) => {
                assert!(summary.streamed);
                println!("{kind:?}: {:?}", summary.quality.failures);
                assert!(
                    !summary.quality.passed(),
                    "{kind:?}: a file broken after {after} rows passed the gate"
                );
            }
        }
    }
}

/// A file broken in only its last 5 % (after 45,600 of 48,001 rows: within the last block,
/// whose earlier rows are clean) is withheld, the file's last rows named, for each kind of
/// break and two seeds; the clean files pass (issue 25: the last block's median window passed
/// such a break).
#[test]
fn a_file_broken_in_its_last_rows_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let columns = ColumnNames::default();
    let options = Options::default();
    let stream = small_blocks();
    for seed in [24, 25] {
        let base = EvehOptions {
            rate: 2000.0,
            t_end: 24.0,
            seed,
            ..EvehOptions::default()
        };
        let lines = eveh_lines(dir.path(), "clean", &base);
        let other = eveh_lines(
            dir.path(),
            "mono",
            &EvehOptions {
                wells: Wells::Monostable,
                seed: seed + 10,
                ..base.clone()
            },
        );
        let (_, clean) = identify_file(
            dir.path().join("clean.csv"),
            &columns,
            &options,
            &stream,
            |_, _| {},
        )
        .unwrap();
        assert!(
            clean.streamed && clean.quality.passed(),
            "{seed}: {clean:?}"
        );
        let after = lines.len() - 1 - (lines.len() - 1) / 20;
        for (k, kind) in [Break::Flat, Break::Noise, Break::Other]
            .into_iter()
            .enumerate()
        {
            let path = broken(
                dir.path(),
                &format!("tail-{kind:?}.csv"),
                &lines,
                &other,
                after,
                kind,
                seed + k as u64,
            );
            match identify_file(&path, &columns, &options, &stream, |_, _| {}) {
                Err(e) => println!("{kind:?}: refused: {e}"),
                Ok((_, summary)) => {
                    let failures = summary.quality.failures.join("; ");
                    println!("{seed} {kind:?}: {failures}");
                    assert!(
                        !summary.quality.passed(),
                        "{seed} {kind:?}: a file broken after {after} rows passed the gate"
                    );
                    // Where: the stuck rows, or the file's last rows.
                    assert!(
                        failures.contains("stuck at")
                            || failures.contains("the file's last rows")
                            || failures.contains("–48001)"),
                        "{seed} {kind:?}: {failures}"
                    );
                }
            }
        }
    }
}

/// The CLI on files over `STREAM_BYTES` (50 kHz, 10 s): the clean file gives its model (exit
/// 0), broken after 100,000 rows (2 s, past the 65,536-row excerpt) it is withheld (exit 3)
/// with the gate's sentence; `cat FILE | lssi identify -` says the same. About 20 s per file
/// in a debug build: run with `--ignored` (or scripts/stream-gate.sh on a release build).
#[test]
#[ignore = "about a minute: files over 8 MiB through the CLI"]
fn a_big_file_that_breaks_after_the_excerpt_is_withheld() {
    let dir = tempfile::tempdir().unwrap();
    let base = EvehOptions {
        rate: 50_000.0,
        t_end: 10.0,
        seed: 31,
        ..EvehOptions::default()
    };
    let lines = eveh_lines(dir.path(), "clean", &base);
    let run = |path: &Path| {
        Command::new(LSSI)
            .arg("identify")
            .arg(path)
            .output()
            .unwrap()
    };
    let out = run(&dir.path().join("clean.csv"));
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for kind in [Break::Flat, Break::Noise] {
        let path = broken(
            dir.path(),
            &format!("{kind:?}.csv"),
            &lines,
            &[],
            100_000,
            kind,
            5,
        );
        assert!(std::fs::metadata(&path).unwrap().len() > STREAM_BYTES);
        let out = run(&path);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{kind:?}: {stderr}");
        assert!(
            stderr.contains("no deterministic dynamics found in")
                && stderr.contains("the gate judged the whole file"),
            "{stderr}"
        );
    }
}
