//! A harvester shaken broadband (`lssi gen eveh --excitation random`: 48 tones at random
//! phases), issue 25's "white noise" variation: with the excitation recorded as u the truth,
//! without it a withheld model that names the forcing the recording lacks.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use crate::common::{gen_eveh, identify_json, terms, truth};

#[test]
fn a_broadband_forcing_recorded_as_u_gives_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "r.csv",
        &[
            "--wells",
            "monostable",
            "--excitation",
            "random",
            "--omega",
            "10",
            "--sweep-to",
            "60",
            "--amplitude",
            "3",
            "--input",
            "--rate",
            "1000",
            "--t-end",
            "20",
            "--delta",
            "0.01",
            "--seed",
            "7",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 0, "{out:?}");
    let got = terms(&out.unwrap());
    let want = terms(&truth(&path));
    let names = |t: &[(String, f64)]| t.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&got), names(&want));
    for ((name, c), (_, w)) in got.iter().zip(&want) {
        let bar = if name == "v" { 0.25 } else { 0.1 };
        assert!((c / w - 1.0).abs() <= bar, "{name}: {c} against {w}");
    }
}

#[test]
fn a_broadband_forcing_not_recorded_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = gen_eveh(
        dir.path(),
        "r.csv",
        &[
            "--wells",
            "bistable",
            "--excitation",
            "random",
            "--omega",
            "10",
            "--sweep-to",
            "60",
            "--rate",
            "1000",
            "--t-end",
            "20",
            "--seed",
            "8",
        ],
    );
    let (code, out) = identify_json(&path, &[]);
    assert_eq!(code, 3, "{out:?}");
    let err = out.unwrap_err();
    assert!(err.contains("not one steady tone"), "{err}");
}
