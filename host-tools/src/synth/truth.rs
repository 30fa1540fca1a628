//! The truth file a generator writes beside its CSV: the equation the data obey, so that an
//! identification can be scored against it ([`score`]).
//!
//! Coefficients are those of the target solved for explicitly, x'' = Σ ξᵢ θᵢ(x, x', t), with the
//! terms named by [`crate::identify::terms`]; terms whose coefficient is exactly zero are left out.
//!
//! ```
//! use lssi_host::synth::truth::Truth;
//!
//! let json = r#"{"model": "paper-eq17", "target": "x''", "omega": 2.0,
//!     "terms": [{"term": "x", "coef": -1.0}, {"term": "cos(2t)", "coef": 5.0}],
//!     "params": {}, "noise": {"kind": "gauss", "delta": 0.001, "offset_x": 0.0, "rms_x": 0.0}}"#;
//! let truth: Truth = serde_json::from_str(json).unwrap();
//! assert_eq!(truth.coefficient("cos(2t)"), Some(5.0));
//! assert_eq!(truth.coefficient("v"), None);
//! ```

use serde::{Deserialize, Serialize};

use crate::identify::Report;
use crate::synth::noise::NoiseKind;

/// The known equation behind a generated recording, and the noise that was added to it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Which generator made the data, e.g. `paper-eq17`.
    pub model: String,
    /// The left-hand side the terms add up to, e.g. `x''`.
    pub target: String,
    /// The excitation's angular frequency Ω in rad/s.
    pub omega: f64,
    /// The active terms and their coefficients ξ.
    pub terms: Vec<TruthTerm>,
    /// Every parameter and option of the generator, model-specific.
    pub params: serde_json::Value,
    /// The noise that was added to the observed channels.
    pub noise: NoiseTruth,
}

impl Truth {
    /// The true coefficient of the term named `term`, or `None` if the term is not active.
    pub fn coefficient(&self, term: &str) -> Option<f64> {
        self.terms.iter().find(|t| t.term == term).map(|t| t.coef)
    }

    /// The active terms as (name, coefficient) pairs, in the truth's order.
    pub fn named_terms(&self) -> Vec<(String, f64)> {
        self.terms
            .iter()
            .map(|t| (t.term.clone(), t.coef))
            .collect()
    }
}

/// One active term of the true equation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthTerm {
    /// The term's name in the project's convention, e.g. `x^2*v`.
    pub term: String,
    /// Its coefficient ξ.
    pub coef: f64,
}

/// What noise was added, eq. (16), and what it came to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiseTruth {
    /// Distribution of the raw noise.
    pub kind: NoiseKind,
    /// Noise level δ.
    pub delta: f64,
    /// Mean of the noise added to x.
    pub offset_x: f64,
    /// Mean of the noise added to v, when v was observed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_v: Option<f64>,
    /// Root mean square of the noise added to x.
    pub rms_x: f64,
    /// Root mean square of the noise added to v, when v was observed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_v: Option<f64>,
}

/// Per-coefficient errors (%) (100 for a missed term) and the number of spurious terms.
pub fn score(report: &Report, truth: &[(&str, f64)]) -> (Vec<f64>, usize) {
    let errors = truth
        .iter()
        .map(
            |(name, c)| match report.terms.iter().find(|t| t.term == *name) {
                Some(t) => ((t.coef - c) / c).abs() * 100.0,
                None => 100.0,
            },
        )
        .collect();
    let spurious = report
        .terms
        .iter()
        .filter(|t| !truth.iter().any(|(n, _)| *n == t.term))
        .count();
    (errors, spurious)
}
