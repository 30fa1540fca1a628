//! The paper's membrane electromagnetic vibration energy harvester (EVEH), eq. (19):
//!
//! x'' + B x' + D x + H x³ = F cos(Ω t),
//!
//! with x the magnet's displacement in metres and the coefficients derived from the physical
//! parameters of the paper's Table 5.
//!
//! # From Table 5 to eq. (19)
//!
//! Newton's law for the centre magnet of mass m on a membrane with restoring force
//! k₁x + k₃x³ and viscous damping c is m x'' + c x' + k₁ x + k₃ x³ = m a(t), where a(t) is the
//! excitation acceleration (for a base-excited harvester, minus the base acceleration).
//! Dividing by m:
//!
//! | eq. (19) | from Table 5 | default value |
//! |---|---|---|
//! | D = ±k₁/m | linear stiffness, + monostable, − bistable | ±336.61 s⁻² |
//! | H = k₃/m | k₃ = 8.432·10⁻³ N/mm³ = 8.432·10⁶ N/m³, m = 10.6 g | 7.9547·10⁸ m⁻² s⁻² |
//! | B = 2ζω₁ = 2ζ√(k₁/m) | damping ratio ζ = 0.011 | 0.40363 s⁻¹ |
//! | F | the excitation acceleration, 0.98 m/s² as in the paper's experiment | 0.98 m s⁻² |
//! | Ω | 21.4 rad/s, the paper's `cos(21.4t)` (3.41 Hz, its measured resonance) | 21.4 rad/s |
//!
//! Table 5 lists k₁ = 2.700 N/mm, but with m = 10.6 g that is a natural frequency of
//! √(2700/0.0106)/2π = 80.3 Hz, not the 2.92 Hz it lists as the resonance ω₁, and not the
//! 3.0–3.4 Hz (|ξ_x| = 355–468 s⁻²) of the identified Table 7 either; at 80 Hz and F ≈ 1 m/s²
//! the cubic term would be invisible (H x²/D ≈ 10⁻⁷). So the default net linear stiffness is
//! the one Table 5's own resonance gives, k₁ = m (2π · 2.92 Hz)² = 3.5681 N/m; `--k1 2700`
//! gives the printed value. k₃ as printed gives H ≈ 8·10⁸, the scale of Table 7's x³
//! coefficients (−9·10⁷ to −1.2·10⁹). Solved for x'', the true library coefficients are
//! x: −D, v: −B, x³: −H and cos(Ωt): F, spanning 10⁻¹ to 10⁹ as in Table 7.
//!
//! In the bistable (double-well) configuration D < 0: the wells are at ±√(−D/H) = ±0.650 mm
//! and small oscillations in a well have frequency √(−2D)/2π = 4.13 Hz. ζ is taken relative to
//! √|D| in both configurations, so B is the same.
//!
//! # What the recording holds
//!
//! - `t` in seconds at the sample rate, `x` in metres, `v` in m/s with `observe = xv`, and
//!   with `input` the excitation `u` = F cos(φ(t)) in m/s² (then the true equation has the
//!   term `u` with coefficient 1 instead of the cosine).
//! - Excitation: a fixed frequency Ω, or a linear sweep from Ω to `sweep_to` over the record
//!   (φ(t) = Ω t + (Ω_end − Ω) t²/(2 t_end)); a sweep is not in the sin/cos library, so it is
//!   only identifiable with the `u` column.
//! - Sensor noise: Gaussian, added to every written channel, with RMS `delta` times the
//!   channel's RMS (eq. 16 with Gaussian e).
//! - ADC quantisation after the noise: `adc_bits` bits over ±`full_scale` metres for x
//!   (samples beyond it clip, and are counted in the truth); v and u get their own range,
//!   the smallest 1-2-5 value at least 1.25 times their largest clean magnitude.
//! - Every written value is rounded to 7 significant digits, the in-memory data included, so
//!   the file and [`generate_eveh`]'s output are the same numbers.
//! - A drift: from time `at` the linear stiffness k₁ (so D) or the damping c (so B) is
//!   multiplied by 1 + `by`, as a step or over a linear ramp of `ramp` seconds. The truth
//!   lists the coefficients before; the coefficients after are in its `params.drift_after`.
//!
//! ```
//! use lssi_host::synth::eveh::{EvehOptions, Wells, generate_eveh};
//!
//! let options = EvehOptions { t_end: 1.0, wells: Wells::Monostable, ..EvehOptions::default() };
//! options.validate().unwrap();
//! let generated = generate_eveh(&options);
//! assert_eq!(generated.generated.t.len(), 2001);
//! let d = generated.generated.truth.coefficient("x").unwrap();
//! assert!((d + 336.6088).abs() < 1e-3);
//! ```

