//! A two-degree-of-freedom piezoelectric harvester (issue 26, item 1: several
//! displacements): a primary mass on the base and a secondary mass (a piezoelectric beam's
//! tip) on it, coupled by a linear spring, the piezo across a load.
//!
//! Per unit mass, with x1 and x2 the two displacements relative to the base and a(t) the base
//! acceleration,
//!
//! ```text
//! x1'' = −(ω1² + μ ωc²) x1 + μ ωc² x2 − 2ζ1ω1 x1' − h x1³ − a
//! x2'' = ωc² x1 − ωc² x2 − 2ζ2ωc x2' + χ V − a
//! V'   = −λ V − κ x2'
//! ```
//!
//! m1 x1'' = −k1 x1 − c1 x1' − k3 x1³ + k_c (x2 − x1) − m1 a and m2 x2'' = −k_c (x2 − x1) −
//! c2 x2' + θ V − m2 a, with ω1² = k1/m1, ωc² = k_c/m2, μ = m2/m1, χ = θ/m2, κ = θ/C_p and
//! λ = 1/(R C_p) as in the one-mass model ([`super::harvester`]); the lumped transducer reads
//! the secondary mass's velocity and its reaction acts on that mass alone (the form the
//! identifier is asked to recover, V' = −λV − κ x2').
//!
//! Defaults: a 100 g primary at 8 Hz (ζ1 = 0.02), a 20 g secondary (μ = 0.2) tuned to 12 Hz
//! (ζ2 = 0.015), C_p = 50 nF across R = 1 MΩ (λ = 20 s⁻¹) and θ from k² = θ²/(m2 ωc² C_p) =
//! 0.025, Erturk & Inman's coupling; linear springs (h = 0, `--cubic` adds the primary's
//! hardening). The base is shaken broadband, as a two-mode harvester is meant to be: a(t) is
//! A/√6 times the sum of six tones at 0.52…2.45 f1 (4.2–19.6 Hz by default), recorded as the
//! column `u` (so both displacement equations hold the term `u`, coefficient −1). Released
//! from x1 = 1 mm at rest, uncharged.
//!
//! The recording: `t`, `x1`, `x2` (with `--observe xv` also `v1`, `v2`), `V`, `u`; Gaussian
//! noise of RMS `delta` times each channel's own on every channel but t.
//!
//! ```
//! use lssi_host::synth::twodof::{TwoDofOptions, generate_twodof};
//!
//! let options = TwoDofOptions { t_end: 1.0, ..TwoDofOptions::default() };
//! options.validate().unwrap();
//! let g = generate_twodof(&options);
//! assert_eq!(g.header(), ["t", "x1", "x2", "V", "u"]);
//! let targets: Vec<&str> = g.truth.equations.iter().map(|e| e.target.as_str()).collect();
//! assert_eq!(targets, ["x1''", "x2''", "V'"]);
//! ```

use std::collections::BTreeMap;
use std::f64::consts::TAU;

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::harvester::{ChannelNoise, Equation, HarvesterGenerated, SystemTruth};
use super::{OptionError, require_finite, require_positive, sample_times, validate_grid};
use crate::synth::noise::{NoiseKind, add_noise, stats};
use crate::synth::truth::TruthTerm;

/// The name of the two-degree-of-freedom model in truth files.
pub const TWODOF_MODEL: &str = "twodof-piezo";

/// The excitation's tones as multiples of f1, and their phases.
const TONES: [(f64, f64); 6] = [
    (0.52, 0.3),
    (0.79, 2.1),
    (1.09, 4.0),
    (1.49, 1.2),
    (1.90, 5.3),
    (2.45, 3.3),
];

