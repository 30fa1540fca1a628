//! A simulated piezoelectric harvester (Erturk–Inman form, mono- and bistable), integrated
//! here by RK4, identified as a system: both equations, every true term, none spurious.

use super::*;
use crate::library::{LibraryConfig, PolyFamily, StateTerm};
use lssi_testkit::Noise;
use std::string::{String, ToString};
use std::vec::Vec;

/// x'' = k1 x + k3 x³ + c v + χ V + F cos Ωt,  V' = −λ V − κ v.
#[derive(Clone, Copy, Debug)]
struct Piezo {
    k1: f64,
    k3: f64,
    c: f64,
    chi: f64,
    lambda: f64,
    kappa: f64,
    force: f64,
    omega: f64,
    /// Forcing by a measured base acceleration u (a multisine) instead of F cos Ωt.
    input: bool,
}

/// The multisine base acceleration: five incommensurate tones about the resonances, unit
/// amplitude each.
fn multisine(t: f64) -> f64 {
    const TONES: [(f64, f64); 5] = [
        (0.43, 0.3),
        (0.71, 2.1),
        (0.97, 4.0),
        (1.29, 1.2),
        (1.63, 5.3),
    ];
    TONES
        .iter()
        .map(|(w, phi)| (w * t + phi).cos())
        .sum::<f64>()
        / 2.0
}

impl Piezo {
    fn monostable() -> Self {
        Self {
            k1: -1.0,
            k3: -0.5,
            c: -0.04,
            chi: 0.1,
            lambda: 1.0,
            kappa: 0.5,
            force: 0.4,
            omega: 0.8,
            input: false,
        }
    }

    fn bistable() -> Self {
        Self {
            k1: 0.5,
            k3: -0.5,
            c: -0.04,
            chi: 0.1,
            lambda: 1.0,
            kappa: 0.5,
            force: 0.3,
            omega: 0.8,
            input: false,
        }
    }

    fn with_input(self, force: f64) -> Self {
        Self {
            input: true,
            force,
            ..self
        }
    }

    fn forcing(&self, t: f64) -> f64 {
        if self.input {
            self.force * multisine(t)
        } else {
            self.force * (self.omega * t).cos()
        }
    }

    fn derivative(&self, t: f64, s: [f64; 3]) -> [f64; 3] {
        let [x, v, e] = s;
        [
            v,
            self.k1 * x + self.k3 * x * x * x + self.c * v + self.chi * e + self.forcing(t),
            -self.lambda * e - self.kappa * v,
        ]
    }

