//! The paper's classic test equation, eq. (17), with its noise, eq. (16), and Table 1's values:
//!
//! x'' + ω₀² x + ε((α₁ x² + α₂ x³) + x'(β₁ + β₂ x²)) = ε F₀ cos(Ω₀ t),
//!
//! ω₀ = 1, β₁ = −1, β₂ = 2, α₁ = −2, α₂ = 4, F₀ = 5, Ω₀ = 2, from x₀ = 2, x'₀ = 0. Solved for x'',
//! the true library coefficients are
//! x: −ω₀², v: −εβ₁, x²: −εα₁, x³: −εα₂, x²v: −εβ₂, cos(Ω₀t): εF₀.
//!
//! ```
//! use lssi_host::synth::paper::{PaperOptions, generate_paper};
//! use lssi_host::synth::noise::NoiseKind;
//!
//! let options = PaperOptions {
//!     epsilon: 0.5,
//!     noise: NoiseKind::Gauss,
//!     t_end: 2.0,
//!     ..PaperOptions::default()
//! };
//! options.validate().unwrap();
//! let generated = generate_paper(&options);
//! assert_eq!(generated.truth.coefficient("x^2*v"), Some(-1.0));
//! assert_eq!(generated.truth.coefficient("cos(2t)"), Some(2.5));
//! ```

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{
    Generated, Observe, OptionError, require_finite, require_positive, sample_times, validate_grid,
};
use crate::identify::terms::{Harmonic, harmonic_name, monomial_name};
use crate::synth::noise::{NoiseKind, add_noise};
use crate::synth::ode::{State, integrate_at};
use crate::synth::truth::{NoiseTruth, Truth, TruthTerm};

/// The name of this model in truth files.
pub const MODEL: &str = "paper-eq17";

/// The longest RK4 step used, in seconds.
///
/// At Table 1's values (ε from 0.1 to 3, t up to 100 s) halving h from 2e-4 to 1e-4 or from
/// 1e-4 to 5e-5 changes no sample by more than 3e-12: RK4's O(h⁴) truncation error is already
/// below the round-off of the sums, four orders under the 1e-9 the benchmarks need. The
/// step-halving test in `tests/generate.rs` keeps that true.
pub const MAX_STEP: f64 = 1e-4;

/// At least this many RK4 steps per sample interval, so a fine sampling grid is never
/// integrated more coarsely than Δt/10.
pub const MIN_STEPS_PER_SAMPLE: f64 = 10.0;

/// The coefficients and initial state of eq. (17); defaults are Table 1's values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PaperParams {
    /// Natural frequency ω₀ (rad/s).
    pub natural_frequency: f64,
    /// Linear damping β₁ (negative: self-excited at small amplitude).
    pub linear_damping: f64,
    /// Amplitude-dependent damping β₂, multiplying x² x'.
    pub nonlinear_damping: f64,
    /// Quadratic stiffness α₁.
    pub quadratic_stiffness: f64,
    /// Cubic stiffness α₂.
    pub cubic_stiffness: f64,
    /// Excitation amplitude F₀.
    pub force_amplitude: f64,
    /// Excitation angular frequency Ω₀ (rad/s).
    pub excitation_frequency: f64,
    /// Initial displacement x₀.
    pub initial_displacement: f64,
    /// Initial velocity x'₀.
    pub initial_velocity: f64,
}

impl Default for PaperParams {
    fn default() -> Self {
        Self {
            natural_frequency: 1.0,
            linear_damping: -1.0,
            nonlinear_damping: 2.0,
            quadratic_stiffness: -2.0,
            cubic_stiffness: 4.0,
            force_amplitude: 5.0,
            excitation_frequency: 2.0,
            initial_displacement: 2.0,
            initial_velocity: 0.0,
        }
    }
}