/// Everything [`generate_twodof`] needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TwoDofOptions {
    /// Primary mass m1, kg.
    pub mass1: f64,
    /// Secondary mass m2, kg.
    pub mass2: f64,
    /// Primary natural frequency f1 = √(k1/m1)/2π, Hz.
    pub frequency1_hz: f64,
    /// Secondary (coupling) frequency √(k_c/m2)/2π, Hz.
    pub coupling_hz: f64,
    /// Primary damping ratio ζ1.
    pub zeta1: f64,
    /// Secondary damping ratio ζ2.
    pub zeta2: f64,
    /// Primary cubic stiffness per unit mass h, m⁻² s⁻² (0: linear).
    pub cubic: f64,
    /// Coupling θ, N/V.
    pub theta: f64,
    /// Piezo capacitance C_p, farads.
    pub capacitance: f64,
    /// Load resistance R, ohms.
    pub load_ohms: f64,
    /// Base acceleration scale A, m/s² (the multisine's RMS is A/√2).
    pub amplitude: f64,
    /// Write v1 and v2 too.
    pub velocities: bool,
    /// Sensor noise RMS as a fraction of each channel's RMS.
    pub delta: f64,
    /// Sample rate, Hz.
    pub rate: f64,
    /// Last sample time, seconds.
    pub t_end: f64,
    /// Initial x1, metres.
    pub initial_displacement: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for TwoDofOptions {
    fn default() -> Self {
        let m2 = 0.02;
        let wc = TAU * 12.0;
        let cp = 50e-9;
        Self {
            mass1: 0.1,
            mass2: m2,
            frequency1_hz: 8.0,
            coupling_hz: 12.0,
            zeta1: 0.02,
            zeta2: 0.015,
            cubic: 0.0,
            theta: (0.025 * m2 * wc * wc * cp).sqrt(),
            capacitance: cp,
            load_ohms: 1e6,
            amplitude: 2.0,
            velocities: false,
            delta: 0.0,
            rate: 1000.0,
            t_end: 30.0,
            initial_displacement: 1e-3,
            seed: 1,
        }
    }
}

/// The coefficients of the three equations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TwoDofCoefficients {
    /// x1 in x1'': −(ω1² + μ ωc²).
    pub x1_x1: f64,
    /// x2 in x1'': μ ωc².
    pub x1_x2: f64,
    /// v1 in x1'': −2ζ1ω1.
    pub x1_v1: f64,
    /// x1³ in x1'': −h.
    pub x1_cubic: f64,
    /// x1 in x2'': ωc².
    pub x2_x1: f64,
    /// x2 in x2'': −ωc².
    pub x2_x2: f64,
    /// v2 in x2'': −2ζ2ωc.
    pub x2_v2: f64,
    /// V in x2'': χ = θ/m2.
    pub chi: f64,
    /// V in V': −λ = −1/(R C_p).
    pub minus_lambda: f64,
    /// v2 in V': −κ = −θ/C_p.
    pub minus_kappa: f64,
}

impl TwoDofOptions {
    /// Checks every field once, naming the first that cannot be used.
    pub fn validate(&self) -> Result<(), OptionError> {
        require_positive("mass1", self.mass1)?;
        require_positive("mass2", self.mass2)?;
        require_positive("frequency1_hz", self.frequency1_hz)?;
        require_positive("coupling_hz", self.coupling_hz)?;
        for (field, value) in [
            ("zeta1", self.zeta1),
            ("zeta2", self.zeta2),
            ("cubic", self.cubic),
            ("delta", self.delta),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(OptionError {
                    field,
                    value,
                    requirement: "zero or positive, and finite",
                });
            }
        }
        require_finite("theta", self.theta)?;
        require_positive("capacitance", self.capacitance)?;
        require_positive("load_ohms", self.load_ohms)?;
        require_finite("amplitude", self.amplitude)?;
        require_positive("rate", self.rate)?;
        validate_grid(1.0 / self.rate, self.t_end)?;
        require_finite("initial_displacement", self.initial_displacement)
    }

    /// The three equations' coefficients.
    pub fn coefficients(&self) -> TwoDofCoefficients {
        let w1 = TAU * self.frequency1_hz;
        let wc = TAU * self.coupling_hz;
        let mu = self.mass2 / self.mass1;
        TwoDofCoefficients {
            x1_x1: -(w1 * w1 + mu * wc * wc),
            x1_x2: mu * wc * wc,
            x1_v1: -2.0 * self.zeta1 * w1,
            x1_cubic: -self.cubic,
            x2_x1: wc * wc,
            x2_x2: -wc * wc,
            x2_v2: -2.0 * self.zeta2 * wc,
            chi: self.theta / self.mass2,
            minus_lambda: -1.0 / (self.load_ohms * self.capacitance),
            minus_kappa: -self.theta / self.capacitance,
        }
    }

    /// The base acceleration a(t), m/s².
    pub fn base_acceleration(&self, t: f64) -> f64 {
        let w1 = TAU * self.frequency1_hz;
        self.amplitude / (TONES.len() as f64).sqrt()
            * TONES
                .iter()
                .map(|(r, phi)| (r * w1 * t + phi).cos())
                .sum::<f64>()
    }

    /// The true equations in the identifier's names: x1'', x2'', V'.
    pub fn equations(&self) -> Vec<Equation> {
        let c = self.coefficients();
        let equation = |target: &str, terms: Vec<(&str, f64)>| Equation {
            target: target.to_owned(),
            terms: terms
                .into_iter()
                .filter(|(_, c)| *c != 0.0)
                .map(|(term, coef)| TruthTerm {
                    term: term.to_owned(),
                    coef,
                })
                .collect(),
        };
        vec![
            equation(
                "x1''",
                vec![
                    ("x1", c.x1_x1),
                    ("v1", c.x1_v1),
                    ("x2", c.x1_x2),
                    ("x1^3", c.x1_cubic),
                    ("u", -1.0),
                ],
            ),
            equation(
                "x2''",
                vec![
                    ("x1", c.x2_x1),
                    ("x2", c.x2_x2),
                    ("v2", c.x2_v2),
                    ("V", c.chi),
                    ("u", -1.0),
                ],
            ),
            equation("V'", vec![("v2", c.minus_kappa), ("V", c.minus_lambda)]),
        ]
    }

    /// The RK4 step: 1/(10 × rate), at most 1e-4 s.
    pub fn max_step(&self) -> f64 {
        (0.1 / self.rate).min(1e-4)
    }
}