    /// `n` samples `dt` apart of (t, x, V, u, v), after a second of transient is dropped; RK4
    /// with `substeps` steps per sample.
    fn simulate(&self, n: usize, dt: f64, substeps: usize, start: [f64; 3]) -> Vec<[f64; 5]> {
        let h = dt / substeps as f64;
        let mut s = start;
        let mut t = 0.0;
        let mut out = Vec::with_capacity(n);
        let skip = (100.0 / dt) as usize;
        for i in 0..n + skip {
            if i >= skip {
                let t = i as f64 * dt;
                out.push([t, s[0], s[2], multisine(t), s[1]]);
            }
            for _ in 0..substeps {
                let add = |s: [f64; 3], k: [f64; 3], f: f64| {
                    [s[0] + f * k[0], s[1] + f * k[1], s[2] + f * k[2]]
                };
                let k1 = self.derivative(t, s);
                let k2 = self.derivative(t + h / 2.0, add(s, k1, h / 2.0));
                let k3 = self.derivative(t + h / 2.0, add(s, k2, h / 2.0));
                let k4 = self.derivative(t + h, add(s, k3, h));
                for j in 0..3 {
                    s[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
                }
                t += h;
            }
        }
        out
    }

    /// The true terms of each equation by name.
    fn truth(&self) -> [Vec<(&'static str, f64)>; 2] {
        let forcing = if self.input { "u" } else { "cos(0.8t)" };
        [
            vec![
                ("x", self.k1),
                ("v", self.c),
                ("V", self.chi),
                ("x^3", self.k3),
                (forcing, self.force),
            ],
            vec![("v", -self.kappa), ("V", -self.lambda)],
        ]
    }
}

/// 100 samples a second: about 600 per period of the linear resonance (ω = 1 rad/s).
const DT: f64 = 0.01;
/// 1 200 s of record, 190 periods.
const SAMPLES: usize = 120_000;

fn config(window: usize, input: bool) -> SystemConfig {
    SystemConfig {
        base: Config {
            sample_period: DT,
            window,
            derivative_degree: 5,
            library: LibraryConfig {
                poly_order: 3,
                family: PolyFamily::All,
                constant: true,
                harmonics: if input { 0 } else { 1 },
                input,
            },
            channels: crate::config::Channels {
                velocity: false,
                input,
            },
            omega: 0.8,
            screening_period: u32::MAX,
            ..Config::default()
        },
        electrical: [Some(Electrical::Voltage), None],
        coupling_order: 2,
        displacements: 1,
    }
}

/// The record with `noise` (relative RMS) added to x and V.
fn record(p: &Piezo, n: usize, noise: f64, seed: u64) -> Vec<[f64; 4]> {
    let mut points: Vec<[f64; 4]> = p
        .simulate(n, DT, 10, [0.1, 0.0, 0.0])
        .iter()
        .map(|q| [q[0], q[1], q[2], q[3]])
        .collect();
    if noise > 0.0 {
        let mut rng = Noise::new(seed);
        let mut x: Vec<f64> = points.iter().map(|q| q[1]).collect();
        let mut e: Vec<f64> = points.iter().map(|q| q[2]).collect();
        rng.add_relative(&mut x, noise);
        rng.add_relative(&mut e, noise);
        for ((q, x), e) in points.iter_mut().zip(x).zip(e) {
            q[1] = x;
            q[2] = e;
        }
    }
    points
}

fn identify<T: Real>(config: SystemConfig, points: &[[f64; 4]]) -> SystemModel<T, 16, 2> {
    let input = config.base.channels.input;
    let mut id: Box<SystemIdentifier<T, 256, 16, 2, 3>> =
        Box::new(SystemIdentifier::new(config).expect("a valid configuration"));
    for q in points {
        let e = [T::from_f64(q[2])];
        id.push(&SystemSample {
            x2: None,
            v2: None,
            t: q[0],
            x: T::from_f64(q[1]),
            v: None,
            u: input.then(|| T::from_f64(q[3])),
            electrical: &e,
        })
        .expect("a clean sample");
    }
    assert!(id.screen(), "a screening");
    id.model().expect("a model").clone()
}

/// Per equation: each true term's relative error (%), and the selected terms that are not
/// true.
fn errors<T: Real>(
    model: &SystemModel<T, 16, 2>,
    truth: &[Vec<(&'static str, f64)>; 2],
) -> [(Vec<f64>, Vec<String>); 2] {
    let names: Vec<String> = (0..model.terms.len())
        .map(|j| model.term_name(j).expect("a column").to_string())
        .collect();
    core::array::from_fn(|k| {
        let e = &model.equations[k];
        let coefficient = |name: &str| {
            names
                .iter()
                .position(|n| n == name)
                .filter(|&j| e.support() & (1 << j) != 0)
                .map_or(0.0, |j| e.coefficients[j].to_f64())
        };
        let errors = truth[k]
            .iter()
            .map(|&(name, c)| 100.0 * ((coefficient(name) - c) / c).abs())
            .collect();
        let spurious = names
            .iter()
            .enumerate()
            .filter(|&(j, n)| e.support() & (1 << j) != 0 && !truth[k].iter().any(|(t, _)| t == n))
            .map(|(_, n)| n.clone())
            .collect();
        (errors, spurious)
    })
}

fn text<T: Real>(model: &SystemModel<T, 16, 2>) -> String {
    let mut s = String::new();
    for k in 0..model.equations.len() {
        let _ = model.write_equation(k, 4, &mut s);
        s.push('\n');
    }
    s
}

/// Identifies `p` over seeds at a noise level with the configuration the host would choose
/// (`tuned`, or rows as they are with `window`); asserts both equations' supports are the
/// true ones and every coefficient is within `tolerance` %. Prints the worst error per
/// equation over the seeds.
fn check<T: Real>(
    name: &str,
    p: &Piezo,
    noise: f64,
    seeds: &[u64],
    window: Option<usize>,
    tolerance: f64,
) -> [f64; 2] {
    let truth = p.truth();
    let mut worst = [0.0f64; 2];
    for &seed in seeds {
        let points = record(p, SAMPLES, noise, seed);
        let c = match window {
            Some(w) => config(w, p.input),
            None => tuned(&points, p.input),
        };
        let model = identify::<T>(c, &points);
        let found = errors(&model, &truth);
        for (k, (errs, spurious)) in found.iter().enumerate() {
            let max = errs.iter().copied().fold(0.0, f64::max);
            worst[k] = worst[k].max(max);
            assert!(
                spurious.is_empty() && max < tolerance,
                "{name}, noise {noise}, seed {seed}, equation {k}: errors {errs:.3?} %, spurious {spurious:?}\n{}",
                text(&model)
            );
        }
    }
    std::println!(
        "{name} {} noise {:.0} % ({}): worst coefficient error x'' {:.3} %, V' {:.3} % over {} seeds",
        core::any::type_name::<T>(),
        noise * 100.0,
        window.map_or("weak form, tuned".to_string(), |w| std::format!(
            "rows as they are, window {w}"
        )),
        worst[0],
        worst[1],
        seeds.len()
    );
    worst
}

/// Noise-free records, mono- and bistable, f64 and f32: both equations with exactly the
/// true terms, every coefficient within 1 %.
#[test]
fn a_clean_piezo_harvester_gives_both_equations() {
    for p in [
        Piezo::monostable().with_input(0.4),
        Piezo::bistable().with_input(0.3),
    ] {
        let name = if p.k1 < 0.0 { "monostable" } else { "bistable" };
        check::<f64>(name, &p, 0.0, &[0], None, 1.0);
        check::<f32>(name, &p, 0.0, &[0], None, 1.0);
        check::<f64>(name, &p, 0.0, &[0], Some(15), 1.0);
        check::<f32>(name, &p, 0.0, &[0], Some(15), 1.0);
    }
}

/// 1 % white noise on x and on V, four seeds (two in f32): the true terms only, every
/// coefficient within 5 %.
#[test]
fn a_noisy_piezo_harvester_gives_both_equations() {
    for p in [
        Piezo::monostable().with_input(0.4),
        Piezo::bistable().with_input(0.3),
    ] {
        let name = if p.k1 < 0.0 { "monostable" } else { "bistable" };
        check::<f64>(name, &p, 0.01, &[11, 12, 13, 14], None, 5.0);
        check::<f32>(name, &p, 0.01, &[11, 12], None, 5.0);
    }
}

/// An f32 identification is a pure function of its samples: two runs, the same bits.
#[test]
fn an_f32_run_equals_itself() {
    let p = Piezo::bistable().with_input(0.3);
    let points = record(&p, SAMPLES / 4, 0.01, 21);
    let c = tuned(&points, true);
    let a = identify::<f32>(c, &points);
    let b = identify::<f32>(c, &points);
    for (ea, eb) in a.equations.iter().zip(&b.equations) {
        assert_eq!(
            ea.coefficients.map(f32::to_bits),
            eb.coefficients.map(f32::to_bits)
        );
        assert_eq!(ea.solutions, eb.solutions);
        assert_eq!(ea.selected, eb.selected);
    }
}

/// `forget` keeps the configuration and its taps and forgets the rest: a used identifier
/// forgotten (twice: the test-function sums' bump kept) gives the model of a new one, bit
/// for bit.
#[test]
fn forgotten_gives_the_model_of_new_bit_for_bit() {
    let p = Piezo::bistable();
    let points = record(&p, SAMPLES / 4, 0.01, 21);
    for c in [tuned(&points, false), config(41, false)] {
        let want = identify::<f32>(c, &points);
        let mut id: Box<SystemIdentifier<f32, 256, 16, 2, 3>> =
            Box::new(SystemIdentifier::new(c).expect("a valid configuration"));
        for _ in 0..2 {
            for q in points.iter().take(points.len() / 2) {
                let _ = id.push(&SystemSample {
                    x2: None,
                    v2: None,
                    t: q[0],
                    x: q[1] as f32,
                    v: None,
                    u: None,
                    electrical: &[q[2] as f32],
                });
            }
            id.forget();
            assert!(id.model().is_none());
            for q in &points {
                id.push(&SystemSample {
                    x2: None,
                    v2: None,
                    t: q[0],
                    x: q[1] as f32,
                    v: None,
                    u: None,
                    electrical: &[q[2] as f32],
                })
                .expect("a clean sample");
            }
            assert!(id.screen());
            let got = id.model().expect("a model");
            for (eg, ew) in got.equations.iter().zip(&want.equations) {
                assert_eq!(
                    eg.coefficients.map(f32::to_bits),
                    ew.coefficients.map(f32::to_bits)
                );
            }
            id.forget();
        }
    }
}

/// What the two-equation identifier takes in memory (printed for the record; the bound
/// holds the design's figure).
#[test]
fn memory_of_the_two_equation_identifier() {
    let device = core::mem::size_of::<SystemIdentifier<f32, 256, 16, 2, 2>>();
    let with_input = core::mem::size_of::<SystemIdentifier<f32, 256, 16, 2, 3>>();
    let host = core::mem::size_of::<SystemIdentifier<f64, 256, 16, 2, 3>>();
    let one = core::mem::size_of::<crate::Identifier<f32, 256, 16, 2>>();
    let multi = core::mem::size_of::<MultiFactor<f32, 16, 2>>();
    let single = core::mem::size_of::<Factor<f32, 16>>();
    let snapshot = core::mem::size_of::<SystemSnapshot<f32, 16, 2>>();
    std::println!("SystemSnapshot<f32, 16, 2>: {snapshot} B");
    std::println!(
        "SystemIdentifier<f32, 256, 16, 2, 2> (x, V): {device} B; with u: {with_input} B; f64 with u: {host} B; \
         single-equation Identifier<f32, 256, 16, 2>: {one} B; MultiFactor<f32, 16, 2>: {multi} B against 2 × Factor<f32, 16>: {} B",
        2 * single
    );
    assert!(multi < 2 * single);
    assert!(device < 12 * 1024, "{device}");
}

/// The host's choice for a record: the weak form's test function and short window from the
/// mean period of x (`tuning`), or rows as they are with the window `tuning` picks.
fn tuned(points: &[[f64; 4]], input: bool) -> SystemConfig {
    let x: Vec<f64> = points.iter().map(|q| q[1]).collect();
    let choice = crate::tuning::choose_window::<f64, 256>(&x, 2, DT, x.len()).expect("a window");
    let mut c = config(choice.window, input);
    c.base.derivative_degree = choice.degree;
    if let Some(weak) = crate::tuning::choose_test_rows::<256>(choice.period, x.len()) {
        c.base.test_rows = weak.test_rows;
        c.base.window = weak.window;
        c.base.derivative_degree = weak.degree;
        c.base.row_stride = 1;
    }
    c
}

/// Every refused configuration says what is wrong; the capacities are checked.
#[test]
fn bad_configurations_are_refused_with_a_reason() {
    let good = config(63, false);
    assert!(SystemIdentifier::<f32, 256, 16, 2, 2>::new(good).is_ok());
    let cases: [(SystemConfig, &str); 5] = [
        (
            SystemConfig {
                electrical: [None, None],
                ..good
            },
            "electrical channels",
        ),
        (
            SystemConfig {
                coupling_order: 4,
                ..good
            },
            "coupling_order is 4",
        ),
        (
            SystemConfig {
                base: Config {
                    window: 300,
                    ..good.base
                },
                ..good
            },
            "window is 300",
        ),
        (
            SystemConfig {
                base: Config {
                    noise_correction: true,
                    ..good.base
                },
                ..good
            },
            "noise_correction",
        ),
        (
            SystemConfig {
                coupling_order: 3,
                ..good
            },
            "22 terms",
        ),
    ];
    for (c, words) in cases {
        let e = SystemIdentifier::<f32, 256, 16, 2, 2>::new(c)
            .err()
            .expect("refused");
        assert!(e.to_string().contains(words), "{e}");
    }
    // Two electrical channels need three equations and three rings.
    let two = SystemConfig {
        electrical: [Some(Electrical::Voltage), Some(Electrical::Current)],
        coupling_order: 1,
        ..good
    };
    let e = SystemIdentifier::<f32, 256, 16, 2, 3>::new(two)
        .err()
        .expect("refused");
    assert_eq!(
        e,
        SystemConfigError::Equations {
            equations: 3,
            capacity: 2
        }
    );
    let e = SystemIdentifier::<f32, 256, 16, 3, 2>::new(two)
        .err()
        .expect("refused");
    assert!(e.to_string().contains("3 channels"), "{e}");
    assert!(SystemIdentifier::<f32, 256, 16, 3, 3>::new(two).is_ok());
}

/// Bad samples are counted and rejected, a gap restarts the window, nothing panics.
#[test]
fn bad_samples_are_rejected_and_counted() {
    let mut id: Box<SystemIdentifier<f64, 256, 16, 2, 2>> =
        Box::new(SystemIdentifier::new(config(63, false)).expect("valid"));
    let sample = |t: f64, x: f64, e: &'static [f64]| SystemSample {
        x2: None,
        v2: None,
        t,
        x,
        v: None,
        u: None,
        electrical: e,
    };
    assert_eq!(id.push(&sample(0.0, 0.0, &[0.0])), Ok(false));
    let bad = [
        (sample(0.01, 0.0, &[]), Rejection::Channels),
        (sample(0.01, 0.0, &[0.0, 1.0]), Rejection::Channels),
        (sample(0.01, f64::NAN, &[0.0]), Rejection::NonFinite),
        (sample(0.01, 0.0, &[f64::INFINITY]), Rejection::NonFinite),
        (sample(0.01, 0.0, &[2e9]), Rejection::OutOfRange),
        (sample(0.004, 0.0, &[0.0]), Rejection::OutOfOrder),
        (
            SystemSample {
                x2: None,
                v2: None,
                u: Some(1.0),
                ..sample(0.01, 0.0, &[0.0])
            },
            Rejection::Channels,
        ),
    ];
    for (s, why) in bad {
        assert_eq!(id.push(&s), Err(why), "{s:?}");
    }
    assert_eq!(id.counters().rejected(), 7);
    assert_eq!(id.counters().accepted, 1);
    // A gap of more than 1.5 periods restarts the window.
    assert_eq!(id.push(&sample(0.05, 0.0, &[0.0])), Ok(false));
    assert_eq!(id.counters().gaps, 1);
    assert!(id.model().is_none() && !id.screen());
}

/// An electromagnetic harvester's coil current i: x'' = −x − 0.04 v − 0.5 x³ − θ i + u,
/// i' = −(R/L) i + (θ/L) v, the same system under other names; the equation is `i'`.
#[test]
fn a_coil_current_gives_its_own_equation() {
    // The piezo system with V read as i and χ = −θ: the same integration.
    let p = Piezo {
        chi: -0.1,
        kappa: -0.5,
        lambda: 2.0,
        ..Piezo::monostable().with_input(0.4)
    };
    let points = record(&p, SAMPLES, 0.0, 0);
    let mut c = tuned(&points, true);
    c.electrical = [Some(Electrical::Current), None];
    let model = identify::<f64>(c, &points);
    let rate = Target::Rate(Electrical::Current);
    let i = StateTerm::Monomial([0, 0, 1, 0, 0, 0]);
    let v = StateTerm::Monomial([0, 1, 0, 0, 0, 0]);
    let terms: Vec<StateTerm> = model.active(rate).map(|(t, _)| t).collect();
    assert_eq!(terms, [v, i], "{}", text(&model));
    let coefficient = |target, term| model.coefficient(target, term).expect("in the library");
    assert!(
        (coefficient(rate, i) + 2.0).abs() < 1e-3,
        "{}",
        text(&model)
    );
    assert!(
        (coefficient(rate, v) - 0.5).abs() < 1e-3,
        "{}",
        text(&model)
    );
    assert!(
        (coefficient(Target::Acceleration, i) + 0.1).abs() < 1e-3,
        "{}",
        text(&model)
    );
    let printed = text(&model);
    assert!(printed.contains("i' = 0.5000 v - 2.0000 i"), "{printed}");
}

/// Under one forcing tone the motion is periodic and V, x, v and cos Ωt are nearly
/// collinear (V is v through a first-order lag: at one frequency, a combination of x and
/// v): the electrical equation still comes out (its target is V' itself), but the
/// mechanical one cannot tell χV from the stiffness, damping and forcing. Printed, not
/// asserted: it is the data's limit (only the harmonics that the cubic adds tell them
/// apart; on the monostable record rows as they are, window 15, noise-free, drop χV too,
/// and 0.1 % noise spoils both equations).
#[test]
fn one_forcing_tone_still_gives_the_electrical_equation() {
    for p in [Piezo::monostable(), Piezo::bistable()] {
        let points = record(&p, SAMPLES, 0.0, 0);
        let model = identify::<f64>(tuned(&points, false), &points);
        let found = errors(&model, &p.truth());
        let (errs, spurious) = &found[1];
        assert!(
            spurious.is_empty() && errs.iter().all(|e| *e < 1.0),
            "{errs:?} {spurious:?}\n{}",
            text(&model)
        );
        std::println!(
            "one tone, k1 = {}: x'' errors {:.2?} % spurious {:?}\n{}",
            p.k1,
            found[0].0,
            found[0].1,
            text(&model)
        );
    }
}

/// The cost on the host (printed; run with `--ignored`): a row into one factor with two
/// right-hand sides against two factors, and whole samples through the identifiers.
#[test]
#[ignore = "a timing, printed for the record"]
fn cost_on_the_host() {
    use std::time::Instant;
    let rows: Vec<([f32; 16], [f32; 2])> = (0..4096)
        .map(|i| {
            let t = i as f32 * 0.01;
            (
                core::array::from_fn(|j| (t * (1.0 + j as f32 * 0.37)).sin()),
                [t.cos(), (2.0 * t).sin()],
            )
        })
        .collect();
    let repeat = 200;
    let mut multi = MultiFactor::<f32, 16, 2>::new(16, 2);
    let start = Instant::now();
    for _ in 0..repeat {
        for (theta, y) in &rows {
            multi.update(theta, y, 1.0);
        }
    }
    let one = start.elapsed().as_secs_f64() / (repeat * rows.len()) as f64;
    let mut two = [Factor::<f32, 16>::new(16), Factor::<f32, 16>::new(16)];
    let start = Instant::now();
    for _ in 0..repeat {
        for (theta, y) in &rows {
            two[0].update(theta, y[0], 1.0);
            two[1].update(theta, y[1], 1.0);
        }
    }
    let separate = start.elapsed().as_secs_f64() / (repeat * rows.len()) as f64;
    std::println!(
        "a row of 16 columns, two targets (f32): one factor, two right-hand sides {:.0} ns; two factors {:.0} ns ({})",
        one * 1e9,
        separate * 1e9,
        multi.weight() + two[0].weight() + two[1].weight()
    );
    let p = Piezo::bistable().with_input(0.3);
    let points = record(&p, SAMPLES, 0.01, 31);
    for c in [tuned(&points, true), config(127, true)] {
        let start = Instant::now();
        let model = identify::<f32>(c, &points);
        let per = start.elapsed().as_secs_f64() / points.len() as f64;
        std::println!(
            "SystemIdentifier<f32> x, V, u, test_rows {}, window {}: {:.0} ns a sample (with one screening), {} rows",
            c.base.test_rows,
            c.base.window,
            per * 1e9,
            model.rows
        );
        // The single-equation path on the same x and u, same settings.
        let mut id: Box<crate::Identifier<f32, 256, 16, 3>> =
            Box::new(crate::Identifier::new(c.base).expect("valid"));
        let start = Instant::now();
        for q in &points {
            let _ = id.push(crate::Sample {
                t: q[0],
                x: q[1] as f32,
                v: None,
                u: Some(q[3] as f32),
            });
        }
        id.screen();
        let per = start.elapsed().as_secs_f64() / points.len() as f64;
        std::println!(
            "  Identifier<f32> x, u, same settings: {:.0} ns a sample",
            per * 1e9
        );
    }
}

/// A slot configured (twice, the first time with another configuration and some samples)
/// gives what `new` gives, bit for bit; with a memory the identifier still finds the
/// system, from the recent rows.
#[test]
fn a_slot_and_a_memory() {
    let p = Piezo::bistable().with_input(0.3);
    let points = record(&p, SAMPLES / 2, 0.01, 41);
    let c = tuned(&points, true);
    let mut slot: Box<SystemSlot<f32, 256, 16, 2, 3>> = Box::default();
    let other = config(31, true);
    let id = slot.configure(other).expect("valid");
    for q in &points[..5000] {
        let e = [q[2] as f32];
        let s = SystemSample {
            x2: None,
            v2: None,
            t: q[0],
            x: q[1] as f32,
            v: None,
            u: Some(q[3] as f32),
            electrical: &e,
        };
        id.push(&s).expect("clean");
    }
    let id = slot.configure(c).expect("valid");
    for q in &points {
        let e = [q[2] as f32];
        let s = SystemSample {
            x2: None,
            v2: None,
            t: q[0],
            x: q[1] as f32,
            v: None,
            u: Some(q[3] as f32),
            electrical: &e,
        };
        id.push(&s).expect("clean");
    }
    assert!(id.screen());
    let fresh = identify::<f32>(c, &points);
    let slotted = id.model().expect("a model");
    for (a, b) in slotted.equations.iter().zip(&fresh.equations) {
        assert_eq!(
            a.coefficients.map(f32::to_bits),
            b.coefficients.map(f32::to_bits)
        );
    }
    // A memory of 200 s (a sixth of the record): the same terms.
    let mut remembering = c;
    remembering.base.memory = Some(200.0);
    let model = identify::<f64>(remembering, &points);
    let found = errors(&model, &p.truth());
    for (errs, spurious) in &found {
        assert!(
            spurious.is_empty() && errs.iter().all(|e| *e < 5.0),
            "{errs:?} {spurious:?}\n{}",
            text(&model)
        );
    }
}

/// A measured velocity (a laser vibrometer's) beside x: v̂ and x̂'' come from v, the rest as
/// before; 1 % noise on x, v and V, two seeds.
#[test]
fn a_measured_velocity_gives_both_equations() {
    let p = Piezo::bistable().with_input(0.3);
    let truth = p.truth();
    for seed in [51, 52] {
        let mut points = p.simulate(SAMPLES, DT, 10, [0.1, 0.0, 0.0]);
        let mut rng = Noise::new(seed);
        for column in [1, 2, 4] {
            let mut values: Vec<f64> = points.iter().map(|q| q[column]).collect();
            rng.add_relative(&mut values, 0.01);
            for (q, v) in points.iter_mut().zip(values) {
                q[column] = v;
            }
        }
        let four: Vec<[f64; 4]> = points.iter().map(|q| [q[0], q[1], q[2], q[3]]).collect();
        let mut c = tuned(&four, true);
        c.base.channels.velocity = true;
        let mut id: Box<SystemIdentifier<f64, 256, 16, 2, 4>> =
            Box::new(SystemIdentifier::new(c).expect("valid"));
        for q in &points {
            let e = [q[2]];
            id.push(&SystemSample {
                x2: None,
                v2: None,
                t: q[0],
                x: q[1],
                v: Some(q[4]),
                u: Some(q[3]),
                electrical: &e,
            })
            .expect("clean");
        }
        assert!(id.screen());
        let model = id.model().expect("a model");
        // The helpers take the capacity-3 model's shape: compare by name here.
        for (k, equation) in model.equations.iter().enumerate() {
            for (j, term) in model.terms.iter().enumerate() {
                let mut name = String::new();
                let _ = term.write_name(&mut name, model.omega, &model.electrical);
                let truth = truth[k].iter().find(|(n, _)| *n == name).map(|t| t.1);
                let active = equation.support() & (1 << j) != 0;
                assert_eq!(active, truth.is_some(), "seed {seed}, equation {k}, {name}");
                if let Some(c) = truth {
                    let error = 100.0 * ((equation.coefficients[j] - c) / c).abs();
                    assert!(error < 5.0, "seed {seed}, equation {k}, {name}: {error} %");
                }
            }
        }
    }
}

/// The spread over variants (printed; run with `--ignored`): mono- and bistable, two
/// forcing amplitudes, noise 0, 1 and 5 %, eight seeds, f64 and f32. Per cell: the records
/// whose equations hold exactly the true terms, and the median and worst coefficient error
/// of those.
#[test]
#[ignore = "a table for the report, about two minutes"]
fn spread_over_seeds_and_noise() {
    fn table<T: Real>() {
        for (name, p) in [
            ("monostable F 0.4", Piezo::monostable().with_input(0.4)),
            ("monostable F 0.8", Piezo::monostable().with_input(0.8)),
            ("bistable F 0.3", Piezo::bistable().with_input(0.3)),
            ("bistable F 0.15", Piezo::bistable().with_input(0.15)),
        ] {
            for noise in [0.0, 0.01, 0.05] {
                let seeds: Vec<u64> = if noise == 0.0 {
                    vec![0]
                } else {
                    (100..108).collect()
                };
                let mut exact = [0usize; 2];
                let mut all: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
                for &seed in &seeds {
                    let points = record(&p, SAMPLES, noise, seed);
                    let model = identify::<T>(tuned(&points, true), &points);
                    for (k, (errs, spurious)) in errors(&model, &p.truth()).iter().enumerate() {
                        let missing = errs.iter().any(|e| *e >= 100.0 - 1e-9);
                        if spurious.is_empty() && !missing {
                            exact[k] += 1;
                            all[k].push(errs.iter().copied().fold(0.0, f64::max));
                        }
                    }
                }
                let stats = |v: &mut Vec<f64>| {
                    v.sort_by(|a, b| a.total_cmp(b));
                    if v.is_empty() {
                        (f64::NAN, f64::NAN)
                    } else {
                        (v[v.len() / 2], v[v.len() - 1])
                    }
                };
                let (m0, w0) = stats(&mut all[0]);
                let (m1, w1) = stats(&mut all[1]);
                std::println!(
                    "{:<18} {:<4} noise {:>2.0} %: x'' exact {}/{} (max error median {m0:.2} %, worst {w0:.2} %); V' exact {}/{} (median {m1:.3} %, worst {w1:.3} %)",
                    name,
                    core::any::type_name::<T>(),
                    noise * 100.0,
                    exact[0],
                    seeds.len(),
                    exact[1],
                    seeds.len()
                );
            }
        }
    }
    table::<f64>();
    table::<f32>();
}

/// A screening deferred to a snapshot gives the model of the inline one, bit for bit, and
/// the identifier that deferred it goes on exactly as the inline one.
#[test]
fn a_deferred_screening_is_the_inline_one() {
    let p = Piezo::bistable().with_input(0.3);
    let points = record(&p, SAMPLES / 4, 0.01, 61);
    let mut c = tuned(&points, true);
    c.base.screening_period = 7_000;
    let mut inline: Box<SystemIdentifier<f32, 256, 16, 2, 3>> =
        Box::new(SystemIdentifier::new(c).expect("valid"));
    let mut deferred: Box<SystemIdentifier<f32, 256, 16, 2, 3>> =
        Box::new(SystemIdentifier::new(c).expect("valid"));
    let mut snapshot: Box<SystemSnapshot<f32, 16, 2>> = Box::new(SystemSnapshot::snapshot());
    let mut screenings = 0;
    for q in &points {
        let e = [q[2] as f32];
        let s = SystemSample {
            x2: None,
            v2: None,
            t: q[0],
            x: q[1] as f32,
            v: None,
            u: Some(q[3] as f32),
            electrical: &e,
        };
        let screened = inline.push(&s).expect("clean");
        let mut taken = false;
        deferred
            .push_with(&s, |id| {
                id.snapshot_into(&mut snapshot);
                taken = true;
                false
            })
            .expect("clean");
        assert_eq!(screened, taken);
        if taken {
            screenings += 1;
            assert!(snapshot.select());
            let (a, b) = (
                inline.model().expect("a model"),
                snapshot.model().expect("a model"),
            );
            for (ea, eb) in a.equations.iter().zip(&b.equations) {
                assert_eq!(
                    ea.coefficients.map(f32::to_bits),
                    eb.coefficients.map(f32::to_bits)
                );
                assert_eq!(ea.solutions, eb.solutions);
            }
        }
    }
    assert!(screenings >= 3, "{screenings}");
    assert!(deferred.model().is_none());
    assert_eq!(inline.counters(), deferred.counters());
}

/// A two-degree-of-freedom piezo harvester, per unit mass, shaken by the measured multisine u:
/// x1'' = −1.5 x1 + 0.5 x2 − 0.04 v1 + u,  x2'' = 0.8 x1 − 0.8 x2 − 0.03 v2 + 0.2 V + u,
/// V' = −V − 0.5 v2. Returns (t, x1, x2, V, u) samples, after 100 s of transient.
fn two_dof_record(n: usize, noise: f64, seed: u64) -> Vec<[f64; 5]> {
    let rate = |t: f64, s: [f64; 5]| -> [f64; 5] {
        let [x1, v1, x2, v2, e] = s;
        let u = multisine(t);
        [
            v1,
            -1.5 * x1 + 0.5 * x2 - 0.04 * v1 + u,
            v2,
            0.8 * x1 - 0.8 * x2 - 0.03 * v2 + 0.2 * e + u,
            -e - 0.5 * v2,
        ]
    };
    let substeps = 10;
    let h = DT / substeps as f64;
    let skip = (100.0 / DT) as usize;
    let mut s = [0.1, 0.0, 0.0, 0.0, 0.0];
    let mut t = 0.0;
    let mut out = Vec::with_capacity(n);
    for i in 0..n + skip {
        if i >= skip {
            let ti = i as f64 * DT;
            out.push([ti, s[0], s[2], s[4], multisine(ti)]);
        }
        for _ in 0..substeps {
            let add = |a: [f64; 5], k: [f64; 5], f: f64| -> [f64; 5] {
                core::array::from_fn(|j| a[j] + f * k[j])
            };
            let k1 = rate(t, s);
            let k2 = rate(t + h / 2.0, add(s, k1, h / 2.0));
            let k3 = rate(t + h / 2.0, add(s, k2, h / 2.0));
            let k4 = rate(t + h, add(s, k3, h));
            s = core::array::from_fn(|j| {
                s[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
            });
            t += h;
        }
    }
    if noise > 0.0 {
        let mut rng = Noise::new(seed);
        for c in 1..4 {
            let mut col: Vec<f64> = out.iter().map(|q| q[c]).collect();
            rng.add_relative(&mut col, noise);
            for (q, v) in out.iter_mut().zip(col) {
                q[c] = v;
            }
        }
    }
    out
}

fn two_dof_config(window: usize) -> SystemConfig {
    let mut c = config(window, true);
    c.displacements = 2;
    c.coupling_order = 1;
    c
}

fn identify_two_dof<T: Real>(config: SystemConfig, points: &[[f64; 5]]) -> SystemModel<T, 16, 3> {
    let mut id: Box<SystemIdentifier<T, 256, 16, 3, 4>> =
        Box::new(SystemIdentifier::new(config).expect("a valid configuration"));
    for q in points {
        let e = [T::from_f64(q[3])];
        id.push(&SystemSample {
            t: q[0],
            x: T::from_f64(q[1]),
            x2: Some(T::from_f64(q[2])),
            v: None,
            v2: None,
            u: Some(T::from_f64(q[4])),
            electrical: &e,
        })
        .expect("a clean sample");
    }
    assert!(id.screen(), "a screening");
    id.model().expect("a model").clone()
}

/// Two displacements, f64 and f32, clean and with 1 % noise on x1, x2 and V: x1'', x2'' and
/// V' with exactly the true terms (named x1, v1, x2, v2), every coefficient within 1 %
/// (clean) or 5 % (noisy).
#[test]
fn a_two_degree_of_freedom_harvester_gives_its_three_equations() {
    let truth: [&[(&str, f64)]; 3] = [
        &[("x1", -1.5), ("v1", -0.04), ("x2", 0.5), ("u", 1.0)],
        &[
            ("x1", 0.8),
            ("x2", -0.8),
            ("v2", -0.03),
            ("V", 0.2),
            ("u", 1.0),
        ],
        &[("v2", -0.5), ("V", -1.0)],
    ];
    for (noise, seed, tolerance) in [(0.0, 0, 1.0), (0.01, 31, 5.0)] {
        let points = two_dof_record(SAMPLES, noise, seed);
        // Clean: rows as they are, a short window; noisy: the host's choice from x1 (the weak
        // form), as `lssi identify` makes it.
        let config = if noise == 0.0 {
            two_dof_config(15)
        } else {
            let x1: Vec<[f64; 4]> = points.iter().map(|q| [q[0], q[1], q[3], q[4]]).collect();
            let mut c = tuned(&x1, true);
            c.displacements = 2;
            c.coupling_order = 1;
            c
        };
        for f32_run in [false, true] {
            let (names, targets, coefficients, supports) = if f32_run {
                summarise(&identify_two_dof::<f32>(config, &points))
            } else {
                summarise(&identify_two_dof::<f64>(config, &points))
            };
            assert_eq!(targets, ["x1''", "x2''", "V'"]);
            for (k, eq) in truth.iter().enumerate() {
                let active: Vec<&str> = names
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| supports[k] & (1 << j) != 0)
                    .map(|(_, n)| n.as_str())
                    .collect();
                let mut want: Vec<&str> = eq.iter().map(|t| t.0).collect();
                let mut got = active.clone();
                want.sort_unstable();
                got.sort_unstable();
                assert_eq!(got, want, "noise {noise}, f32 {f32_run}, {}", targets[k]);
                for &(name, c) in eq.iter() {
                    let j = names.iter().position(|n| n == name).expect("a column");
                    let error = 100.0 * ((coefficients[k][j] - c) / c).abs();
                    assert!(
                        error < tolerance,
                        "noise {noise}, f32 {f32_run}, {} {name}: {} against {c}",
                        targets[k],
                        coefficients[k][j]
                    );
                }
            }
        }
    }
}

/// Names, target names, coefficients and supports of a model.
#[allow(clippy::type_complexity)]
fn summarise<T: Real>(
    m: &SystemModel<T, 16, 3>,
) -> (Vec<String>, Vec<String>, Vec<Vec<f64>>, Vec<u32>) {
    let names = (0..m.terms.len())
        .map(|j| m.term_name(j).expect("a column").to_string())
        .collect();
    let targets = (0..m.equations.len())
        .map(|k| m.target_name(k).expect("an equation").to_string())
        .collect();
    let coefficients = m
        .equations
        .iter()
        .map(|e| e.coefficients.iter().map(|c| c.to_f64()).collect())
        .collect();
    let supports = m.equations.iter().map(|e| e.support()).collect();
    (names, targets, coefficients, supports)
}

/// What the two-displacement identifier takes (printed for the record): x1, x2, V and u
/// (four rings), three equations, 16 terms.
#[test]
fn memory_of_the_two_displacement_identifier() {
    let two = core::mem::size_of::<SystemIdentifier<f32, 256, 16, 3, 4>>();
    let one = core::mem::size_of::<SystemIdentifier<f32, 256, 16, 2, 3>>();
    std::println!(
        "SystemIdentifier<f32, 256, 16, 3, 4> (x1, x2, V, u): {two} B; one displacement with u, <f32, 256, 16, 2, 3>: {one} B"
    );
    let snapshot_two = core::mem::size_of::<SystemSnapshot<f32, 16, 3>>();
    let snapshot_one = core::mem::size_of::<SystemSnapshot<f32, 16, 2>>();
    let device_one = core::mem::size_of::<SystemIdentifier<f32, 256, 16, 2, 2>>();
    let device_two = core::mem::size_of::<SystemIdentifier<f32, 256, 16, 3, 3>>();
    std::println!(
        "snapshot <f32, 16, 3>: {snapshot_two} B against <f32, 16, 2>: {snapshot_one} B; without u: <f32, 256, 16, 3, 3> (x1, x2, V): {device_two} B against <f32, 256, 16, 2, 2> (x, V): {device_one} B"
    );
    assert!(two < 16 * 1024, "{two}");
    // A sample without x2 where two displacements are configured is refused.
    let mut id: Box<SystemIdentifier<f64, 256, 16, 3, 4>> =
        Box::new(SystemIdentifier::new(two_dof_config(15)).expect("valid"));
    let sample = SystemSample {
        t: 0.0,
        x: 0.0,
        x2: None,
        v: None,
        v2: None,
        u: Some(0.0),
        electrical: &[0.0],
    };
    assert_eq!(id.push(&sample), Err(Rejection::Channels));
    // Too few rings for x2: refused with a reason.
    let small = SystemIdentifier::<f64, 256, 16, 3, 3>::new(two_dof_config(15));
    assert!(small.is_err());
}