use lssi_core::{RestoringForce, Term};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{
    Generated, Observe, OptionError, require_finite, require_positive, sample_times, validate_grid,
};
use crate::identify::terms::{Harmonic, harmonic_name, monomial_name};
use crate::recording::{ColumnNames, Recording};
use crate::synth::noise::{NoiseKind, add_noise, stats};
use crate::synth::ode::{State, integrate_at};
use crate::synth::truth::{NoiseTruth, Truth, TruthTerm};

/// The name of this model in truth files.
pub const MODEL: &str = "eveh-eq19";

/// Table 5's resonance ω₁, Hz: the default net linear stiffness reproduces it.
pub const TABLE5_RESONANCE_HZ: f64 = 2.92;

/// The longest RK4 step, seconds. At the largest default amplitude (≈ 2.6 mm, bistable) the
/// local stiffness D + 3H x² is ≈ 1.6·10⁴ s⁻², ω h ≈ 0.013: RK4's error is far below the
/// 7 written digits.
pub const MAX_STEP: f64 = 1e-4;

/// Significant digits of every written value.
pub const DIGITS: usize = 7;

/// Single or double well.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Wells {
    /// D > 0: one well at x = 0 (hardening Duffing).
    Monostable,
    /// D < 0: a double well at ±√(−D/H).
    Bistable,
}

/// The shape of the excitation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Excitation {
    /// F cos(Ω t).
    Fixed,
    /// F cos(φ(t)) with the frequency rising linearly from Ω to `sweep_to`.
    Sweep,
    /// Broadband: [`RANDOM_TONES`] tones evenly spaced from Ω to `sweep_to`, each of amplitude
    /// F/√K at a phase drawn from `seed` (a random-phase multisine: Gaussian-like, the same
    /// RMS as F cos(Ωt)).
    Random,
}

/// Tones of [`Excitation::Random`].
pub const RANDOM_TONES: usize = 48;

/// The phase of tone `k` of [`Excitation::Random`] for `seed`, radians in [0, 2π): SplitMix64
/// of the two (portable and value-stable).
fn random_phase(seed: u64, k: usize) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(k as u64)
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    std::f64::consts::TAU * (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Which physical parameter drifts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum DriftParameter {
    /// The linear stiffness k₁ (so D; B stays, c being the physical damping).
    Stiffness,
    /// The damping c (so B).
    Damping,
}

/// A parameter change during the record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Drift {
    /// Which parameter.
    pub parameter: DriftParameter,
    /// When the change starts, seconds.
    pub at: f64,
    /// Relative change: the parameter is multiplied by 1 + `by`.
    pub by: f64,
    /// Duration of the linear ramp, seconds (0: a step).
    pub ramp: f64,
}

impl Drift {
    /// The factor on the parameter at time `t`: 1 before, 1 + `by` after the ramp.
    pub fn factor(&self, t: f64) -> f64 {
        if t < self.at {
            1.0
        } else if self.ramp > 0.0 && t < self.at + self.ramp {
            1.0 + self.by * (t - self.at) / self.ramp
        } else {
            1.0 + self.by
        }
    }

    /// When the new value is reached, seconds.
    pub fn end(&self) -> f64 {
        self.at + self.ramp
    }
}

/// Table 5's physical parameters, SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvehParams {
    /// Magnet mass m, kg.
    pub mass: f64,
    /// Magnitude of the net linear stiffness k₁, N/m (its sign comes from [`Wells`]).
    pub linear_stiffness: f64,
    /// Cubic stiffness k₃, N/m³.
    pub cubic_stiffness: f64,
    /// Damping ratio ζ.
    pub damping_ratio: f64,
}

