//! End to end: recordings made by `lssi gen paper` through `lssi identify`'s code path, and
//! the bundled recording through the binary. Each assertion can fail: it compares with the
//! true coefficients of eq. 17.

use lssi_host::identify::identify_recording;
use lssi_host::identify::{Options, Report};
use lssi_host::synth::Observe;
use lssi_host::synth::noise::NoiseKind;
use lssi_host::synth::paper::{PaperOptions, generate_paper};
use lssi_host::synth::truth::score;

/// Eq. 17's coefficients at the generator's ε (one copy, in lssi-testkit).
fn truth() -> [(&'static str, f64); 6] {
    lssi_testkit::eq17_truth(PaperOptions::default().epsilon)
}

fn paper_options(f32: bool) -> Options {
    Options {
        omega: Some(1.0),
        harmonics: Some(3),
        poly_order: 3,
        f32,
        ..Options::default()
    }
}

/// The recording `opts` makes, identified with `options`, scored against eq. 17: the
/// report, the per-coefficient errors (%), their mean and worst, the spurious terms, and
/// the x offset the generator's noise put in.
struct Scored {
    report: Report,
    errors: Vec<f64>,
    mean: f64,
    worst: f64,
    spurious: usize,
    offset_x: f64,
}

fn scored(opts: &PaperOptions, options: &Options) -> Scored {
    let generated = generate_paper(opts);
    let offset_x = generated.truth.noise.offset_x;
    let recording = generated.to_recording("eq17.csv");
    let report = identify_recording(&recording, options).expect("identifies");
    let (errors, spurious) = score(&report, &truth());
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let worst = errors.iter().cloned().fold(0.0, f64::max);
    Scored {
        report,
        errors,
        mean,
        worst,
        spurious,
        offset_x,
    }
}

/// Asserts a mean and a worst coefficient error (%) and no spurious term.
fn check_within(opts: PaperOptions, options: &Options, max_mean: f64, max_worst: f64) -> Scored {
    let s = scored(&opts, options);
    assert!(
        s.mean <= max_mean && s.worst <= max_worst && s.spurious == 0,
        "{opts:?}: errors {:?} %, {} spurious, model {:?}",
        s.errors,
        s.spurious,
        s.report.terms
    );
    s
}

fn check(opts: PaperOptions, options: &Options, max_error: f64) {
    check_within(opts, options, max_error, max_error);
}

#[test]
fn recovers_eq17_in_f32_and_f64_at_low_noise() {
    for f32 in [true, false] {
        check(
            PaperOptions {
                delta: 0.001,
                ..PaperOptions::default()
            },
            &paper_options(f32),
            0.5,
        );
    }
}

#[test]
fn recovers_eq17_from_displacement_alone() {
    let opts = PaperOptions {
        delta: 0.001,
        observe: Observe::X,
        seed: 7,
        ..PaperOptions::default()
    };
    check(opts, &paper_options(true), 1.5);
}

#[test]
fn removes_the_sensor_offsets_of_eq16_noise() {
    // δ = 0.01: the offset alone would put the x^2 term 7 % off.
    let opts = PaperOptions {
        delta: 0.01,
        seed: 3,
        ..PaperOptions::default()
    };
    check_within(opts, &paper_options(true), 1.0, 2.0);
}

#[test]
fn zero_mean_noise_at_delta_0_1() {
    let opts = PaperOptions {
        delta: 0.1,
        noise: NoiseKind::Uniform0,
        seed: 5,
        ..PaperOptions::default()
    };
    // Over seeds 4–11 the worst coefficient is 0.3–2.4 % off (the weak x term; the noise
    // differs from seed to seed, not the sign of the error) and the mean 0.13–0.78 %.
    check_within(opts, &paper_options(true), 1.0, 3.0);
}

#[test]
fn removes_the_sensor_offset_from_displacement_alone_at_delta_0_1() {
    // Eq. 16 noise: x is 0.087 off its zero. With test-function rows an origin 5 % of that
    // off keeps spurious terms; the offset search sheds them (before it: 17.5 %, 2 spurious
    // on seed 1).
    let opts = PaperOptions {
        delta: 0.1,
        observe: Observe::X,
        seed: 1,
        ..PaperOptions::default()
    };
    let s = check_within(opts, &paper_options(true), 1.0, 100.0);
    assert!(
        (s.report.offsets[0] - s.offset_x).abs() < 0.005,
        "x offset {} against {}",
        s.report.offsets[0],
        s.offset_x
    );
}

#[test]
fn zero_mean_noise_at_delta_0_1_from_displacement_alone() {
    // The case the test-function rows are for: x'' from x alone at δ = 0.1 (with rows
    // as they are, 25–36 % off with spurious terms on two of the benchmark's three seeds).
    let opts = PaperOptions {
        delta: 0.1,
        noise: NoiseKind::Uniform0,
        observe: Observe::X,
        seed: 5,
        ..PaperOptions::default()
    };
    check_within(opts, &paper_options(true), 3.0, 100.0);
}

#[test]
fn estimates_the_excitation_frequency() {
    let recording = generate_paper(&PaperOptions {
        delta: 0.001,
        t_end: 60.0,
        ..PaperOptions::default()
    })
    .to_recording("eq17.csv");
    let options = Options {
        omega: None,
        harmonics: Some(1),
        ..Options::default()
    };
    let report = identify_recording(&recording, &options).expect("identifies");
    assert!(report.omega_estimated);
    assert!((report.omega - 2.0).abs() < 1e-3, "Ω = {}", report.omega);
    assert!(
        report.terms.iter().any(|t| t.term == "cos(2t)"),
        "{:?}",
        report.terms
    );
}

#[test]
fn bad_samples_are_counted_and_the_rest_still_identifies() {
    let mut recording = generate_paper(&PaperOptions {
        delta: 0.001,
        ..PaperOptions::default()
    })
    .to_recording("eq17.csv");
    recording.x[5000] = f64::NAN;
    recording.x[6000] = 1e12;
    recording.t[7000] = recording.t[6999];
    let report = identify_recording(&recording, &paper_options(true)).expect("identifies");
    assert_eq!(report.rejected, 3);
    let (errors, spurious) = score(&report, &truth());
    assert!(
        errors.iter().all(|e| *e < 1.0) && spurious == 0,
        "{errors:?} {spurious}"
    );
}
