//! The CSV reader: what it accepts, and the one-sentence error for each file it cannot use.
#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};

use lssi_host::recording::{
    ColumnNames, RecordingError, parse_csv, read_csv, write_csv, write_csv_to,
};
use proptest::prelude::*;

/// Writes `content` to a file named `name` in a fresh directory and returns both.
fn file(name: &str, content: &[u8]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, content).unwrap();
    (dir, path)
}

/// The error message for reading `content` with `columns`.
fn error_with(content: &str, columns: &ColumnNames) -> (String, PathBuf, tempfile::TempDir) {
    let (dir, path) = file("data.csv", content.as_bytes());
    let error = read_csv(&path, columns).unwrap_err();
    assert_eq!(error.path(), path);
    (error.to_string(), path, dir)
}

fn error(content: &str) -> (String, PathBuf, tempfile::TempDir) {
    error_with(content, &ColumnNames::default())
}

fn shown(path: &Path) -> String {
    path.display().to_string()
}

#[test]
fn text_that_is_not_a_number() {
    let (message, path, _dir) = error("t,x\n0,1\n0.001,1.2.3\n");
    assert_eq!(
        message,
        format!(
            r#"{}: line 3, column 'x': "1.2.3" is not a number."#,
            shown(&path)
        )
    );
}

#[test]
fn long_bad_text_is_cut_short() {
    let long = "y".repeat(100);
    let (message, _path, _dir) = error(&format!("t,x\n0,{long}\n"));
    assert!(message.ends_with(&format!("\"{}\"… is not a number.", "y".repeat(40))));
}

#[test]
fn missing_column_lists_the_header() {
    let columns = ColumnNames {
        t: "time".into(),
        ..ColumnNames::default()
    };
    let (message, path, _dir) = error_with("time,pos\n0,1\n", &columns);
    assert_eq!(
        message,
        format!(
            "{}: no column named 'x' in the header (found: time, pos); name the motion's \
             column with --x-col or --v-col, a measured excitation's with --u-col, and the \
             load's voltage or current with --V-col or --i-col.",
            shown(&path)
        )
    );
}

#[test]
fn a_header_with_units_in_its_names_gets_the_option_to_give() {
    // BistableX's header, as its recordings come.
    let (message, path, _dir) =
        error("t_s,base_acc_g,piezo_voltage_V_raw,vibrometer_velocity_V_raw\n0,1,2,3\n");
    assert_eq!(
        message,
        format!(
            "{}: no column named 't' in the header (found: t_s, base_acc_g, piezo_voltage_V_raw, \
             vibrometer_velocity_V_raw); if 't_s' is t, give --t-col t_s; name the motion's \
             column with --x-col or --v-col, a measured excitation's with --u-col, and the \
             load's voltage or current with --V-col or --i-col.",
            shown(&path)
        )
    );
    for (header, name) in [("Time (s),x\n", "Time (s)"), ("time,x\n", "time")] {
        let (message, _path, _dir) = error(&format!("{header}0,1\n"));
        assert!(
            message.contains(&format!("give --t-col {name};")),
            "{message}"
        );
    }
    let columns = ColumnNames {
        t: "time".into(),
        ..ColumnNames::default()
    };
    let (message, _path, _dir) = error_with("time,x [mm],u\n0,1,2\n", &columns);
    assert!(message.contains("give --x-col x [mm];"), "{message}");
}

#[test]
fn a_velocity_column_named_by_the_user_must_exist() {
    let columns = ColumnNames {
        v: Some("vel".into()),
        ..ColumnNames::default()
    };
    let (message, path, _dir) = error_with("t,x,v\n0,1,2\n", &columns);
    assert_eq!(
        message,
        format!(
            "{}: no column named 'vel' in the header (found: t, x, v).",
            shown(&path)
        )
    );
}

#[test]
fn headerless_file_gets_a_hint() {
    let (message, path, _dir) = error("0,1.5\n0.001,1.6\n");
    assert_eq!(
        message,
        format!(
            "{}: no column named 't' in the header (found: 0, 1.5); line 1 looks like data, so \
             the file seems to have no header row: add one such as 't,x,v'.",
            shown(&path)
        )
    );
}

#[test]
fn empty_file() {
    for content in ["", "\n\n", "\r\n"] {
        let (message, path, _dir) = error(content);
        assert_eq!(
            message,
            format!(
                "{}: the file is empty; a recording needs a header row such as 't,x,v' and \
                 then one row per sample.",
                shown(&path)
            ),
            "{content:?}"
        );
    }
}

#[test]
fn header_without_data() {
    for content in ["t,x", "t,x\n", "t,x\n\n\n"] {
        let (message, path, _dir) = error(content);
        assert_eq!(
            message,
            format!(
                "{}: the header is there but no data rows follow it.",
                shown(&path)
            )
        );
    }
}

#[test]
fn ragged_rows_name_the_missing_or_extra_column() {
    let (message, path, _dir) = error("t,x,v\n0,1,2\n0.001,1\n");
    assert_eq!(
        message,
        format!(
            "{}: line 3 has 2 fields but the header has 3, so column 'v' is missing (perhaps the \
             line was cut short).",
            shown(&path)
        )
    );
    let (message, path, _dir) = error("t,x\n0,1\n0.001,1,7\n");
    assert_eq!(
        message,
        format!(
            "{}: line 3 has 3 fields but the header has 2, so it has fields beyond column 'x'.",
            shown(&path)
        )
    );
}

