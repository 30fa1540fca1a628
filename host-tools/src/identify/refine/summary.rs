//! The `"refined"` object of `lssi identify --json`, and its lines in the text report.

use serde::Serialize;

use super::{Check, Chosen, Fit};

/// One refined term, as `lssi identify --refine` reports it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TermSummary {
    /// Name (`x`, `x^3`, `cos(21.4t)`, …).
    pub term: String,
    /// Coefficient in physical units.
    pub coef: f64,
    /// Its standard error (absent for the streaming model).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub se: Option<f64>,
}

/// The `"refined"` object of `lssi identify --refine --json`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Summary {
    /// `refined` or `streaming`.
    pub chosen: Chosen,
    /// Why, in one sentence.
    pub reason: String,
    /// The reported model's terms, with standard errors when refined.
    pub terms: Vec<TermSummary>,
    /// Held-out simulation error of the streaming model (segments of a few periods, each
    /// from its own fitted initial state).
    pub held_out_streaming: Option<Fit>,
    /// The same for the model refined on the first half.
    pub held_out_refined: Option<Fit>,
    /// The reported model's free run over the held-out half (one fitted initial state).
    pub free_run: Option<Fit>,
    /// Samples per period at the top of x's band (under ~20: derivatives are biased, which
    /// is what refinement corrects).
    pub samples_per_period: Option<f64>,
    /// When the reported model's support is not the streaming model's (another solution of
    /// the sweep predicted the held-out half better): the terms added and removed. Absent
    /// when the support is the streaming one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub support_changed: Option<SupportChange>,
}

/// How the refined model's support differs from the streaming model's.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SupportChange {
    /// Terms the refined model has and the streaming model has not.
    pub added: Vec<String>,
    /// Terms the streaming model has and the refined model has not.
    pub removed: Vec<String>,
}

impl Summary {
    /// The summary of a check, terms named at Ω = `omega`.
    pub fn of(check: &Check, omega: f64) -> Self {
        let terms = check
            .model
            .terms
            .iter()
            .enumerate()
            .map(|(j, (term, coef))| TermSummary {
                term: term.name(omega).to_string(),
                coef: *coef,
                se: check
                    .standard_errors
                    .as_ref()
                    .and_then(|se| se.get(j).copied()),
            })
            .collect();
        Self {
            chosen: check.chosen,
            reason: check.reason.clone(),
            terms,
            held_out_streaming: check.held_out[0],
            held_out_refined: check.held_out[1],
            free_run: check.free_run,
            samples_per_period: check.samples_per_period,
            support_changed: check.support_changed(omega),
        }
    }

    /// Lines for the text report after the equation, `unit` the recording's unit of x: why
    /// this model, its free run over the held-out half, and coarse sampling when found.
    pub fn render(&self, unit: &str) -> String {
        let mut out = String::new();
        out.push_str(&format!("  {}\n", self.reason));
        if let Some(change) = &self.support_changed {
            let list = |terms: &[String]| {
                if terms.is_empty() {
                    "none".to_owned()
                } else {
                    terms.join(", ")
                }
            };
            out.push_str(&format!(
                "  support changed from the streaming model's: added {}; removed {}\n",
                list(&change.added),
                list(&change.removed)
            ));
        }
        if let Some(f) = self.free_run {
            out.push_str(&format!(
                "  free run over the held-out half: NRMSE {:.2} %, RMS {:.4e} {unit}\n",
                f.nrmse_percent, f.rms
            ));
        }
        if let Some(spp) = self.samples_per_period
            && spp < 20.0
        {
            out.push_str(&format!(
                "  coarse sampling: {spp:.1} samples per period at the top of the band (derivatives from samples are biased there; the refined model is not)\n"
            ));
        }
        out
    }
}
