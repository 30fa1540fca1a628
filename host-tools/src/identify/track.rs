//! The identified coefficients over time, and the settle time after a change.
//!
//! [`track`] streams a recording through the identifier as [`crate::identify::run`] does, but
//! screens every [`TrackOptions::every`] seconds and keeps every model it selects (a
//! [`Snapshot`]). With a forgetting time constant (`Config::memory`) the estimates follow a
//! parameter drift; [`settle`] measures how long they took.
//!
//! **Settle time.** For a change at time t_c and a reference model (the true coefficients after
//! the change when a truth file says them, else the last snapshot's), the settle time is
//! t_s − t_c, where t_s is the time of the first snapshot at or after t_c from which on *every*
//! snapshot has exactly the reference's terms and every coefficient within `tolerance`
//! (relative) of the reference's. A snapshot's time is that of the sample whose arrival ran
//! the screening; the data in it end [`lssi_core::Identifier::lag_samples`] earlier, which
//! is part of the settle time, as it is on a device.
//!
//! ```
//! use lssi_core::Term;
//! use lssi_host::identify::track::{Snapshot, Track, settle};
//!
//! let x = Term::Monomial { px: 1, pv: 0 };
//! let track = Track {
//!     terms: vec![x],
//!     names: vec!["x".into()],
//!     omega: 1.0,
//!     snapshots: [(1.0, -1.0), (2.0, -1.5), (3.0, -1.98), (4.0, -2.01)]
//!         .iter()
//!         .map(|&(t, c)| Snapshot { t, coefficients: vec![c], resonance_hz: None, wells: None })
//!         .collect(),
//! };
//! let s = settle(&track, &[-2.0], 1.5, 0.05);
//! assert_eq!(s.settle_time, Some(1.5)); // from t = 3 on, within 5 % of -2
//! ```

use lssi_core::{Config, Identifier, Real, Sample, Term};
use serde::Serialize;

use crate::identify::{IdentifyError, TERM_CAPACITY, WINDOW_CAPACITY};
use crate::recording::Recording;
use crate::synth::eveh::round_digits;
use crate::synth::truth::Truth;

/// How to track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackOptions {
    /// Seconds between two screenings (snapshots).
    pub every: f64,
}

/// One selected model during the run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Snapshot {
    /// Time of the sample that ran the screening, seconds.
    pub t: f64,
    /// Coefficient of every library term, in [`Track::terms`] order (0: inactive).
    pub coefficients: Vec<f64>,
    /// Linear resonance, Hz (when ξ_x < 0).
    pub resonance_hz: Option<f64>,
    /// Well positions ±w for a double well.
    pub wells: Option<f64>,
}

/// The models selected over a run.
#[derive(Clone, Debug, PartialEq)]
pub struct Track {
    /// The library's terms, in column order.
    pub terms: Vec<Term>,
    /// Their names (with Ω).
    pub names: Vec<String>,
    /// Base angular frequency Ω, rad/s.
    pub omega: f64,
    /// The snapshots, in time order.
    pub snapshots: Vec<Snapshot>,
}

/// How long the estimates took to settle after a change; see the module documentation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Settle {
    /// The change's time t_c, seconds.
    pub change_at: f64,
    /// The time t_s from which on every snapshot is within the tolerance, if there is one.
    pub settled_at: Option<f64>,
    /// t_s − t_c, seconds.
    pub settle_time: Option<f64>,
    /// The relative tolerance.
    pub tolerance: f64,
}

impl Settle {
    /// The settle time as a sentence (`lssi identify --track` prints it on stderr), against
    /// `reference` (what the coefficients settle to, in words).
    pub fn sentence(&self, reference: &str) -> String {
        let s = self;
        let tol = 100.0 * s.tolerance;
        match (s.settled_at, s.settle_time) {
            (Some(at), Some(time)) => format!(
                "settled {time:.3} s after the change at {} s (from t = {at} s every coefficient stays within {tol} % of {reference}).",
                s.change_at
            ),
            _ => format!(
                "not settled: after the change at {} s the coefficients never stay within {tol} % of {reference} to the end of the record.",
                s.change_at
            ),
        }
    }
}

