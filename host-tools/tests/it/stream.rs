//! Large recordings streamed (`lssi_host::identify::stream`): the chunked reader reads what
//! `parse_csv` reads, and the streamed model is the in-memory one.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use lssi_host::identify::stream::{CsvStream, StreamOptions, describe_file, identify_file};
use lssi_host::identify::{Options, identify_recording};
use lssi_host::recording::{ColumnNames, Recording, parse_csv};
use lssi_host::synth::eveh::{EvehOptions, generate_eveh};
use lssi_host::synth::files::write_eveh;
use lssi_host::synth::truth::Truth;
use proptest::prelude::*;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(name)
}

/// Every row of the file through [`CsvStream`].
fn stream_all(path: &Path, columns: &ColumnNames) -> Result<Recording, String> {
    let mut csv = CsvStream::open(path, columns).map_err(|e| e.to_string())?;
    let recording = csv.read_rows(usize::MAX).map_err(|e| e.to_string())?;
    if recording.is_empty() {
        return Err(format!(
            "{}: the header is there but no data rows follow it.",
            path.display()
        ));
    }
    Ok(recording)
}

#[test]
fn the_stream_reads_the_shipped_recordings_as_parse_csv_does() {
    for name in [
        "eveh-bistable.csv",
        "eveh-drift.csv",
        "eveh-monostable.csv",
        "paper-eq17.csv",
    ] {
        let path = data(name);
        let columns = ColumnNames::default();
        let whole = Recording::read(&path, &columns).unwrap();
        assert_eq!(stream_all(&path, &columns).unwrap(), whole, "{name}");
        assert_eq!(
            describe_file(&path, &columns).unwrap(),
            whole.describe(),
            "{name}"
        );
    }
}

#[test]
fn a_file_within_the_excerpt_is_identified_in_memory() {
    let path = data("eveh-bistable.csv");
    let columns = ColumnNames::default();
    for f32 in [true, false] {
        let options = Options {
            f32,
            ..Options::default()
        };
        let (streamed, summary) = identify_file(
            &path,
            &columns,
            &options,
            &StreamOptions::default(),
            |_, _| {},
        )
        .unwrap();
        assert!(!summary.streamed);
        let whole = identify_recording(&Recording::read(&path, &columns).unwrap(), &options);
        assert_eq!(streamed, whole.unwrap());
    }
}

/// 2·10⁵ rows (100 s at 2 kHz) with the default 2¹⁶-row excerpt: configured on 33 s, Ω
/// refined on probes of 2¹² rows, streamed; against the same file identified in memory and
/// the truth. (With a 2¹⁵-row excerpt the period estimated on 16 s gives a test function of
/// 196 samples instead of 192, and the damping term, 0.1 % of x'', moves by 2.4 %.)
#[test]
fn a_streamed_recording_gives_the_in_memory_model() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("long.csv");
    let json = dir.path().join("long.json");
    let generated = generate_eveh(&EvehOptions {
        rate: 2000.0,
        t_end: 100.0,
        ..EvehOptions::default()
    });
    write_eveh(&csv, &json, &generated).unwrap();
    let truth: Truth = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let columns = ColumnNames::default();
    let stream = StreamOptions {
        excerpt_rows: 1 << 16,
        probe_rows: 1 << 12,
        ..StreamOptions::default()
    };
    for f32 in [true, false] {
        let options = Options {
            f32,
            ..Options::default()
        };
        let mut calls = 0;
        let (streamed, summary) =
            identify_file(&csv, &columns, &options, &stream, |_, _| calls += 1).unwrap();
        assert!(summary.streamed && summary.probes >= 2, "{summary:?}");
        assert!(calls > 0);
        let whole =
            identify_recording(&Recording::read(&csv, &columns).unwrap(), &options).unwrap();
        assert_eq!(streamed.samples, whole.samples);
        assert_eq!(streamed.samples, 200_001);
        let names = |r: &lssi_host::identify::Report| {
            r.terms.iter().map(|t| t.term.clone()).collect::<Vec<_>>()
        };
        assert_eq!(names(&streamed), names(&whole));
        // Ω: within 2·10⁻⁵ rad/s, as the in-memory estimate (a phase drift of 2 mrad over the
        // record); the excerpt's own estimate is only checked for sanity.
        let excerpt_error = (summary.excerpt_omega.unwrap() - truth.omega).abs();
        let streamed_error = (streamed.omega - truth.omega).abs();
        let whole_error = (whole.omega - truth.omega).abs();
        assert!(
            streamed_error < 2e-5 && excerpt_error < 1e-3,
            "Ω: streamed {} (excerpt {}), in memory {}, truth {}",
            streamed.omega,
            summary.excerpt_omega.unwrap(),
            whole.omega,
            truth.omega
        );
        assert!(whole_error < 2e-5);
        // Coefficients: the same terms within 1 % of each other and 2 % of the truth (the
        // excerpt's period estimate can give a test function a few samples longer or
        // shorter, and Ω differs in the 6th digit).
        for (s, w) in streamed.terms.iter().zip(&whole.terms) {
            let relative = ((s.coef - w.coef) / w.coef).abs();
            assert!(
                relative < 0.01,
                "{}: {} vs {} (Ω {} vs {})",
                s.term,
                s.coef,
                w.coef,
                streamed.omega,
                whole.omega
            );
        }
        for t in &truth.terms {
            // The forcing's name carries Ω ("cos(21.4t)"): one harmonic, so the cos term.
            let same = |s: &&lssi_host::identify::TermReport| {
                s.term == t.term || (t.term.starts_with("cos(") && s.term.starts_with("cos("))
            };
            let s = streamed.terms.iter().find(same);
            let s = s.unwrap_or_else(|| panic!("{} missing from {:?}", t.term, names(&streamed)));
            let relative = ((s.coef - t.coef) / t.coef).abs();
            assert!(
                relative < 0.02,
                "{}: {} vs truth {}",
                t.term,
                s.coef,
                t.coef
            );
        }
    }
}