/// Everything [`generate_paper`] needs; defaults are the paper's run (ε = 1, δ = 0.001).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PaperOptions {
    /// The equation's coefficients and initial state.
    #[serde(flatten)]
    pub params: PaperParams,
    /// Nonlinear perturbation strength ε.
    pub epsilon: f64,
    /// Noise level δ of eq. (16).
    pub delta: f64,
    /// Distribution of the raw noise.
    pub noise: NoiseKind,
    /// Which channels are written.
    pub observe: Observe,
    /// Last sample time, in seconds.
    pub t_end: f64,
    /// Sampling interval Δt, in seconds.
    pub dt: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for PaperOptions {
    fn default() -> Self {
        Self {
            params: PaperParams::default(),
            epsilon: 1.0,
            delta: 0.001,
            noise: NoiseKind::Paper,
            observe: Observe::Xv,
            t_end: 100.0,
            dt: 0.001,
            seed: 1,
        }
    }
}

impl PaperOptions {
    /// Checks every field once, naming the first one that cannot be used.
    ///
    /// [`generate_paper`] never panics, but on options that fail this check its output is
    /// meaningless (e.g. a single sample, or non-finite values).
    pub fn validate(&self) -> Result<(), OptionError> {
        let p = &self.params;
        require_finite("natural_frequency", p.natural_frequency)?;
        require_finite("linear_damping", p.linear_damping)?;
        require_finite("nonlinear_damping", p.nonlinear_damping)?;
        require_finite("quadratic_stiffness", p.quadratic_stiffness)?;
        require_finite("cubic_stiffness", p.cubic_stiffness)?;
        require_finite("force_amplitude", p.force_amplitude)?;
        require_positive("excitation_frequency", p.excitation_frequency)?;
        require_finite("initial_displacement", p.initial_displacement)?;
        require_finite("initial_velocity", p.initial_velocity)?;
        require_finite("epsilon", self.epsilon)?;
        if !(self.delta.is_finite() && self.delta >= 0.0) {
            return Err(OptionError {
                field: "delta",
                value: self.delta,
                requirement: "zero or positive, and finite",
            });
        }
        validate_grid(self.dt, self.t_end)
    }

    /// The RK4 step length used between samples: Δt/10 or [`MAX_STEP`], whichever is shorter.
    pub fn max_step(&self) -> f64 {
        (self.dt / MIN_STEPS_PER_SAMPLE).min(MAX_STEP)
    }

    /// x'' as eq. (17) gives it, f(t, x, x').
    pub fn acceleration(&self, t: f64, x: f64, v: f64) -> f64 {
        let p = &self.params;
        let stiffness = p.quadratic_stiffness * x * x + p.cubic_stiffness * x * x * x;
        let damping = v * (p.linear_damping + p.nonlinear_damping * x * x);
        -p.natural_frequency * p.natural_frequency * x - self.epsilon * (stiffness + damping)
            + self.epsilon * p.force_amplitude * (p.excitation_frequency * t).cos()
    }

    /// The true terms of x'' = Σ ξᵢ θᵢ, in the order x, v, x², x³, x²v, cos(Ω₀t), leaving out
    /// terms whose coefficient is zero.
    pub fn terms(&self) -> Vec<TruthTerm> {
        let p = &self.params;
        let e = self.epsilon;
        [
            (
                monomial_name(1, 0),
                -p.natural_frequency * p.natural_frequency,
            ),
            (monomial_name(0, 1), -e * p.linear_damping),
            (monomial_name(2, 0), -e * p.quadratic_stiffness),
            (monomial_name(3, 0), -e * p.cubic_stiffness),
            (monomial_name(2, 1), -e * p.nonlinear_damping),
            (
                harmonic_name(Harmonic::Cos, p.excitation_frequency),
                e * p.force_amplitude,
            ),
        ]
        .into_iter()
        .filter(|(_, coef)| *coef != 0.0)
        .map(|(term, coef)| TruthTerm { term, coef })
        .collect()
    }
}

/// What the truth file's `params` holds: the options plus how the trajectory was integrated.
#[derive(Serialize)]
struct ParamsRecord<'a> {
    #[serde(flatten)]
    options: &'a PaperOptions,
    integrator: &'static str,
    integrator_step: f64,
}

