//! `lssi gen MODEL [OPTIONS] OUT.csv`: writes a synthetic recording and, beside it, its truth.
//!
//! `OUT.csv` gets the observed columns (`t,x`, `t,x,v`, and for `eveh --input` also `u`) and
//! `OUT.json` the [`Truth`]: the equation's terms and coefficients, every option, and the
//! noise that was added. Models: `paper` (eq. 17), `eveh` (the harvester, eq. 19; see
//! [`crate::synth::eveh`] for how Table 5 becomes its coefficients), and `piezo` and
//! `electromagnetic` (harvesters with their electrical equation, columns `t`, `x` and/or `v`,
//! `V` or `i`, and `u` with `--input`; their truth holds both equations, see
//! [`crate::synth::harvester`]).
//!
//! [`Truth`]: crate::synth::truth::Truth

use std::path::PathBuf;

use clap::{Args, Subcommand};

use crate::error::CliError;
use crate::synth::Observe;
use crate::synth::eveh::{
    Drift, DriftParameter, EvehOptions, EvehParams, Excitation, Wells, generate_eveh,
};
use crate::synth::files::{truth_path, write_eveh, write_generated, write_harvester};
use crate::synth::harvester::{
    Coil, Electrical, HarvesterOptions, Mechanical, Transducer, generate_harvester,
};
use crate::synth::noise::NoiseKind;
use crate::synth::paper::{PaperOptions, PaperParams, generate_paper};
use crate::synth::twodof::{TwoDofOptions, diverged_at, generate_twodof};

/// Arguments of `lssi gen`.
#[derive(Debug, Clone, Args)]
pub struct GenArgs {
    /// Which model to simulate.
    #[command(subcommand)]
    pub model: GenModel,
}

/// The models `lssi gen` can simulate.
#[derive(Debug, Clone, Subcommand)]
pub enum GenModel {
    /// The paper's eq. (17) with Table 1's parameters and eq. (16) noise.
    Paper(PaperArgs),
    /// The paper's harvester, eq. (19), from Table 5's physical parameters, in SI units.
    Eveh(Box<EvehArgs>),
    /// A piezoelectric harvester across a load (Erturk & Inman), mono- or bistable: x'' and
    /// V' = −λV − κx'.
    Piezo(Box<PiezoArgs>),
    /// An electromagnetic harvester (a magnet in a coil across a load): x'' and i' (or V', or
    /// V ∝ x' with --coil negligible).
    #[command(alias = "em")]
    Electromagnetic(Box<EmArgs>),
    /// A two-degree-of-freedom piezoelectric harvester (a primary mass on the base, a
    /// secondary piezo beam on it, coupled by a spring), shaken broadband: x1'', x2'' and
    /// V' = −λV − κx2'; columns t, x1, x2 (v1, v2), V, u.
    #[command(name = "twodof", alias = "2dof")]
    TwoDof(Box<TwoDofArgs>),
}

