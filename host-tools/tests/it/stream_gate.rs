//! A file read in chunks (over `STREAM_BYTES`) whose model the gate withholds: exit status 3,
//! and its `--json` is the in-memory file's shape ("withheld": true, the reason, the model
//! only under "withheld_model", no top-level "terms").

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::io::Write;
use std::process::Command;

use lssi_host::identify::stream::STREAM_BYTES;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

const LSSI: &str = env!("CARGO_BIN_EXE_lssi");

#[test]
fn a_withheld_streamed_model_has_no_top_level_terms() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("noise.csv");
    let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    writeln!(file, "t,x").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(61);
    let mut i = 0u64;
    while std::fs::metadata(&path).map_or(0, |m| m.len()) <= STREAM_BYTES + (1 << 20) {
        for _ in 0..10_000 {
            let x: f64 = StandardNormal.sample(&mut rng);
            writeln!(file, "{:?},{:?}", i as f64 / 50_000.0, 1e-3 * x).unwrap();
            i += 1;
        }
        file.flush().unwrap();
    }
    drop(file);
    let out = Command::new(LSSI)
        .arg("identify")
        .arg(&path)
        .arg("--json")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains("no deterministic dynamics found in"),
        "{stderr}"
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["withheld"], true);
    assert!(
        json["reason"]
            .as_str()
            .unwrap()
            .contains("no deterministic dynamics")
    );
    assert!(json.get("terms").is_none(), "{json}");
    assert!(json["withheld_model"]["terms"].is_array(), "{json}");
}
