//! Systems of equations (issue 26): simulated piezoelectric harvesters (Erturk–Inman, mono-
//! and bistable) through `lssi identify`, `lssi simulate` and `--load-ohms`, as a user runs
//! them.
//!
//! x'' = a x + b x³ + c v + χ V + F(t),   V' = −λ V − κ v,
//! with F(t) = F cos Ωt (bistable: the chaotic motion is broadband) or F·u(t), u a measured
//! base excitation of five incommensurate tones (monostable: under one tone in steady state
//! χ V is a combination of x and v, and the data cannot tell them apart; see the core's
//! system module).

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::path::Path;

use crate::common::lssi;
use serde_json::Value;

/// A harvester's truth.
#[derive(Clone, Copy)]
struct Harvester {
    a: f64,
    b: f64,
    c: f64,
    chi: f64,
    lambda: f64,
    kappa: f64,
    /// Forcing amplitude: of cos(Ωt), or of u when `broadband`.
    f: f64,
    omega: f64,
    broadband: bool,
    x0: f64,
}

const MONO: Harvester = Harvester {
    a: -1.0,
    b: 0.0,
    c: -0.05,
    chi: 0.2,
    lambda: 1.0,
    kappa: 0.5,
    f: 0.3,
    omega: 0.0,
    broadband: true,
    x0: 0.5,
};

const BI: Harvester = Harvester {
    a: 1.0,
    b: -1.0,
    c: -0.1,
    chi: 0.2,
    lambda: 1.0,
    kappa: 0.5,
    f: 0.8,
    omega: 1.2,
    broadband: false,
    x0: 1.0,
};

/// The measured base excitation of the broadband case.
fn u_of(t: f64) -> f64 {
    [
        (0.37, 0.1),
        (0.71, 1.3),
        (1.13, 2.2),
        (1.61, 0.4),
        (2.3, 4.0),
    ]
    .iter()
    .map(|(w, p)| (w * t + p).sin())
    .sum()
}

impl Harvester {
    fn rate(&self, t: f64, s: [f64; 3]) -> [f64; 3] {
        let [x, v, e] = s;
        let force = if self.broadband {
            self.f * u_of(t)
        } else {
            self.f * (self.omega * t).cos()
        };
        [
            v,
            self.a * x + self.b * x.powi(3) + self.c * v + self.chi * e + force,
            -self.lambda * e - self.kappa * v,
        ]
    }