/// Arguments of `lssi gen twodof`.
#[derive(Debug, Clone, Args)]
pub struct TwoDofArgs {
    /// Primary mass m1, kg.
    #[arg(long, value_name = "KG", default_value_t = TwoDofOptions::default().mass1,
          allow_negative_numbers = true)]
    pub mass1: f64,
    /// Secondary mass m2, kg.
    #[arg(long, value_name = "KG", default_value_t = TwoDofOptions::default().mass2,
          allow_negative_numbers = true)]
    pub mass2: f64,
    /// Primary natural frequency √(k1/m1)/2π, Hz.
    #[arg(long = "freq1", value_name = "HZ", default_value_t = TwoDofOptions::default().frequency1_hz,
          allow_negative_numbers = true)]
    pub frequency1_hz: f64,
    /// Secondary (coupling spring) frequency √(k_c/m2)/2π, Hz.
    #[arg(long = "freq2", value_name = "HZ", default_value_t = TwoDofOptions::default().coupling_hz,
          allow_negative_numbers = true)]
    pub coupling_hz: f64,
    /// Primary damping ratio ζ1.
    #[arg(long, value_name = "ZETA", default_value_t = TwoDofOptions::default().zeta1,
          allow_negative_numbers = true)]
    pub zeta1: f64,
    /// Secondary damping ratio ζ2.
    #[arg(long, value_name = "ZETA", default_value_t = TwoDofOptions::default().zeta2,
          allow_negative_numbers = true)]
    pub zeta2: f64,
    /// The primary's cubic stiffness per unit mass h, m⁻² s⁻² (0: linear).
    #[arg(
        long,
        value_name = "PER_M2_S2",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub cubic: f64,
    /// Electromechanical coupling θ, N/V [default: k² = θ²/(k_c C_p) = 0.025].
    #[arg(long, value_name = "N_PER_V", allow_negative_numbers = true)]
    pub theta: Option<f64>,
    /// Piezo capacitance C_p, farads.
    #[arg(long, value_name = "F", default_value_t = TwoDofOptions::default().capacitance,
          allow_negative_numbers = true)]
    pub capacitance: f64,
    /// Load resistance R, ohms.
    #[arg(long = "load-ohms", value_name = "OHMS", default_value_t = TwoDofOptions::default().load_ohms,
          allow_negative_numbers = true)]
    pub load_ohms: f64,
    /// Base acceleration scale A, m/s² (six tones, RMS A/√2).
    #[arg(long, value_name = "M_PER_S2", default_value_t = TwoDofOptions::default().amplitude,
          allow_negative_numbers = true)]
    pub amplitude: f64,
    /// Mechanical channels to write: x (x1, x2) or xv (also v1, v2).
    #[arg(long, value_enum, default_value_t = Observe::X)]
    pub observe: Observe,
    /// Sensor noise: Gaussian, RMS = D times each channel's RMS (0.01 = 1 %).
    #[arg(
        long,
        value_name = "D",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub delta: f64,
    /// Sample rate, Hz.
    #[arg(long, value_name = "HZ", default_value_t = TwoDofOptions::default().rate,
          allow_negative_numbers = true)]
    pub rate: f64,
    /// Last sample time, seconds.
    #[arg(long = "t-end", value_name = "T", default_value_t = TwoDofOptions::default().t_end,
          allow_negative_numbers = true)]
    pub t_end: f64,
    /// Initial x1, metres (released from rest there, uncharged).
    #[arg(long, value_name = "METRES", default_value_t = TwoDofOptions::default().initial_displacement,
          allow_negative_numbers = true)]
    pub x0: f64,
    /// Seed of the noise generator; the same seed gives the same file.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// The CSV file to write; the truth goes beside it with the extension .json.
    #[arg(value_name = "OUT.csv")]
    pub out: PathBuf,
}

impl TwoDofArgs {
    /// The options these flags ask for.
    pub fn options(&self) -> TwoDofOptions {
        let wc = std::f64::consts::TAU * self.coupling_hz;
        TwoDofOptions {
            mass1: self.mass1,
            mass2: self.mass2,
            frequency1_hz: self.frequency1_hz,
            coupling_hz: self.coupling_hz,
            zeta1: self.zeta1,
            zeta2: self.zeta2,
            cubic: self.cubic,
            theta: self
                .theta
                .unwrap_or_else(|| (0.025 * self.mass2 * wc * wc * self.capacitance).sqrt()),
            capacitance: self.capacitance,
            load_ohms: self.load_ohms,
            amplitude: self.amplitude,
            velocities: self.observe == Observe::Xv,
            delta: self.delta,
            rate: self.rate,
            t_end: self.t_end,
            initial_displacement: self.x0,
            seed: self.seed,
        }
    }
}