/// CSV-like text: a header of t/x/v/other, rows of numbers, blanks, spaces, bad tokens.
fn csv_text() -> impl Strategy<Value = String> {
    let field = prop_oneof![
        6 => (-1e3f64..1e3).prop_map(|v| v.to_string()),
        1 => Just("nan".to_owned()),
        1 => Just(" 1.5 ".to_owned()),
        1 => Just(String::new()),
        1 => Just("1.2.3".to_owned()),
        1 => Just("\"2\"".to_owned()),
    ];
    let row = proptest::collection::vec(field, 1..5).prop_map(|f| f.join(","));
    let line = prop_oneof![8 => row, 1 => Just(String::new()), 1 => Just("  ".to_owned())];
    let header = prop_oneof![
        Just("t,x".to_owned()),
        Just("t,x,v".to_owned()),
        Just("x, t ,v,w".to_owned()),
        Just("t,t,x".to_owned()),
        Just("a,b".to_owned()),
        Just(String::new()),
    ];
    (
        header,
        proptest::collection::vec(line, 0..40),
        any::<bool>(),
    )
        .prop_map(|(header, lines, crlf)| {
            let end = if crlf { "\r\n" } else { "\n" };
            let mut text = header;
            for line in lines {
                text.push_str(end);
                text.push_str(&line);
            }
            text
        })
}

proptest! {
    /// The stream and `parse_csv` agree: the same recording, or the same sentence (with the
    /// same line number).
    #[test]
    fn the_stream_reads_what_parse_csv_reads(text in csv_text()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        std::fs::write(&path, &text).unwrap();
        let columns = ColumnNames::default();
        let whole = parse_csv(&path, text.as_bytes(), &columns).map_err(|e| e.to_string());
        // Compared as printed: a NaN value reads as NaN on both sides (NaN != NaN), and
        // Debug prints every f64 exactly.
        prop_assert_eq!(
            format!("{:?}", stream_all(&path, &columns)),
            format!("{:?}", whole)
        );
    }

    /// Arbitrary bytes: an error or a recording, never a panic, whichever reader.
    #[test]
    fn arbitrary_bytes_never_panic_the_csv_readers(
        bytes in proptest::collection::vec(any::<u8>(), 0..600),
        prefix in prop_oneof![Just(&b""[..]), Just(&b"t,x\n"[..]), Just(&b"t,x,v,u\n0,1,"[..])],
    ) {
        let mut all = prefix.to_vec();
        all.extend_from_slice(&bytes);
        let columns = ColumnNames::default();
        let whole = parse_csv("fuzz.csv", all.as_slice(), &columns);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fuzz.csv");
        std::fs::write(&path, &all).unwrap();
        let streamed = stream_all(&path, &columns);
        // Both readers accept the same files.
        prop_assert_eq!(whole.is_ok(), streamed.is_ok());
        let _ = describe_file(&path, &columns);
    }
}