impl Default for EvehParams {
    fn default() -> Self {
        let mass = 10.6e-3;
        let w1 = 2.0 * std::f64::consts::PI * TABLE5_RESONANCE_HZ;
        Self {
            mass,
            linear_stiffness: mass * w1 * w1,
            // 8.432e-3 N/mm³ = 8.432e-3 N / (1e-9 m³).
            cubic_stiffness: 8.432e6,
            damping_ratio: 0.011,
        }
    }
}

/// The coefficients of eq. (19).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Coefficients {
    /// Damping coefficient B, 1/s.
    pub b: f64,
    /// Linear stiffness per mass D, 1/s² (negative: double well).
    pub d: f64,
    /// Cubic stiffness per mass H, 1/(m² s²).
    pub h: f64,
    /// Excitation acceleration amplitude F, m/s².
    pub f: f64,
}

impl Coefficients {
    /// The restoring force of eq. (19), −Dx − Hx³ about x = 0.
    pub fn restoring_force(&self) -> RestoringForce {
        RestoringForce::from_terms(
            [
                (Term::Monomial { px: 1, pv: 0 }, -self.d),
                (Term::Monomial { px: 3, pv: 0 }, -self.h),
            ],
            0.0,
        )
    }

    /// Linear resonance √D/2π in Hz (monostable), or `None`.
    pub fn resonance_hz(&self) -> Option<f64> {
        self.restoring_force().resonance_hz()
    }

    /// Well positions ±√(−D/H) in metres (bistable), or `None`.
    pub fn wells(&self) -> Option<f64> {
        self.restoring_force().wells()
    }

    /// Small-oscillation frequency in a well √(−2D)/2π in Hz (bistable), or `None`.
    pub fn well_resonance_hz(&self) -> Option<f64> {
        self.restoring_force().well_resonance_hz()
    }
}

/// Everything [`generate_eveh`] needs; the defaults are the shipped bistable recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvehOptions {
    /// Physical parameters (Table 5).
    #[serde(flatten)]
    pub params: EvehParams,
    /// Single or double well.
    pub wells: Wells,
    /// Fixed frequency or sweep.
    pub excitation: Excitation,
    /// Excitation acceleration amplitude F, m/s².
    pub amplitude: f64,
    /// Excitation angular frequency Ω (the sweep's start), rad/s.
    pub omega: f64,
    /// End of the sweep, rad/s (used by [`Excitation::Sweep`] only).
    pub sweep_to: f64,
    /// Write the excitation as a measured column `u`.
    pub input: bool,
    /// Which response channels are written.
    pub observe: Observe,
    /// Sensor noise RMS as a fraction of each channel's RMS.
    pub delta: f64,
    /// ADC resolution in bits (0: no quantisation).
    pub adc_bits: u8,
    /// ADC full scale for x: the range is ±`full_scale` metres.
    pub full_scale: f64,
    /// Sample rate, Hz.
    pub rate: f64,
    /// Last sample time, seconds.
    pub t_end: f64,
    /// Initial displacement, metres (released from it at t = 0, so the record starts with a
    /// free transient at the system's own frequencies: without it a steady periodic orbit
    /// leaves x, x³ and cos(Ωt) nearly collinear and the weak damping unresolved).
    pub initial_displacement: f64,
    /// Initial velocity, m/s.
    pub initial_velocity: f64,
    /// A parameter change, if any.
    pub drift: Option<Drift>,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for EvehOptions {
    fn default() -> Self {
        Self {
            params: EvehParams::default(),
            wells: Wells::Bistable,
            excitation: Excitation::Fixed,
            amplitude: 0.98,
            omega: 21.4,
            sweep_to: 2.0 * std::f64::consts::PI * 8.0,
            input: false,
            observe: Observe::X,
            delta: 0.005,
            adc_bits: 16,
            full_scale: 5e-3,
            rate: 2000.0,
            t_end: 20.0,
            initial_displacement: 2e-3,
            initial_velocity: 0.0,
            drift: None,
            seed: 1,
        }
    }
}