/// What the piezoelectric and electromagnetic harvesters share.
#[derive(Debug, Clone, Args)]
pub struct HarvesterArgs {
    /// Single well, or the double well of a beam between magnets.
    #[arg(long, value_enum, default_value_t = Wells::Monostable)]
    pub wells: Wells,
    /// Base acceleration amplitude A, m/s².
    #[arg(long, value_name = "M_PER_S2", default_value_t = HarvesterOptions::piezo().amplitude,
          allow_negative_numbers = true)]
    pub amplitude: f64,
    /// Excitation angular frequency Ω, rad/s [default: 2π·8 Hz].
    #[arg(long, value_name = "RAD_PER_S", default_value_t = HarvesterOptions::piezo().omega,
          allow_negative_numbers = true)]
    pub omega: f64,
    /// Write the base acceleration as a measured column u (m/s²).
    #[arg(long)]
    pub input: bool,
    /// Mechanical channels to write: x, v (a vibrometer's velocity alone), or xv.
    #[arg(long, value_enum, default_value_t = Mechanical::X)]
    pub observe: Mechanical,
    /// Sensor noise: Gaussian, RMS = D times each channel's RMS (0.01 = 1 %).
    #[arg(
        long,
        value_name = "D",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub delta: f64,
    /// Sample rate, Hz.
    #[arg(long, value_name = "HZ", default_value_t = HarvesterOptions::piezo().rate,
          allow_negative_numbers = true)]
    pub rate: f64,
    /// Last sample time, seconds.
    #[arg(long = "t-end", value_name = "T", default_value_t = HarvesterOptions::piezo().t_end,
          allow_negative_numbers = true)]
    pub t_end: f64,
    /// Initial displacement, metres (released from rest there, uncharged) [default: 2 mm
    /// monostable, the well + 2 mm bistable].
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    pub x0: Option<f64>,
    /// Modal mass m, kg.
    #[arg(long, value_name = "KG", default_value_t = HarvesterOptions::piezo().mass,
          allow_negative_numbers = true)]
    pub mass: f64,
    /// Natural frequency (short-circuit; in a well for the bistable), Hz.
    #[arg(long = "freq", value_name = "HZ", default_value_t = HarvesterOptions::piezo().frequency_hz,
          allow_negative_numbers = true)]
    pub frequency_hz: f64,
    /// Mechanical damping ratio ζ [default: 0.015 piezo, 0.01 electromagnetic].
    #[arg(long, value_name = "ZETA", allow_negative_numbers = true)]
    pub zeta: Option<f64>,
    /// Monostable: cubic stiffness per unit mass, m⁻² s⁻² (0: a linear beam).
    #[arg(
        long,
        value_name = "PER_M2_S2",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub cubic: f64,
    /// Bistable: the wells' position ±x_w, metres.
    #[arg(long, value_name = "METRES", default_value_t = HarvesterOptions::piezo().well,
          allow_negative_numbers = true)]
    pub well: f64,
    /// Seed of the noise generator; the same seed gives the same file.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// The CSV file to write; the truth goes beside it with the extension .json.
    #[arg(value_name = "OUT.csv")]
    pub out: PathBuf,
}

impl HarvesterArgs {
    /// The options these flags ask for, on `base` (the model's defaults).
    fn options(&self, base: HarvesterOptions) -> HarvesterOptions {
        let x0 = self.x0.unwrap_or(match self.wells {
            Wells::Monostable => base.initial_displacement,
            Wells::Bistable => self.well + base.initial_displacement,
        });
        HarvesterOptions {
            wells: self.wells,
            amplitude: self.amplitude,
            omega: self.omega,
            input: self.input,
            mechanical: self.observe,
            delta: self.delta,
            rate: self.rate,
            t_end: self.t_end,
            initial_displacement: x0,
            mass: self.mass,
            frequency_hz: self.frequency_hz,
            damping_ratio: self.zeta.unwrap_or(base.damping_ratio),
            cubic: self.cubic,
            well: self.well,
            seed: self.seed,
            ..base
        }
    }
}

/// Arguments of `lssi gen piezo`.
#[derive(Debug, Clone, Args)]
pub struct PiezoArgs {
    /// The options both harvesters take.
    #[command(flatten)]
    pub common: HarvesterArgs,
    /// Electromechanical coupling θ, N/V [default: k² = θ²/(m ω² C_p) = 0.025, Erturk & Inman's].
    #[arg(long, value_name = "N_PER_V", allow_negative_numbers = true)]
    pub theta: Option<f64>,
    /// Piezo capacitance C_p, farads.
    #[arg(
        long,
        value_name = "FARADS",
        default_value_t = 50e-9,
        allow_negative_numbers = true
    )]
    pub capacitance: f64,
    /// Load resistance R, ohms.
    #[arg(
        long = "load-ohms",
        value_name = "OHMS",
        default_value_t = 1e6,
        allow_negative_numbers = true
    )]
    pub load_ohms: f64,
}