/// The shipped bistable recording with `x` of the given rows replaced.
fn blemished_copy(dir: &Path, name: &str, rows: &[(usize, &str)]) -> PathBuf {
    let text = std::fs::read_to_string(data("eveh-bistable.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for &(row, value) in rows {
        // Data row `row` is line `row` (line 0 is the header); columns t,x.
        let t = lines[row].split(',').next().unwrap().to_owned();
        lines[row] = format!("{t},{value}");
    }
    let path = dir.join(name);
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path
}

fn small_stream() -> StreamOptions {
    // A small excerpt, so the shipped 40,001-row recording is streamed (the default streams
    // files over 8 MiB only).
    StreamOptions {
        excerpt_rows: 1 << 13,
        probe_rows: 1 << 11,
        ..StreamOptions::default()
    }
}

/// Issue 16 leftover (b): a streamed file gets the in-memory path's blemish handling: a spike
/// in the excerpt and spikes in the streamed part are repaired and named, and the model is
/// the clean file's streamed model within the 2 % (measured: v 0.023 %, the others
/// under 0.001 %).
#[test]
fn a_streamed_file_has_its_spikes_repaired_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let columns = ColumnNames::default();
    let options = Options::default();
    let (clean, clean_summary) = identify_file(
        data("eveh-bistable.csv"),
        &columns,
        &options,
        &small_stream(),
        |_, _| {},
    )
    .unwrap();
    assert!(clean_summary.streamed);
    assert!(
        clean_summary.quality.passed(),
        "{:?}",
        clean_summary.quality
    );
    assert_eq!(clean.rejected, 0);
    let spiked = blemished_copy(
        dir.path(),
        "spiked.csv",
        &[(3_001, "1e300"), (15_001, "1e300"), (30_001, "-0.5")],
    );
    let (report, summary) =
        identify_file(&spiked, &columns, &options, &small_stream(), |_, _| {}).unwrap();
    assert!(summary.streamed && summary.quality.passed());
    assert_eq!(report.rejected, 3, "{:?}", report.rejections);
    for row in [3_001, 15_001, 30_001] {
        assert!(
            report
                .rejections
                .iter()
                .any(|w| w.contains(&format!("data row {row} ")) && w.contains("spike")),
            "row {row}: {:?}",
            report.rejections
        );
    }
    let names = |r: &lssi_host::identify::Report| {
        r.terms.iter().map(|t| t.term.clone()).collect::<Vec<_>>()
    };
    assert_eq!(names(&report), names(&clean));
    for (got, want) in report.terms.iter().zip(&clean.terms) {
        let e = (got.coef / want.coef - 1.0).abs();
        println!(
            "{}: {:.4} % off the clean streamed model",
            got.term,
            100.0 * e
        );
        assert!(e <= 0.02, "{}: {:.3} % off", got.term, 100.0 * e);
    }
}

/// Issue 16 leftover (b): the quality gate runs on a streamed file (on its excerpt): white
/// noise gets no model.
#[test]
fn a_streamed_noise_file_fails_the_quality_gate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("noise.csv");
    let text = lssi_testkit::Noise::new(2).white_noise_csv(40_000, 0.0005, 1e-3);
    std::fs::write(&path, text).unwrap();
    // An excerpt of 2^15 rows (16 s) of the 40,000: on 2^13 rows (4 s) this noise passes the
    // gate in memory too (the held-out check needs a longer record), and the default
    // excerpt is 2^16 rows.
    let stream = StreamOptions {
        excerpt_rows: 1 << 15,
        probe_rows: 1 << 11,
        ..StreamOptions::default()
    };
    let result = identify_file(
        &path,
        &ColumnNames::default(),
        &Options::default(),
        &stream,
        |_, _| {},
    );
    // Either the identifier itself refuses (no spectral peak, …) or the gate withholds it.
    if let Ok((_, summary)) = result {
        assert!(summary.streamed);
        assert!(!summary.quality.passed(), "white noise passed the gate");
        // The gate's blocks spread over the whole file.
        assert!(summary.gated_blocks >= 2 && summary.gated_rows > 1 << 15);
    }
}