/// Integrates eq. (17) on the sampling grid and adds eq. (16) noise.
///
/// The noise generator is [`ChaCha8Rng`] seeded with `seed`: its output is fixed by the
/// algorithm and rand documents it as portable and value-stable, so a seed gives the same file
/// on every machine and release (unlike `StdRng`, whose algorithm may change, or `SmallRng`,
/// which differs by platform); eight rounds are far more than noise statistics need. The x
/// noise is drawn first and then the v noise, so for one seed the x column is the same whether
/// or not v is observed. Gaussian draws come from `rand_distr`, pinned by Cargo.lock.
///
/// Validate the options first ([`PaperOptions::validate`]); this function does no I/O.
pub fn generate_paper(opts: &PaperOptions) -> Generated {
    let t = sample_times(opts.dt, opts.t_end);
    let initial = State {
        x: opts.params.initial_displacement,
        v: opts.params.initial_velocity,
    };
    let states = integrate_at(
        |time, x, v| opts.acceleration(time, x, v),
        initial,
        &t,
        opts.max_step(),
    );
    let clean_x: Vec<f64> = states.iter().map(|s| s.x).collect();
    let clean_v: Vec<f64> = states.iter().map(|s| s.v).collect();

    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let noisy_x = add_noise(&clean_x, opts.delta, opts.noise, &mut rng);
    let noisy_v = match opts.observe {
        Observe::X => None,
        Observe::Xv => Some(add_noise(&clean_v, opts.delta, opts.noise, &mut rng)),
    };

    let params = ParamsRecord {
        options: opts,
        integrator: "rk4",
        integrator_step: opts.max_step(),
    };
    let truth = Truth {
        model: MODEL.to_owned(),
        target: "x''".to_owned(),
        omega: opts.params.excitation_frequency,
        terms: opts.terms(),
        // Serialising plain numbers and enums into a Value cannot fail.
        params: serde_json::to_value(&params).unwrap_or_default(),
        noise: NoiseTruth {
            kind: opts.noise,
            delta: opts.delta,
            offset_x: noisy_x.stats.offset,
            offset_v: noisy_v.as_ref().map(|n| n.stats.offset),
            rms_x: noisy_x.stats.rms,
            rms_v: noisy_v.as_ref().map(|n| n.stats.rms),
        },
    };

    Generated {
        t,
        x: noisy_x.values,
        v: noisy_v.map(|n| n.values),
        clean_x,
        clean_v,
        truth,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_1_coefficients() {
        let terms = PaperOptions::default().terms();
        let pairs: Vec<(&str, f64)> = terms.iter().map(|t| (t.term.as_str(), t.coef)).collect();
        assert_eq!(
            pairs,
            [
                ("x", -1.0),
                ("v", 1.0),
                ("x^2", 2.0),
                ("x^3", -4.0),
                ("x^2*v", -2.0),
                ("cos(2t)", 5.0)
            ]
        );
    }

    #[test]
    fn zero_epsilon_leaves_the_linear_oscillator() {
        let options = PaperOptions {
            epsilon: 0.0,
            ..PaperOptions::default()
        };
        let terms = options.terms();
        assert_eq!(terms.len(), 1);
        assert_eq!(terms[0].term, "x");
    }

    #[test]
    fn validation_names_the_field() {
        let bad = |options: PaperOptions| options.validate().map_err(|e| e.field);
        let base = PaperOptions::default();
        assert_eq!(bad(base.clone()), Ok(()));
        assert_eq!(
            bad(PaperOptions {
                epsilon: f64::NAN,
                ..base.clone()
            }),
            Err("epsilon")
        );
        assert_eq!(
            bad(PaperOptions {
                delta: -0.1,
                ..base.clone()
            }),
            Err("delta")
        );
        assert_eq!(
            bad(PaperOptions {
                dt: 0.0,
                ..base.clone()
            }),
            Err("dt")
        );
        let mut params = base.params;
        params.excitation_frequency = 0.0;
        assert_eq!(
            bad(PaperOptions { params, ..base }),
            Err("excitation_frequency")
        );
    }

    #[test]
    fn observe_x_has_no_velocity_and_the_same_x() {
        let xv = PaperOptions {
            t_end: 1.0,
            ..PaperOptions::default()
        };
        let x_only = PaperOptions {
            observe: Observe::X,
            ..xv.clone()
        };
        let a = generate_paper(&xv);
        let b = generate_paper(&x_only);
        assert!(a.v.is_some() && b.v.is_none());
        assert_eq!(a.x, b.x);
        assert_eq!(b.truth.noise.offset_v, None);
    }
}