/// Streams `recording` through the identifier configured by `config`, screening every
/// `options.every` seconds, and returns every model selected.
pub fn track<T: Real>(
    recording: &Recording,
    config: Config,
    options: &TrackOptions,
) -> Result<Track, IdentifyError> {
    let file = recording.path.display();
    let period = (options.every / config.sample_period).round();
    let config = Config {
        screening_period: if period.is_finite() && period >= 1.0 {
            period.min(f64::from(u32::MAX)) as u32
        } else {
            1
        },
        ..config
    };
    let mut identifier: Identifier<T, WINDOW_CAPACITY, TERM_CAPACITY> =
        Identifier::new(config).map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    let terms: Vec<Term> = identifier.library().terms().to_vec();
    let names = terms
        .iter()
        .map(|t| t.name(config.omega).to_string())
        .collect();
    let mut snapshots = Vec::new();
    // Blemished samples are left out as `identify` leaves them out (`crate::identify::blemish`).
    // (a repaired spike as the cubic through its neighbours).
    let scan = crate::identify::blemish::Scan::of(recording);
    for (i, s) in recording.samples().enumerate() {
        let (x, v, u) = match scan.feed(i) {
            crate::identify::blemish::Feed::Skip => continue,
            crate::identify::blemish::Feed::AsIs => (s.x, s.v, s.u),
            crate::identify::blemish::Feed::Repaired(r) => (r.x, r.v, r.u),
        };
        let sample = Sample {
            t: s.t,
            x: T::from_f64(x),
            v: v.map(T::from_f64),
            u: u.map(T::from_f64),
        };
        // A rejected sample is counted by the identifier; it never stops the run.
        if let Ok(true) = identifier.push(sample)
            && let Some(model) = identifier.model()
        {
            snapshots.push(Snapshot {
                t: s.t,
                coefficients: model.coefficients[..terms.len()]
                    .iter()
                    .map(|c| c.to_f64())
                    .collect(),
                resonance_hz: model.resonance_hz(),
                wells: model.wells(),
            });
        }
    }
    if snapshots.is_empty() {
        return Err(IdentifyError(format!(
            "{file}: no model during the run: {} samples were accepted, too few regression rows for the {}-term library.",
            identifier.counters().accepted,
            terms.len()
        )));
    }
    Ok(Track {
        terms,
        names,
        omega: config.omega,
        snapshots,
    })
}

/// A key that matches a term across Ω estimates: `cos#1` for cos(Ωt), the name otherwise.
fn key(term: Term, omega: f64) -> String {
    match term {
        Term::Sin(k) => format!("sin#{k}"),
        Term::Cos(k) => format!("cos#{k}"),
        other => other.name(omega).to_string(),
    }
}

/// The same key for a truth term name: `cos(21.4t)` with the truth's Ω = 21.4 is `cos#1`.
fn truth_key(name: &str, omega: f64) -> String {
    for kind in ["sin", "cos"] {
        if let Some(inner) = name
            .strip_prefix(kind)
            .and_then(|r| r.strip_prefix('('))
            .and_then(|r| r.strip_suffix("t)"))
        {
            let w = if inner.is_empty() {
                Some(1.0)
            } else {
                inner.parse::<f64>().ok()
            };
            if let Some(w) = w
                && omega > 0.0
            {
                return format!("{kind}#{}", (w / omega).round());
            }
        }
    }
    name.to_owned()
}

/// The reference coefficients, in the track's term order, from a truth file: the terms after
/// its drift (`params.drift_after.terms_after`) if it has one, else its terms. Also returns
/// the drift's start time, if any. An error names a true term the library lacks.
pub fn reference_from_truth(
    truth: &Truth,
    track: &Track,
) -> Result<(Vec<f64>, Option<f64>), String> {
    let drift = truth.params.get("drift_after").filter(|d| !d.is_null());
    let after: Option<Vec<crate::synth::truth::TruthTerm>> = drift
        .and_then(|d| d.get("terms_after"))
        .and_then(|v| serde_json::from_value(v.clone()).ok());
    let change_at = drift.and_then(|d| d.get("at")).and_then(|v| v.as_f64());
    let terms = after.unwrap_or_else(|| truth.terms.clone());
    let keys: Vec<String> = track.terms.iter().map(|&t| key(t, track.omega)).collect();
    let mut reference = vec![0.0; keys.len()];
    for term in &terms {
        let k = truth_key(&term.term, truth.omega);
        let j = keys
            .iter()
            .position(|c| *c == k)
            .ok_or_else(|| format!("the true term '{}' is not in the library", term.term))?;
        reference[j] = term.coef;
    }
    Ok((reference, change_at))
}

/// Whether a snapshot matches the reference: the same active terms, and every coefficient
/// within `tolerance` of the reference's.
fn within(coefficients: &[f64], reference: &[f64], tolerance: f64) -> bool {
    coefficients.iter().zip(reference).all(|(&c, &r)| {
        if r == 0.0 {
            c == 0.0
        } else {
            (c - r).abs() <= tolerance * r.abs()
        }
    })
}