impl PiezoArgs {
    /// The generator options these flags ask for.
    pub fn options(&self) -> HarvesterOptions {
        let mut o = self.common.options(HarvesterOptions::piezo());
        let w = 2.0 * std::f64::consts::PI * o.frequency_hz;
        let theta = self
            .theta
            .unwrap_or_else(|| (0.025 * o.mass * w * w * self.capacitance.abs()).sqrt());
        o.transducer = Transducer::Piezo {
            theta,
            capacitance: self.capacitance,
            load_ohms: self.load_ohms,
        };
        o
    }
}

/// Arguments of `lssi gen electromagnetic`.
#[derive(Debug, Clone, Args)]
pub struct EmArgs {
    /// The options both harvesters take.
    #[command(flatten)]
    pub common: HarvesterArgs,
    /// With the coil's inductance (an i' equation), or negligible (V ∝ x').
    #[arg(long, value_enum, default_value_t = Coil::Inductive)]
    pub coil: Coil,
    /// The electrical channel written: the load voltage V or the current i.
    #[arg(long, value_enum, default_value_t = Electrical::V)]
    pub electrical: Electrical,
    /// Transduction factor Φ, N/A (= V s/m).
    #[arg(
        long,
        value_name = "N_PER_A",
        default_value_t = 5.0,
        allow_negative_numbers = true
    )]
    pub phi: f64,
    /// Coil resistance R_c, ohms.
    #[arg(
        long = "coil-ohms",
        value_name = "OHMS",
        default_value_t = 1e3,
        allow_negative_numbers = true
    )]
    pub coil_ohms: f64,
    /// Load resistance R_L, ohms.
    #[arg(
        long = "load-ohms",
        value_name = "OHMS",
        default_value_t = 1e3,
        allow_negative_numbers = true
    )]
    pub load_ohms: f64,
    /// Coil inductance L, henries.
    #[arg(
        long,
        value_name = "HENRIES",
        default_value_t = 10.0,
        allow_negative_numbers = true
    )]
    pub inductance: f64,
}

impl EmArgs {
    /// The generator options these flags ask for.
    pub fn options(&self) -> HarvesterOptions {
        let mut o = self.common.options(HarvesterOptions::electromagnetic());
        o.transducer = Transducer::Electromagnetic {
            phi: self.phi,
            coil_ohms: self.coil_ohms,
            load_ohms: self.load_ohms,
            inductance: self.inductance,
            coil: self.coil,
            electrical: self.electrical,
        };
        o
    }
}

