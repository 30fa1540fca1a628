//! Vibration energy harvesters with their electrical side (issue 26, item 7): a mechanical
//! equation for the beam's displacement x relative to the base and an electrical one for the
//! load's voltage V or current i, base-excited by an acceleration a(t) = A cos(Ω t).
//!
//! # Piezoelectric (Erturk & Inman)
//!
//! The lumped single-mode model of a piezoelectric cantilever across a load resistor R
//! (A. Erturk, D. J. Inman, "Broadband piezoelectric power generation on high-energy orbits of
//! the bistable Duffing oscillator with electromechanical coupling", J. Sound Vib. 330 (2011)
//! 2339–2353, eqs. 1–2; their book *Piezoelectric Energy Harvesting*, Wiley 2011, ch. 2):
//!
//! m x'' + c x' + k₁ x (+ k₃ x³) − θ V = −m a(t),    C_p V' + V/R + θ x' = 0,
//!
//! so, per unit mass and capacitance,
//!
//! x'' = −2ζω x' ∓ ω_k² x − h x³ + χ V − a,    V' = −λ V − κ x',
//!
//! with χ = θ/m, κ = θ/C_p, λ = 1/(R C_p). Monostable: −ω² x with ω = √(k₁/m) the
//! short-circuit natural frequency. Bistable (the piezomagnetoelastic beam, magnets making a
//! double well): +k₁ x − k₃ x³ per unit mass, wells at ±x_w = ±√(k₁/k₃) and small oscillations
//! in a well at ω = √(2 k₁/m); ζ is taken relative to that ω in both cases.
//!
//! Defaults: a beam like BistableX's (the measured harvester beside this project: a 145 mm
//! steel beam with MIDE QP16n patches into R = 1 MΩ) with round figures: m = 20 g, ω = 2π·10 Hz
//! (in a well, for the bistable), ζ = 0.015 (Erturk & Inman 2011 use ζ = 0.01–0.025),
//! C_p = 50 nF, R = 1 MΩ (λ = 20 s⁻¹, R C_p ω = 3.1: near the optimal load 1/(C_p ω)), and
//! θ from the coupling Erturk & Inman's dimensionless χκ = 0.05 · 0.5 = 0.025 gives,
//! k² = θ²/(m ω² C_p) = 0.025: θ = 3.1·10⁻⁴ N/V, χ = 0.0157 m s⁻² V⁻¹, κ = 6.3·10³ V/m. The
//! base is driven at 8 Hz, 2 m/s² (monostable: x ≈ 1.3 mm, V ≈ 7.7 V amplitude). Wells at
//! ±5 mm (BistableX's intrawell orbits are 2–3 mm RMS, its chaotic ones 20 mm): released at
//! 7 mm, the bistable beam snaps through between the wells at 2 m/s² and stays in the right
//! well at 1 m/s².
//!
//! # Electromagnetic (a magnet in a coil)
//!
//! m x'' + c x' + k₁ x (+ k₃ x³) + Φ i = −m a(t),    L i' + (R_c + R_L) i = Φ x',
//!
//! with Φ the transduction factor (N/A = V s/m), R_c the coil's and R_L the load's
//! resistance, L the coil's inductance and V = R_L i the load voltage. So
//! x'' = … − (Φ/m) i − a and i' = (Φ/L) x' − ((R_c+R_L)/L) i (or, recording V,
//! V' = (R_L Φ/L) x' − ((R_c+R_L)/L) V and the force −Φ/(m R_L) V). When the coil's time
//! constant L/(R_c+R_L) is far under the period (the usual case: a few mH over a few hundred Ω
//! is 10 µs), i = Φ x'/(R_c+R_L): the load voltage is proportional to the velocity,
//! V = R_L Φ/(R_c+R_L) x', and the coil only adds a damping Φ²/(m (R_c+R_L)) to x''
//! ([`Coil::Negligible`]). Defaults (Beeby et al., "A micro electromagnetic generator for
//! vibration energy harvesting", J. Micromech. Microeng. 17 (2007) 1257, and the large-coil
//! harvesters reviewed there, scaled to the piezo beam's mass and frequency): m = 20 g,
//! ω = 2π·10 Hz, ζ = 0.01, Φ = 5 N/A, R_c = R_L = 1 kΩ (the electrical damping
//! Φ²/(m (R_c+R_L)) = 0.63 s⁻¹ is half the mechanical 2ζω = 1.26 s⁻¹), and L = 10 H: a
//! many-turn coil whose time constant, 5 ms, the sample rate resolves, so that the i'
//! equation is there to identify ([`Coil::Inductive`]).
//!
//! # What the recording holds
//!
//! `t` in seconds; the mechanical channels chosen ([`Mechanical`]: x in metres, v in m/s, or
//! both); the electrical channel (V in volts, or i in amperes for the electromagnetic
//! harvester); with `input`, the base acceleration `u` = a(t) in m/s² (then the x'' equation
//! has the term `u` with coefficient −1 instead of −A cos(Ωt)). Every written channel gets
//! Gaussian noise of RMS `delta` times its own RMS, as `lssi gen eveh` does (eq. 16 with
//! Gaussian e). The truth lists both equations (for the negligible-inductance coil, the
//! algebraic `V` or `i` in terms of v), the physical parameters and the load.
//!
//! ```
//! use lssi_host::synth::harvester::{HarvesterOptions, generate_harvester};
//!
//! let options = HarvesterOptions { t_end: 1.0, ..HarvesterOptions::piezo() };
//! options.validate().unwrap();
//! let g = generate_harvester(&options);
//! assert_eq!(g.header(), ["t", "x", "V"]);
//! assert_eq!(g.truth.equations[1].target, "V'");
//! ```

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::eveh::Wells;
use super::{OptionError, require_finite, require_positive, sample_times, validate_grid};
use crate::identify::terms::{Harmonic, harmonic_name, monomial_name};
use crate::synth::noise::{NoiseKind, NoiseStats, add_noise, stats};
use crate::synth::truth::TruthTerm;

