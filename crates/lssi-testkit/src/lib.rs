//! # lssi-testkit — known truths for the lssi tests
//!
//! Systems whose equation of motion is known, integrated finely by classical RK4, and seeded
//! noise: what the identifier's known-truth tests feed it; with the `wire` feature, the
//! proptest strategies of the wire configuration ([`wire`]). One copy, used by every crate's
//! tests (a dev-dependency only; `publish = false`; lssi-proto only for `wire`).
//!
//! ```
//! use lssi_testkit::{Noise, duffing, eq17};
//! // The forced Duffing oscillator of the identifier's tests, 1 ms samples of (t, x, v, u).
//! let d = duffing(2000);
//! assert_eq!(d.len(), 2000);
//! assert_eq!(d[0].x, 0.01);
//! // The paper's eq. 17 (ε = 1) at 10 ms for 5 s.
//! let p = eq17(1.0, 0.01, 5.0);
//! assert_eq!(p.len(), 501);
//! assert_eq!((p[0].x, p[0].v), (2.0, 0.0));
//! // Seeded noise: the same seed gives the same sequence.
//! let (mut a, mut b) = (Noise::new(7), Noise::new(7));
//! assert_eq!(a.gauss(), b.gauss());
//! ```

pub mod harvester;
pub mod ode;
pub mod systems;
#[cfg(feature = "wire")]
pub mod wire;

pub use ode::{State, integrate_at, rk4_step};
pub use systems::{
    DUFFING_TRUTH, EQ17_OMEGA, Point, duffing, duffing_at, eq17, eq17_acceleration, eq17_truth,
};

/// A seeded pseudo-random sequence (SplitMix64): uniform and Gaussian (Box–Muller) draws.
#[derive(Clone, Debug)]
pub struct Noise {
    state: u64,
    spare: Option<f64>,
}

impl Noise {
    /// The sequence of `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            state: seed,
            spare: None,
        }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard Gaussian.
    pub fn gauss(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let a = 2.0 * std::f64::consts::PI * u2;
        self.spare = Some(r * a.sin());
        r * a.cos()
    }

    /// A recording of white Gaussian noise of RMS `sigma` as CSV text (header `t,x`), `rows`
    /// samples `dt` apart: a signal with no deterministic dynamics, which a quality gate
    /// must refuse.
    pub fn white_noise_csv(&mut self, rows: usize, dt: f64, sigma: f64) -> String {
        let mut text = String::from("t,x\n");
        for i in 0..rows {
            text.push_str(&format!("{},{:e}\n", i as f64 * dt, sigma * self.gauss()));
        }
        text
    }

    /// Adds zero-mean Gaussian noise of RMS `delta`·RMS(`values`) to `values`.
    pub fn add_relative(&mut self, values: &mut [f64], delta: f64) {
        let n = values.len().max(1) as f64;
        let rms = (values.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        for v in values.iter_mut() {
            *v += delta * rms * self.gauss();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_noise_csv_has_the_rows_and_the_level_asked_for() {
        let text = Noise::new(3).white_noise_csv(4000, 0.001, 0.5);
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("t,x"));
        let x: Vec<f64> = lines
            .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
            .collect();
        assert_eq!(x.len(), 4000);
        let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        assert!((rms - 0.5).abs() < 0.03, "{rms}");
        assert_eq!(text, Noise::new(3).white_noise_csv(4000, 0.001, 0.5));
    }

    #[test]
    fn gaussian_noise_has_unit_variance_and_zero_mean() {
        let mut noise = Noise::new(1);
        let n = 200_000;
        let draws: Vec<f64> = (0..n).map(|_| noise.gauss()).collect();
        let mean = draws.iter().sum::<f64>() / n as f64;
        let var = draws.iter().map(|d| (d - mean) * (d - mean)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.01, "{var}");
    }

    #[test]
    fn relative_noise_scales_with_the_signal() {
        let mut values: Vec<f64> = (0..10_000)
            .map(|i| 3.0 * (f64::from(i) * 0.1).sin())
            .collect();
        let clean = values.clone();
        Noise::new(5).add_relative(&mut values, 0.1);
        let n = values.len() as f64;
        let rms = |v: &[f64]| (v.iter().map(|a| a * a).sum::<f64>() / n).sqrt();
        let diff: Vec<f64> = values.iter().zip(&clean).map(|(a, b)| a - b).collect();
        let ratio = rms(&diff) / rms(&clean);
        assert!((ratio - 0.1).abs() < 0.005, "{ratio}");
    }
}
