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

/// The standalone device at the rate the harvester needs: `lssi identify` proposes 210 Hz
/// for eveh (50 samples a period of its in-well resonance, 4.13 Hz); the ADC converts at
/// 10 kHz (what its anti-alias filter needs) and the firmware decimates by 47, the largest
/// whole factor whose rows are at least that fast (a CIC of order 3), to rows at 212.8 Hz,
/// with the configuration `lssi identify` chooses for those rows (stored in the image as a
/// host's `Configure`).
///
/// No conversion may be lost (0 overruns), the final model must be, coefficient for
/// coefficient, lssi-core's `f32` identifier run on the same rows (decimated here by the
/// same `lssi_device::decimate::Decimator`, its droop compensator included), and it must
/// hold every true term, each within 1 % of the truth, and no other.
#[test]
#[ignore = "needs qemu-system-arm and the standalone firmware ELF: bash scripts/ci-qemu.sh runs it"]
fn standalone_device_decimates_10_khz_to_the_proposed_rate_and_ends_with_the_identifiers_model() {
    use lssi_core::{Identifier, Sample};
    use lssi_device::decimate::{Decimator, factor_for};
    use lssi_proto::{DeviceFrameDecoder, DeviceMsg, SnapshotCause};

    const ADC_HZ: f64 = 10_000.0;
    // What `lssi identify` proposes for eveh ("a device needs 210 Hz for this harvester").
    const PROPOSED_HZ: f64 = 210.0;
    const FACTOR: u32 = 47;
    const ROW_HZ: f64 = ADC_HZ / FACTOR as f64;
    // The firmware's CIC order (CIC_ORDER in src/bin/lssi-standalone.rs).
    const ORDER: u8 = 3;
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("eveh-10k.csv");
    let gen_args = Gen::try_parse_from([
        "gen".as_ref(),
        "eveh".as_ref(),
        csv.as_os_str(),
        "--rate".as_ref(),
        "10000".as_ref(),
        "--t-end".as_ref(),
        "20".as_ref(),
        "--observe".as_ref(),
        "x".as_ref(),
    ] as [&std::ffi::OsStr; 9])
    .expect("gen arguments")
    .args;
    generate::run(&gen_args).expect("lssi gen eveh");
    let recording = Recording::read(&csv, &ColumnNames::default()).expect("the recording");

    // The rows the device makes: the conversions as the image holds them (f32), decimated.
    let factor = factor_for(ADC_HZ, 1.0 / ROW_HZ).expect("a whole factor");
    assert_eq!(factor, FACTOR);
    assert!(ROW_HZ >= PROPOSED_HZ && ADC_HZ / f64::from(FACTOR + 1) < PROPOSED_HZ);
    let mut decimator = Decimator::new(factor, ORDER).expect("a decimator");
    let period = f64::from(factor) / ADC_HZ;
    let offset = decimator.time_offset(ADC_HZ);
    let rows: Vec<f32> = recording
        .samples()
        .filter_map(|s| decimator.push([s.x as f32, 0.0, 0.0]).map(|r| r[0]))
        .collect();
    let times: Vec<f64> = (0..rows.len())
        .map(|i| i as f64 * period + offset)
        .collect();
    let xs: Vec<f64> = rows.iter().map(|&x| f64::from(x)).collect();
    let decimated = dir.path().join("eveh-200.csv");
    lssi_host::recording::write_csv(&decimated, &["t", "x"], &[&times, &xs]).expect("CSV");
    let decimated = Recording::read(&decimated, &ColumnNames::default()).expect("rows");
    let (mut config, _) = lssi_host::identify::configure(&decimated, &Options::default())
        .expect("lssi identify's configuration for the rows");
    config.sample_period = period;

    // The identifier on the host, as the device runs it (f32, its capacities).
    let mut identifier: Box<Identifier<f32, 256, 16, 2>> =
        Box::new(Identifier::new(config).expect("a valid configuration"));
    for (&t, &x) in times.iter().zip(&rows) {
        let _ = identifier.push(Sample {
            t,
            x,
            v: None,
            u: None,
        });
    }
    assert!(identifier.screen(), "a model from {} rows", rows.len());
    let expected =
        lssi_device::wire::snapshot(identifier.model().expect("a model"), SnapshotCause::Final)
            .expect("fits a snapshot");

    // The firmware under QEMU, the configuration stored as a host's Configure frame.
    let elf = standalone_elf();
    assert!(elf.is_file(), "{}: build the firmware first", elf.display());
    let image = dir.path().join("recording.bin");
    let bytes = lssi_host::serial::monitor::recording_image(&recording, ADC_HZ, Some(&config))
        .expect("the PSRAM image");
    std::fs::write(&image, bytes).expect("write the image");
    let uart = dir.path().join("uart.bin");
    let qemu = lssi_host::serial::qemu::find().expect("qemu-system-arm on the PATH");
    let status = lssi_host::serial::qemu::command(&qemu)
        .args(["-icount", "shift=4,sleep=off", "-kernel"])
        .arg(&elf)
        .arg("-device")
        .arg(format!("loader,file={},addr=0x21000000", image.display()))
        .arg("-serial")
        .arg(format!("file:{}", uart.display()))
        .output()
        .expect("QEMU runs");
    assert_eq!(status.status.code(), Some(0), "the firmware's exit status");
    print_log(&elf, &status.stdout, dir.path());
    let frames = std::fs::read(&uart).expect("the UART's bytes");
    let mut decoder = DeviceFrameDecoder::new();
    let messages: Vec<DeviceMsg> = decoder
        .feed::<DeviceMsg>(&frames)
        .map(|m| m.expect("a valid frame"))
        .collect();
    let last_model = messages.iter().rev().find_map(|m| match m {
        DeviceMsg::Model(s) if s.cause == SnapshotCause::Final => Some(s),
        _ => None,
    });
    let last_health = messages.iter().rev().find_map(|m| match m {
        DeviceMsg::Health {
            samples,
            overruns,
            sample_rate_hz,
            ..
        } => Some((*samples, *overruns, *sample_rate_hz)),
        _ => None,
    });
    let (Some(got), Some((samples, overruns, rate))) = (last_model, last_health) else {
        panic!("no final model and health in {} frames", messages.len());
    };
    println!("device: {samples} rows at {rate} Hz, {overruns} overruns; {got:?}");
    assert_eq!(overruns, 0, "conversions lost");
    assert_eq!(samples, rows.len() as u64, "rows");
    assert!((f64::from(rate) - ROW_HZ).abs() < 1e-3, "row rate {rate}");
    assert_eq!(got.terms, expected.terms);
    for (i, (g, w)) in got
        .coefficients
        .iter()
        .zip(&expected.coefficients)
        .enumerate()
    {
        assert!(
            (g - w).abs() <= 1e-5 * w.abs(),
            "term {i}: {g} on the device, {w} on the host"
        );
    }

    // Every true term of eveh (x, v, x^3, cos Ωt) is in the device's model.
    use lssi_proto::TermKind;
    let active: Vec<_> = got
        .terms
        .iter()
        .zip(&got.coefficients)
        .filter(|(_, c)| **c != 0.0)
        .map(|(t, c)| (t.kind, t.a, t.b, *c))
        .collect();
    println!("device's active terms (kind, a, b, coefficient): {active:?}");
    // The truth, as `lssi gen` wrote it beside the recording.
    let truth: Value = serde_json::from_str(
        &std::fs::read_to_string(csv.with_extension("json")).expect("the truth JSON"),
    )
    .expect("JSON");
    let true_coef = |name: &str| {
        truth["terms"]
            .as_array()
            .expect("terms")
            .iter()
            .find(|t| t["term"] == name)
            .and_then(|t| t["coef"].as_f64())
            .expect("a true term")
    };
    for (kind, a, b, name) in [
        (TermKind::Monomial, 1, 0, "x"),
        (TermKind::Monomial, 0, 1, "v"),
        (TermKind::Monomial, 3, 0, "x^3"),
        (TermKind::Cos, 1, 0, "cos(21.4t)"),
    ] {
        let got = active
            .iter()
            .find(|t| (t.0, t.1, t.2) == (kind, a, b))
            .map(|t| f64::from(t.3));
        let Some(got) = got else {
            panic!("{kind:?} {a} {b} missing: {active:?}");
        };
        let want = true_coef(name);
        let error = (got / want - 1.0).abs();
        println!(
            "{name}: {got} on the device, {want} true, {:.3} % off",
            100.0 * error
        );
        assert!(error <= 0.01, "{name}: {got} against the true {want}");
    }
    // And nothing else: the model's terms are exactly the truth's (the CIC's passband droop,
    // uncompensated, made the identifier add a spurious x·v² ≈ −13,500 here).
    assert_eq!(
        active.len(),
        4,
        "the device's model has terms the truth has not: {active:?}"
    );
}