#[test]
fn empty_field() {
    let (message, path, _dir) = error("t,x\n0,1\n0.001, \n");
    assert_eq!(
        message,
        format!("{}: line 3, column 'x' is empty.", shown(&path))
    );
}

#[test]
fn repeated_header_name() {
    let (message, path, _dir) = error("t,x,x\n0,1,2\n");
    assert_eq!(
        message,
        format!(
            "{}: line 1, column 'x' appears more than once in the header, so which one to use \
             is unclear.",
            shown(&path)
        )
    );
}

#[test]
fn binary_file() {
    let (dir, path) = file("data.csv", b"t,x\n0,\xff\xfe\n");
    let message = read_csv(&path, &ColumnNames::default())
        .unwrap_err()
        .to_string();
    assert_eq!(
        message,
        format!(
            "{}: line 2, column 'x' is not UTF-8 text, so this is probably not a CSV file.",
            shown(&path)
        )
    );
    drop(dir);
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("absent.csv");
    let error = read_csv(&path, &ColumnNames::default()).unwrap_err();
    assert!(matches!(error, RecordingError::Io { .. }));
    let message = error.to_string();
    assert!(
        message.starts_with(&format!("{}: cannot read the file: ", shown(&path))),
        "{message}"
    );
    assert!(message.ends_with('.'));
}

#[test]
fn line_numbers_count_skipped_blank_lines() {
    for (content, line) in [
        ("t,x\n0,1\n\n\n0.003,oops\n", 5),
        ("t,x\r\n\r\n1,oops\r\n", 3),
        ("\n\nt,x\n0,1\n0.001,oops\n", 5),
        ("t,x\n0,1\n\n0.001,1\n0.002,oops\n", 5),
    ] {
        let (message, _path, _dir) = error(content);
        assert!(
            message.contains(&format!("line {line}, column 'x'")),
            "{content:?}: {message}"
        );
    }
    let (message, _path, _dir) = error("\n\nt,x,x\n0,1,2\n");
    assert!(
        message.contains("line 3, column 'x' appears more than once"),
        "{message}"
    );
    let (message, _path, _dir) = error("t,x,v\n\n0,1\n");
    assert!(message.contains("line 3 has 2 fields"), "{message}");
}

#[test]
fn tolerates_spaces_crlf_bom_and_trailing_blank_lines() {
    let text = "\u{feff}t , x\r\n 0 , 1\r\n0.5,2 \r\n\r\n   \r\n";
    let (_dir, path) = file("ok.csv", text.as_bytes());
    let recording = read_csv(&path, &ColumnNames::default()).unwrap();
    assert_eq!(recording.t, [0.0, 0.5]);
    assert_eq!(recording.x, [1.0, 2.0]);
    assert_eq!(recording.path, path);
}

#[test]
fn written_files_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.csv");
    let t = [0.0, 0.1, 0.2];
    let x = [1.0, f64::NAN, -3.5e-12];
    let u = [0.0, 1.0, f64::INFINITY];
    write_csv(&path, &["t", "x", "u"], &[&t, &x, &u]).unwrap();
    let recording = read_csv(&path, &ColumnNames::default()).unwrap();
    assert_eq!(recording.t, t);
    assert_eq!(recording.x[0], 1.0);
    assert!(recording.x[1].is_nan());
    assert_eq!(recording.u.unwrap(), u);
    assert_eq!(recording.v, None);
}

/// Equal as bit patterns, so NaN equals NaN and -0.0 differs from 0.0.
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()))
}

proptest! {
    #[test]
    fn any_bytes_are_read_or_rejected_without_panicking(
        bytes in proptest::collection::vec(any::<u8>(), 0..200)
    ) {
        let _ = parse_csv("fuzz.csv", bytes.as_slice(), &ColumnNames::default());
    }

    #[test]
    fn any_csv_like_text_is_read_or_rejected_without_panicking(
        text in "[tx,v0-9.\\-\\n nae\"]{0,80}"
    ) {
        let _ = parse_csv("fuzz.csv", text.as_bytes(), &ColumnNames::default());
    }

    #[test]
    fn any_values_round_trip_exactly(
        rows in proptest::collection::vec((any::<f64>(), any::<f64>(), any::<f64>()), 1..50)
    ) {
        let t: Vec<f64> = rows.iter().map(|r| r.0).collect();
        let x: Vec<f64> = rows.iter().map(|r| r.1).collect();
        let v: Vec<f64> = rows.iter().map(|r| r.2).collect();
        let mut text = Vec::new();
        write_csv_to(&mut text, &["t", "x", "v"], &[&t, &x, &v]).unwrap();
        let recording = parse_csv("round.csv", text.as_slice(), &ColumnNames::default()).unwrap();
        prop_assert!(same_bits(&recording.t, &t));
        prop_assert!(same_bits(&recording.x, &x));
        prop_assert!(same_bits(recording.v.as_deref().unwrap(), &v));
    }
}