/// Arguments of `lssi gen eveh` (defaults: the shipped bistable recording).
#[derive(Debug, Clone, Args)]
pub struct EvehArgs {
    /// Single well (D > 0) or double well (D < 0).
    #[arg(long, value_enum, default_value_t = EvehOptions::default().wells)]
    pub wells: Wells,
    /// Excitation: fixed frequency F cos(Ωt), a linear sweep from --omega to --sweep-to, or
    /// broadband (random-phase tones from --omega to --sweep-to, the RMS of F cos(Ωt)).
    #[arg(long, value_enum, default_value_t = EvehOptions::default().excitation)]
    pub excitation: Excitation,
    /// Excitation acceleration amplitude F, m/s².
    #[arg(long, value_name = "M_PER_S2", default_value_t = EvehOptions::default().amplitude,
          allow_negative_numbers = true)]
    pub amplitude: f64,
    /// Excitation angular frequency Ω (start of a sweep), rad/s.
    #[arg(long, value_name = "RAD_PER_S", default_value_t = EvehOptions::default().omega,
          allow_negative_numbers = true)]
    pub omega: f64,
    /// End of the sweep, or the top of the broadband excitation's band, rad/s (with
    /// --excitation sweep or random).
    #[arg(long = "sweep-to", value_name = "RAD_PER_S",
          default_value_t = EvehOptions::default().sweep_to, allow_negative_numbers = true)]
    pub sweep_to: f64,
    /// Write the excitation as a measured column u (m/s²).
    #[arg(long)]
    pub input: bool,
    /// Response channels to write: x, or x and v.
    #[arg(long, value_enum, default_value_t = EvehOptions::default().observe)]
    pub observe: Observe,
    /// Sensor noise: Gaussian, RMS = D times each channel's RMS (0.005 = 0.5 %).
    #[arg(long, value_name = "D", default_value_t = EvehOptions::default().delta,
          allow_negative_numbers = true)]
    pub delta: f64,
    /// ADC resolution in bits (0: no quantisation).
    #[arg(long = "adc-bits", value_name = "BITS", default_value_t = EvehOptions::default().adc_bits)]
    pub adc_bits: u8,
    /// ADC full scale for x: the range is ±METRES.
    #[arg(long = "full-scale", value_name = "METRES",
          default_value_t = EvehOptions::default().full_scale, allow_negative_numbers = true)]
    pub full_scale: f64,
    /// Sample rate, Hz.
    #[arg(long, value_name = "HZ", default_value_t = EvehOptions::default().rate,
          allow_negative_numbers = true)]
    pub rate: f64,
    /// Last sample time, seconds.
    #[arg(long = "t-end", value_name = "T", default_value_t = EvehOptions::default().t_end,
          allow_negative_numbers = true)]
    pub t_end: f64,
    /// Initial displacement, metres (released from rest there at t = 0).
    #[arg(long, value_name = "METRES",
          default_value_t = EvehOptions::default().initial_displacement,
          allow_negative_numbers = true)]
    pub x0: f64,
    /// Initial velocity, m/s.
    #[arg(
        long,
        value_name = "M_PER_S",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub v0: f64,
    /// A parameter that changes during the record (with --drift-at and --drift-by).
    #[arg(long, value_enum)]
    pub drift: Option<DriftParameter>,
    /// When the drift starts, seconds.
    #[arg(long = "drift-at", value_name = "T", allow_negative_numbers = true)]
    pub drift_at: Option<f64>,
    /// Relative change of the drifting parameter (-0.2: 20 % less).
    #[arg(
        long = "drift-by",
        value_name = "FRACTION",
        allow_negative_numbers = true
    )]
    pub drift_by: Option<f64>,
    /// Duration of the change, seconds (0: a step).
    #[arg(
        long = "drift-ramp",
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub drift_ramp: Option<f64>,
    /// Magnet mass m, kg (Table 5: 10.6 g).
    #[arg(long, value_name = "KG", default_value_t = EvehParams::default().mass,
          allow_negative_numbers = true)]
    pub mass: f64,
    /// Magnitude of the net linear stiffness k₁, N/m [default: m (2π 2.92 Hz)², Table 5's
    /// resonance].
    #[arg(long, value_name = "N_PER_M", default_value_t = EvehParams::default().linear_stiffness,
          allow_negative_numbers = true)]
    pub k1: f64,
    /// Cubic stiffness k₃, N/m³ (Table 5: 8.432e-3 N/mm³).
    #[arg(long, value_name = "N_PER_M3", default_value_t = EvehParams::default().cubic_stiffness,
          allow_negative_numbers = true)]
    pub k3: f64,
    /// Damping ratio ζ (Table 5: 0.011).
    #[arg(long, value_name = "ZETA", default_value_t = EvehParams::default().damping_ratio,
          allow_negative_numbers = true)]
    pub zeta: f64,
    /// Seed of the noise generator; the same seed gives the same file.
    #[arg(long, value_name = "S", default_value_t = EvehOptions::default().seed)]
    pub seed: u64,
    /// The CSV file to write; the truth goes beside it with the extension .json.
    #[arg(value_name = "OUT.csv")]
    pub out: PathBuf,
}

