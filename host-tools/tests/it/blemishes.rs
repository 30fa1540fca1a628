//! Issue 16, item 1: blemished recordings. Each test generates the harvester recording with
//! `lssi gen eveh` (the one `data/eveh-bistable.csv` holds), blemishes a copy the way the
//! issue describes, and compares `lssi identify --json` on it with the clean file's model.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lssi_host::identify::blemish::{Kind, Scan};
use lssi_host::recording::{ColumnNames, Recording};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

/// A freshly generated harvester recording (`lssi gen eveh`): its header and data lines.
fn generated(dir: &Path) -> (PathBuf, String, Vec<String>) {
    let path = dir.join("clean.csv");
    let out = Command::new(LSSI)
        .args(["gen", "eveh"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines().map(str::to_owned);
    let header = lines.next().unwrap();
    (path, header, lines.collect())
}

fn write(dir: &Path, name: &str, header: &str, rows: &[String]) -> PathBuf {
    let path = dir.join(name);
    let mut text = String::from(header);
    text.push('\n');
    for r in rows {
        text.push_str(r);
        text.push('\n');
    }
    std::fs::write(&path, text).unwrap();
    path
}

/// Row `i` with its x replaced by `value`.
fn with_x(rows: &mut [String], i: usize, value: &str) {
    let t = rows[i].split(',').next().unwrap().to_owned();
    rows[i] = format!("{t},{value}");
}

fn identify(path: &Path) -> Output {
    Command::new(LSSI)
        .arg("identify")
        .arg(path)
        .arg("--json")
        // The streaming identifier's blemish handling (refinement has its own tests).
        .arg("--no-refine")
        .output()
        .unwrap()
}

/// The model of a successful `identify --json`: term → coefficient, Ω, and the JSON.
fn model(out: &Output) -> (BTreeMap<String, f64>, serde_json::Value) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let terms = json["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["term"].as_str().unwrap().to_owned(),
                t["coef"].as_f64().unwrap(),
            )
        })
        .collect();
    (terms, json)
}

/// The largest relative difference of the coefficients, per term; the term sets must match.
fn errors(clean: &BTreeMap<String, f64>, other: &BTreeMap<String, f64>) -> BTreeMap<String, f64> {
    assert_eq!(
        clean.keys().collect::<Vec<_>>(),
        other.keys().collect::<Vec<_>>(),
        "the blemished file selects other terms"
    );
    clean
        .iter()
        .map(|(k, c)| (k.clone(), (other[k] / c - 1.0).abs()))
        .collect()
}

/// The bound, 2 %, on every coefficient. The damping `v` is the weakest term of this
/// model (ζ = 0.011) and the one a blemish moves: a sample left out restarts the derivative
/// window, which leaves a hole in the test-function sums around it (measured with the streaming
/// model: two NaN rows 1.66 %, the 0.1 s gap 0.75 %; an isolated spike left out moved it by up
/// to 2.12 %, which is why a spike is now repaired instead: ≤ 0.03 % at the three places below).
fn assert_close(clean: &BTreeMap<String, f64>, other: &BTreeMap<String, f64>, what: &str) {
    assert_within(clean, other, what, 0.02);
}

fn assert_within(
    clean: &BTreeMap<String, f64>,
    other: &BTreeMap<String, f64>,
    what: &str,
    bound: f64,
) {
    for (term, e) in errors(clean, other) {
        assert!(e <= bound, "{what}: {term} off by {:.3} %", 100.0 * e);
    }
}

