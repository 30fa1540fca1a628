//! Issue 25's gaps found after the hostile sets: a false withhold of a single well driven
//! hard (the gate's short-horizon windows and refinement's segments fitted from one start), a
//! blemish sentence that named no column and a step in u taken for a spike, and a sweep's
//! range read from the well's own line.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use lssi_host::identify::blemish::{Kind, Scan};
use lssi_host::identify::sweep::sweep;
use lssi_host::recording::{ColumnNames, Recording};

use crate::common::{gen_eveh, identify_json, lssi, terms, truth};

/// A single well driven hard (amplitude 2.2) at 800 and 400 Hz, 25 s, 1–2 % noise: the true
/// model printed (exit 0; coefficients within 10 %, the damping within 25 %). It was withheld
/// ("cannot follow … median NRMSE 70 %") for the true model: each short-horizon window was
/// fitted from the samples' guess alone, and then refinement's shooting segments, from the
/// same guess, bent the coefficients to another optimum (x at −2696 for −337).
#[test]
fn gate_prints_a_hard_driven_single_well() {
    let dir = tempfile::tempdir().unwrap();
    for (rate, delta, seed) in [("800", "0.02", "4242"), ("400", "0.02", "5840")] {
        let args = [
            "--wells",
            "monostable",
            "--amplitude",
            "2.2",
            "--rate",
            rate,
            "--t-end",
            "25",
            "--delta",
            delta,
            "--seed",
            seed,
        ];
        let path = gen_eveh(dir.path(), &format!("hard{seed}.csv"), &args);
        let (code, found) = identify_json(&path, &[]);
        let found = found.unwrap_or_else(|e| panic!("{args:?}: exit {code}: {e}"));
        let (truth, found) = (terms(&truth(&path)), terms(&found));
        assert_eq!(found.len(), truth.len(), "{args:?}: {found:?}");
        for (name, coef) in &truth {
            let (_, c) = found
                .iter()
                .find(|(n, _)| n == name)
                .unwrap_or_else(|| panic!("{args:?}: {name} missing: {found:?}"));
            let tolerance = if name == "v" { 0.25 } else { 0.10 };
            assert!(
                (c - coef).abs() <= tolerance * coef.abs(),
                "{args:?}: {name} {c} against {coef}"
            );
        }
    }
}

/// A generated record with a measured u, its rows from `cut` on with u = 0 (a forcing
/// switched off, as FrID's magneto-mechanical record at row 11000), as CSV text.
fn with_u_cut(recording: &Recording, cut: usize, edit: impl Fn(usize, &mut [f64; 3])) -> String {
    let u = recording.u.as_ref().unwrap();
    let mut text = String::from("t,x,u\n");
    for i in 0..recording.len() {
        let mut row = [
            recording.x[i],
            if i >= cut { 0.0 } else { u[i] },
            recording.t[i],
        ];
        edit(i, &mut row);
        text.push_str(&format!("{},{},{}\n", row[2], row[0], row[1]));
    }
    text
}