/// The name of the piezoelectric model in truth files.
pub const PIEZO_MODEL: &str = "piezo-erturk-inman";
/// The name of the electromagnetic model in truth files.
pub const EM_MODEL: &str = "electromagnetic";

/// The longest RK4 step, seconds: ω h ≤ 0.06 at 10 Hz and λ h ≤ 0.02 for the default coil.
pub const MAX_STEP: f64 = 1e-4;

/// Which transducer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum Transducer {
    /// Piezoelectric patches across a load resistor.
    Piezo {
        /// Coupling θ, N/V.
        theta: f64,
        /// Piezo capacitance C_p, farads.
        capacitance: f64,
        /// Load resistance R, ohms.
        load_ohms: f64,
    },
    /// A magnet moving in a coil closed by a load resistor.
    Electromagnetic {
        /// Transduction factor Φ, N/A.
        phi: f64,
        /// Coil resistance R_c, ohms.
        coil_ohms: f64,
        /// Load resistance R_L, ohms.
        load_ohms: f64,
        /// Coil inductance L, henries.
        inductance: f64,
        /// Whether the inductance is modelled.
        coil: Coil,
        /// Which electrical channel is recorded.
        electrical: Electrical,
    },
}

/// Whether the coil's inductance is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Coil {
    /// L i' + (R_c + R_L) i = Φ x': a first-order electrical equation.
    Inductive,
    /// L negligible: i = Φ x'/(R_c + R_L), the voltage proportional to the velocity.
    Negligible,
}

/// The electrical channel of an electromagnetic harvester.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum Electrical {
    /// The load voltage V = R_L i, volts (column `V`).
    #[value(name = "V")]
    V,
    /// The current i, amperes (column `i`).
    #[value(name = "i")]
    #[serde(rename = "i")]
    I,
}

/// Which mechanical channels are recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mechanical {
    /// The displacement x.
    X,
    /// The velocity v alone (as a laser vibrometer gives it).
    V,
    /// Both.
    Xv,
}