/// The warnings of `--json`, less the note that `--no-refine` asked for the streaming model.
fn warnings(json: &serde_json::Value) -> Vec<String> {
    json["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_owned())
        .filter(|w| w != "not refined (--no-refine)")
        .collect()
}

#[test]
fn blemished_copies_give_the_clean_model_and_name_the_blemish() {
    let dir = tempfile::tempdir().unwrap();
    let (clean_path, header, rows) = generated(dir.path());
    let (clean, clean_json) = model(&identify(&clean_path));
    assert!(warnings(&clean_json).is_empty());
    assert_eq!(clean_json["rejected"], 0);
    let omega = clean_json["omega"].as_f64().unwrap();

    // Two rows set to NaN (was: `sin`, no `v`, no warning).
    let mut nan = rows.clone();
    with_x(&mut nan, 12_000, "NaN");
    with_x(&mut nan, 25_000, "NaN");
    let (m, json) = model(&identify(&write(dir.path(), "nan.csv", &header, &nan)));
    assert_close(&clean, &m, "two NaN rows");
    assert_eq!(json["rejected"], 2);
    let w = warnings(&json).join("\n");
    assert!(
        w.contains("data row 12001") && w.contains("data row 25001"),
        "{w}"
    );
    assert!(w.contains("NaN"), "{w}");

    // 200 rows cut out, a 0.1 s gap (was: Ω = 21.52 rad/s, a wrong model, no warning).
    let cut: Vec<String> = rows[..20_000]
        .iter()
        .chain(&rows[20_200..])
        .cloned()
        .collect();
    let (m, json) = model(&identify(&write(dir.path(), "gap.csv", &header, &cut)));
    assert!(
        (json["omega"].as_f64().unwrap() - omega).abs() < 1e-3,
        "Ω {} against {omega}",
        json["omega"]
    );
    assert_close(&clean, &m, "a 0.1 s gap");
    let w = warnings(&json).join("\n");
    assert!(w.contains("data row 20001") && w.contains("gap"), "{w}");

    // One sample of 1e300, at three places (was: "x'' has no spectral peak").
    for at in [6_000, 15_000, 30_000] {
        let mut spike = rows.clone();
        with_x(&mut spike, at, "1e300");
        let (m, json) = model(&identify(&write(dir.path(), "spike.csv", &header, &spike)));
        // Repaired by the cubic through its neighbours: the window goes on, the model is
        // the clean one to a fraction of the 2 %.
        assert_within(&clean, &m, &format!("a spike at row {at}"), 0.001);
        assert_eq!(json["rejected"], 1);
        let w = warnings(&json).join("\n");
        assert!(
            w.contains(&format!("data row {}", at + 1))
                && w.contains("spike")
                && w.contains("replaced by the cubic"),
            "{w}"
        );
    }
}

/// A NaN every 200 samples leaves stretches shorter than a derivative window and a test
/// function: refused with a sentence that names the blemish and where it is (was: "too few
/// regression rows").
#[test]
fn a_nan_every_200_rows_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let (_, header, mut rows) = generated(dir.path());
    for i in (100..rows.len()).step_by(200) {
        with_x(&mut rows, i, "NaN");
    }
    let out = identify(&write(dir.path(), "nan200.csv", &header, &rows));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("too broken to identify"), "{stderr}");
    assert!(stderr.contains("NaN or infinite values"), "{stderr}");
    assert!(
        stderr.contains("data rows 101, 301, 501") && stderr.contains("every 200 rows"),
        "{stderr}"
    );
    assert!(!stderr.contains("too few regression rows"), "{stderr}");
}

/// The spike rule finds nothing in the shipped recordings (noisy, quantised) nor in a fresh
/// noisy one, finds a spike where there is one, and takes a step for no spike.
#[test]
fn the_spike_rule_finds_spikes_only() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data");
    for name in [
        "eveh-bistable.csv",
        "eveh-monostable.csv",
        "eveh-drift.csv",
        "paper-eq17.csv",
    ] {
        let r = Recording::read(root.join(name), &ColumnNames::default()).unwrap();
        let scan = Scan::of(&r);
        assert!(scan.is_clean(), "{name}: {:?}", scan.summary());
    }
    let dir = tempfile::tempdir().unwrap();
    let noisy = dir.path().join("noisy.csv");
    let out = Command::new(LSSI)
        .args(["gen", "eveh", "--delta", "0.05", "--seed", "7"])
        .arg(&noisy)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let mut r = Recording::read(&noisy, &ColumnNames::default()).unwrap();
    assert!(Scan::of(&r).is_clean(), "{:?}", Scan::of(&r).summary());
    // A spike of twice the RMS (40 noise σ) at one sample, and a step as high elsewhere.
    let rms = (r.x.iter().map(|x| x * x).sum::<f64>() / r.x.len() as f64).sqrt();
    r.x[9_000] += 2.0 * rms;
    for x in &mut r.x[20_000..] {
        *x += 2.0 * rms;
    }
    let scan = Scan::of(&r);
    let found: Vec<(Kind, usize)> = scan.blemishes.iter().map(|b| (b.kind, b.index)).collect();
    assert_eq!(found, vec![(Kind::Spike, 9_000)]);
    assert!(scan.skip[9_000] && scan.restart[9_001]);
    // Repaired: x there as the cubic through its four neighbours, within the noise of the
    // sample it replaces.
    let repaired = scan.repairs[&9_000].x;
    let expected = (-r.x[8_998] + 4.0 * r.x[8_999] + 4.0 * r.x[9_001] - r.x[9_002]) / 6.0;
    assert!((repaired - expected).abs() <= 1e-12 * expected.abs().max(1e-300));
    let original = r.x[9_000] - 2.0 * rms;
    assert!(
        (repaired - original).abs() < 0.25 * rms,
        "{repaired} for {original}"
    );
}
