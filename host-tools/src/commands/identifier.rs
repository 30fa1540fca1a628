//! The identifier's flags that `lssi identify`, `lssi plot` and `lssi replay` share: one clap
//! struct, flattened into each command (`#[command(flatten)]`), so they parse, check and
//! default them alike.

use clap::{Args, ValueEnum};

use crate::error::CliError;
use crate::identify::Options;

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

impl From<Family> for lssi_core::PolyFamily {
    fn from(family: Family) -> Self {
        match family {
            Family::All => lssi_core::PolyFamily::All,
            Family::Families => lssi_core::PolyFamily::Families,
            Family::Odd => lssi_core::PolyFamily::OddFamilies,
        }
    }
}

/// The identifier's flags: the library (Ω, harmonics, monomials), the smoothing and the
/// memory.
#[derive(Debug, Clone, Args)]
#[command(next_help_heading = "Library")]
pub struct IdentifierArgs {
    /// Base excitation frequency Ω in rad/s (default: estimated from the data).
    #[arg(long, value_name = "RAD_PER_S")]
    pub omega: Option<f64>,
    /// sin/cos(kΩt) terms for k = 1..H (default: 1, or 0 when the recording has a measured
    /// excitation u, which is the forcing).
    #[arg(long, value_name = "H")]
    pub harmonics: Option<u8>,
    /// Highest order of the monomials of (x, v).
    #[arg(long, default_value_t = 3, value_name = "P")]
    pub poly_order: u8,
    /// Which monomials.
    #[arg(long, value_enum, default_value_t = Family::All)]
    pub family: Family,
    /// Turn the k-neighbour smoothing off (the ablation).
    #[arg(long, help_heading = "Identifier")]
    pub no_smoothing: bool,
    /// Forgetting time constant in seconds (default: remember everything).
    #[arg(long, value_name = "SECONDS", help_heading = "Identifier")]
    pub memory: Option<f64>,
}

impl IdentifierArgs {
    /// The identifier options these flags ask for, in f32 (as a device computes) and without
    /// the noise correction; `lssi identify` sets those two from its own flags.
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
        if let Some(h) = self.harmonics
            && h > 8
        {
            return Err(CliError::BadFlag {
                flag: "--harmonics",
                value: h.to_string(),
                requirement: "at most 8".into(),
            });
        }
        Ok(Options {
            omega: self.omega,
            harmonics: self.harmonics,
            poly_order: self.poly_order,
            family: self.family.into(),
            f32: true,
            smoothing: !self.no_smoothing,
            memory: self.memory,
            noise_correction: false,
        })
    }
}
