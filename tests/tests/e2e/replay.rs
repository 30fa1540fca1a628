//! Host == device over the serial link: the bundled recording replayed through firmware-sim
//! on a pty (`lssi replay`'s code, in this process) reports exactly the model of
//! `lssi identify --f32 --no-refine`, on a clean line and on one with bit flips, dropped bytes and bursts,
//! and no sample is lost.
//!
//! firmware-sim is the workspace's binary: `cargo test --workspace` builds it into the same
//! target directory as this test, where `lssi replay` looks for it (next to the running
//! executable, or one directory up); `LSSI_FIRMWARE_SIM` overrides the path.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use lssi_host::commands::replay::{ReplayArgs, replay};
use lssi_host::identify::identify_recording;
use lssi_host::recording::{ColumnNames, Recording};
use lssi_host::serial::device::find_firmware_sim;
use lssi_host::telemetry::{RecordKind, read_log};

fn bundled() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/paper-eq17.csv")
}

fn args(file: &Path, log: &Path, baud: u32) -> ReplayArgs {
    assert!(
        find_firmware_sim().is_some(),
        "firmware-sim is not built: run `cargo test --workspace` (or `cargo build -p firmware-sim --profile test`)"
    );
    ReplayArgs {
        baud,
        log: Some(log.to_path_buf()),
        json: true,
        ..ReplayArgs::for_file(file).unwrap()
    }
}

#[test]
fn replay_over_firmware_sim_reports_what_identify_f32_reports() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("clean.tlm");
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let clean = args(&bundled(), &log, 4_000_000);
    // `lssi identify --f32 --no-refine` with the same flags.
    let expected = identify_recording(&recording, &clean.options().unwrap()).unwrap();

    let report = replay(&clean).unwrap();
    assert_eq!(report.report, expected);
    assert_eq!(report.report.precision, "f32");
    assert_eq!(report.link.samples_lost, 0);
    assert_eq!(report.link.samples_acked, recording.len() as u64);
    let contents = read_log(&std::fs::read(&log).unwrap()).unwrap();
    assert_eq!(contents.records[0].kind, RecordKind::Session);
    // The link's summary, then firmware-sim's own line (a note) once it has exited.
    assert!(
        contents
            .records
            .iter()
            .any(|r| r.kind == RecordKind::Summary)
    );
}

#[test]
fn flips_drops_and_bursts_on_the_line_change_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("faulty.tlm");
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let mut faulty = args(&bundled(), &log, 4_000_000);
    let expected = identify_recording(&recording, &faulty.options().unwrap()).unwrap();
    // The figure: 0.1 % of the bytes flipped and 0.1 % dropped, both directions.
    faulty.flip_rate = 1e-3;
    faulty.drop_rate = 1e-3;
    faulty.burst = 16;
    faulty.seed = 7;
    let report = replay(&faulty).unwrap();
    assert_eq!(report.report.terms, expected.terms);
    assert_eq!(report.report, expected);
    assert_eq!(report.link.samples_lost, 0);
    assert!(report.link.retransmits > 0, "{:?}", report.link);
    assert!(report.link.crc_errors > 0, "{:?}", report.link);
}