/// Issue 25 leftover: bursts past the excerpt are found as in memory (they went into the
/// identifier as measured, and a glitch of 1000× the amplitude withheld a 12 MB file as "no
/// deterministic dynamics"): a burst of 3 and one of 4 inside the stream are repaired, one
/// at the file's last rows left out, each named; the model is the clean file's within 2 %.
#[test]
fn a_streamed_file_has_its_bursts_repaired_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let columns = ColumnNames::default();
    let options = Options::default();
    let (clean, _) = identify_file(
        data("eveh-bistable.csv"),
        &columns,
        &options,
        &small_stream(),
        |_, _| {},
    )
    .unwrap();
    let rows = std::fs::read_to_string(data("eveh-bistable.csv"))
        .unwrap()
        .lines()
        .count()
        - 1;
    let mut glitches: Vec<(usize, &str)> = (20_001..=20_003).map(|r| (r, "0.5")).collect();
    glitches.extend((33_001..=33_004).map(|r| (r, "-0.5")));
    glitches.extend((rows - 2..=rows).map(|r| (r, "0.5")));
    let bursty = blemished_copy(dir.path(), "bursty.csv", &glitches);
    let (report, summary) =
        identify_file(&bursty, &columns, &options, &small_stream(), |_, _| {}).unwrap();
    assert!(
        summary.streamed && summary.quality.passed(),
        "{:?}",
        summary.quality
    );
    for (first, last, what) in [
        (20_001, 20_003, "replaced"),
        (33_001, 33_004, "replaced"),
        (rows - 2, rows, "left out"),
    ] {
        assert!(
            report
                .rejections
                .iter()
                .any(|w| w.contains(&format!("data rows {first}–{last} "))
                    && w.contains("burst")
                    && w.contains(what)),
            "rows {first}–{last}: {:?}",
            report.rejections
        );
    }
    assert_eq!(report.rejected, 10, "{:?}", report.rejections);
    let names = |r: &lssi_host::identify::Report| {
        r.terms.iter().map(|t| t.term.clone()).collect::<Vec<_>>()
    };
    assert_eq!(names(&report), names(&clean));
    for (got, want) in report.terms.iter().zip(&clean.terms) {
        let e = (got.coef / want.coef - 1.0).abs();
        assert!(e <= 0.02, "{}: {:.3} % off", got.term, 100.0 * e);
    }
}

/// Issue 25 (fresh hostile seed 20635): what decides streaming is a file's rows, not its
/// bytes: 200,000 rows of t, x, v, u with long numbers (over 8 MiB) are read whole, so refined
/// with ±; 500,000 short rows over 8 MiB are streamed.
#[test]
fn a_file_is_streamed_for_its_rows_not_its_bytes() {
    use lssi_host::identify::stream::{STREAM_BYTES, STREAM_ROWS, is_large};
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, rows: u64, row: &dyn Fn(u64) -> String| {
        let path = dir.path().join(name);
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        writeln!(f, "t,x,v,u").unwrap();
        for i in 0..rows {
            writeln!(f, "{}", row(i)).unwrap();
        }
        drop(f);
        path
    };
    let wide = write("wide.csv", 200_000, &|i| {
        let t = i as f64 * 7.63e-4;
        format!(
            "{t:?},{:?},{:?},{:?}",
            2.0508 + 1e-3 * (19.79 * t).sin(),
            1.979e-2 * (19.79 * t).cos(),
            (19.79 * t).cos() / 3.0
        )
    });
    assert!(std::fs::metadata(&wide).unwrap().len() > STREAM_BYTES);
    assert!(!is_large(&wide), "200,000 rows are read whole");
    let long = write("long.csv", STREAM_ROWS + 100_000, &|i| {
        format!("{:.5},0.00{},0,0", i as f64 * 1e-5, i % 997)
    });
    assert!(std::fs::metadata(&long).unwrap().len() > STREAM_BYTES);
    assert!(
        is_large(&long),
        "{} rows are streamed",
        STREAM_ROWS + 100_000
    );
}