/// Runs the standalone image on `recording` converted at `adc_hz`, its stored
/// configuration `config` (a host's `Configure` frame); returns every frame it sent.
fn run_standalone(
    recording: &Recording,
    adc_hz: f64,
    config: &lssi_proto::WireConfig,
    dir: &Path,
) -> (Vec<lssi_proto::DeviceMsg>, String) {
    use lssi_proto::{DeviceFrameDecoder, DeviceMsg, HostMsg, MAX_HOST_FRAME_LEN, encode};
    let elf = standalone_elf();
    assert!(elf.is_file(), "{}: build the firmware first", elf.display());
    let mut bytes = lssi_host::serial::monitor::recording_image(recording, adc_hz, None)
        .expect("the PSRAM image");
    let mut frame = [0u8; MAX_HOST_FRAME_LEN];
    let len = encode(&HostMsg::Configure(*config), &mut frame).expect("encodes");
    // The header's stored configuration: its length at 24, the frame at 28.
    bytes[24..28].copy_from_slice(&(len as u32).to_le_bytes());
    bytes[28..28 + len].copy_from_slice(&frame[..len]);
    let image = dir.join("recording.bin");
    std::fs::write(&image, bytes).expect("write the image");
    let uart = dir.join("uart.bin");
    let qemu = lssi_host::serial::qemu::find().expect("qemu-system-arm on the PATH");
    let status = lssi_host::serial::qemu::command(&qemu)
        .args(["-icount", "shift=4,sleep=off", "-kernel"])
        .arg(&elf)
        .arg("-device")
        .arg(format!("loader,file={},addr=0x21000000", image.display()))
        .arg("-serial")
        .arg(format!("file:{}", uart.display()))
        .output()
        .expect("QEMU runs");
    assert_eq!(status.status.code(), Some(0), "the firmware's exit status");
    let log = print_log(&elf, &status.stdout, dir);
    let frames = std::fs::read(&uart).expect("the UART's bytes");
    let mut decoder = DeviceFrameDecoder::new();
    let messages = decoder
        .feed::<DeviceMsg>(&frames)
        .map(|m| m.expect("a valid frame"))
        .collect();
    (messages, log)
}

