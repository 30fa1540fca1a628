//! `lssi replay` as a person runs it: the same JSON as `lssi identify --f32 --no-refine --json` plus
//! `"link"`; a simulator killed mid-replay gives one sentence naming the port and leaves a
//! readable log; bad flags and missing devices are one sentence each.
//!
//! These start firmware-sim, which `cargo test --workspace` builds next to `lssi` (see
//! `tests/tests/replay.rs` for how it is found).

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::common::lssi;
use lssi_host::telemetry::{RecordKind, read_log};

fn bundled() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/paper-eq17.csv")
}

pub(crate) fn require_firmware_sim() {
    let next_to_lssi = Path::new(env!("CARGO_BIN_EXE_lssi")).with_file_name("firmware-sim");
    assert!(
        next_to_lssi.is_file() || std::env::var_os("LSSI_FIRMWARE_SIM").is_some(),
        "{} is not built: run `cargo test --workspace` (or `cargo build -p firmware-sim --profile test`)",
        next_to_lssi.display()
    );
}

#[test]
fn replay_json_is_identify_json_plus_the_link() {
    require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    // A copy of the recording, so that the default log lands in the temporary directory.
    let file = dir.path().join("eq17.csv");
    std::fs::copy(bundled(), &file).unwrap();
    let file = file.to_str().unwrap();

    let identify = lssi(&["identify", "--f32", "--no-refine", "--json", file]);
    assert!(identify.status.success());
    let mut identify: serde_json::Value = serde_json::from_slice(&identify.stdout).unwrap();
    // identify's last key, "warnings" (left-out samples, the quality gate), is not replay's.
    let warnings = identify
        .as_object_mut()
        .unwrap()
        .remove("warnings")
        .unwrap();
    assert_eq!(warnings, serde_json::json!(["not refined (--no-refine)"]));

    let replay = lssi(&["replay", "--json", "--baud", "4000000", file]);
    assert!(
        replay.status.success(),
        "{}",
        String::from_utf8_lossy(&replay.stderr)
    );
    let mut replay: serde_json::Value = serde_json::from_slice(&replay.stdout).unwrap();
    let link = replay.as_object_mut().unwrap().remove("link").unwrap();
    assert_eq!(replay, identify);
    for key in ["frames_sent", "retransmits", "crc_errors"] {
        assert!(link[key].is_u64(), "{key} in {link}");
    }
    assert_eq!(link["samples_lost"], 0);

    // The default log is next to the input, and `lssi log` reads it.
    let log = dir.path().join("eq17.tlm");
    let out = lssi(&["log", log.to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("model (query, 20001 samples): x'' ="),
        "{text}"
    );
    assert!(text.contains("summary:"), "{text}");
}

/// The children of a process (Linux: /proc/PID/task/PID/children).
fn children(pid: u32) -> Vec<u32> {
    std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/children"))
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|p| p.parse().ok())
        .collect()
}

