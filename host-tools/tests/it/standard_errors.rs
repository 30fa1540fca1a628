//! Error bars that mean what they say (issue 15, item 4): over seeds, the true coefficients
//! of the harvester of eq. 19 lie within 3 standard errors of the refined ones at least 9
//! times in 10, and the standard errors are not inflated to get there.
//!
//! The data is made in-process as `lssi gen eveh --observe x --delta 0.02 --seed S` would
//! (20 s at 2 kHz, x alone, 2 % noise), identified by the streaming identifier in f32 as
//! `lssi identify --family odd` does (so the excitation frequency Ω is the streaming
//! estimate, with its error), and refined on the whole record by `refine::refine`, the pass
//! `lssi identify --refine` reports (the held-out check, which only decides whether to
//! report it, is left out to keep the test short).

use lssi_core::PolyFamily;
use lssi_host::identify::refine::{self, Data, Settings};
use lssi_host::identify::simulate::SimModel;
use lssi_host::identify::{self, Options};
use lssi_host::synth::eveh::{EvehOptions, Wells, generate_eveh};

/// |refined − true| ÷ standard error of every true term (infinity for a term the streaming
/// selection missed: it counts as outside).
fn errors_in_standard_errors(wells: Wells, delta: f64, seed: u64) -> Vec<f64> {
    let options = EvehOptions {
        delta,
        seed,
        wells,
        ..EvehOptions::default()
    };
    let generated = generate_eveh(&options);
    let omega = generated.generated.truth.omega;
    let truth = generated.generated.truth.named_terms();
    let recording = generated.to_recording(format!("eveh-{delta}-{seed}"));
    let id_options = Options {
        family: PolyFamily::OddFamilies,
        f32: true,
        ..Options::default()
    };
    let report = identify::identify_recording(&recording, &id_options).expect("identifies");
    let streaming = SimModel::from_report(&report);
    let data = Data {
        t: &recording.t,
        x: &recording.x,
        u: None,
    };
    let refined = refine::refine(&streaming, &data, &Settings::for_data(&data)).expect("refines");
    assert_eq!(refined.standard_errors.len(), refined.model.terms.len());
    truth
        .iter()
        .map(|(name, want)| {
            refined
                .model
                .terms
                .iter()
                .zip(&refined.standard_errors)
                .find(|((term, _), _)| term.name(omega).to_string() == *name)
                .map_or(f64::INFINITY, |((_, got), se)| (got - want).abs() / se)
        })
        .collect()
}

#[test]
fn three_standard_errors_hold_the_truth_nine_times_in_ten_without_inflation() {
    let mut ratios: Vec<f64> = (1..=10u64)
        .flat_map(|seed| errors_in_standard_errors(Wells::Bistable, 0.02, seed))
        .collect();
    assert_eq!(ratios.len(), 40);
    let inside = ratios.iter().filter(|r| **r <= 3.0).count();
    ratios.sort_by(f64::total_cmp);
    let median = 0.5 * (ratios[19] + ratios[20]);
    eprintln!("within 3 se: {inside}/40; median |error|/se {median:.3}; ratios {ratios:.2?}");
    assert!(
        inside >= 36,
        "only {inside}/40 true values within 3 standard errors"
    );
    // Calibrated errors put the median near 0.67 (a normal's); far under it, they are inflated.
    assert!(
        median >= 0.2,
        "median |error|/se {median:.3}: the standard errors are inflated"
    );
}
