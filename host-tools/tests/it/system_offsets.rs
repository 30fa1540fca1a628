//! Offsets and ranges of a system's channels (issue 25, item 3, for issue 26's systems): a
//! piezo harvester's x and V offset far from zero, V off centre, and both as raw 12-bit ADC
//! counts give in f32 the model of the same recording with each channel's mean removed (the
//! same terms, coefficients within 0.5 % or one of their ±; counts: the coefficients that do
//! not depend on the channels' scales), the report names what was removed, and `lssi
//! simulate` of that model on the offset recording follows it as well as the centred model
//! follows the centred recording (issue 26, item 4: the recording's units and coordinates).

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::{Path, PathBuf};

use crate::common::{equations, generate, identify_json, lssi};

/// The columns t, x, V of a CSV.
fn read(path: &Path) -> (Vec<String>, Vec<f64>, Vec<f64>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "t,x,V");
    let (mut t, mut x, mut v) = (Vec::new(), Vec::new(), Vec::new());
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        t.push(f[0].to_owned());
        x.push(f[1].parse().unwrap());
        v.push(f[2].parse().unwrap());
    }
    (t, x, v)
}

fn write(dir: &Path, name: &str, t: &[String], x: &[f64], v: &[f64]) -> PathBuf {
    let path = dir.join(name);
    let mut s = String::from("t,x,V\n");
    for ((t, x), v) in t.iter().zip(x).zip(v) {
        s.push_str(&format!("{t},{x:e},{v:e}\n"));
    }
    std::fs::write(&path, s).unwrap();
    path
}

fn mean(s: &[f64]) -> f64 {
    s.iter().sum::<f64>() / s.len() as f64
}

/// `lssi simulate`'s NRMSE of x and V (its table's rows).
fn simulated(model: &serde_json::Value, dir: &Path, csv: &Path) -> Vec<f64> {
    let path = dir.join("model.json");
    std::fs::write(&path, model.to_string()).unwrap();
    let o = lssi(&["simulate", path.to_str().unwrap(), csv.to_str().unwrap()]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(o.status.success(), "{text}");
    ["x", "V"]
        .iter()
        .map(|s| {
            let line = text
                .lines()
                .find(|l| l.trim_start().starts_with(&format!("{s} ")))
                .unwrap_or_else(|| panic!("{text}"));
            line.split_whitespace().nth(1).unwrap().parse().unwrap()
        })
        .collect()
}

#[test]
fn offset_channels_give_the_centred_recordings_model() {
    let dir = tempfile::tempdir().unwrap();
    let source = generate(
        dir.path(),
        "source.csv",
        &["piezo", "--delta", "0.01", "--t-end", "6", "--seed", "41"],
    );
    let (t, x, v) = read(&source);
    let (mx, mv) = (mean(&x), mean(&v));
    let xc: Vec<f64> = x.iter().map(|q| q - mx).collect();
    let vc: Vec<f64> = v.iter().map(|q| q - mv).collect();
    let amplitude = xc.iter().fold(0.0f64, |m, q| m.max(q.abs()));
    let range_v = vc.iter().fold(0.0f64, |m, q| m.max(q.abs())) * 2.0;
    let centred = write(dir.path(), "centred.csv", &t, &xc, &vc);
    let (code, want) = identify_json(&centred, &[]);
    let want = want.unwrap_or_else(|e| panic!("exit {code}: {e}"));
    assert!(want.get("reference").is_none(), "{want}");
    let want_eq = equations(&want);
    let want_fit = simulated(&want, dir.path(), &centred);
    let shifted = |dx: f64, dv: f64| -> (Vec<f64>, Vec<f64>) {
        (
            xc.iter().map(|q| q + dx).collect(),
            vc.iter().map(|q| q + dv).collect(),
        )
    };
    type Case<'a> = (&'a str, (Vec<f64>, Vec<f64>), &'a [&'a str]);
    let cases: Vec<Case> = vec![
        ("x + 1e4 amplitudes", shifted(1e4 * amplitude, 0.0), &["x"]),
        ("V + 10 ranges", shifted(0.0, 10.0 * range_v), &["V"]),
        ("V + 0.2 range", shifted(0.0, 0.2 * range_v), &["V"]),
        ("both off", shifted(0.5, 300.0 * range_v), &["V", "x"]),
    ];
    for (label, (xo, vo), removed) in cases {
        let path = write(dir.path(), "offset.csv", &t, &xo, &vo);
        let (code, have) = identify_json(&path, &[]);
        let have = have.unwrap_or_else(|e| panic!("{label}: exit {code}: {e}"));
        let names: Vec<&str> = have["reference"]
            .as_object()
            .unwrap_or_else(|| panic!("{label}: {have}"))
            .keys()
            .map(String::as_str)
            .collect();
        assert_eq!(names, removed, "{label}");
        let have_eq = equations(&have);
        assert_eq!(
            have_eq.keys().collect::<Vec<_>>(),
            want_eq.keys().collect::<Vec<_>>(),
            "{label}"
        );
        for (target, terms) in &want_eq {
            let got = &have_eq[target];
            assert_eq!(
                got.keys().collect::<Vec<_>>(),
                terms.keys().collect::<Vec<_>>(),
                "{label}: {target}"
            );
            for (k, (c, se)) in terms {
                let d = (got[k].0 - c).abs();
                assert!(
                    d <= 0.005 * c.abs() || d <= *se,
                    "{label}: {target}'s {k} {} against {c} ± {se}",
                    got[k].0
                );
            }
        }
        let fit = simulated(&have, dir.path(), &path);
        for (a, b) in fit.iter().zip(&want_fit) {
            assert!(
                (a - b).abs() <= 0.002,
                "{label}: NRMSE {fit:?} against {want_fit:?}"
            );
        }
    }
    // Raw 12-bit counts of both, about mid-scale (x over 0.8 of the range, V over 0.9).
    let counts = |s: &[f64], full: f64| -> Vec<f64> {
        s.iter()
            .map(|q| (q / full * 2047.0 + 2048.0).round())
            .collect()
    };
    let xq = counts(&xc, 1.25 * amplitude);
    let vq = counts(&vc, range_v / 1.8);
    let path = write(dir.path(), "counts.csv", &t, &xq, &vq);
    let (code, have) = identify_json(&path, &[]);
    let have = have.unwrap_or_else(|e| panic!("counts: exit {code}: {e}"));
    assert!(have["reference"].get("x").is_some(), "{have}");
    assert!(have["reference"].get("V").is_some(), "{have}");
    let have_eq = equations(&have);
    for (target, k) in [("x''", "x"), ("x''", "v"), ("V'", "V")] {
        let (c, _) = want_eq[target][k];
        let got = have_eq[target][k].0;
        assert!(
            (got / c - 1.0).abs() < 0.01,
            "counts: {target}'s {k} {got} against {c}"
        );
    }
    // (A constant is the channels' means' business: each is the recording's less its own.)
    for (target, terms) in &want_eq {
        assert_eq!(
            have_eq[target]
                .keys()
                .filter(|k| *k != "1")
                .collect::<Vec<_>>(),
            terms.keys().filter(|k| *k != "1").collect::<Vec<_>>(),
            "counts: {target}"
        );
    }
}