/// Everything [`generate_harvester`] needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HarvesterOptions {
    /// The transducer and its circuit.
    pub transducer: Transducer,
    /// Single or double well.
    pub wells: Wells,
    /// Modal mass m, kg.
    pub mass: f64,
    /// Natural frequency f = ω/2π, Hz (short-circuit; in a well for the bistable).
    pub frequency_hz: f64,
    /// Mechanical damping ratio ζ.
    pub damping_ratio: f64,
    /// Monostable: the cubic stiffness per mass h (m⁻² s⁻², 0 for a linear beam); bistable:
    /// unused (the wells set it).
    pub cubic: f64,
    /// Bistable: the wells' position x_w, metres.
    pub well: f64,
    /// Base acceleration amplitude A, m/s².
    pub amplitude: f64,
    /// Excitation angular frequency Ω, rad/s.
    pub omega: f64,
    /// Write the base acceleration as a column `u`.
    pub input: bool,
    /// The mechanical channels written.
    pub mechanical: Mechanical,
    /// Sensor noise RMS as a fraction of each channel's RMS.
    pub delta: f64,
    /// Sample rate, Hz.
    pub rate: f64,
    /// Last sample time, seconds.
    pub t_end: f64,
    /// Initial displacement, metres (released from it, at rest, with no charge).
    pub initial_displacement: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl HarvesterOptions {
    /// The default piezoelectric harvester (see the module docs), monostable, x and V written.
    pub fn piezo() -> Self {
        let m = 0.02;
        let w = 2.0 * std::f64::consts::PI * 10.0;
        let cp = 50e-9;
        Self {
            transducer: Transducer::Piezo {
                theta: (0.025 * m * w * w * cp).sqrt(),
                capacitance: cp,
                load_ohms: 1e6,
            },
            wells: Wells::Monostable,
            mass: m,
            frequency_hz: 10.0,
            damping_ratio: 0.015,
            cubic: 0.0,
            well: 5e-3,
            amplitude: 2.0,
            omega: 2.0 * std::f64::consts::PI * 8.0,
            input: false,
            mechanical: Mechanical::X,
            delta: 0.0,
            rate: 2000.0,
            t_end: 20.0,
            initial_displacement: 2e-3,
            seed: 1,
        }
    }

    /// The default electromagnetic harvester (see the module docs), with its coil's
    /// inductance, x and V written.
    pub fn electromagnetic() -> Self {
        Self {
            transducer: Transducer::Electromagnetic {
                phi: 5.0,
                coil_ohms: 1e3,
                load_ohms: 1e3,
                inductance: 10.0,
                coil: Coil::Inductive,
                electrical: Electrical::V,
            },
            damping_ratio: 0.01,
            ..Self::piezo()
        }
    }

    /// Checks every field once, naming the first that cannot be used.
    pub fn validate(&self) -> Result<(), OptionError> {
        match self.transducer {
            Transducer::Piezo {
                theta,
                capacitance,
                load_ohms,
            } => {
                require_finite("theta", theta)?;
                require_positive("capacitance", capacitance)?;
                require_positive("load_ohms", load_ohms)?;
            }
            Transducer::Electromagnetic {
                phi,
                coil_ohms,
                load_ohms,
                inductance,
                ..
            } => {
                require_finite("phi", phi)?;
                if !(coil_ohms.is_finite() && coil_ohms >= 0.0) {
                    return Err(OptionError {
                        field: "coil_ohms",
                        value: coil_ohms,
                        requirement: "zero or positive, and finite",
                    });
                }
                require_positive("load_ohms", load_ohms)?;
                require_positive("inductance", inductance)?;
            }
        }
        require_positive("mass", self.mass)?;
        require_positive("frequency_hz", self.frequency_hz)?;
        if !(self.damping_ratio.is_finite() && self.damping_ratio >= 0.0) {
            return Err(OptionError {
                field: "damping_ratio",
                value: self.damping_ratio,
                requirement: "zero or positive, and finite",
            });
        }
        if !(self.cubic.is_finite() && self.cubic >= 0.0) {
            return Err(OptionError {
                field: "cubic",
                value: self.cubic,
                requirement: "zero or positive (hardening), and finite",
            });
        }
        require_positive("well", self.well)?;
        require_finite("amplitude", self.amplitude)?;
        require_positive("omega", self.omega)?;
        if !(self.delta.is_finite() && self.delta >= 0.0) {
            return Err(OptionError {
                field: "delta",
                value: self.delta,
                requirement: "zero or positive, and finite",
            });
        }
        require_positive("rate", self.rate)?;
        validate_grid(1.0 / self.rate, self.t_end)?;
        require_finite("initial_displacement", self.initial_displacement)
    }

    /// The model's name in truth files.
    pub fn model(&self) -> &'static str {
        match self.transducer {
            Transducer::Piezo { .. } => PIEZO_MODEL,
            Transducer::Electromagnetic { .. } => EM_MODEL,
        }
    }

    /// The coefficients of both equations, per unit mass (and capacitance or inductance).
    pub fn coefficients(&self) -> Coefficients {
        let w = 2.0 * std::f64::consts::PI * self.frequency_hz;
        let (linear, cubic) = match self.wells {
            Wells::Monostable => (-w * w, -self.cubic),
            // Well stiffness 2 k₁/m = ω², k₃ = k₁/x_w².
            Wells::Bistable => {
                let k1 = w * w / 2.0;
                (k1, -k1 / (self.well * self.well))
            }
        };
        let mut c = Coefficients {
            linear,
            cubic,
            damping: -2.0 * self.damping_ratio * w,
            force: 0.0,
            electrical_self: 0.0,
            electrical_velocity: 0.0,
            algebraic: None,
        };
        match self.transducer {
            Transducer::Piezo {
                theta,
                capacitance,
                load_ohms,
            } => {
                c.force = theta / self.mass;
                c.electrical_self = -1.0 / (load_ohms * capacitance);
                c.electrical_velocity = -theta / capacitance;
            }
            Transducer::Electromagnetic {
                phi,
                coil_ohms,
                load_ohms,
                inductance,
                coil,
                electrical,
            } => {
                let total = coil_ohms + load_ohms;
                // The state is i; a recorded V = R_L i scales the channel.
                let scale = match electrical {
                    Electrical::I => 1.0,
                    Electrical::V => load_ohms,
                };
                match coil {
                    Coil::Inductive => {
                        c.force = -phi / self.mass / scale;
                        c.electrical_self = -total / inductance;
                        c.electrical_velocity = scale * phi / inductance;
                    }
                    Coil::Negligible => {
                        c.damping -= phi * phi / (self.mass * total);
                        c.algebraic = Some(scale * phi / total);
                    }
                }
            }
        }
        c
    }

    /// The electrical channel's name: `V` or `i`.
    pub fn electrical_name(&self) -> &'static str {
        match self.transducer {
            Transducer::Electromagnetic {
                electrical: Electrical::I,
                ..
            } => "i",
            _ => "V",
        }
    }

    /// The base acceleration a(t) = A cos(Ω t), m/s².
    pub fn base_acceleration(&self, t: f64) -> f64 {
        self.amplitude * (self.omega * t).cos()
    }

    /// The RK4 step: 1/(10 × rate) or [`MAX_STEP`], whichever is shorter.
    pub fn max_step(&self) -> f64 {
        (0.1 / self.rate).min(MAX_STEP)
    }

    /// Both equations' true terms, in the identifier's names: x'' (x, v, x^3, the electrical
    /// channel, u or the cosine) and the electrical one (`V'`/`i'`, or the algebraic `V`/`i`).
    pub fn equations(&self) -> Vec<Equation> {
        let c = self.coefficients();
        let e = self.electrical_name();
        let mut mechanical = vec![
            (monomial_name(1, 0), c.linear),
            (monomial_name(0, 1), c.damping),
            (monomial_name(3, 0), c.cubic),
            (e.to_owned(), c.force),
        ];
        if self.input {
            mechanical.push(("u".to_owned(), -1.0));
        } else {
            mechanical.push((harmonic_name(Harmonic::Cos, self.omega), -self.amplitude));
        }
        let electrical = match c.algebraic {
            None => Equation::new(
                format!("{e}'"),
                vec![
                    (monomial_name(0, 1), c.electrical_velocity),
                    (e.to_owned(), c.electrical_self),
                ],
            ),
            Some(g) => Equation::new(e.to_owned(), vec![(monomial_name(0, 1), g)]),
        };
        vec![Equation::new("x''".to_owned(), mechanical), electrical]
    }
}