impl EvehOptions {
    /// Checks every field once, naming the first that cannot be used.
    pub fn validate(&self) -> Result<(), OptionError> {
        let p = &self.params;
        require_positive("mass", p.mass)?;
        require_positive("linear_stiffness", p.linear_stiffness)?;
        if !(p.cubic_stiffness.is_finite() && p.cubic_stiffness >= 0.0) {
            return Err(OptionError {
                field: "cubic_stiffness",
                value: p.cubic_stiffness,
                requirement: "zero or positive, and finite",
            });
        }
        if self.wells == Wells::Bistable && p.cubic_stiffness <= 0.0 {
            return Err(OptionError {
                field: "cubic_stiffness",
                value: p.cubic_stiffness,
                requirement: "positive for a double well (else the motion is unbounded)",
            });
        }
        if !(p.damping_ratio.is_finite() && p.damping_ratio >= 0.0) {
            return Err(OptionError {
                field: "damping_ratio",
                value: p.damping_ratio,
                requirement: "zero or positive, and finite",
            });
        }
        require_finite("amplitude", self.amplitude)?;
        require_positive("omega", self.omega)?;
        if self.excitation != Excitation::Fixed {
            require_positive("sweep_to", self.sweep_to)?;
        }
        if !(self.delta.is_finite() && self.delta >= 0.0) {
            return Err(OptionError {
                field: "delta",
                value: self.delta,
                requirement: "zero or positive, and finite",
            });
        }
        if self.adc_bits > 32 || self.adc_bits == 1 {
            return Err(OptionError {
                field: "adc_bits",
                value: f64::from(self.adc_bits),
                requirement: "0 (no quantisation) or between 2 and 32",
            });
        }
        require_positive("full_scale", self.full_scale)?;
        require_positive("rate", self.rate)?;
        validate_grid(1.0 / self.rate, self.t_end)?;
        require_finite("initial_displacement", self.initial_displacement)?;
        require_finite("initial_velocity", self.initial_velocity)?;
        if let Some(d) = &self.drift {
            require_finite("drift_at", d.at)?;
            if !(d.by.is_finite() && d.by > -1.0) {
                return Err(OptionError {
                    field: "drift_by",
                    value: d.by,
                    requirement: "a finite relative change above -1 (the parameter stays positive)",
                });
            }
            if !(d.ramp.is_finite() && d.ramp >= 0.0) {
                return Err(OptionError {
                    field: "drift_ramp",
                    value: d.ramp,
                    requirement: "zero or positive, and finite",
                });
            }
        }
        Ok(())
    }

    /// The coefficients of eq. (19) before any drift.
    pub fn coefficients(&self) -> Coefficients {
        let p = &self.params;
        let omega_n = (p.linear_stiffness / p.mass).sqrt();
        let sign = match self.wells {
            Wells::Monostable => 1.0,
            Wells::Bistable => -1.0,
        };
        Coefficients {
            b: 2.0 * p.damping_ratio * omega_n,
            d: sign * p.linear_stiffness / p.mass,
            h: p.cubic_stiffness / p.mass,
            f: self.amplitude,
        }
    }

    /// The coefficients at time `t` (after the drift's factor).
    pub fn coefficients_at(&self, t: f64) -> Coefficients {
        let mut c = self.coefficients();
        if let Some(d) = &self.drift {
            match d.parameter {
                DriftParameter::Stiffness => c.d *= d.factor(t),
                DriftParameter::Damping => c.b *= d.factor(t),
            }
        }
        c
    }

    /// The excitation phase φ(t), radians (of the first tone for [`Excitation::Random`]).
    pub fn phase(&self, t: f64) -> f64 {
        match self.excitation {
            Excitation::Fixed | Excitation::Random => self.omega * t,
            Excitation::Sweep => {
                self.omega * t + (self.sweep_to - self.omega) * t * t / (2.0 * self.t_end)
            }
        }
    }

    /// The excitation acceleration, m/s²: F cos(φ(t)), or the broadband sum of
    /// [`Excitation::Random`].
    pub fn excitation_at(&self, t: f64) -> f64 {
        if self.excitation != Excitation::Random {
            return self.amplitude * self.phase(t).cos();
        }
        let step = (self.sweep_to - self.omega) / (RANDOM_TONES - 1) as f64;
        self.amplitude / (RANDOM_TONES as f64).sqrt()
            * (0..RANDOM_TONES)
                .map(|k| ((self.omega + step * k as f64) * t + random_phase(self.seed, k)).cos())
                .sum::<f64>()
    }

    /// x'' of eq. (19), f(t, x, x').
    pub fn acceleration(&self, t: f64, x: f64, v: f64) -> f64 {
        let c = self.coefficients_at(t);
        -c.b * v - c.d * x - c.h * x * x * x + self.excitation_at(t)
    }