impl EvehArgs {
    /// The generator options these flags ask for.
    pub fn options(&self) -> Result<EvehOptions, CliError> {
        let drift = match self.drift {
            Some(parameter) => {
                let at = self.drift_at.ok_or_else(|| CliError::BadFlag {
                    flag: "--drift-at",
                    value: "nothing".into(),
                    requirement: "given with --drift: the time the change starts, in seconds"
                        .into(),
                })?;
                let by = self.drift_by.ok_or_else(|| CliError::BadFlag {
                    flag: "--drift-by",
                    value: "nothing".into(),
                    requirement: "given with --drift: the relative change, e.g. -0.2".into(),
                })?;
                Some(Drift {
                    parameter,
                    at,
                    by,
                    ramp: self.drift_ramp.unwrap_or(0.0),
                })
            }
            None => {
                let stray = [
                    ("--drift-at", self.drift_at),
                    ("--drift-by", self.drift_by),
                    ("--drift-ramp", self.drift_ramp),
                ]
                .into_iter()
                .find_map(|(flag, value)| value.map(|v| (flag, v)));
                if let Some((flag, value)) = stray {
                    return Err(CliError::BadFlag {
                        flag,
                        value: value.to_string(),
                        requirement: "used with --drift stiffness or --drift damping only".into(),
                    });
                }
                None
            }
        };
        Ok(EvehOptions {
            params: EvehParams {
                mass: self.mass,
                linear_stiffness: self.k1,
                cubic_stiffness: self.k3,
                damping_ratio: self.zeta,
            },
            wells: self.wells,
            excitation: self.excitation,
            amplitude: self.amplitude,
            omega: self.omega,
            sweep_to: self.sweep_to,
            input: self.input,
            observe: self.observe,
            delta: self.delta,
            adc_bits: self.adc_bits,
            full_scale: self.full_scale,
            rate: self.rate,
            t_end: self.t_end,
            initial_displacement: self.x0,
            initial_velocity: self.v0,
            drift,
            seed: self.seed,
        })
    }
}

/// Arguments of `lssi gen paper`.
#[derive(Debug, Clone, Args)]
pub struct PaperArgs {
    /// Nonlinear perturbation strength ε.
    #[arg(long, value_name = "E", default_value_t = PaperOptions::default().epsilon,
          allow_negative_numbers = true)]
    pub eps: f64,
    /// Noise level δ: the noise has 2-norm δ times the signal's (eq. 16).
    #[arg(long, value_name = "D", default_value_t = PaperOptions::default().delta,
          allow_negative_numbers = true)]
    pub delta: f64,
    /// Raw noise distribution: paper = uniform (0,1) as in the paper (biased), uniform0 =
    /// uniform (-1,1), gauss = standard normal; all scaled to the same norm.
    #[arg(long, value_enum, default_value_t = PaperOptions::default().noise)]
    pub noise: NoiseKind,
    /// Channels to write: x, or x and v.
    #[arg(long, value_enum, default_value_t = PaperOptions::default().observe)]
    pub observe: Observe,
    /// Last sample time, seconds.
    #[arg(long = "t-end", value_name = "T", default_value_t = PaperOptions::default().t_end,
          allow_negative_numbers = true)]
    pub t_end: f64,
    /// Sampling interval, seconds.
    #[arg(long, value_name = "DT", default_value_t = PaperOptions::default().dt,
          allow_negative_numbers = true)]
    pub dt: f64,
    /// Seed of the noise generator; the same seed gives the same file.
    #[arg(long, value_name = "S", default_value_t = PaperOptions::default().seed)]
    pub seed: u64,
    /// The CSV file to write; the truth goes beside it with the extension .json.
    #[arg(value_name = "OUT.csv")]
    pub out: PathBuf,
}

impl PaperArgs {
    /// The generator options these flags ask for.
    pub fn options(&self) -> PaperOptions {
        PaperOptions {
            params: PaperParams::default(),
            epsilon: self.eps,
            delta: self.delta,
            noise: self.noise,
            observe: self.observe,
            t_end: self.t_end,
            dt: self.dt,
            seed: self.seed,
        }
    }
}