/// A forcing switched off (u's last part set to 0) at 16 phases of its period: no spike is
/// found in u where it steps, and nothing is repaired there; a spike in x, one in the sine of
/// u and one in u's zero part are still found, each sentence naming its column, as are a NaN
/// in u and a time gap (t); `lssi identify` names no spike at the step.
#[test]
fn blemish_a_step_in_u_is_no_spike_and_every_sentence_names_its_column() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "u.csv",
        &["--input", "--delta", "0.01", "--t-end", "5", "--seed", "7"],
    );
    let recording = Recording::read(&path, &ColumnNames::default()).unwrap();
    let n = recording.len();
    // Ω = 21.4 rad/s at 2 kHz: 587 samples a period; 16 cuts a 37-sample step apart.
    for k in 0..16 {
        let cut = 6000 + 37 * k;
        let text = with_u_cut(&recording, cut, |_, _| {});
        let file = dir.path().join(format!("cut{k}.csv"));
        std::fs::write(&file, text).unwrap();
        let cut_recording = Recording::read(&file, &ColumnNames::default()).unwrap();
        let scan = Scan::of(&cut_recording);
        assert!(
            scan.blemishes.iter().all(|b| b.kind != Kind::Spike),
            "cut at data row {}: {:?}",
            cut + 1,
            scan.summary()
        );
    }
    // Blemishes of every kind, each in its column.
    let (spike_x, spike_u, spike_zero, nan_u) = (2000, 3000, 8000, 9000);
    let mut text = with_u_cut(&recording, 6000, |i, row| {
        if i == spike_x {
            row[0] += 0.5 * 3e-3;
        }
        if i == spike_u {
            row[1] += 5.0;
        }
        if i == spike_zero {
            row[1] = 3.0;
        }
        if i == nan_u {
            row[1] = f64::NAN;
        }
    });
    // A time gap: three rows cut out after data row 7000 (lines 1..=n after the header).
    let lines: Vec<&str> = text.lines().collect();
    text = lines
        .iter()
        .enumerate()
        .filter(|(j, _)| !(7001..7004).contains(j))
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    assert_eq!(text.lines().count(), n + 1 - 3);
    let file = dir.path().join("blemished.csv");
    std::fs::write(&file, &text).unwrap();
    let blemished = Recording::read(&file, &ColumnNames::default()).unwrap();
    let scan = Scan::of(&blemished);
    let sentences: Vec<String> = scan.blemishes.iter().map(|b| b.sentence()).collect();
    let find = |row: usize| {
        sentences
            .iter()
            .find(|s| s.starts_with(&format!("data row {row} (")))
            .unwrap_or_else(|| panic!("data row {row}: {sentences:?}"))
            .clone()
    };
    assert!(
        find(spike_x + 1).contains("isolated spike in x"),
        "{sentences:?}"
    );
    assert!(
        find(spike_u + 1).contains("isolated spike in u"),
        "{sentences:?}"
    );
    // After the three rows cut out, a row's data row is 3 fewer.
    assert!(
        find(spike_zero + 1 - 3).contains("isolated spike in u"),
        "{sentences:?}"
    );
    assert!(
        find(nan_u + 1 - 3).contains("infinite value in u"),
        "{sentences:?}"
    );
    assert!(
        find(7001).contains("gap of") && find(7001).contains("in t"),
        "{sentences:?}"
    );
    assert_eq!(sentences.len(), 5, "{sentences:?}");
    let summary = scan.summary().join("; ");
    assert!(summary.contains("isolated spikes in x and u"), "{summary}");
    // The way a user meets it: the cut record through `lssi identify`, which names no spike
    // at the step (withheld or not: x goes on as driven after u is cut).
    let out = lssi(&[
        "identify",
        dir.path().join("cut0.csv").to_str().unwrap(),
        "--no-refine",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("spike"), "{stderr}");
}

/// Sweeps without u read with their range within 5 % of the swept band: 10→30 rad/s over 5 s
/// (dechirped whole: x's strongest dechirped line is the well's own at 38→45 rad/s, which
/// was the range named) and over 20 s (the segments' drift, carried to the record's ends:
/// 10.65→29.20 at the end segments' centres), and 30→12 rad/s over 8 s.
#[test]
fn sweep_ranges_are_read_to_the_record_ends() {
    let dir = tempfile::tempdir().unwrap();
    for (from, to, seconds, seed) in [
        (10.0_f64, 30.0_f64, "5", "61"),
        (10.0, 30.0, "20", "62"),
        (30.0, 12.0, "8", "63"),
    ] {
        let args = [
            "--wells",
            "monostable",
            "--excitation",
            "sweep",
            "--omega",
            &format!("{from}"),
            "--sweep-to",
            &format!("{to}"),
            "--t-end",
            seconds,
            "--delta",
            "0.01",
            "--seed",
            seed,
        ];
        let path = gen_eveh(dir.path(), &format!("sweep{seed}.csv"), &args);
        let recording = Recording::read(&path, &ColumnNames::default()).unwrap();
        let found = sweep(&recording).unwrap_or_else(|| panic!("{args:?}: no sweep"));
        let tolerance = 0.05 * (to - from).abs();
        assert!(
            (found.from - from).abs() < tolerance && (found.to - to).abs() < tolerance,
            "{args:?}: {found:?}"
        );
    }
}

#[test]
fn a_model_driven_by_u_names_no_omega() {
    // With u the library has no harmonics: the report had printed "Ω = 1.0000 rad/s", a
    // placeholder a user would read as the forcing's frequency.
    let dir = tempfile::tempdir().unwrap();
    for (name, args, omega) in [
        ("u.csv", &["--input", "--t-end", "6"][..], false),
        ("cos.csv", &["--t-end", "6"][..], true),
    ] {
        let path = gen_eveh(dir.path(), name, args);
        let out = lssi(&["identify", "--no-refine", path.to_str().unwrap()]);
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{name}: {text}");
        assert_eq!(
            text.contains("Ω: none (no harmonics in the library)"),
            !omega,
            "{text}"
        );
        assert_eq!(text.contains("Ω = 21.4"), omega, "{text}");
    }
}
