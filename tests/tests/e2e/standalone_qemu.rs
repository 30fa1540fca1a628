//! The standalone instrument under QEMU (`-icount shift=4,sleep=off`: guest time tied to
//! instructions at a 64 MHz Cortex-M4F's pace): the firmware samples a 10 kHz recording
//! from its PSRAM by its timer, identifies on its own and reports by itself.
//!
//! What `lssi monitor --qemu FILE.csv --json` does, called in this process: no sample may be
//! lost (0 overruns), and the final model must equal `lssi identify --f32 --no-refine`'s on the same
//! file (same terms; coefficients within 10⁻⁵ relative; in practice bit for bit).
//!
//! `#[ignore]`d with the reason `cargo test` shows: it needs `qemu-system-arm` and the
//! standalone image (`cargo build --release` in crates/lssi-firmware builds it);
//! `scripts/ci-qemu.sh` runs it with `--include-ignored`, where a missing prerequisite fails.

use std::path::{Path, PathBuf};

use clap::Parser;
use lssi_host::commands::generate::{self, GenArgs};
use lssi_host::commands::monitor::{MonitorArgs, monitor};
use lssi_host::identify::Options;
use lssi_host::identify::identify_recording;
use lssi_host::recording::{ColumnNames, Recording};
use serde_json::Value;

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ is inside the repository")
        .to_path_buf()
}

fn standalone_elf() -> PathBuf {
    std::env::var_os("LSSI_STANDALONE_ELF").map_or_else(
        || {
            repository()
                .join("crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-standalone")
        },
        PathBuf::from,
    )
}

#[derive(Parser)]
struct Gen {
    #[command(flatten)]
    args: GenArgs,
}

#[derive(Parser)]
struct Monitor {
    #[command(flatten)]
    args: MonitorArgs,
}

#[test]
#[ignore = "needs qemu-system-arm and the standalone firmware ELF: bash scripts/ci-qemu.sh runs it"]
fn standalone_device_keeps_up_at_10_khz_and_ends_with_the_model_of_identify_f32() {
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("eveh-10k.csv");
    // lssi gen eveh FILE --rate 10000 --t-end 8 --observe x
    let gen_args = Gen::try_parse_from([
        "gen".as_ref(),
        "eveh".as_ref(),
        csv.as_os_str(),
        "--rate".as_ref(),
        "10000".as_ref(),
        "--t-end".as_ref(),
        "8".as_ref(),
        "--observe".as_ref(),
        "x".as_ref(),
    ] as [&std::ffi::OsStr; 9])
    .expect("gen arguments")
    .args;
    generate::run(&gen_args).expect("lssi gen eveh");

    // lssi monitor --qemu FILE --json --firmware ELF --log LOG
    let elf = standalone_elf();
    assert!(elf.is_file(), "{}: build the firmware first", elf.display());
    let log = dir.path().join("monitor.tlm");
    let args = Monitor::try_parse_from([
        "monitor".as_ref(),
        "--qemu".as_ref(),
        csv.as_os_str(),
        "--json".as_ref(),
        "--firmware".as_ref(),
        elf.as_os_str(),
        "--log".as_ref(),
        log.as_os_str(),
    ] as [&std::ffi::OsStr; 8])
    .expect("monitor arguments")
    .args;
    let mut lines = Vec::new();
    let summary = monitor(&args, &mut lines)
        .expect("lssi monitor --qemu")
        .expect("a summary with --qemu");
    let text = String::from_utf8(lines).expect("UTF-8");
    println!("{text}\n{summary}");

    let recording = Recording::read(&csv, &ColumnNames::default()).expect("the recording");
    assert_eq!(summary["samples"], recording.len() as u64);
    assert_eq!(summary["overruns"], 0, "samples lost at 10 kHz");
    assert!(summary["queue_high_water"].as_u64().expect("a count") <= 64);
    // Unsolicited frames: a Model and a Health every second of the 8 s, and the final pair.
    assert!(
        summary["frames"].as_u64().expect("a count") >= 10,
        "{summary}"
    );
    let health_lines = text
        .lines()
        .filter(|l| l.contains("\"kind\":\"health\""))
        .count();
    assert!(health_lines >= 8, "{health_lines} health frames");

    let expected = identify_recording(&recording, &Options::default()).expect("identify --f32");
    let expected = serde_json::to_value(&expected).expect("JSON")["terms"].clone();
    let (Value::Array(got), Value::Array(want)) = (&summary["terms"], &expected) else {
        panic!("terms: {summary} against {expected}");
    };
    assert_eq!(got.len(), want.len(), "{summary} against {expected}");
    for (g, w) in got.iter().zip(want) {
        assert_eq!(g["term"], w["term"]);
        let (g, w) = (
            g["coef"].as_f64().expect("a number"),
            w["coef"].as_f64().expect("a number"),
        );
        assert!((g / w - 1.0).abs() <= 1e-5, "{g} against {w}");
    }
    // The telemetry log was written (lssi log reads it).
    assert!(std::fs::metadata(&log).expect("the log").len() > 1000);
}