/// The coefficients of the two equations, solved for x'' and for the electrical channel's
/// derivative (or, with a negligible inductance, for the channel itself).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Coefficients {
    /// Of x in x'' (−ω² monostable, +k₁/m bistable), s⁻².
    pub linear: f64,
    /// Of x³ in x'' (−k₃/m), m⁻² s⁻².
    pub cubic: f64,
    /// Of v in x'' (−2ζω, less the coil's damping when its inductance is negligible), s⁻¹.
    pub damping: f64,
    /// Of the electrical channel in x'' (χ = θ/m; −Φ/m per ampere, −Φ/(m R_L) per volt).
    pub force: f64,
    /// Of the electrical channel in its own derivative (−λ = −1/(R C_p), −(R_c+R_L)/L), s⁻¹.
    pub electrical_self: f64,
    /// Of v in the electrical channel's derivative (−κ = −θ/C_p; Φ/L per ampere).
    pub electrical_velocity: f64,
    /// With a negligible inductance: the channel = this × v.
    pub algebraic: Option<f64>,
}

/// One true equation: its left-hand side and terms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Equation {
    /// `x''`, `V'`, `i'`, or `V`/`i` for an algebraic relation.
    pub target: String,
    /// The active terms.
    pub terms: Vec<TruthTerm>,
}