    /// (t, x, v, V, u) every 0.02 s for `n` samples, RK4 at 0.002 s.
    fn simulate(&self, n: usize) -> Vec<[f64; 5]> {
        let h = 0.002;
        let mut s = [self.x0, 0.0, 0.0];
        let mut out = Vec::with_capacity(n);
        for i in 0..n * 10 {
            let t = i as f64 * h;
            if i % 10 == 0 {
                out.push([t, s[0], s[1], s[2], u_of(t)]);
            }
            let add = |a: [f64; 3], k: [f64; 3], c: f64| {
                [a[0] + c * k[0], a[1] + c * k[1], a[2] + c * k[2]]
            };
            let k1 = self.rate(t, s);
            let k2 = self.rate(t + h / 2.0, add(s, k1, h / 2.0));
            let k3 = self.rate(t + h / 2.0, add(s, k2, h / 2.0));
            let k4 = self.rate(t + h, add(s, k3, h));
            for j in 0..3 {
                s[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
        out
    }

    /// The true terms of x'' and V'.
    fn truth(&self) -> [Vec<(&'static str, f64)>; 2] {
        let mut x = vec![("x", self.a), ("v", self.c), ("V", self.chi)];
        if self.b != 0.0 {
            x.push(("x^3", self.b));
        }
        if self.broadband {
            x.push(("u", self.f));
        } else {
            // cos(Ωt), with Ω as estimated.
            x.push(("cos", self.f));
        }
        [x, vec![("v", -self.kappa), ("V", -self.lambda)]]
    }
}

/// Gaussian noise from a seed (xorshift and Box–Muller: no dependency).
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn gauss(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// Writes the columns `names` (of t, x, v, V, u) with noise `level` × each channel's RMS.
fn write(path: &Path, rows: &[[f64; 5]], names: &[&str], level: f64, seed: u64) {
    let all = ["t", "x", "v", "V", "u"];
    let cols: Vec<usize> = names
        .iter()
        .map(|n| all.iter().position(|a| a == n).unwrap())
        .collect();
    let rms: Vec<f64> = (0..5)
        .map(|j| (rows.iter().map(|r| r[j] * r[j]).sum::<f64>() / rows.len() as f64).sqrt())
        .collect();
    let mut noise = Noise(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut text = format!("t,{}\n", names.join(","));
    for r in rows {
        text.push_str(&format!("{}", r[0]));
        for &c in &cols {
            // u is the measured excitation: noisy too.
            text.push_str(&format!(",{}", r[c] + level * rms[c] * noise.gauss()));
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

/// Runs `lssi identify FILE --json` (and `extra`), returns the JSON.
fn identify(path: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["identify", path.to_str().unwrap(), "--json"];
    args.extend(extra);
    let out = lssi(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Checks each equation's support against the truth (every true term, no other) and each
/// coefficient within `tol` (relative); prints the errors and standard errors. Returns the
/// largest relative error.
fn check(json: &Value, truth: &[Vec<(&str, f64)>; 2], tol: f64, label: &str) -> f64 {
    let equations = json["equations"].as_array().unwrap();
    assert_eq!(equations.len(), 2, "{label}: {json}");
    assert_eq!(equations[0]["target"], "x''");
    assert_eq!(equations[1]["target"], "V'");
    let mut worst = 0.0f64;
    for (e, truth) in equations.iter().zip(truth) {
        let terms = e["terms"].as_array().unwrap();
        // A harmonic by its function alone (Ω is estimated).
        let short =
            |name: &str| -> String { name.split_once('(').map_or(name, |(f, _)| f).to_owned() };
        let names: Vec<String> = terms
            .iter()
            .map(|t| short(t["term"].as_str().unwrap()))
            .collect();
        let mut want: Vec<&str> = truth.iter().map(|t| t.0).collect();
        let mut got: Vec<&str> = names.iter().map(String::as_str).collect();
        want.sort_unstable();
        got.sort_unstable();
        assert_eq!(got, want, "{label}: {} terms {names:?}", e["target"]);
        for (name, value) in truth {
            let t = terms
                .iter()
                .find(|t| short(t["term"].as_str().unwrap()) == *name)
                .unwrap();
            let coef = t["coef"].as_f64().unwrap();
            let se = t["se"].as_f64().unwrap();
            let error = (coef - value).abs() / value.abs();
            eprintln!(
                "{label}: {} {name}: {coef:.5} (true {value}), error {:.2} %, ± {se:.2e}",
                e["target"],
                100.0 * error
            );
            assert!(error < tol, "{label}: {name} {coef} vs {value}");
            worst = worst.max(error);
        }
    }
    worst
}

/// A case: label, harvester, rows, the columns recorded, noise, tolerance.
type Case<'a> = (&'a str, Harvester, &'a [[f64; 5]], &'a [&'a str], f64, f64);

#[test]
fn piezo_harvesters_come_out_as_their_two_equations() {
    let dir = tempfile::tempdir().unwrap();
    let mono = MONO.simulate(60_000);
    let bi = BI.simulate(60_000);
    // (harvester, rows, columns recorded, noise, relative tolerance of every coefficient);
    // x integrated from v loses its slowest content to the drift removal: the damping
    // (−0.05, the smallest term) comes out 10–15 % off at 1 % noise. A bistable x from v
    // is about its time mean, not the symmetric origin: x³ then shows a small spurious x²
    // (see the ignored spread below).
    let cases: [Case<'_>; 6] = [
        ("mono x V u clean", MONO, &mono, &["x", "V", "u"], 0.0, 0.01),
        ("mono x V u 1 %", MONO, &mono, &["x", "V", "u"], 0.01, 0.1),
        ("mono v V u 1 %", MONO, &mono, &["v", "V", "u"], 0.01, 0.2),
        ("bi x V clean", BI, &bi, &["x", "V"], 0.0, 0.01),
        ("bi x v V 1 %", BI, &bi, &["x", "v", "V"], 0.01, 0.1),
        ("mono v V u clean", MONO, &mono, &["v", "V", "u"], 0.0, 0.05),
    ];
    for (k, (label, h, rows, names, noise, tol)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("case{k}.csv"));
        write(&path, rows, names, *noise, k as u64 + 1);
        for precision in ["--f64", "--f32"] {
            // The streaming identifier's selection and coefficients (refinement: below).
            let json = identify(&path, &[precision, "--no-refine"]);
            check(&json, &h.truth(), *tol, &format!("{label} {precision}"));
            assert_eq!(json["model"], "streaming");
            assert_eq!(
                json["precision"],
                if precision == "--f64" { "f64" } else { "f32" }
            );
            if names[0] == "v" {
                assert!(json["x_from_v"].as_str().unwrap().contains("integrated"));
            }
        }
    }
}

#[test]
fn the_text_report_prints_each_equation_on_its_own_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.csv");
    write(&path, &MONO.simulate(30_000), &["x", "V", "u"], 0.0, 3);
    let out = lssi(&["identify", path.to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("x'' = ("), "{text}");
    assert!(
        lines[0].contains(" ± ") && lines[0].contains(") V"),
        "{text}"
    );
    assert!(lines[1].starts_with("V' = ("), "{text}");
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("model: refined on simulation error")
                || l.starts_with("model: not refined: refined on the first half")),
        "{text}"
    );
    let out = lssi(&["identify", path.to_str().unwrap(), "--no-refine"]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("model: not refined (--no-refine)"), "{text}");
    // A recording without an electrical column keeps the single equation's JSON.
    let plain = dir.path().join("x.csv");
    write(&plain, &MONO.simulate(30_000), &["x", "u"], 0.0, 3);
    let json = identify(&plain, &["--no-refine"]);
    assert_eq!(json["target"], "x''");
    assert!(json.get("equations").is_none());
    // The system's flags on a recording without an electrical column are refused.
    let out = lssi(&["identify", plain.to_str().unwrap(), "--load-ohms", "1e5"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.contains("--load-ohms applies to a recording with an electrical column"),
        "{err}"
    );
    // A named electrical column that is missing is an input error.
    let out = lssi(&["identify", path.to_str().unwrap(), "--V-col", "Vload"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("no column 'Vload'"), "{err}");
    // A voltage column named as people name it ('Voltage') is read as V, and said; two such
    // columns are an input error naming both.
    let text = std::fs::read_to_string(&path).unwrap();
    let (head, body) = text.split_once('\n').unwrap();
    let renamed = dir.path().join("named.csv");
    std::fs::write(
        &renamed,
        format!("{}\n{body}", head.replace(",V,", ",Voltage,")),
    )
    .unwrap();
    let out = lssi(&[
        "identify",
        renamed.to_str().unwrap(),
        "--json",
        "--no-refine",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("reading the voltage across the load from column 'Voltage'"),
        "{err}"
    );
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["equations"][1]["target"], "V'", "{json}");
    let twice = dir.path().join("twice.csv");
    std::fs::write(
        &twice,
        format!(
            "{}\n{body}",
            head.replace(",V,", ",voltage_V,").replace(",u", ",Volts")
        ),
    )
    .unwrap();
    let out = lssi(&["identify", twice.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("columns 'voltage_V', 'Volts' each look like the voltage"),
        "{err}"
    );
}

#[test]
fn simulate_predicts_every_state_from_the_excitation() {
    let dir = tempfile::tempdir().unwrap();
    let rows = MONO.simulate(40_000);
    let train = dir.path().join("train.csv");
    let test = dir.path().join("test.csv");
    write(&train, &rows[..20_000], &["x", "V", "u"], 0.01, 5);
    write(&test, &rows[20_000..], &["x", "V", "u"], 0.0, 6);
    let json = identify(&train, &["--f64"]);
    let model = dir.path().join("model.json");
    std::fs::write(&model, json.to_string()).unwrap();
    let out_csv = dir.path().join("sim.csv");
    let out = lssi(&[
        "simulate",
        model.to_str().unwrap(),
        test.to_str().unwrap(),
        "--out",
        out_csv.to_str().unwrap(),
        "--load-ohms",
        "1000",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sim = std::fs::read_to_string(&out_csv).unwrap();
    assert_eq!(sim.lines().next(), Some("t,x,v,V"));
    let sim: Vec<Vec<f64>> = sim
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|q| q.parse().unwrap()).collect())
        .collect();
    assert_eq!(sim.len(), 20_000);
    let truth = &rows[20_000..];
    for (k, name) in [(1, "x"), (2, "v"), (3, "V")] {
        let e: f64 = sim
            .iter()
            .zip(truth)
            .map(|(s, r)| (s[k] - r[k]).powi(2))
            .sum();
        let d: f64 = truth.iter().map(|r| r[k] * r[k]).sum();
        let nrmse = (e / d).sqrt();
        eprintln!("simulated {name}: NRMSE {:.3} %", 100.0 * nrmse);
        assert!(nrmse < 0.05, "{name}: {nrmse}");
    }
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("mean power V²/R at 1000 Ω"), "{text}");
}

#[test]
fn load_ohms_gives_the_coupling_and_the_optimal_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.csv");
    write(&path, &MONO.simulate(40_000), &["x", "V", "u"], 0.0, 7);
    let ohms = 1.0e5;
    let json = identify(&path, &["--f64", "--load-ohms", "1e5"]);
    let h = &json["harvester"];
    let get = |k: &str| h[k].as_f64().unwrap_or(f64::NAN);
    // C_p = 1/(λR), θ = κ C_p, m = θ/χ, k² = κχ/(ω² + κχ).
    let cp = 1.0 / (MONO.lambda * ohms);
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    assert!(rel(get("capacitance_f"), cp) < 0.01, "{h}");
    assert!(rel(get("theta"), MONO.kappa * cp) < 0.01, "{h}");
    assert!(rel(get("mass"), MONO.kappa * cp / MONO.chi) < 0.02, "{h}");
    let k2 = MONO.kappa * MONO.chi / (-MONO.a + MONO.kappa * MONO.chi);
    assert!(rel(get("coupling_k2"), k2) < 0.02, "{h}");
    assert!(rel(get("time_constant_s"), 1.0 / MONO.lambda) < 0.01, "{h}");
    // The free run of an exact model reproduces the measured power.
    assert!(
        rel(get("power_predicted_w"), get("power_measured_w")) < 0.05,
        "{h}"
    );
    // The optimum is inside the sweep, with less power on both sides.
    let sweep = h["load_sweep"].as_array().unwrap();
    let best = get("optimal_load_ohms");
    let first = sweep[0]["at"].as_f64().unwrap();
    let last = sweep[sweep.len() - 1]["at"].as_f64().unwrap();
    assert!(first < best && best < last, "{h}");
    let most = get("optimal_power_w");
    for p in sweep {
        assert!(p["power_w"].as_f64().unwrap() <= most * (1.0 + 1e-9), "{h}");
    }
    // A linear harvester's optimum: near 1/(Ω C_p) at its dominant frequency, within the
    // factor the broadband excitation spreads it over.
    assert!(best > 0.2 / (1.0 * cp) && best < 5.0 / (1.0 * cp), "{h}");
    assert!(!h["frequency_sweep"].as_array().unwrap().is_empty());
}

/// The largest relative error of the true terms' coefficients, and whether each equation's
/// support is the truth's.
fn worst_error(json: &Value, truth: &[Vec<(&str, f64)>; 2]) -> (f64, bool) {
    let mut worst = 0.0f64;
    let mut exact = true;
    for (e, truth) in json["equations"].as_array().unwrap().iter().zip(truth) {
        let terms = e["terms"].as_array().unwrap();
        exact &= terms.len() == truth.len();
        for (name, value) in truth {
            match terms.iter().find(|t| t["term"] == *name) {
                Some(t) => {
                    let c = t["coef"].as_f64().unwrap();
                    worst = worst.max((c - value).abs() / value.abs());
                }
                None => {
                    exact = false;
                    worst = worst.max(1.0);
                }
            }
        }
    }
    (worst, exact)
}

#[test]
fn refinement_is_no_worse_than_the_streaming_model() {
    // Broadband piezo harvesters at 1 % noise on x, V and u (seeds the refinement was not
    // tuned on): the refined system's worst coefficient error is no worse than the
    // streaming one's, and --no-refine keeps the streaming model.
    let dir = tempfile::tempdir().unwrap();
    let mut totals = (0.0, 0.0);
    for seed in [31u64, 32] {
        let h = Harvester {
            x0: MONO.x0 * (1.0 + 0.1 * seed as f64 / 8.0),
            ..MONO
        };
        let path = dir.path().join(format!("r{seed}.csv"));
        write(&path, &h.simulate(30_000), &["x", "V", "u"], 0.01, seed);
        let streaming = identify(&path, &["--f64", "--no-refine"]);
        assert_eq!(streaming["model"], "streaming");
        assert!(streaming.get("refinement").is_none());
        let refined = identify(&path, &["--f64"]);
        let info = &refined["refinement"];
        let (s, r) = (
            info["held_out_streaming_percent"].as_f64().unwrap(),
            info["held_out_refined_percent"].as_f64().unwrap(),
        );
        // Taken exactly when it predicts the held-out half no worse.
        assert_eq!(
            refined["model"] == "refined",
            r <= s * 1.005 || info["taken"] == true,
            "{info}"
        );
        let (ws, es) = worst_error(&streaming, &h.truth());
        let (wr, er) = worst_error(&refined, &h.truth());
        eprintln!(
            "seed {seed}: worst coefficient error streaming {:.3} %, {} {:.3} %; held out {s:.3} % -> {r:.3} %",
            100.0 * ws,
            refined["model"],
            100.0 * wr
        );
        assert!(es && er, "{streaming} {refined}");
        // Each coefficient within 2 % (the damping, −0.05, is the loosest) …
        assert!(wr < 0.02, "refined {wr} vs streaming {ws}");
        totals.0 += ws;
        totals.1 += wr;
    }
    // … and over the seeds no worse than the streaming model's.
    assert!(totals.1 <= 1.1 * totals.0, "{totals:?}");
}

#[test]
fn plot_draws_a_harvesters_power_and_voltage() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.csv");
    write(&path, &MONO.simulate(20_000), &["x", "V", "u"], 0.01, 9);
    let out_dir = dir.path().join("figs");
    let out = lssi(&[
        "plot",
        path.to_str().unwrap(),
        "--load-ohms",
        "1e5",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for figure in ["voltage", "power-load", "power-frequency"] {
        for ext in ["png", "svg"] {
            let f = out_dir.join(format!("h-{figure}.{ext}"));
            let size = std::fs::metadata(&f).map(|m| m.len()).unwrap_or(0);
            assert!(size > 1000, "{} is {size} bytes", f.display());
        }
    }
    // Without the load: the voltage alone, and a note saying what the power needs.
    let bare = dir.path().join("bare");
    let out = lssi(&[
        "plot",
        path.to_str().unwrap(),
        "--out",
        bare.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    assert!(bare.join("h-voltage.png").exists());
    assert!(!bare.join("h-power-load.png").exists());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("--load-ohms"), "{err}");
}

/// The spread over harvesters, recorded channels, noise and seeds (printed, not asserted:
/// the figures of the report). `cargo test -p lssi-host --test it system_spread -- --ignored
/// --nocapture`
#[test]
#[ignore = "a table for the report, about two minutes"]
fn system_spread() {
    let dir = tempfile::tempdir().unwrap();
    eprintln!("case                 noise  seed  support          worst coefficient error");
    for (label, h) in [("mono (u)", MONO), ("bistable", BI)] {
        for seed in 0..3u64 {
            // Each seed its own initial state too.
            let h = Harvester {
                x0: h.x0 * (1.0 + 0.2 * seed as f64),
                ..h
            };
            let rows = h.simulate(60_000);
            for noise in [0.0, 0.01, 0.05] {
                for names in [
                    &["x", "V", "u"][..],
                    &["v", "V", "u"],
                    &["x", "v", "V", "u"],
                ] {
                    let names: Vec<&str> = names
                        .iter()
                        .copied()
                        .filter(|n| *n != "u" || h.broadband)
                        .collect();
                    let path = dir.path().join("s.csv");
                    write(&path, &rows, &names, noise, seed + 100);
                    let json = identify(&path, &["--f32"]);
                    let truth = h.truth();
                    let mut ok = true;
                    let mut worst = 0.0f64;
                    for (e, truth) in json["equations"].as_array().unwrap().iter().zip(&truth) {
                        let terms = e["terms"].as_array().unwrap();
                        let short = |t: &Value| {
                            let n = t["term"].as_str().unwrap();
                            n.split_once('(').map_or(n, |(f, _)| f).to_owned()
                        };
                        ok &= terms.len() == truth.len();
                        for (name, value) in truth {
                            match terms.iter().find(|t| short(t) == *name) {
                                Some(t) => {
                                    let c = t["coef"].as_f64().unwrap();
                                    worst = worst.max((c - value).abs() / value.abs());
                                }
                                None => {
                                    ok = false;
                                    worst = worst.max(1.0);
                                }
                            }
                        }
                    }
                    eprintln!(
                        "{label:<9} {:<10} {:>4.0} %  {seed:>4}  {:<15}  {:.2} %",
                        names.join(","),
                        100.0 * noise,
                        if ok { "exact" } else { "wrong" },
                        100.0 * worst
                    );
                }
            }
        }
    }
}
