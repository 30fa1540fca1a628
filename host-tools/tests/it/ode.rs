//! The RK4 integrator against closed-form solutions of the linear oscillator.

use lssi_host::synth::ode::{State, integrate_at};

/// Samples every 1 ms over 20 s, integrated with 10 steps per sample, as the generators do.
fn grid() -> Vec<f64> {
    (0..=20_000).map(|k| k as f64 / 1000.0).collect()
}

#[test]
fn undamped_oscillator_matches_closed_form() {
    // x'' = -ω² x from x = 2, v = 0: x = 2 cos ωt, v = -2ω sin ωt.
    let omega = 3.0;
    let times = grid();
    let states = integrate_at(
        |_t, x, _v| -omega * omega * x,
        State { x: 2.0, v: 0.0 },
        &times,
        1e-4,
    );
    for (t, s) in times.iter().zip(&states) {
        assert!((s.x - 2.0 * (omega * t).cos()).abs() < 1e-9, "x at t = {t}");
        assert!(
            (s.v + 2.0 * omega * (omega * t).sin()).abs() < 1e-9,
            "v at t = {t}"
        );
    }
}

#[test]
fn damped_forced_oscillator_matches_closed_form() {
    // x'' + 2ζω x' + ω² x = F cos Ωt. The particular solution is A cos Ωt + B sin Ωt; start on
    // it plus a decaying homogeneous part with known constants.
    let (omega, zeta, force, drive) = (2.0_f64, 0.1_f64, 1.5_f64, 1.3_f64);
    let c = 2.0 * zeta * omega;
    let k = omega * omega;
    let det = (k - drive * drive).powi(2) + (c * drive).powi(2);
    let a = force * (k - drive * drive) / det;
    let b = force * c * drive / det;
    let decay = zeta * omega;
    let omega_d = omega * (1.0 - zeta * zeta).sqrt();
    let (p, q) = (0.7, -0.4);
    let exact = |t: f64| {
        let e = (-decay * t).exp();
        let (s, co) = (omega_d * t).sin_cos();
        let x = a * (drive * t).cos() + b * (drive * t).sin() + e * (p * co + q * s);
        let v = -a * drive * (drive * t).sin()
            + b * drive * (drive * t).cos()
            + e * (-decay * (p * co + q * s) + omega_d * (-p * s + q * co));
        State { x, v }
    };
    let times = grid();
    let states = integrate_at(
        |t, x, v| force * (drive * t).cos() - c * v - k * x,
        exact(0.0),
        &times,
        1e-4,
    );
    for (&t, s) in times.iter().zip(&states) {
        let e = exact(t);
        assert!((s.x - e.x).abs() < 1e-9, "x at t = {t}: {} vs {}", s.x, e.x);
        assert!((s.v - e.v).abs() < 1e-9, "v at t = {t}: {} vs {}", s.v, e.v);
    }
}

#[test]
fn error_falls_as_the_fourth_power_of_the_step() {
    let final_error = |step: f64| {
        let states = integrate_at(|_t, x, _v| -x, State { x: 1.0, v: 0.0 }, &[0.0, 10.0], step);
        (states[1].x - 10f64.cos()).abs()
    };
    let ratio = final_error(0.02) / final_error(0.01);
    assert!(
        (14.0..18.0).contains(&ratio),
        "halving the step cut the error by {ratio}"
    );
}