/// What the truth's `params` holds besides the options.
#[derive(Serialize)]
struct Params<'a> {
    #[serde(flatten)]
    options: &'a TwoDofOptions,
    coefficients: TwoDofCoefficients,
    /// The excitation's tones, Hz.
    tones_hz: Vec<f64>,
    /// k² = θ²/(k_c C_p).
    coupling_squared: f64,
    /// R C_p, seconds.
    electrical_time_constant: f64,
    /// Mean power V²/R over the record (clean), watts.
    mean_power_w: f64,
    integrator: &'static str,
    integrator_step: f64,
}

/// The state (x1, v1, x2, v2, V).
type S = [f64; 5];

/// Integrates the three equations on the sampling grid (RK4), then adds the noise (drawn
/// channel by channel in the column order from [`ChaCha8Rng`] seeded with `seed`). Validate
/// the options first; no I/O.
pub fn generate_twodof(opts: &TwoDofOptions) -> HarvesterGenerated {
    let t = sample_times(1.0 / opts.rate, opts.t_end);
    let c = opts.coefficients();
    let f = |time: f64, y: S| -> S {
        let [x1, v1, x2, v2, e] = y;
        let a = opts.base_acceleration(time);
        [
            v1,
            c.x1_x1 * x1 + c.x1_x2 * x2 + c.x1_v1 * v1 + c.x1_cubic * x1 * x1 * x1 - a,
            v2,
            c.x2_x1 * x1 + c.x2_x2 * x2 + c.x2_v2 * v2 + c.chi * e - a,
            c.minus_lambda * e + c.minus_kappa * v2,
        ]
    };
    let add = |y: S, k: S, h: f64| -> S { std::array::from_fn(|j| y[j] + h * k[j]) };
    let mut y: S = [opts.initial_displacement, 0.0, 0.0, 0.0, 0.0];
    let mut states = Vec::with_capacity(t.len());
    let mut now = 0.0;
    for &target in &t {
        let span = target - now;
        if span > 0.0 {
            let steps = (span / opts.max_step()).ceil().max(1.0) as usize;
            let h = span / steps as f64;
            for k in 0..steps {
                let s = now + k as f64 * h;
                let k1 = f(s, y);
                let k2 = f(s + h / 2.0, add(y, k1, h / 2.0));
                let k3 = f(s + h / 2.0, add(y, k2, h / 2.0));
                let k4 = f(s + h, add(y, k3, h));
                y = std::array::from_fn(|j| {
                    y[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
                });
            }
        }
        now = target;
        states.push(y);
    }
    let column = |j: usize| -> Vec<f64> { states.iter().map(|s| s[j]).collect() };
    let clean_u: Vec<f64> = t.iter().map(|&s| opts.base_acceleration(s)).collect();
    let mut clean: BTreeMap<&'static str, Vec<f64>> = BTreeMap::new();
    for (name, j) in [("x1", 0), ("v1", 1), ("x2", 2), ("v2", 3), ("V", 4)] {
        clean.insert(name, column(j));
    }
    clean.insert("u", clean_u);
    let mut order = vec!["x1", "x2"];
    if opts.velocities {
        order.extend(["v1", "v2"]);
    }
    order.extend(["V", "u"]);
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let mut noise = BTreeMap::new();
    let columns: Vec<(&'static str, Vec<f64>)> = order
        .into_iter()
        .map(|name| {
            let c = &clean[name];
            let noisy = add_noise(c, opts.delta, NoiseKind::Gauss, &mut rng).values;
            let e: Vec<f64> = noisy.iter().zip(c).map(|(o, c)| o - c).collect();
            noise.insert(name.to_owned(), stats(&e));
            (name, noisy)
        })
        .collect();
    let v = &clean["V"];
    let mean_power_w =
        v.iter().map(|e| e * e).sum::<f64>() / v.len().max(1) as f64 / opts.load_ohms;
    let kc = opts.mass2 * (TAU * opts.coupling_hz).powi(2);
    let params = Params {
        options: opts,
        coefficients: c,
        tones_hz: TONES.iter().map(|(r, _)| r * opts.frequency1_hz).collect(),
        coupling_squared: opts.theta * opts.theta / (kc * opts.capacitance),
        electrical_time_constant: opts.load_ohms * opts.capacitance,
        mean_power_w,
        integrator: "rk4",
        integrator_step: opts.max_step(),
    };
    let truth = SystemTruth {
        model: TWODOF_MODEL.to_owned(),
        // No harmonic: the forcing is the recorded u. Ω is the primary's natural frequency.
        omega: TAU * opts.frequency1_hz,
        equations: opts.equations(),
        // Serialising plain numbers into a Value cannot fail.
        params: serde_json::to_value(&params).unwrap_or_default(),
        noise: ChannelNoise {
            kind: NoiseKind::Gauss,
            delta: opts.delta,
            channels: noise,
        },
    };
    HarvesterGenerated {
        t,
        columns,
        clean,
        truth,
    }
}

/// The first sample time at which the clean trajectory is not finite or runs past 1 km.
pub fn diverged_at(g: &HarvesterGenerated) -> Option<f64> {
    let (x1, x2) = (&g.clean["x1"], &g.clean["x2"]);
    (0..g.t.len())
        .find(|&i| !(x1[i].abs() < 1e3 && x2[i].abs() < 1e3))
        .map(|i| g.t[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The clean record satisfies its own truth: fourth-order differences of x1, x2 and V
    /// against the truth's terms, each residual under 0.1 % of its target's RMS.
    #[test]
    fn a_record_satisfies_its_truth() {
        let o = TwoDofOptions {
            t_end: 5.0,
            velocities: true,
            ..TwoDofOptions::default()
        };
        o.validate().unwrap();
        let g = generate_twodof(&o);
        assert_eq!(g.header(), ["t", "x1", "x2", "v1", "v2", "V", "u"]);
        let dt = 1.0 / o.rate;
        let c = &g.clean;
        let d1 = |s: &[f64], k: usize| {
            (s[k - 2] - 8.0 * s[k - 1] + 8.0 * s[k + 1] - s[k + 2]) / (12.0 * dt)
        };
        let value = |name: &str, k: usize| match name {
            "x1^3" => c["x1"][k].powi(3),
            n => c[n][k],
        };
        for (eq, of) in g.truth.equations.iter().zip(["v1", "v2", "V"]) {
            let (mut e, mut y) = (0.0, 0.0);
            for k in 2..g.t.len() - 2 {
                let lhs = d1(&c[of], k);
                let rhs: f64 = eq.terms.iter().map(|t| t.coef * value(&t.term, k)).sum();
                e += (lhs - rhs).powi(2);
                y += lhs * lhs;
            }
            assert!((e / y).sqrt() < 1e-3, "{}: {}", eq.target, (e / y).sqrt());
        }
        assert_eq!(diverged_at(&g), None);
    }

    #[test]
    fn validation_names_the_field() {
        let o = TwoDofOptions {
            zeta2: -1.0,
            ..TwoDofOptions::default()
        };
        assert_eq!(o.validate().map_err(|e| e.field), Err("zeta2"));
    }
}