/// Prints the firmware's defmt log (its semihosting output), decoded by `defmt-print` when
/// that is installed (scripts/ci-qemu.sh installs it), and returns it; empty otherwise.
pub(crate) fn print_log(elf: &Path, defmt: &[u8], dir: &Path) -> String {
    let raw = dir.join("defmt.bin");
    std::fs::write(&raw, defmt).expect("write the log");
    let Ok(file) = std::fs::File::open(&raw) else {
        return String::new();
    };
    match std::process::Command::new("defmt-print")
        .arg("-e")
        .arg(elf)
        .stdin(file)
        .output()
    {
        Ok(out) => {
            let text = String::from_utf8_lossy(&out.stdout).into_owned();
            println!("{text}");
            text
        }
        Err(_) => String::new(),
    }
}

/// The firmware's longest wake-up while sampling, in clock ticks (its last log line).
fn longest_wake_up(log: &str) -> u64 {
    let after = log
        .split("the longest while sampling ")
        .nth(1)
        .unwrap_or_else(|| panic!("no wake-up figure in the firmware's log (is defmt-print installed? cargo install defmt-print --locked):\n{log}"));
    after
        .split(' ')
        .next()
        .and_then(|n| n.parse().ok())
        .expect("a number of ticks")
}

/// The duty-cycled device under QEMU: 10 kHz conversions decimated to 200 Hz rows, windows
/// of 4 s every 10 s over a 30 s recording, a model every second window. It reports at the
/// end of each window and nothing in between: a Model and a Health at window 2, a Health
/// alone at windows 1 and 3 (no screening); it goes on from the kept model (the rows add up
/// over the windows, the Health-only windows' too), and its window-2 and final models are
/// lssi-core's f32 identifier's on the same windows' rows (the host runs lssi-device's own
/// sampler on the recording to make them).
#[test]
#[ignore = "needs qemu-system-arm and the standalone firmware ELF: bash scripts/ci-qemu.sh runs it"]
fn standalone_device_identifies_in_windows_and_reports_at_each_windows_end() {
    use lssi_core::{Identifier, Sample};
    use lssi_device::decimate::{Decimator, factor_for};
    use lssi_device::standalone::{Event, EventQueue, Reading, Sampler, Schedule, Shared};
    use lssi_proto::{DeviceMsg, SnapshotCause, WireDuty};

    const ADC_HZ: f64 = 10_000.0;
    const ORDER: u8 = 3;
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("eveh-10k.csv");
    let gen_args = Gen::try_parse_from([
        "gen".as_ref(),
        "eveh".as_ref(),
        csv.as_os_str(),
        "--rate".as_ref(),
        "10000".as_ref(),
        "--t-end".as_ref(),
        "30".as_ref(),
        "--observe".as_ref(),
        "x".as_ref(),
    ] as [&std::ffi::OsStr; 9])
    .expect("gen arguments")
    .args;
    generate::run(&gen_args).expect("lssi gen eveh");
    let recording = Recording::read(&csv, &ColumnNames::default()).expect("the recording");

    // The configuration lssi identify chooses for 200 Hz rows of this harvester (made from
    // the whole recording decimated, as a host would from an earlier recording).
    let factor = factor_for(ADC_HZ, 1.0 / 200.0).expect("a whole factor");
    let mut decimator = Decimator::new(factor, ORDER).expect("a decimator");
    let period = f64::from(factor) / ADC_HZ;
    let offset = decimator.time_offset(ADC_HZ);
    let all: Vec<f32> = recording
        .samples()
        .filter_map(|s| decimator.push([s.x as f32, 0.0, 0.0]).map(|r| r[0]))
        .collect();
    let times: Vec<f64> = (0..all.len()).map(|i| i as f64 * period + offset).collect();
    let xs: Vec<f64> = all.iter().map(|&x| f64::from(x)).collect();
    let decimated = dir.path().join("eveh-200.csv");
    lssi_host::recording::write_csv(&decimated, &["t", "x"], &[&times, &xs]).expect("CSV");
    let decimated = Recording::read(&decimated, &ColumnNames::default()).expect("rows");
    let (mut config, _) = lssi_host::identify::configure(&decimated, &Options::default())
        .expect("lssi identify's configuration for the rows");
    config.sample_period = period;
    let duty = WireDuty {
        window: 4.0,
        interval: 6.0,
        model_every: 2,
    };
    let mut wire = lssi_device::wire::config_to_wire(&config).expect("encodable");
    wire.duty = Some(duty);

    // The rows the device makes in its windows, by lssi-device's sampler itself.
    let shared: Box<Shared<16>> = Box::new(Shared::new());
    let mut queue: EventQueue = EventQueue::new();
    let (producer, mut consumer) = queue.split();
    let mut sampler = Sampler::new(producer);
    sampler.set_decimator(Decimator::new(factor, ORDER).expect("a decimator"));
    let schedule = Schedule::duty(duty.window, duty.interval, ADC_HZ, factor);
    assert_eq!(schedule.window, 40_000);
    sampler.set_schedule(schedule);
    let mut identifier: Box<Identifier<f32, 256, 16, 2>> =
        Box::new(Identifier::new(config).expect("a valid configuration"));
    let (mut rows, mut pauses) = (0u64, 0u32);
    // The second window's model, screened on a snapshot as the device does.
    let mut snapshot: Box<lssi_core::Snapshot<f32, 16>> = Box::new(lssi_core::Snapshot::empty());
    let mut second = None;
    for (i, s) in recording.samples().enumerate() {
        let reading = Reading {
            x: s.x as f32,
            v: None,
            u: None,
            e: None,
        };
        sampler.tick(i as u32, reading, &shared.counters);
        while let Some(event) = consumer.dequeue() {
            match event {
                Event::Sample { index, reading, .. } => {
                    rows += 1;
                    let _ = identifier.push(Sample {
                        t: index as f64 * period + offset,
                        x: reading.x,
                        v: None,
                        u: None,
                    });
                }
                Event::Pause => {
                    pauses += 1;
                    if pauses == 2 {
                        identifier.snapshot_into(&mut snapshot);
                        assert!(snapshot.select(), "a model from {rows} rows");
                        second = Some(
                            lssi_device::wire::snapshot(
                                snapshot.model().expect("a model"),
                                SnapshotCause::Scheduled,
                            )
                            .expect("fits a snapshot"),
                        );
                    }
                }
                Event::End => {}
            }
        }
    }
    assert_eq!(pauses, 3);
    assert!(identifier.screen(), "a model from {rows} rows");
    let expected =
        lssi_device::wire::snapshot(identifier.model().expect("a model"), SnapshotCause::Final)
            .expect("fits a snapshot");

    let (messages, log) = run_standalone(&recording, ADC_HZ, &wire, dir.path());
    // Each window's screening (≈ 8 M instructions, 3.3 M clock ticks in one wake-up before
    // it was sliced) is spread over row periods: no wake-up while sampling is longer than a
    // slice and a row (lssi-standalone's SLICE_TICKS, 25,000, plus the worst row, about
    // 32,000 with the snapshot's copy).
    let longest = longest_wake_up(&log);
    println!("the longest wake-up while sampling: {longest} ticks of 25 MHz");
    assert!(
        longest < 100_000,
        "a wake-up of {longest} ticks: the screening is not spread over rows"
    );
    // One screening while sampling, window 2's: windows 1 and 3 ran none.
    assert!(
        log.contains("screenings run while sampling: 1 "),
        "the windows' screenings:\n{log}"
    );
    // A Health alone at the end of windows 1 and 3, a Model then a Health at window 2,
    // then the final pair.
    let kinds: Vec<&str> = messages
        .iter()
        .map(|m| match m {
            DeviceMsg::Model(s) if s.cause == SnapshotCause::Final => "final",
            DeviceMsg::Model(_) => "model",
            DeviceMsg::Health { .. } => "health",
            _ => "other",
        })
        .collect();
    assert_eq!(
        kinds,
        ["health", "model", "health", "health", "final", "health"],
        "{messages:?}"
    );
    // Each Health carries the drift of the last model made (window 2's, the first: 0).
    let drifts: Vec<Option<(u32, f32)>> = messages
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::Health { drift, .. } => Some(drift.map(|d| (d.windows, d.relative))),
            _ => None,
        })
        .collect();
    assert_eq!(
        drifts,
        [None, Some((2, 0.0)), Some((2, 0.0)), Some((2, 0.0))]
    );
    let samples: Vec<u64> = messages
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::Health {
                samples, overruns, ..
            } => {
                assert_eq!(*overruns, 0);
                Some(*samples)
            }
            _ => None,
        })
        .collect();
    // Each window adds its rows (4 s at 200 Hz, less the warm-up's blocks but one: the
    // CIC's two and its compensator's two) to the kept model; the last report is after the
    // third window (the recording ends asleep).
    let warm_up = Decimator::new(factor, ORDER)
        .expect("a decimator")
        .warm_up();
    assert_eq!(warm_up, u32::from(ORDER) + 2);
    let per_window = 800 - u64::from(warm_up - 1);
    assert_eq!(
        samples,
        [per_window, 2 * per_window, 3 * per_window, 3 * per_window]
    );
    assert_eq!(rows, 3 * per_window);
    let Some(DeviceMsg::Model(got)) = messages
        .iter()
        .rev()
        .find(|m| matches!(m, DeviceMsg::Model(s) if s.cause == SnapshotCause::Final))
    else {
        panic!("no final model");
    };
    let Some(DeviceMsg::Model(got_second)) = messages
        .iter()
        .find(|m| matches!(m, DeviceMsg::Model(s) if s.cause == SnapshotCause::Scheduled))
    else {
        panic!("no window's model");
    };
    let second = second.expect("two pauses");
    for (what, got, expected) in [
        ("final", got, &expected),
        ("window 2's", got_second, &second),
    ] {
        assert_eq!(got.terms, expected.terms, "{what}");
        for (i, (g, w)) in got
            .coefficients
            .iter()
            .zip(&expected.coefficients)
            .enumerate()
        {
            assert!(
                (g - w).abs() <= 1e-5 * w.abs(),
                "{what} model, term {i}: {g} on the device, {w} on the host"
            );
        }
    }
    println!("windowed device's final model: {:?}", got.coefficients);
}

