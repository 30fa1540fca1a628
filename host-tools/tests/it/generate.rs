//! The eq. (17) generator: integration accuracy, eq. (16) noise, determinism, and the round trip
//! through files.
#![allow(clippy::unwrap_used)] // a test fails by panicking

use lssi_host::recording::{ColumnNames, read_csv};
use lssi_host::synth::files::{truth_path, write_generated};
use lssi_host::synth::noise::{NoiseKind, norm, stats};
use lssi_host::synth::ode::{State, integrate_at};
use lssi_host::synth::paper::{MAX_STEP, PaperOptions, generate_paper};
use lssi_host::synth::truth::Truth;
use lssi_host::synth::{Observe, sample_times};

const KINDS: [NoiseKind; 3] = [NoiseKind::Paper, NoiseKind::Uniform0, NoiseKind::Gauss];

fn short(noise: NoiseKind, delta: f64) -> PaperOptions {
    PaperOptions {
        noise,
        delta,
        t_end: 20.0,
        ..PaperOptions::default()
    }
}

fn difference(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(a, b)| a - b).collect()
}

#[test]
fn trajectory_survives_step_halving_over_the_full_run() {
    // The default run, t = 0..100 s: the data must obey eq. (17) to 1e-9, so a finer step
    // must not move any sample by more than that.
    let options = PaperOptions::default();
    let times = sample_times(options.dt, options.t_end);
    let run = |step: f64| {
        integrate_at(
            |t, x, v| options.acceleration(t, x, v),
            State { x: 2.0, v: 0.0 },
            &times,
            step,
        )
    };
    let coarse = run(MAX_STEP);
    let fine = run(MAX_STEP / 2.0);
    let worst = coarse
        .iter()
        .zip(&fine)
        .map(|(a, b)| (a.x - b.x).abs().max((a.v - b.v).abs()))
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-10,
        "halving the step moved a sample by {worst:e}"
    );
    assert_eq!(options.max_step(), MAX_STEP);
}

#[test]
fn clean_data_satisfy_the_truth() {
    // x'' from the truth terms equals the right-hand side the integrator used.
    let generated = generate_paper(&short(NoiseKind::Gauss, 0.0));
    let truth = &generated.truth;
    let options = PaperOptions::default();
    for i in (0..generated.t.len()).step_by(997) {
        let (t, x, v) = (generated.t[i], generated.clean_x[i], generated.clean_v[i]);
        let from_truth = truth.coefficient("x").unwrap() * x
            + truth.coefficient("v").unwrap() * v
            + truth.coefficient("x^2").unwrap() * x * x
            + truth.coefficient("x^3").unwrap() * x * x * x
            + truth.coefficient("x^2*v").unwrap() * x * x * v
            + truth.coefficient("cos(2t)").unwrap() * (2.0 * t).cos();
        assert!((from_truth - options.acceleration(t, x, v)).abs() < 1e-12);
    }
    assert_eq!(generated.x, generated.clean_x, "δ = 0 adds no noise");
}

#[test]
fn noise_has_norm_delta_times_the_signal_for_every_kind() {
    for kind in KINDS {
        let g = generate_paper(&short(kind, 0.01));
        let noise_x = difference(&g.x, &g.clean_x);
        let noise_v = difference(g.v.as_ref().unwrap(), &g.clean_v);
        for (noise, clean) in [(&noise_x, &g.clean_x), (&noise_v, &g.clean_v)] {
            let ratio = norm(noise) / norm(clean);
            assert!((ratio - 0.01).abs() < 1e-14, "{kind:?}: ratio {ratio}");
        }
        let noise = &g.truth.noise;
        assert_eq!(noise.kind, kind);
        assert!((noise.offset_x - stats(&noise_x).offset).abs() < 1e-15);
        assert!((noise.rms_x - stats(&noise_x).rms).abs() < 1e-15);
        assert!((noise.offset_v.unwrap() - stats(&noise_v).offset).abs() < 1e-15);
        assert!((noise.rms_v.unwrap() - stats(&noise_v).rms).abs() < 1e-15);
        // ‖noise‖ = δ‖g‖ means rms(noise) = δ rms(g).
        assert!((noise.rms_x - 0.01 * stats(&g.clean_x).rms).abs() < 1e-15);
    }
}