    /// The RK4 step: 1/(10 × rate) or [`MAX_STEP`], whichever is shorter.
    pub fn max_step(&self) -> f64 {
        (0.1 / self.rate).min(MAX_STEP)
    }

    /// The true terms of x'' = Σ ξᵢ θᵢ for coefficients `c`: x, v, x³ and the excitation
    /// (`u` with coefficient 1 when it is written, cos(Ωt) at a fixed frequency, nothing for a
    /// sweep without `u`).
    pub fn terms(&self, c: &Coefficients) -> Vec<TruthTerm> {
        let mut terms = vec![
            (monomial_name(1, 0), -c.d),
            (monomial_name(0, 1), -c.b),
            (monomial_name(3, 0), -c.h),
        ];
        if self.input {
            terms.push(("u".to_owned(), 1.0));
        } else if self.excitation == Excitation::Fixed {
            terms.push((harmonic_name(Harmonic::Cos, self.omega), c.f));
        }
        terms
            .into_iter()
            .filter(|(_, coef)| *coef != 0.0)
            .map(|(term, coef)| TruthTerm { term, coef })
            .collect()
    }
}

/// A generated harvester recording: the [`Generated`] channels and truth, plus the measured
/// excitation when it is written.
#[derive(Debug, Clone, PartialEq)]
pub struct EvehGenerated {
    /// t, x (and v), the clean trajectory and the truth.
    pub generated: Generated,
    /// The measured excitation u, m/s², when [`EvehOptions::input`] is set.
    pub u: Option<Vec<f64>>,
    /// Samples of x that the ADC clipped at its full scale.
    pub clipped: usize,
}

impl EvehGenerated {
    /// The CSV header and columns: `t,x`, then `v` and `u` when written.
    pub fn csv_columns(&self) -> (Vec<&'static str>, Vec<&[f64]>) {
        let (mut header, mut columns) = self.generated.csv_columns();
        if let Some(u) = &self.u {
            header.push("u");
            columns.push(u.as_slice());
        }
        (header, columns)
    }

    /// The observed data as a [`Recording`], as if written to `path` and read back.
    pub fn to_recording(&self, path: impl Into<std::path::PathBuf>) -> Recording {
        let mut recording = self.generated.to_recording(path);
        recording.u = self.u.clone();
        recording.columns = ColumnNames {
            u: self.u.as_ref().map(|_| "u".to_owned()),
            ..recording.columns
        };
        recording
    }
}

/// `value` rounded to [`DIGITS`] significant digits.
pub fn round_digits(value: f64) -> f64 {
    if !value.is_finite() || value == 0.0 {
        return value;
    }
    format!("{value:.prec$e}", prec = DIGITS - 1)
        .parse()
        .unwrap_or(value)
}

/// The smallest value of the 1-2-5 series at least `value`.
fn one_two_five(value: f64) -> f64 {
    if !(value.is_finite() && value > 0.0) {
        return 1.0;
    }
    let decade = 10f64.powf(value.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&s| s >= value * (1.0 - 1e-12))
        .unwrap_or(10.0 * decade)
}

/// Quantises `values` in place with `bits` bits over ±`full_scale`; returns how many clipped.
fn quantise(values: &mut [f64], bits: u8, full_scale: f64) -> usize {
    if bits == 0 {
        return 0;
    }
    let levels = 2f64.powi(i32::from(bits));
    let lsb = 2.0 * full_scale / levels;
    let (lo, hi) = (-levels / 2.0, levels / 2.0 - 1.0);
    let mut clipped = 0;
    for v in values.iter_mut() {
        let code = (*v / lsb).round();
        if code < lo || code > hi {
            clipped += 1;
        }
        *v = code.clamp(lo, hi) * lsb;
    }
    clipped
}

/// Noise, quantisation and rounding of one channel; returns the values and the clipped count.
fn measure(
    clean: &[f64],
    delta: f64,
    bits: u8,
    full_scale: f64,
    rng: &mut ChaCha8Rng,
) -> (Vec<f64>, usize) {
    let mut values = add_noise(clean, delta, NoiseKind::Gauss, rng).values;
    let clipped = quantise(&mut values, bits, full_scale);
    for v in values.iter_mut() {
        *v = round_digits(*v);
    }
    (values, clipped)
}

