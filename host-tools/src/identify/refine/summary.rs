//! The `"refined"` object of `lssi identify --json`, and its lines in the text report.

use serde::Serialize;

use super::{Check, Chosen, Fit, Horizon, Paired};

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
    /// The horizon of the comparison: windows of the held-out half, each predicted from its
    /// own fitted state.
    pub horizon: Horizon,
    /// The reported model's prediction error over those windows.
    pub prediction: Option<Fit>,
    /// The paired comparison of the refined model with the streaming one over those windows
    /// (`gain`: the fraction of the streaming model's error removed; `z`: in standard errors).
    pub paired: Option<Paired>,
    /// Every support refined on the first half (the streaming one first): its terms with
    /// their coefficients and standard errors there, its prediction error over the held-out
    /// windows and its paired comparison with the streaming model.
    pub candidates: Vec<Candidate>,
    /// The reported model's free run over the whole held-out half (one fitted initial state):
    /// long-range behaviour, which a chaotic record shares with no model.
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

/// One support refined on the first half, as the `"refined"` object lists it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Candidate {
    /// Its terms, refined on the first half, with standard errors (NaN, `null` in the JSON,
    /// when its refinement failed).
    pub terms: Vec<TermSummary>,
    /// Its prediction error over the held-out windows.
    pub held_out: Option<Fit>,
    /// Its paired comparison with the streaming model there.
    pub paired: Option<Paired>,
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
            horizon: check.horizon,
            prediction: check.prediction,
            paired: check.paired,
            free_run: check.free_run,
            candidates: check
                .supports
                .iter()
                .map(|t| Candidate {
                    terms: match &t.refined {
                        Some(refined) => refined
                            .iter()
                            .map(|(term, coef, se)| TermSummary {
                                term: term.name(omega).to_string(),
                                coef: *coef,
                                se: Some(*se),
                            })
                            .collect(),
                        None => t
                            .terms
                            .iter()
                            .map(|term| TermSummary {
                                term: term.name(omega).to_string(),
                                coef: f64::NAN,
                                se: None,
                            })
                            .collect(),
                    },
                    held_out: t.held_out,
                    paired: t.paired,
                })
                .collect(),
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
        if let Some(f) = self.prediction {
            out.push_str(&format!(
                "  prediction of the held-out half over {:.3} s ({} windows of {} samples, each from its fitted state): NRMSE {:.2} %, RMS {:.4e} {unit}\n",
                self.horizon.seconds, self.horizon.windows, self.horizon.samples, f.nrmse_percent, f.rms
            ));
        }
        if let Some(f) = self.free_run {
            out.push_str(&format!(
                "  free run over the whole held-out half from one fitted state: NRMSE {:.2} %{}\n",
                f.nrmse_percent,
                if f.nrmse_percent > 2.0 * self.prediction.map_or(f64::INFINITY, |p| p.nrmse_percent) && f.nrmse_percent > 10.0 {
                    " (it parts from the recording: long-range prediction is not what this record allows)"
                } else {
                    ""
                }
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