/// The standalone device on a displacement 10⁴ amplitudes from zero (the shipped harvester,
/// `lssi gen eveh` at 10 kHz for 3 s, offset by 10⁴ times its largest |x|): it learns the
/// reference from its first 1,024 rows (their mean, in f64), restarts its identifier at the
/// 1,024th and pushes every row from there less it. Its final model must be, term for term
/// and bit for bit, `lssi identify --f32 --no-refine`'s on those rows (1023..) less the
/// reference its Health reports (identify's own reference rule sees them about zero), and
/// that reference must be the first 1,024 readings' mean as the host sums them.
#[test]
#[ignore = "needs qemu-system-arm and the standalone firmware ELF: bash scripts/ci-qemu.sh runs it"]
fn standalone_device_takes_its_first_rows_mean_off_a_displacement_far_from_zero() {
    use lssi_host::identify::Reference;
    use lssi_host::serial::replay::report_from_snapshot;
    use lssi_proto::{DeviceMsg, SnapshotCause, WireReference};

    const ADC_HZ: f64 = 10_000.0;
    const FIRST: usize = 1024;
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("eveh-10k.csv");
    let gen_args = Gen::try_parse_from([
        "gen".as_ref(),
        "eveh".as_ref(),
        csv.as_os_str(),
        "--rate".as_ref(),
        "10000".as_ref(),
        "--t-end".as_ref(),
        "3".as_ref(),
        "--observe".as_ref(),
        "x".as_ref(),
    ] as [&std::ffi::OsStr; 9])
    .expect("gen arguments")
    .args;
    generate::run(&gen_args).expect("lssi gen eveh");
    let about_zero = Recording::read(&csv, &ColumnNames::default()).expect("the recording");
    let amplitude = about_zero.x.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let offset = 1.0e4 * amplitude;
    let far: Vec<f64> = about_zero.x.iter().map(|x| x + offset).collect();
    let far_csv = dir.path().join("eveh-far.csv");
    lssi_host::recording::write_csv(&far_csv, &["t", "x"], &[&about_zero.t, &far]).expect("CSV");
    let recording = Recording::read(&far_csv, &ColumnNames::default()).expect("the recording");

    // The readings as the image holds them (f32), their first 1,024's mean in f64, and the
    // rows from the 1,024th on less it, as the device pushes them.
    let readings: Vec<f32> = recording.x.iter().map(|&x| x as f32).collect();
    let reference = readings[..FIRST].iter().map(|&x| f64::from(x)).sum::<f64>() / FIRST as f64;
    let shifted = |reference: f64| -> Recording {
        let xs: Vec<f64> = readings[FIRST - 1..]
            .iter()
            .map(|&x| f64::from((f64::from(x) - reference) as f32))
            .collect();
        let path = dir.path().join("eveh-less-reference.csv");
        lssi_host::recording::write_csv(&path, &["t", "x"], &[&recording.t[FIRST - 1..], &xs])
            .expect("CSV");
        Recording::read(&path, &ColumnNames::default()).expect("rows")
    };
    let rows = shifted(reference);
    assert!(
        Reference::of(&rows).is_zero(),
        "identify sees the rows about zero"
    );
    let (config, estimated) = lssi_host::identify::configure(&rows, &Options::default())
        .expect("lssi identify's configuration for the rows");
    let wire = lssi_device::wire::config_to_wire(&config).expect("encodable");

    let (messages, _) = run_standalone(&recording, ADC_HZ, &wire, dir.path());
    let got = messages.iter().rev().find_map(|m| match m {
        DeviceMsg::Model(s) if s.cause == SnapshotCause::Final => Some(s),
        _ => None,
    });
    let health = messages.iter().rev().find_map(|m| match m {
        DeviceMsg::Health {
            samples,
            overruns,
            reference,
            cost_mean,
            cost_max,
            queue_high_water,
            latency_max_ns,
            ..
        } => {
            println!(
                "device: cost {cost_mean} ticks a row on average, {cost_max} at most; queue high-water {queue_high_water}, worst latency {latency_max_ns} ns"
            );
            Some((*samples, *overruns, *reference))
        }
        _ => None,
    });
    let (Some(got), Some((samples, overruns, device_reference))) = (got, health) else {
        panic!("no final model and health in {} frames", messages.len());
    };
    println!("device: {samples} rows, {overruns} overruns, reference {device_reference:?}");
    assert_eq!(overruns, 0, "samples lost");
    assert_eq!(
        device_reference,
        Some(WireReference {
            x: reference,
            v: 0.0,
            e: 0.0
        }),
        "the first 1,024 readings' mean, {reference}"
    );
    assert_eq!(samples, (readings.len() - (FIRST - 1)) as u64);
    assert_eq!(got.samples, samples);

    // lssi identify --f32 --no-refine on the rows less the device's reference.
    let device_rows = shifted(device_reference.expect("a reference").x);
    let want = lssi_host::identify::identify_recording(&device_rows, &Options::default())
        .expect("identify --f32");
    let got = report_from_snapshot(got, &config, estimated).expect("a readable model");
    let terms = |r: &lssi_host::identify::Report| -> Vec<(String, u64)> {
        r.terms
            .iter()
            .map(|t| (t.term.clone(), t.coef.to_bits()))
            .collect()
    };
    println!("device's model less the reference: {:?}", got.terms);
    assert_eq!(terms(&got), terms(&want), "bit for bit: {:?}", want.terms);
    assert!(!want.terms.is_empty());
}