/// Runs `lssi gen`.
pub fn run(args: &GenArgs) -> Result<(), CliError> {
    match &args.model {
        GenModel::Paper(paper) => run_paper(paper),
        GenModel::Eveh(eveh) => run_eveh(eveh),
        GenModel::Piezo(piezo) => run_harvester(&piezo.options(), &piezo.common.out),
        GenModel::Electromagnetic(em) => run_harvester(&em.options(), &em.common.out),
        GenModel::TwoDof(twodof) => run_twodof(&twodof.options(), &twodof.out),
    }
}

fn run_twodof(options: &TwoDofOptions, out: &std::path::Path) -> Result<(), CliError> {
    options.validate().map_err(|error| {
        let flag = match error.field {
            "mass1" => "--mass1",
            "mass2" => "--mass2",
            "frequency1_hz" => "--freq1",
            "coupling_hz" => "--freq2",
            "zeta1" => "--zeta1",
            "zeta2" => "--zeta2",
            "cubic" => "--cubic",
            "theta" => "--theta",
            "capacitance" => "--capacitance",
            "load_ohms" => "--load-ohms",
            "amplitude" => "--amplitude",
            "delta" => "--delta",
            "rate" | "dt" => "--rate",
            "t_end" => "--t-end",
            "initial_displacement" => "--x0",
            other => other,
        };
        CliError::from_option(error, flag)
    })?;
    let json = truth_path(out)?;
    let generated = generate_twodof(options);
    if let Some(t) = diverged_at(&generated) {
        return Err(CliError::Diverged {
            model: generated.truth.model.clone(),
            t,
        });
    }
    write_harvester(out, &json, &generated)?;
    crate::outln!(
        "wrote {} ({} samples of {} over {} s at {} Hz) and {}",
        out.display(),
        generated.t.len(),
        generated.header().join(","),
        options.t_end,
        options.rate,
        json.display()
    );
    Ok(())
}

fn run_harvester(options: &HarvesterOptions, out: &std::path::Path) -> Result<(), CliError> {
    options.validate().map_err(|error| {
        let flag = match error.field {
            "theta" => "--theta",
            "capacitance" => "--capacitance",
            "load_ohms" => "--load-ohms",
            "phi" => "--phi",
            "coil_ohms" => "--coil-ohms",
            "inductance" => "--inductance",
            "mass" => "--mass",
            "frequency_hz" => "--freq",
            "damping_ratio" => "--zeta",
            "cubic" => "--cubic",
            "well" => "--well",
            "amplitude" => "--amplitude",
            "omega" => "--omega",
            "delta" => "--delta",
            "rate" | "dt" => "--rate",
            "t_end" => "--t-end",
            "initial_displacement" => "--x0",
            other => other,
        };
        let mut error = CliError::from_option(error, flag);
        if let CliError::BadFlag {
            flag: "--rate",
            requirement,
            ..
        } = &mut error
        {
            *requirement = "a positive sample rate in Hz giving at least two and at most 10 \
                            million samples over --t-end"
                .into();
        }
        error
    })?;
    let json = truth_path(out)?;
    let generated = generate_harvester(options);
    if let Some(t) = generated.diverged_at() {
        return Err(CliError::Diverged {
            model: generated.truth.model.clone(),
            t,
        });
    }
    write_harvester(out, &json, &generated)?;
    crate::outln!(
        "wrote {} ({} samples of {} over {} s at {} Hz) and {}",
        out.display(),
        generated.t.len(),
        generated.header().join(","),
        options.t_end,
        options.rate,
        json.display()
    );
    Ok(())
}