/// What the truth's `params` holds besides the options.
#[derive(Serialize)]
struct ParamsRecord<'a> {
    #[serde(flatten)]
    options: &'a EvehOptions,
    coefficients: Coefficients,
    resonance_hz: Option<f64>,
    wells: Option<f64>,
    well_resonance_hz: Option<f64>,
    full_scale_v: Option<f64>,
    full_scale_u: Option<f64>,
    clipped_x: usize,
    drift_after: Option<DriftRecord>,
    integrator: &'static str,
    integrator_step: f64,
}

/// The coefficients after a drift, in the truth.
#[derive(Serialize)]
struct DriftRecord {
    parameter: DriftParameter,
    at: f64,
    by: f64,
    ramp: f64,
    end: f64,
    coefficients_after: Coefficients,
    terms_after: Vec<TruthTerm>,
    resonance_hz_after: Option<f64>,
    wells_after: Option<f64>,
    well_resonance_hz_after: Option<f64>,
}

/// Integrates eq. (19) on the sampling grid, then adds noise, quantises and rounds.
///
/// The noise comes from [`ChaCha8Rng`] seeded with `seed` (portable and value-stable, see
/// [`super::paper::generate_paper`]): x's draws first, then v's, then u's. Validate the options
/// first ([`EvehOptions::validate`]); this function does no I/O.
pub fn generate_eveh(opts: &EvehOptions) -> EvehGenerated {
    let t = sample_times(1.0 / opts.rate, opts.t_end);
    let initial = State {
        x: opts.initial_displacement,
        v: opts.initial_velocity,
    };
    let states = integrate_at(
        |time, x, v| opts.acceleration(time, x, v),
        initial,
        &t,
        opts.max_step(),
    );
    let clean_x: Vec<f64> = states.iter().map(|s| s.x).collect();
    let clean_v: Vec<f64> = states.iter().map(|s| s.v).collect();
    let clean_u: Vec<f64> = t.iter().map(|&s| opts.excitation_at(s)).collect();
    let auto_scale = |c: &[f64]| one_two_five(1.25 * c.iter().fold(0.0f64, |m, v| m.max(v.abs())));

    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let (x, clipped) = measure(
        &clean_x,
        opts.delta,
        opts.adc_bits,
        opts.full_scale,
        &mut rng,
    );
    let full_scale_v = (opts.observe == Observe::Xv).then(|| auto_scale(&clean_v));
    let v = full_scale_v.map(|fs| measure(&clean_v, opts.delta, opts.adc_bits, fs, &mut rng).0);
    let full_scale_u = opts.input.then(|| auto_scale(&clean_u));
    let u = full_scale_u.map(|fs| measure(&clean_u, opts.delta, opts.adc_bits, fs, &mut rng).0);

    let before = opts.coefficients();
    let drift = opts.drift.map(|d| {
        let after = opts.coefficients_at(d.end());
        DriftRecord {
            parameter: d.parameter,
            at: d.at,
            by: d.by,
            ramp: d.ramp,
            end: d.end(),
            coefficients_after: after,
            terms_after: opts.terms(&after),
            resonance_hz_after: after.resonance_hz(),
            wells_after: after.wells(),
            well_resonance_hz_after: after.well_resonance_hz(),
        }
    });
    let params = ParamsRecord {
        options: opts,
        coefficients: before,
        resonance_hz: before.resonance_hz(),
        wells: before.wells(),
        well_resonance_hz: before.well_resonance_hz(),
        full_scale_v,
        full_scale_u,
        clipped_x: clipped,
        drift_after: drift,
        integrator: "rk4",
        integrator_step: opts.max_step(),
    };
    let error = |observed: &[f64], clean: &[f64]| {
        let e: Vec<f64> = observed.iter().zip(clean).map(|(o, c)| o - c).collect();
        stats(&e)
    };
    let noise_x = error(&x, &clean_x);
    let noise_v = v.as_ref().map(|v| error(v, &clean_v));
    let truth = Truth {
        model: MODEL.to_owned(),
        target: "x''".to_owned(),
        omega: opts.omega,
        terms: opts.terms(&before),
        // Serialising plain numbers and enums into a Value cannot fail.
        params: serde_json::to_value(&params).unwrap_or_default(),
        noise: NoiseTruth {
            kind: NoiseKind::Gauss,
            delta: opts.delta,
            offset_x: noise_x.offset,
            offset_v: noise_v.map(|n| n.offset),
            rms_x: noise_x.rms,
            rms_v: noise_v.map(|n| n.rms),
        },
    };
    EvehGenerated {
        generated: Generated {
            t,
            x,
            v,
            clean_x,
            clean_v,
            truth,
        },
        u,
        clipped,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_5_coefficients() {
        let c = EvehOptions::default().coefficients();
        assert!((c.d + 336.6088).abs() < 1e-3, "{c:?}");
        assert!((c.h - 7.954717e8).abs() < 1e3, "{c:?}");
        assert!((c.b - 0.403632).abs() < 1e-5, "{c:?}");
        assert!((c.wells().unwrap() - 6.505e-4).abs() < 1e-7);
        let mono = EvehOptions {
            wells: Wells::Monostable,
            ..EvehOptions::default()
        };
        assert!((mono.coefficients().resonance_hz().unwrap() - 2.92).abs() < 1e-12);
        let names: Vec<String> = mono
            .terms(&mono.coefficients())
            .into_iter()
            .map(|t| t.term)
            .collect();
        assert_eq!(names, ["x", "v", "x^3", "cos(21.4t)"]);
    }

    #[test]
    fn input_replaces_the_cosine() {
        let options = EvehOptions {
            input: true,
            t_end: 0.5,
            ..EvehOptions::default()
        };
        let g = generate_eveh(&options);
        assert_eq!(g.csv_columns().0, ["t", "x", "u"]);
        assert_eq!(g.generated.truth.coefficient("u"), Some(1.0));
        assert_eq!(g.generated.truth.coefficient("cos(21.4t)"), None);
        // The x column does not depend on whether u is written.
        let plain = generate_eveh(&EvehOptions {
            input: false,
            ..options
        });
        assert_eq!(plain.generated.x, g.generated.x);
    }

    #[test]
    fn quantisation_and_rounding() {
        let mut v = [0.0, 1.2e-3, -6.0e-3, 4.9999e-3];
        let clipped = quantise(&mut v, 16, 5e-3);
        assert_eq!(clipped, 1);
        let lsb = 1e-2 / 65536.0;
        assert!((v[1] - 1.2e-3).abs() <= lsb / 2.0);
        assert_eq!(v[2], -5e-3);
        assert_eq!(round_digits(1.23456789e-3), 1.234568e-3);
        assert_eq!(one_two_five(0.013), 0.02);
        assert_eq!(one_two_five(3.0), 5.0);
        assert_eq!(one_two_five(5.0), 5.0);
    }

    #[test]
    fn drift_changes_the_stiffness_at_its_time() {
        let options = EvehOptions {
            drift: Some(Drift {
                parameter: DriftParameter::Stiffness,
                at: 2.0,
                by: -0.2,
                ramp: 1.0,
            }),
            ..EvehOptions::default()
        };
        let d0 = options.coefficients().d;
        assert_eq!(options.coefficients_at(1.9).d, d0);
        assert!((options.coefficients_at(2.5).d - 0.9 * d0).abs() < 1e-9);
        assert!((options.coefficients_at(3.5).d - 0.8 * d0).abs() < 1e-9);
        assert_eq!(options.coefficients_at(3.5).b, options.coefficients().b);
    }

    #[test]
    fn validation_names_the_field() {
        let bad = |o: EvehOptions| o.validate().map_err(|e| e.field);
        let base = EvehOptions::default();
        assert_eq!(bad(base.clone()), Ok(()));
        assert_eq!(
            bad(EvehOptions {
                rate: 0.0,
                ..base.clone()
            }),
            Err("rate")
        );
        assert_eq!(
            bad(EvehOptions {
                adc_bits: 40,
                ..base.clone()
            }),
            Err("adc_bits")
        );
        let mut params = base.params;
        params.cubic_stiffness = 0.0;
        assert_eq!(
            bad(EvehOptions {
                params,
                ..base.clone()
            }),
            Err("cubic_stiffness")
        );
        assert_eq!(
            bad(EvehOptions {
                drift: Some(Drift {
                    parameter: DriftParameter::Damping,
                    at: 1.0,
                    by: -1.5,
                    ramp: 0.0
                }),
                ..base
            }),
            Err("drift_by")
        );
    }
}
