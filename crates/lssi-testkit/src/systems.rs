//! Systems with known equations of motion, sampled from fine RK4 integrations.

use crate::ode::{State, integrate_at};

/// One sample of a system: time, displacement, velocity and excitation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Time, s.
    pub t: f64,
    /// Displacement.
    pub x: f64,
    /// Velocity.
    pub v: f64,
    /// Excitation (the forcing term of x'').
    pub u: f64,
}

/// The Duffing oscillator's true coefficients: x, v, x³ and the forcing's amplitude.
pub const DUFFING_TRUTH: [(&str, f64); 4] =
    [("x", -400.0), ("v", -2.0), ("x^3", -4.0e4), ("u", 1.0)];

/// A forced Duffing oscillator x'' = −400x − 2x' − 4·10⁴x³ + u, u = 60 cos(15t), from
/// x = 0.01, v = 0, by RK4 (10 steps a sample of 1 ms): `n` samples. The generator of
/// `lssi_core`'s identifier tests and `lssi_device`'s, step for step.
pub fn duffing(n: usize) -> Vec<Point> {
    duffing_at(n, 1e-3)
}

/// [`duffing`] sampled every `dt` seconds (still 10 RK4 steps a sample).
pub fn duffing_at(n: usize, dt: f64) -> Vec<Point> {
    let u = |t: f64| 60.0 * (15.0 * t).cos();
    let f = |t: f64, x: f64, v: f64| -400.0 * x - 2.0 * v - 4.0e4 * x * x * x + u(t);
    let (mut x, mut v) = (0.01, 0.0);
    let h = dt / 10.0;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let t0 = i as f64 * dt;
        out.push(Point {
            t: t0,
            x,
            v,
            u: u(t0),
        });
        for j in 0..10 {
            let t = t0 + j as f64 * h;
            let (k1x, k1v) = (v, f(t, x, v));
            let (k2x, k2v) = (
                v + 0.5 * h * k1v,
                f(t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v),
            );
            let (k3x, k3v) = (
                v + 0.5 * h * k2v,
                f(t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v),
            );
            let (k4x, k4v) = (v + h * k3v, f(t + h, x + h * k3x, v + h * k3v));
            x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
    }
    out
}

/// Ω₀ of eq. 17: the excitation's angular frequency, rad/s.
pub const EQ17_OMEGA: f64 = 2.0;

/// The right-hand side of the paper's eq. 17 with Table 1's parameters,
/// x'' = −ω₀²x − ε((α₁x² + α₂x³) + x'(β₁ + β₂x²)) + εF₀ cos(Ω₀t), ω₀ = 1, β₁ = −1, β₂ = 2,
/// α₁ = −2, α₂ = 4, F₀ = 5, Ω₀ = 2: the host generator's `PaperOptions::acceleration`.
pub fn eq17_acceleration(epsilon: f64, t: f64, x: f64, v: f64) -> f64 {
    let (w0, b1, b2, a1, a2, f0) = (1.0f64, -1.0, 2.0, -2.0, 4.0, 5.0);
    let stiffness = a1 * x * x + a2 * x * x * x;
    let damping = v * (b1 + b2 * x * x);
    -w0 * w0 * x - epsilon * (stiffness + damping) + epsilon * f0 * (EQ17_OMEGA * t).cos()
}

/// Eq. 17's true coefficients for `epsilon`: x, v, x², x³, x²v and cos(2t).
pub fn eq17_truth(epsilon: f64) -> [(&'static str, f64); 6] {
    [
        ("x", -1.0),
        ("v", epsilon),
        ("x^2", 2.0 * epsilon),
        ("x^3", -4.0 * epsilon),
        ("x^2*v", -2.0 * epsilon),
        ("cos(2t)", 5.0 * epsilon),
    ]
}

/// Eq. 17 from x = 2, x' = 0, sampled every `dt` up to `t_end` (the host generator's grid,
/// t = i·dt, and its step: at most 10⁻⁴ s and a tenth of a sample). u is εF₀ cos(Ω₀t).
pub fn eq17(epsilon: f64, dt: f64, t_end: f64) -> Vec<Point> {
    let n = (t_end / dt).round() as usize + 1;
    let times: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let max_step = (dt / 10.0).min(1e-4);
    let states = integrate_at(
        |t, x, v| eq17_acceleration(epsilon, t, x, v),
        State { x: 2.0, v: 0.0 },
        &times,
        max_step,
    );
    times
        .iter()
        .zip(states)
        .map(|(&t, s)| Point {
            t,
            x: s.x,
            v: s.v,
            u: epsilon * 5.0 * (EQ17_OMEGA * t).cos(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq17_satisfies_its_equation() {
        // The second difference of x matches x'' to the grid's O(dt²).
        let dt = 0.001;
        let p = eq17(1.0, dt, 2.0);
        for i in 1..p.len() - 1 {
            let a = (p[i + 1].x - 2.0 * p[i].x + p[i - 1].x) / (dt * dt);
            let f = eq17_acceleration(1.0, p[i].t, p[i].x, p[i].v);
            assert!((a - f).abs() < 1e-3 * (1.0 + f.abs()), "{i}: {a} {f}");
        }
    }

    #[test]
    fn duffing_velocity_is_the_derivative_of_x() {
        let d = duffing(3000);
        for w in d.windows(3) {
            let dx = (w[2].x - w[0].x) / 2e-3;
            assert!(
                (dx - w[1].v).abs() < 1e-3 * (1.0 + w[1].v.abs()),
                "{dx} {}",
                w[1].v
            );
        }
    }
}
