//! Issue 26, item 3: the power against the forcing frequency is centred on the forcing the
//! harvester was recorded under, also when that forcing is the measured base acceleration u
//! (Ω is then not estimated: the sweep had been centred on its 1 rad/s placeholder), as a
//! user runs `lssi identify FILE --load-ohms R`.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::process::Command;

use serde_json::Value;

#[test]
fn the_power_against_frequency_is_centred_on_the_measured_forcing() {
    let dir = tempfile::tempdir().unwrap();
    let lssi = env!("CARGO_BIN_EXE_lssi");
    // Two forcing frequencies, so that a sweep centred on a constant cannot pass both.
    for (omega, seed) in [("50.26548", "3"), ("31.4159", "4")] {
        let path = dir.path().join(format!("piezo-{seed}.csv"));
        let o = Command::new(lssi)
            .args([
                "gen", "piezo", "--input", "--delta", "0.01", "--t-end", "10",
            ])
            .args(["--omega", omega, "--seed", seed])
            .arg(&path)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let truth: Value =
            serde_json::from_str(&std::fs::read_to_string(path.with_extension("json")).unwrap())
                .unwrap();
        let omega = truth["omega"].as_f64().unwrap();
        let o = Command::new(lssi)
            .arg("identify")
            .arg(&path)
            .args(["--load-ohms", "1e5", "--no-refine", "--json"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let json: Value = serde_json::from_slice(&o.stdout).unwrap();
        let h = &json["harvester"];
        let sweep = h["frequency_sweep"].as_array().unwrap();
        assert_eq!(sweep.len(), 21, "{h}");
        // From half to one and a half times the forcing, its middle point the forcing itself
        // (u's strongest spectral line: within a bin of the 10 s record, 0.63 rad/s).
        let middle = sweep[10]["at"].as_f64().unwrap();
        assert!(
            (middle - omega).abs() < 0.7,
            "{middle} against {omega}: {h}"
        );
        let first = sweep[0]["at"].as_f64().unwrap();
        assert!((first / middle - 0.5).abs() < 1e-9, "{h}");
        // At the forcing (a tone of u's RMS, as recorded) the predicted power is the recorded
        // one's order: the sweep is about this harvester, not a placeholder frequency.
        let at_forcing = sweep[10]["power_w"].as_f64().unwrap();
        let measured = h["power_measured_w"].as_f64().unwrap();
        assert!(
            (at_forcing / measured - 1.0).abs() < 0.25,
            "{at_forcing} W at the forcing against {measured} W measured: {h}"
        );
    }
}