impl Equation {
    fn new(target: String, terms: Vec<(String, f64)>) -> Self {
        Self {
            target,
            terms: terms
                .into_iter()
                .filter(|(_, c)| *c != 0.0)
                .map(|(term, coef)| TruthTerm { term, coef })
                .collect(),
        }
    }

    /// The true coefficient of `term`, or `None`.
    pub fn coefficient(&self, term: &str) -> Option<f64> {
        self.terms.iter().find(|t| t.term == term).map(|t| t.coef)
    }
}

/// The truth file of a harvester recording: both equations, every parameter, the noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SystemTruth {
    /// Which generator made the data.
    pub model: String,
    /// The excitation's angular frequency Ω, rad/s.
    pub omega: f64,
    /// The mechanical equation, then the electrical one.
    pub equations: Vec<Equation>,
    /// The options, the coefficients and the derived physical figures.
    pub params: serde_json::Value,
    /// The noise added to each written channel.
    pub noise: ChannelNoise,
}

impl SystemTruth {
    /// The equation whose left-hand side is `target`.
    pub fn equation(&self, target: &str) -> Option<&Equation> {
        self.equations.iter().find(|e| e.target == target)
    }
}

/// The noise of each written channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelNoise {
    /// Distribution of the raw noise (Gaussian).
    pub kind: NoiseKind,
    /// Noise RMS over each channel's RMS.
    pub delta: f64,
    /// Mean and RMS of the noise added, per column name.
    pub channels: BTreeMap<String, NoiseStats>,
}

/// A generated harvester recording.
#[derive(Debug, Clone, PartialEq)]
pub struct HarvesterGenerated {
    /// Sample times, seconds.
    pub t: Vec<f64>,
    /// The written channels after t, in order: (name, noisy values).
    pub columns: Vec<(&'static str, Vec<f64>)>,
    /// Noise-free x, v, the electrical channel and u at each sample.
    pub clean: BTreeMap<&'static str, Vec<f64>>,
    /// The truth.
    pub truth: SystemTruth,
}

impl HarvesterGenerated {
    /// The CSV header.
    pub fn header(&self) -> Vec<&'static str> {
        std::iter::once("t")
            .chain(self.columns.iter().map(|c| c.0))
            .collect()
    }

    /// The CSV header and columns.
    pub fn csv_columns(&self) -> (Vec<&'static str>, Vec<&[f64]>) {
        let columns = std::iter::once(self.t.as_slice())
            .chain(self.columns.iter().map(|c| c.1.as_slice()))
            .collect();
        (self.header(), columns)
    }

    /// The first sample time at which the clean trajectory is not finite, if any.
    pub fn diverged_at(&self) -> Option<f64> {
        let x = &self.clean["x"];
        self.t
            .iter()
            .zip(x)
            .find(|(_, x)| !x.is_finite() || x.abs() > 1e3)
            .map(|(t, _)| *t)
    }
}

/// What the truth's `params` holds besides the options.
#[derive(Serialize)]
struct ParamsRecord<'a> {
    #[serde(flatten)]
    options: &'a HarvesterOptions,
    coefficients: Coefficients,
    /// Load resistance, ohms.
    load_ohms: f64,
    /// k² = θ²/(k C_p) for the piezo, Φ²/(k L) for the coil: the coupling factor squared.
    coupling_squared: Option<f64>,
    /// R C_p or L/(R_c+R_L), seconds.
    electrical_time_constant: Option<f64>,
    /// Bistable: the barrier height per unit mass k₁ x_w²/4, J/kg.
    barrier_per_mass: Option<f64>,
    /// Mean power into the load over the record (clean), watts.
    mean_power_w: f64,
    integrator: &'static str,
    integrator_step: f64,
}