fn run_eveh(args: &EvehArgs) -> Result<(), CliError> {
    let options = args.options()?;
    options.validate().map_err(|error| {
        let flag = match error.field {
            "mass" => "--mass",
            "linear_stiffness" => "--k1",
            "cubic_stiffness" => "--k3",
            "damping_ratio" => "--zeta",
            "amplitude" => "--amplitude",
            "omega" => "--omega",
            "sweep_to" => "--sweep-to",
            "delta" => "--delta",
            "adc_bits" => "--adc-bits",
            "full_scale" => "--full-scale",
            "rate" => "--rate",
            "t_end" => "--t-end",
            // The grid check names dt, which is 1/rate here.
            "dt" => "--rate",
            "initial_displacement" => "--x0",
            "initial_velocity" => "--v0",
            "drift_at" => "--drift-at",
            "drift_by" => "--drift-by",
            "drift_ramp" => "--drift-ramp",
            other => other,
        };
        let mut error = CliError::from_option(error, flag);
        if let CliError::BadFlag {
            flag: "--rate",
            requirement,
            ..
        } = &mut error
        {
            *requirement = "a positive sample rate in Hz giving at least two and at most 10 \
                            million samples over --t-end"
                .into();
        }
        error
    })?;
    let json = truth_path(&args.out)?;
    let generated = generate_eveh(&options);
    if let Some(t) = generated.generated.diverged_at() {
        return Err(CliError::Diverged {
            model: generated.generated.truth.model.clone(),
            t,
        });
    }
    write_eveh(&args.out, &json, &generated)?;
    crate::outln!(
        "wrote {} ({} samples of {} over {} s at {} Hz) and {}",
        args.out.display(),
        generated.generated.t.len(),
        generated.csv_columns().0.join(","),
        options.t_end,
        options.rate,
        json.display()
    );
    if generated.clipped > 0 {
        eprintln!(
            "lssi: warning: {} samples of x exceeded the ADC full scale of ±{} m and were clipped; \
             raise --full-scale.",
            generated.clipped, options.full_scale
        );
    }
    Ok(())
}

fn run_paper(args: &PaperArgs) -> Result<(), CliError> {
    let options = args.options();
    options.validate().map_err(|error| {
        let flag = match error.field {
            "epsilon" => "--eps",
            "delta" => "--delta",
            "t_end" => "--t-end",
            "dt" => "--dt",
            // Table 1's fields have no flags (and their defaults are valid).
            other => other,
        };
        CliError::from_option(error, flag)
    })?;
    let json = truth_path(&args.out)?;
    let generated = generate_paper(&options);
    if let Some(t) = generated.diverged_at() {
        return Err(CliError::Diverged {
            model: generated.truth.model.clone(),
            t,
        });
    }
    write_generated(&args.out, &json, &generated)?;
    crate::outln!(
        "wrote {} ({} samples of {} over {} s) and {}",
        args.out.display(),
        generated.t.len(),
        generated.csv_columns().0.join(","),
        options.t_end,
        json.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flag_defaults_are_the_library_defaults() {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrapper {
            #[command(flatten)]
            args: PaperArgs,
        }
        let wrapper = Wrapper::parse_from(["test", "out.csv"]);
        assert_eq!(wrapper.args.options(), PaperOptions::default());
    }

    #[test]
    fn harvester_flag_defaults_are_the_library_defaults() {
        use clap::Parser;
        #[derive(Parser)]
        struct Piezo {
            #[command(flatten)]
            args: PiezoArgs,
        }
        #[derive(Parser)]
        struct Em {
            #[command(flatten)]
            args: EmArgs,
        }
        let piezo = Piezo::parse_from(["test", "out.csv"]);
        assert_eq!(piezo.args.options(), HarvesterOptions::piezo());
        let em = Em::parse_from(["test", "out.csv"]);
        assert_eq!(em.args.options(), HarvesterOptions::electromagnetic());
        let bistable = Piezo::parse_from(["test", "--wells", "bistable", "out.csv"]);
        assert_eq!(bistable.args.options().initial_displacement, 7e-3);
    }

    #[test]
    fn eveh_flag_defaults_are_the_library_defaults() {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrapper {
            #[command(flatten)]
            args: EvehArgs,
        }
        let wrapper = Wrapper::parse_from(["test", "out.csv"]);
        assert_eq!(wrapper.args.options().ok(), Some(EvehOptions::default()));
        let stray = Wrapper::parse_from(["test", "--drift-by", "0.1", "out.csv"]);
        assert!(matches!(
            stray.args.options(),
            Err(CliError::BadFlag {
                flag: "--drift-by",
                ..
            })
        ));
    }
}