#[test]
fn paper_noise_is_biased_by_root_3_over_2_delta_rms() {
    let delta = 0.01;
    for kind in KINDS {
        let g = generate_paper(&short(kind, delta));
        for (offset, clean) in [
            (g.truth.noise.offset_x, &g.clean_x),
            (g.truth.noise.offset_v.unwrap(), &g.clean_v),
        ] {
            let scale = delta * stats(clean).rms;
            let bias = offset / scale;
            match kind {
                // E[e] / √E[e²] = (1/2) / √(1/3) = √3/2 for e uniform in (0, 1).
                NoiseKind::Paper => assert!(
                    (bias - 3f64.sqrt() / 2.0).abs() < 0.01,
                    "paper bias {bias}, expected 0.866"
                ),
                _ => assert!(bias.abs() < 0.03, "{kind:?} bias {bias}, expected 0"),
            }
        }
    }
}

#[test]
fn same_seed_same_data_other_seed_other_noise() {
    let a = generate_paper(&short(NoiseKind::Paper, 0.001));
    let b = generate_paper(&short(NoiseKind::Paper, 0.001));
    assert_eq!(a, b);
    let c = generate_paper(&PaperOptions {
        seed: 2,
        ..short(NoiseKind::Paper, 0.001)
    });
    assert_eq!(a.clean_x, c.clean_x);
    assert_ne!(a.x, c.x);
}

#[test]
fn generated_files_read_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for observe in [Observe::Xv, Observe::X] {
        let options = PaperOptions {
            observe,
            t_end: 5.0,
            noise: NoiseKind::Gauss,
            ..PaperOptions::default()
        };
        let generated = generate_paper(&options);
        let csv = dir.path().join(format!("run-{observe:?}.csv"));
        let json = truth_path(&csv).unwrap();
        write_generated(&csv, &json, &generated).unwrap();

        let recording = read_csv(&csv, &ColumnNames::default()).unwrap();
        assert_eq!(recording, generated.to_recording(&csv));
        assert_eq!(recording.v.is_some(), observe == Observe::Xv);

        let text = std::fs::read_to_string(&json).unwrap();
        let truth: Truth = serde_json::from_str(&text).unwrap();
        assert_eq!(truth, generated.truth);
        let params: PaperOptions = serde_json::from_value(truth.params.clone()).unwrap();
        assert_eq!(
            params, options,
            "the truth's params regenerate the same data"
        );
    }
}

#[test]
fn truth_file_has_the_documented_shape() {
    let generated = generate_paper(&short(NoiseKind::Paper, 0.001));
    let value = serde_json::to_value(&generated.truth).unwrap();
    let expected_terms = serde_json::json!([
        {"term": "x", "coef": -1.0}, {"term": "v", "coef": 1.0},
        {"term": "x^2", "coef": 2.0}, {"term": "x^3", "coef": -4.0},
        {"term": "x^2*v", "coef": -2.0}, {"term": "cos(2t)", "coef": 5.0}
    ]);
    assert_eq!(value["model"], "paper-eq17");
    assert_eq!(value["target"], "x''");
    assert_eq!(value["omega"], 2.0);
    assert_eq!(value["terms"], expected_terms);
    assert_eq!(value["params"]["epsilon"], 1.0);
    assert_eq!(value["params"]["seed"], 1);
    assert_eq!(value["noise"]["kind"], "paper");
    for key in ["delta", "offset_x", "offset_v", "rms_x", "rms_v"] {
        assert!(value["noise"][key].is_f64(), "noise.{key}");
    }
}

#[test]
fn coefficients_scale_with_epsilon() {
    let generated = generate_paper(&PaperOptions {
        epsilon: 0.25,
        t_end: 0.01,
        ..PaperOptions::default()
    });
    let truth = &generated.truth;
    assert_eq!(truth.coefficient("x"), Some(-1.0));
    assert_eq!(truth.coefficient("v"), Some(0.25));
    assert_eq!(truth.coefficient("x^2"), Some(0.5));
    assert_eq!(truth.coefficient("x^3"), Some(-1.0));
    assert_eq!(truth.coefficient("x^2*v"), Some(-0.5));
    assert_eq!(truth.coefficient("cos(2t)"), Some(1.25));
}
