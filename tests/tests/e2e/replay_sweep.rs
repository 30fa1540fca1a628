//! The compact encoding over a faulty line (issue 14, items 4 and 5): `lssi replay
//! data/eveh-bistable.csv --encoding i16` through firmware-sim on a pty at 921,600 baud, over
//! a seeded sweep of bit-flip and byte-drop rates from 0 to 1 % (both directions) and batch
//! lengths from 8 to 64. Every run must apply every sample exactly once (`samples_lost == 0`,
//! all 40,001 acknowledged) and report exactly the model `lssi identify --quantise i16 --no-refine`
//! reports: the identifier run in this process on the recording as the device received it
//! (times on the grid, values rounded to i16 quanta).
//!
//! The runs go in parallel (each its own firmware-sim): they mostly wait on the line.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use lssi_host::commands::replay::{Encoding, ReplayArgs, replay};
use lssi_host::identify::identify_recording;
use lssi_host::recording::{ColumnNames, Recording};
use lssi_host::serial::device::find_firmware_sim;
use lssi_host::serial::quantise::quantise;

fn bistable() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/eveh-bistable.csv")
}

/// One run of the sweep: flip rate, drop rate, batch length (`None`: the default, 64), seed.
type Case = (f64, f64, Option<usize>, u64);

const SWEEP: [Case; 6] = [
    (0.0, 0.0, Some(64), 1),
    // The two named cases.
    (0.001, 0.001, Some(16), 3),
    (0.01, 0.01, None, 29),
    (0.003, 0.0, Some(8), 11),
    (0.0, 0.005, Some(32), 17),
    (0.005, 0.005, Some(48), 23),
];

#[test]
fn every_run_of_the_fault_sweep_gives_the_quantised_identify_model_and_loses_nothing() {
    assert!(
        find_firmware_sim().is_some(),
        "firmware-sim is not built: run `cargo test --workspace`"
    );
    let file = bistable();
    let recording = Recording::read(&file, &ColumnNames::default()).unwrap();
    let quantised = quantise(&recording).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let base = ReplayArgs {
        baud: 921_600,
        encoding: Encoding::I16,
        json: true,
        ..ReplayArgs::for_file(&file).unwrap()
    };
    // `lssi identify --quantise i16 --no-refine` with the same flags.
    let expected = identify_recording(&quantised.recording, &base.options().unwrap()).unwrap();

    let runs: Vec<_> = SWEEP
        .iter()
        .map(|&(flip, drop, batch, seed)| {
            let args = ReplayArgs {
                flip_rate: flip,
                drop_rate: drop,
                batch,
                seed,
                log: Some(dir.path().join(format!("sweep-{seed}.tlm"))),
                ..base.clone()
            };
            let started = std::time::Instant::now();
            (
                (flip, drop, batch, seed),
                std::thread::spawn(move || (replay(&args), started.elapsed())),
            )
        })
        .collect();
    for (case, run) in runs {
        let (result, took) = run.join().unwrap();
        let report = result.unwrap_or_else(|e| panic!("{case:?}: {e}"));
        eprintln!(
            "{case:?}: {:.1} s, {} frames sent, {} retransmitted, {} go-backs, {} timeouts, {} model parts, batch {} window {} at the end",
            took.as_secs_f64(),
            report.link.frames_sent,
            report.link.retransmits,
            report.link.go_backs,
            report.link.timeouts,
            report.link.model_parts,
            report.link.batch_len,
            report.link.window
        );
        assert_eq!(report.link.samples_lost, 0, "{case:?}: {:?}", report.link);
        assert_eq!(
            report.link.samples_acked,
            recording.len() as u64,
            "{case:?}"
        );
        assert_eq!(report.report.terms, expected.terms, "{case:?}");
        assert_eq!(report.report, expected, "{case:?}");
        let q = report.quantisation.as_ref().unwrap();
        assert_eq!(q.encoding, "i16");
        // Half a quantum, and the f32 rounding of q·scale (|q| ≤ 32767: 2⁻⁹ of a quantum).
        assert!(q.max_error[0].unwrap() <= 0.51 * f64::from(q.scale[0].unwrap()));
        if case.0 > 0.0 || case.1 > 0.0 {
            assert!(report.link.retransmits > 0, "{case:?}: {:?}", report.link);
        }
    }
}

#[test]
fn the_quantised_model_is_not_the_f32_model_so_the_comparison_can_fail() {
    // The sweep's expectation differs from `lssi identify --f32 --no-refine` on the raw recording: the
    // quantisation changes the coefficients' last bits, so a replay that sent unquantised
    // values (or quantised differently) would not pass.
    let file = bistable();
    let recording = Recording::read(&file, &ColumnNames::default()).unwrap();
    let quantised = quantise(&recording).unwrap();
    let args = ReplayArgs::for_file(&file).unwrap();
    let options = args.options().unwrap();
    let raw = identify_recording(&recording, &options).unwrap();
    let quant = identify_recording(&quantised.recording, &options).unwrap();
    assert_ne!(raw, quant);
}
