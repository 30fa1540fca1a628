//! `lssi plot` on the recording that ships in data/: every figure as a valid, non-trivial PNG
//! and SVG, the paths printed; and one-sentence errors for bad flags.

use std::path::Path;
use std::process::Command;

const FILE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/paper-eq17.csv");
const FIGURES: [&str; 5] = [
    "model",
    "screening",
    "k-neighbours",
    "coefficients",
    "phase",
];

fn lssi(args: &[&str], out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lssi"))
        .arg("plot")
        .arg(FILE)
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .expect("runs lssi")
}

/// Width and height from a PNG's IHDR chunk.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

#[test]
fn every_figure_is_a_valid_png_and_svg() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A directory that does not exist yet.
    let out = dir.path().join("figures");
    let output = lssi(&["--omega", "1", "--harmonics", "3", "--x-unit", "m"], &out);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let printed = String::from_utf8_lossy(&output.stdout);
    for figure in FIGURES {
        let png = out.join(format!("paper-eq17-{figure}.png"));
        let svg = out.join(format!("paper-eq17-{figure}.svg"));
        assert!(
            printed.contains(&*png.to_string_lossy()),
            "{figure}: path not printed in {printed}"
        );
        let bytes = std::fs::read(&png).expect("PNG written");
        let (w, h) = png_size(&bytes);
        assert!(w >= 1000 && h >= 600, "{figure}: {w}×{h}");
        // A blank white image compresses to a few kB; a chart with text is far larger.
        assert!(
            bytes.len() > 30_000,
            "{figure}: PNG only {} bytes",
            bytes.len()
        );
        let text = std::fs::read_to_string(&svg).expect("SVG written");
        assert!(text.contains("<svg") && text.trim_end().ends_with("</svg>"));
        assert!(text.contains("<text"), "{figure}: SVG has no text");
        assert!(text.contains("<polyline") || text.contains("<path") || text.contains("<circle"));
        assert!(
            text.len() > 10_000,
            "{figure}: SVG only {} bytes",
            text.len()
        );
    }
    let model = std::fs::read_to_string(out.join("paper-eq17-model.svg")).expect("SVG");
    assert!(
        model.contains("displacement x [m]"),
        "unit in the axis label"
    );
    assert!(model.contains("identified model, free run"), "legend");
}

#[test]
fn json_lists_the_figures_and_the_model() {
    let dir = tempfile::tempdir().expect("tempdir");
    let output = lssi(&["--omega", "2", "--json"], dir.path());
    assert!(output.status.success());
    let doc: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    assert_eq!(doc["figures"].as_array().map(Vec::len), Some(FIGURES.len()));
    assert!(doc["report"]["terms"].is_array());
}

#[test]
fn bad_flags_are_one_sentence_and_exit_code_2() {
    let dir = tempfile::tempdir().expect("tempdir");
    let output = lssi(&["--x-unit", " "], dir.path());
    assert_eq!(output.status.code(), Some(2));
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(message.starts_with("lssi: --x-unit"), "{message}");
    assert_eq!(message.trim_end().lines().count(), 1, "{message}");

    let output = lssi(&["--poly-order", "12"], dir.path());
    assert_eq!(output.status.code(), Some(2));

    // --out names a file.
    let file = dir.path().join("not-a-dir");
    std::fs::write(&file, "x").expect("write");
    let output = lssi(&[], &file);
    assert_eq!(output.status.code(), Some(2));
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(message.contains("not a directory"), "{message}");
}