/// One RK4 step of the state (x, v, e) of dx/dt = f(t, x).
fn rk4(f: &dyn Fn(f64, [f64; 3]) -> [f64; 3], t: f64, y: [f64; 3], h: f64) -> [f64; 3] {
    let add =
        |a: [f64; 3], b: [f64; 3], s: f64| [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]];
    let k1 = f(t, y);
    let k2 = f(t + h / 2.0, add(y, k1, h / 2.0));
    let k3 = f(t + h / 2.0, add(y, k2, h / 2.0));
    let k4 = f(t + h, add(y, k3, h));
    [
        y[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
        y[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        y[2] + h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
    ]
}

/// Integrates both equations on the sampling grid (RK4 with at most [`MAX_STEP`] per step),
/// then adds the noise. Validate the options first ([`HarvesterOptions::validate`]); no I/O.
/// The noise comes from [`ChaCha8Rng`] seeded with `seed`, drawn channel by channel in the
/// column order.
pub fn generate_harvester(opts: &HarvesterOptions) -> HarvesterGenerated {
    let t = sample_times(1.0 / opts.rate, opts.t_end);
    let c = opts.coefficients();
    // The electrical state e is the recorded channel (V or i); with a negligible inductance it
    // is algebraic and the state's third entry stays 0.
    let f = |time: f64, y: [f64; 3]| {
        let [x, v, e] = y;
        let a = opts.base_acceleration(time);
        [
            v,
            c.linear * x + c.cubic * x * x * x + c.damping * v + c.force * e - a,
            c.electrical_velocity * v + c.electrical_self * e,
        ]
    };
    let mut y = [opts.initial_displacement, 0.0, 0.0];
    let mut states = Vec::with_capacity(t.len());
    let mut now = 0.0;
    for &target in &t {
        let span = target - now;
        if span > 0.0 {
            let steps = (span / opts.max_step()).ceil().max(1.0) as usize;
            let h = span / steps as f64;
            for k in 0..steps {
                y = rk4(&f, now + k as f64 * h, y, h);
            }
        }
        now = target;
        states.push(y);
    }
    let clean_x: Vec<f64> = states.iter().map(|s| s[0]).collect();
    let clean_v: Vec<f64> = states.iter().map(|s| s[1]).collect();
    let clean_e: Vec<f64> = match c.algebraic {
        Some(g) => clean_v.iter().map(|v| g * v).collect(),
        None => states.iter().map(|s| s[2]).collect(),
    };
    let clean_u: Vec<f64> = t.iter().map(|&s| opts.base_acceleration(s)).collect();
    let e_name = opts.electrical_name();
    let mut wanted: Vec<(&'static str, &Vec<f64>)> = Vec::new();
    if matches!(opts.mechanical, Mechanical::X | Mechanical::Xv) {
        wanted.push(("x", &clean_x));
    }
    if matches!(opts.mechanical, Mechanical::V | Mechanical::Xv) {
        wanted.push(("v", &clean_v));
    }
    wanted.push((e_name, &clean_e));
    if opts.input {
        wanted.push(("u", &clean_u));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let mut noise = BTreeMap::new();
    let columns: Vec<(&'static str, Vec<f64>)> = wanted
        .into_iter()
        .map(|(name, clean)| {
            let noisy = add_noise(clean, opts.delta, NoiseKind::Gauss, &mut rng).values;
            let e: Vec<f64> = noisy.iter().zip(clean).map(|(o, c)| o - c).collect();
            noise.insert(name.to_owned(), stats(&e));
            (name, noisy)
        })
        .collect();

    // Power into the load: V²/R for the piezo; R_L i² for the coil.
    let (load_ohms, coupling_squared, time_constant) = match opts.transducer {
        Transducer::Piezo {
            theta,
            capacitance,
            load_ohms,
        } => {
            let k = c_stiffness(opts);
            (
                load_ohms,
                Some(theta * theta / (k * capacitance)),
                Some(load_ohms * capacitance),
            )
        }
        Transducer::Electromagnetic {
            phi,
            coil_ohms,
            load_ohms,
            inductance,
            coil,
            ..
        } => {
            let k = c_stiffness(opts);
            (
                load_ohms,
                Some(phi * phi / (k * inductance)),
                (coil == Coil::Inductive).then(|| inductance / (coil_ohms + load_ohms)),
            )
        }
    };
    let voltage = |e: f64| match opts.transducer {
        Transducer::Electromagnetic {
            electrical: Electrical::I,
            load_ohms,
            ..
        } => e * load_ohms,
        _ => e,
    };
    let mean_power_w = clean_e
        .iter()
        .map(|&e| voltage(e).powi(2) / load_ohms)
        .sum::<f64>()
        / clean_e.len().max(1) as f64;
    let barrier = (opts.wells == Wells::Bistable).then(|| c.linear * opts.well * opts.well / 4.0);
    let params = ParamsRecord {
        options: opts,
        coefficients: c,
        load_ohms,
        coupling_squared,
        electrical_time_constant: time_constant,
        barrier_per_mass: barrier,
        mean_power_w,
        integrator: "rk4",
        integrator_step: opts.max_step(),
    };
    let truth = SystemTruth {
        model: opts.model().to_owned(),
        omega: opts.omega,
        equations: opts.equations(),
        // Serialising plain numbers and enums into a Value cannot fail.
        params: serde_json::to_value(&params).unwrap_or_default(),
        noise: ChannelNoise {
            kind: NoiseKind::Gauss,
            delta: opts.delta,
            channels: noise,
        },
    };
    let mut clean = BTreeMap::new();
    clean.insert("x", clean_x);
    clean.insert("v", clean_v);
    clean.insert(e_name, clean_e);
    clean.insert("u", clean_u);
    HarvesterGenerated {
        t,
        columns,
        clean,
        truth,
    }
}

/// The beam's linear stiffness k, N/m: m ω² (in a well, for the bistable).
fn c_stiffness(opts: &HarvesterOptions) -> f64 {
    let w = 2.0 * std::f64::consts::PI * opts.frequency_hz;
    opts.mass * w * w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erturk_inman_coupling_and_load() {
        let o = HarvesterOptions::piezo();
        let c = o.coefficients();
        let w = 2.0 * std::f64::consts::PI * 10.0;
        assert!((c.linear + w * w).abs() < 1e-9);
        assert!((c.electrical_self + 20.0).abs() < 1e-9);
        // χ κ / ω² = k² = 0.025.
        assert!((c.force * -c.electrical_velocity / (w * w) - 0.025).abs() < 1e-12);
        let names: Vec<String> = o.equations()[0]
            .terms
            .iter()
            .map(|t| t.term.clone())
            .collect();
        assert_eq!(names, ["x", "v", "V", "cos(50.2655t)"]);
    }

    #[test]
    fn a_negligible_inductance_makes_v_proportional_to_the_velocity() {
        let o = HarvesterOptions {
            transducer: Transducer::Electromagnetic {
                phi: 5.0,
                coil_ohms: 1e3,
                load_ohms: 1e3,
                inductance: 10.0,
                coil: Coil::Negligible,
                electrical: Electrical::V,
            },
            ..HarvesterOptions::electromagnetic()
        };
        let eq = o.equations();
        assert_eq!(eq[1].target, "V");
        assert_eq!(eq[1].coefficient("v"), Some(2.5));
        assert_eq!(eq[0].coefficient("V"), None);
        let w = 2.0 * std::f64::consts::PI * 10.0;
        let damping = eq[0].coefficient("v").unwrap();
        assert!((damping + 0.02 * w + 25.0 / (0.02 * 2e3)).abs() < 1e-12);
    }

    #[test]
    fn validation_names_the_field() {
        let mut o = HarvesterOptions::piezo();
        o.rate = -1.0;
        assert_eq!(o.validate().map_err(|e| e.field), Err("rate"));
        let mut o = HarvesterOptions::electromagnetic();
        if let Transducer::Electromagnetic { inductance, .. } = &mut o.transducer {
            *inductance = 0.0;
        }
        assert_eq!(o.validate().map_err(|e| e.field), Err("inductance"));
    }
}
