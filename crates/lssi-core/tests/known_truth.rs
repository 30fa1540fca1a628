//! Known truths: systems whose equations are known (from `lssi_testkit`), identified by the
//! streaming identifier alone, coefficient by coefficient.

use lssi_core::{Channels, Config, Identifier, LibraryConfig, Model, PolyFamily, Real, Sample};
use lssi_testkit::{EQ17_OMEGA, Noise, Point, duffing, eq17, eq17_truth};

/// Streams `points` (x, and v and u where `channels` says) through an identifier with
/// `config` and screens at the end.
fn identify<T: Real>(config: Config, points: &[Point]) -> Model<T, 16> {
    let mut id: Box<Identifier<T, 256, 16, 3>> =
        Box::new(Identifier::new(config).expect("a valid configuration"));
    let c = config.channels;
    for p in points {
        let sample = Sample {
            t: p.t,
            x: T::from_f64(p.x),
            v: c.velocity.then(|| T::from_f64(p.v)),
            u: c.input.then(|| T::from_f64(p.u)),
        };
        id.push(sample).expect("a clean sample");
    }
    assert!(id.screen(), "a screening");
    id.model().expect("a model").clone()
}

/// Each true term's relative error (%), and the terms selected that are not true.
fn errors<T: Real>(model: &Model<T, 16>, truth: &[(&str, f64)]) -> (Vec<f64>, Vec<String>) {
    let names: Vec<String> = model
        .terms
        .iter()
        .map(|t| t.name(model.omega).to_string())
        .collect();
    let coefficient = |name: &str| {
        names
            .iter()
            .position(|n| n == name)
            .map_or(0.0, |i| model.coefficients[i].to_f64())
    };
    let errors = truth
        .iter()
        .map(|&(name, c)| 100.0 * ((coefficient(name) - c) / c).abs())
        .collect();
    let spurious = names
        .iter()
        .zip(model.coefficients.iter())
        .filter(|(n, c)| c.to_f64() != 0.0 && !truth.iter().any(|(t, _)| t == n))
        .map(|(n, _)| n.clone())
        .collect();
    (errors, spurious)
}

fn duffing_config(channels: Channels) -> Config {
    Config {
        sample_period: 1e-3,
        window: 63,
        library: LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: if channels.input { 0 } else { 1 },
            input: channels.input,
        },
        omega: 15.0,
        channels,
        screening_period: 20_000,
        ..Config::default()
    }
}

/// The forced Duffing oscillator with measured v (the forcing as cos(15t)).
const DUFFING: [(&str, f64); 4] = [
    ("x", -400.0),
    ("v", -2.0),
    ("x^3", -4.0e4),
    ("cos(15t)", 60.0),
];

/// Eq. 17 from x alone, sampled at the paper's 1 ms with 0.1 % Gaussian noise on x.
fn eq17_x_only() -> (Config, Vec<Point>) {
    let mut points = eq17(1.0, 0.001, 100.0);
    let mut xs: Vec<f64> = points.iter().map(|p| p.x).collect();
    Noise::new(7).add_relative(&mut xs, 0.001);
    for (p, x) in points.iter_mut().zip(xs) {
        p.x = x;
    }
    let config = Config {
        sample_period: 0.001,
        window: 127,
        library: LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: 1,
            input: false,
        },
        omega: EQ17_OMEGA,
        channels: Channels::default(),
        screening_period: 20_000,
        ..Config::default()
    };
    (config, points)
}

fn assert_within<T: Real>(model: &Model<T, 16>, truth: &[(&str, f64)], percent: f64) {
    let (errors, spurious) = errors(model, truth);
    assert!(
        errors.iter().all(|e| *e <= percent) && spurious.is_empty(),
        "errors {errors:?} %, spurious {spurious:?}"
    );
}

#[test]
fn recovers_a_duffing_oscillator_to_half_a_percent() {
    let channels = Channels {
        velocity: true,
        input: false,
    };
    let model = identify::<f64>(duffing_config(channels), &duffing(60_000));
    assert_within(&model, &DUFFING, 0.5);
}

#[test]
fn recovers_eq17_from_displacement_alone() {
    let (config, points) = eq17_x_only();
    let model = identify::<f64>(config, &points);
    assert_within(&model, &eq17_truth(1.0), 0.5);
}

/// f32 (a device) gives the model of f64 (the reference): the same terms, each coefficient
/// within 0.1 % of f64's.
#[test]
fn f32_matches_f64() {
    let channels = Channels {
        velocity: true,
        input: false,
    };
    let duffing = (duffing_config(channels), duffing(60_000));
    for (config, points) in [duffing, eq17_x_only()] {
        let m64 = identify::<f64>(config, &points);
        let m32 = identify::<f32>(config, &points);
        let s64 = m64.selected_solution().expect("selected").support;
        let s32 = m32.selected_solution().expect("selected").support;
        assert_eq!(s32, s64);
        for (c32, c64) in m32.coefficients.iter().zip(m64.coefficients.iter()) {
            let (c32, c64) = (f64::from(*c32), *c64);
            assert!(
                (c32 - c64).abs() <= 1e-3 * c64.abs(),
                "{:?}: {c32} against {c64}",
                config.channels
            );
        }
    }
}