#[test]
fn killing_the_simulator_mid_replay_names_the_port_and_keeps_the_log() {
    require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("killed.tlm");
    // 115 200 baud: the replay takes about 30 s, far longer than it takes to kill it.
    let child = Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(["replay", "--baud", "115200", "--log", log.to_str().unwrap()])
        .arg(bundled())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until some acknowledgements are in the log (no time limit: the test harness has
    // one), then kill the simulator.
    let sim = loop {
        let frames = std::fs::read(&log)
            .ok()
            .and_then(|bytes| read_log(&bytes).ok())
            .map_or(0, |c| {
                c.records
                    .iter()
                    .filter(|r| r.kind == RecordKind::Frame)
                    .count()
            });
        let sims = children(child.id());
        if frames >= 20 && !sims.is_empty() {
            break sims[0];
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let killed = Command::new("kill")
        .args(["-9", &sim.to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("lssi: /dev/pts/"), "{stderr}");
    assert!(stderr.contains("the link closed"), "{stderr}");
    assert!(out.stdout.is_empty());

    // The log holds everything received, whole, and ends with why the replay stopped.
    let contents = read_log(&std::fs::read(&log).unwrap()).unwrap();
    assert!(contents.partial_tail.is_none());
    assert!(contents.records.iter().any(|r| r.kind == RecordKind::Note
        && String::from_utf8_lossy(&r.data).starts_with("replay stopped: /dev/pts/")));
    let out = lssi(&["log", log.to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("hello: protocol"), "{text}");
    assert!(text.contains("note: replay stopped"), "{text}");
}

#[test]
fn bad_flags_and_missing_devices_are_one_sentence() {
    let file = bundled();
    let file = file.to_str().unwrap();
    let cases: [(&[&str], i32, &str); 5] = [
        (&["--flip-rate", "2"], 2, "--flip-rate 2 cannot be used"),
        (&["--batch", "25"], 2, "--batch 25 cannot be used"),
        (&["--harmonics", "9"], 2, "--harmonics 9 cannot be used"),
        (
            &["--port", "/nonexistent/ttyUSB9"],
            1,
            "/nonexistent/ttyUSB9: cannot open the serial port",
        ),
        (
            &["--qemu", "--firmware", "/nonexistent/fw.elf"],
            2,
            "/nonexistent/fw.elf: the firmware image does not exist",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("bad.tlm");
    for (flags, code, start) in cases {
        let mut args = vec!["replay", "--log", log.to_str().unwrap()];
        args.extend_from_slice(flags);
        args.push(file);
        let out = lssi(&args);
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(code), "{flags:?}: {stderr}");
        assert!(
            stderr.starts_with(&format!("lssi: {start}")),
            "{flags:?}: {stderr}"
        );
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
    }
}

/// `--row-rate proposed`: the rows averaged down to the rate `lssi identify` proposes (the
/// recording's rate over the largest whole number keeping them at or above it), the same
/// model as that rate given as a number, the proposal named on stderr; a recording whose
/// model is withheld has no proposal, and says so.
#[test]
fn the_proposed_row_rate_is_the_identified_rate_averaged_down() {
    require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("eveh.csv");
    let f = file.to_str().unwrap();
    let out = lssi(&[
        "gen", "eveh", "--rate", "2000", "--t-end", "12", "--seed", "5", f,
    ]);
    assert!(out.status.success());
    let identify = lssi(&["identify", "--no-refine", f]);
    let text = String::from_utf8_lossy(&identify.stdout);
    let proposed: f64 = text
        .split("a device needs ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no proposal: {text}"));
    let k = (2000.0 / proposed).floor();
    let rate = 2000.0 / k;
    let run = |row_rate: &str| {
        let out = lssi(&[
            "replay",
            "--json",
            "--baud",
            "4000000",
            "--row-rate",
            row_rate,
            "--log",
            dir.path().join(format!("{row_rate}.tlm")).to_str().unwrap(),
            f,
        ]);
        assert!(
            out.status.success(),
            "{row_rate}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (json, String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (by_name, said) = run("proposed");
    let (by_number, _) = run(&format!("{rate}"));
    assert!(
        said.contains(&format!("averaged {k} at a time"))
            && said.contains(&format!("a device needs {proposed} Hz")),
        "{said}"
    );
    let period = by_name["sample_period"].as_f64().unwrap();
    assert!((1.0 / period - rate).abs() < 1e-6 * rate, "{period}");
    assert!(1.0 / period >= proposed);
    assert_eq!(by_name["terms"], by_number["terms"]);
    // White noise: no model, so no proposal.
    let noise = dir.path().join("noise.csv");
    let mut csv = String::from("t,x\n");
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for i in 0..4000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let x = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        csv.push_str(&format!("{},{x}\n", i as f64 / 2000.0));
    }
    std::fs::write(&noise, csv).unwrap();
    let out = lssi(&["replay", "--row-rate", "proposed", noise.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--row-rate proposed") && err.contains("give --row-rate HZ"),
        "{err}"
    );
    let out = lssi(&["replay", "--row-rate", "fast", f]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("nor `proposed`"), "{err}");
}

/// The shipped monostable harvester's x written in a channel's far-from-zero forms (raw
/// 16-bit ADC counts about mid-scale, an offset of 10⁴ amplitudes): replay sends it less the reference `lssi identify`
/// takes off (before anything meets f32), and reports the device's model back in the
/// recording's coordinates: `identify --f32 --no-refine` to the bit. Sent as it was, the
/// device kept a few bits of the motion and printed another model.
#[test]
fn a_channel_far_from_zero_replays_as_identify_f32_takes_it() {
    require_firmware_sim();
    let dir = tempfile::tempdir().unwrap();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/eveh-monostable.csv");
    let text = std::fs::read_to_string(shipped).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let x_column = header.split(',').position(|h| h.trim() == "x").unwrap();
    let rows: Vec<Vec<String>> = lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split(',').map(|v| v.trim().to_owned()).collect())
        .collect();
    let amplitude = rows
        .iter()
        .map(|r| r[x_column].parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    for (name, shift) in [("counts", None), ("far", Some(1e4 * amplitude))] {
        let mut out = format!("{header}\n");
        for r in &rows {
            let x: f64 = r[x_column].parse().unwrap();
            let mut r = r.clone();
            r[x_column] = match shift {
                Some(s) => format!("{}", x + s),
                None => format!("{}", (32768.0 + 3000.0 * x / amplitude).round()),
            };
            out.push_str(&r.join(","));
            out.push('\n');
        }
        let file = dir.path().join(format!("{name}.csv"));
        std::fs::write(&file, out).unwrap();
        let f = file.to_str().unwrap();
        let identify = lssi(&["identify", "--f32", "--no-refine", "--json", f]);
        assert!(
            identify.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&identify.stderr)
        );
        let mut identify: serde_json::Value = serde_json::from_slice(&identify.stdout).unwrap();
        identify.as_object_mut().unwrap().remove("warnings");
        assert!(
            identify["offsets"][0].as_f64().unwrap().abs() > 100.0 * amplitude,
            "{name}: {identify}"
        );
        let replay = lssi(&["replay", "--json", "--baud", "4000000", f]);
        assert!(
            replay.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&replay.stderr)
        );
        let mut replay: serde_json::Value = serde_json::from_slice(&replay.stdout).unwrap();
        replay.as_object_mut().unwrap().remove("link");
        assert_eq!(replay, identify, "{name}");
    }
}
