//! `lssi identify FILE.csv`: the equation of motion of a recording.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use crate::error::CliError;
use crate::identify::{self, Options};
use crate::recording::{ColumnNames, Recording};

/// Monomial families (clap's view of [`lssi_core::PolyFamily`]).
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Family {
    /// Every monomial x^a v^b up to the order.
    All,
    /// x^k and x^(k-1)*v.
    Families,
    /// x^k and x^(k-1)*v for odd k (the paper's Table 7).
    Odd,
}

/// Arguments of `lssi identify`.
#[derive(Debug, Clone, Args)]
pub struct IdentifyArgs {
    /// The recording: CSV with a header row naming at least t and x.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// Base excitation frequency Ω in rad/s (default: estimated from the data).
    #[arg(long, value_name = "RAD_PER_S")]
    pub omega: Option<f64>,
    /// sin/cos(kΩt) terms for k = 1..H (0: none, for a measured excitation u).
    #[arg(long, default_value_t = 1, value_name = "H")]
    pub harmonics: u8,
    /// Highest order of the monomials of (x, v).
    #[arg(long, default_value_t = 3, value_name = "P")]
    pub poly_order: u8,
    /// Which monomials.
    #[arg(long, value_enum, default_value_t = Family::All)]
    pub family: Family,
    /// Compute in f32, as a device does (the default).
    #[arg(long, conflicts_with = "f64")]
    pub f32: bool,
    /// Compute in f64 (the reference).
    #[arg(long)]
    pub f64: bool,
    /// Turn the k-neighbour smoothing off (the ablation).
    #[arg(long)]
    pub no_smoothing: bool,
    /// Forgetting time constant in seconds (default: remember everything).
    #[arg(long, value_name = "SECONDS")]
    pub memory: Option<f64>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
}

impl IdentifyArgs {
    /// The identifier options these flags ask for.
    pub fn options(&self) -> Result<Options, CliError> {
        if let Some(w) = self.omega
            && !(w.is_finite() && w > 0.0)
        {
            return Err(CliError::BadFlag {
                flag: "--omega",
                value: w.to_string(),
                requirement: "a positive angular frequency in rad/s".into(),
            });
        }
        if let Some(m) = self.memory
            && !(m.is_finite() && m > 0.0)
        {
            return Err(CliError::BadFlag {
                flag: "--memory",
                value: m.to_string(),
                requirement: "a positive time in seconds".into(),
            });
        }
        if !(1..=9).contains(&self.poly_order) {
            return Err(CliError::BadFlag {
                flag: "--poly-order",
                value: self.poly_order.to_string(),
                requirement: "between 1 and 9".into(),
            });
        }
        if self.harmonics > 8 {
            return Err(CliError::BadFlag {
                flag: "--harmonics",
                value: self.harmonics.to_string(),
                requirement: "at most 8".into(),
            });
        }
        Ok(Options {
            omega: self.omega,
            harmonics: self.harmonics,
            poly_order: self.poly_order,
            family: match self.family {
                Family::All => lssi_core::PolyFamily::All,
                Family::Families => lssi_core::PolyFamily::Families,
                Family::Odd => lssi_core::PolyFamily::OddFamilies,
            },
            f32: !self.f64,
            smoothing: !self.no_smoothing,
            memory: self.memory,
        })
    }
}

/// Runs `lssi identify`.
pub fn run(args: &IdentifyArgs) -> Result<(), CliError> {
    let options = args.options()?;
    let recording = Recording::read(&args.file, &args.columns)?;
    let report = identify_recording(&recording, &options)?;
    if args.json {
        println!("{}", serde_json::to_string(&report).unwrap_or_default());
    } else {
        print!("{}", identify::render(&report));
    }
    Ok(())
}

/// Configures and runs the identifier on a recording.
pub fn identify_recording(
    recording: &Recording,
    options: &Options,
) -> Result<identify::Report, CliError> {
    let bad = |e: identify::IdentifyError| CliError::Identify(e.0);
    let (config, estimated) = identify::configure(recording, options).map_err(bad)?;
    if options.f32 {
        identify::run::<f32>(recording, config, estimated).map_err(bad)
    } else {
        identify::run::<f64>(recording, config, estimated).map_err(bad)
    }
}