/// The settle time after a change at `change_at` (see the module documentation).
pub fn settle(track: &Track, reference: &[f64], change_at: f64, tolerance: f64) -> Settle {
    let mut settled_at = None;
    for s in track.snapshots.iter().filter(|s| s.t >= change_at) {
        if within(&s.coefficients, reference, tolerance) {
            settled_at.get_or_insert(s.t);
        } else {
            settled_at = None;
        }
    }
    Settle {
        change_at,
        settled_at,
        settle_time: settled_at.map(|t| t - change_at),
        tolerance,
    }
}

/// The track as CSV: `t`, one column per library term, `resonance_hz`, `wells` (empty when
/// there is none); values to 7 significant digits.
pub fn to_csv(track: &Track) -> String {
    let mut out = String::from("t");
    for name in &track.names {
        out.push(',');
        out.push_str(name);
    }
    out.push_str(",resonance_hz,wells\n");
    let digits = |v: f64| format!("{:?}", round_digits(v));
    let opt = |v: Option<f64>| v.map(digits).unwrap_or_default();
    for s in &track.snapshots {
        out.push_str(&format!("{:?}", s.t));
        for c in &s.coefficients {
            out.push(',');
            out.push_str(&digits(*c));
        }
        out.push_str(&format!(",{},{}\n", opt(s.resonance_hz), opt(s.wells)));
    }
    out
}

/// One JSON line per snapshot: `{"t": …, "terms": {"x": …, …}, "resonance_hz": …, "wells": …}`
/// with the active terms only.
pub fn to_json_lines(track: &Track) -> String {
    let mut out = String::new();
    for s in &track.snapshots {
        let terms: serde_json::Map<String, serde_json::Value> = track
            .names
            .iter()
            .zip(&s.coefficients)
            .filter(|(_, c)| **c != 0.0)
            .map(|(n, c)| (n.clone(), serde_json::json!(c)))
            .collect();
        let line = serde_json::json!({
            "t": s.t,
            "terms": terms,
            "resonance_hz": s.resonance_hz,
            "wells": s.wells,
        });
        out.push_str(&line.to_string());
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track_of(values: &[(f64, f64, f64)]) -> Track {
        Track {
            terms: vec![Term::Monomial { px: 1, pv: 0 }, Term::Cos(1)],
            names: vec!["x".into(), "cos(21.4001t)".into()],
            omega: 21.4001,
            snapshots: values
                .iter()
                .map(|&(t, a, b)| Snapshot {
                    t,
                    coefficients: vec![a, b],
                    resonance_hz: None,
                    wells: None,
                })
                .collect(),
        }
    }

    #[test]
    fn a_relapse_resets_the_settle_time() {
        let track = track_of(&[
            (1.0, -1.0, 1.0),
            (2.0, -2.0, 1.0),
            (3.0, -1.0, 1.0),
            (4.0, -2.0, 1.0),
            (5.0, -2.0, 1.0),
        ]);
        let s = settle(&track, &[-2.0, 1.0], 1.0, 0.01);
        assert_eq!(s.settled_at, Some(4.0));
        assert_eq!(s.settle_time, Some(3.0));
        // A spurious or missing term is not settled.
        let s = settle(&track, &[-2.0, 0.0], 1.0, 0.01);
        assert_eq!(s.settled_at, None);
    }

    #[test]
    fn truth_terms_match_across_omega_estimates() {
        assert_eq!(truth_key("cos(21.4t)", 21.4), "cos#1");
        assert_eq!(truth_key("sin(42.8t)", 21.4), "sin#2");
        assert_eq!(truth_key("cos(t)", 1.0), "cos#1");
        assert_eq!(truth_key("x^3", 21.4), "x^3");
        let track = track_of(&[(1.0, -1.0, 1.0)]);
        let truth: Truth = serde_json::from_str(
            r#"{"model": "m", "target": "x''", "omega": 21.4,
                "terms": [{"term": "x", "coef": -3.0}, {"term": "cos(21.4t)", "coef": 0.5}],
                "params": {"drift_after": {"at": 7.0,
                    "terms_after": [{"term": "x", "coef": -4.0}, {"term": "cos(21.4t)", "coef": 0.5}]}},
                "noise": {"kind": "gauss", "delta": 0.0, "offset_x": 0.0, "rms_x": 0.0}}"#,
        )
        .unwrap();
        assert_eq!(
            reference_from_truth(&truth, &track),
            Ok((vec![-4.0, 0.5], Some(7.0)))
        );
    }
}
