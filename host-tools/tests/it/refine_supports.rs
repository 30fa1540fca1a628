//! Refinement over the sweep's supports (issue 15): at 10 % measurement noise on x alone the
//! streaming selection can lose a true term of the harvester of eq. 19 (the damping, on
//! monostable seed 1: a 100 % error for that term), and refining the support it selected
//! cannot bring it back. `lssi identify` refines the neighbouring solutions of the sweep too
//! and takes the sparsest that predicts the held-out half as well as the best: here the true
//! support, every coefficient within a few per cent, and the change named in the JSON.
//!
//! The data is made in-process as `lssi gen eveh --observe x --delta 0.1 --seed 1 --wells
//! monostable` would (20 s at 2 kHz), identified in f32 as `lssi identify --family odd` does,
//! and refined as `lssi identify` refines (one seed: a few seconds in the test profile).

use lssi_core::PolyFamily;
use lssi_host::identify::refine::{self, Chosen, Data, Summary};
use lssi_host::identify::simulate::SimModel;
use lssi_host::identify::supports::Candidates;
use lssi_host::identify::{self, Options};
use lssi_host::synth::eveh::{EvehOptions, Wells, generate_eveh};

#[test]
fn the_term_the_streaming_selection_lost_at_10_percent_noise_is_recovered() {
    let options = EvehOptions {
        delta: 0.1,
        seed: 1,
        wells: Wells::Monostable,
        ..EvehOptions::default()
    };
    let generated = generate_eveh(&options);
    let omega = generated.generated.truth.omega;
    let truth = generated.generated.truth.named_terms();
    let recording = generated.to_recording("eveh-0.1-1".to_owned());
    let id_options = Options {
        family: PolyFamily::OddFamilies,
        f32: true,
        ..Options::default()
    };
    let report = identify::identify_recording(&recording, &id_options).expect("identifies");
    let named = |m: &SimModel| -> Vec<(String, f64)> {
        m.terms
            .iter()
            .filter(|(_, c)| *c != 0.0)
            .map(|(t, c)| (t.name(omega).to_string(), *c))
            .collect()
    };
    let streaming = SimModel::from_report(&report);
    let lost: Vec<String> = truth
        .iter()
        .filter(|(name, _)| !named(&streaming).iter().any(|(n, _)| n == name))
        .map(|(name, _)| name.clone())
        .collect();
    let data = Data {
        t: &recording.t,
        x: &recording.x,
        u: None,
    };
    let check =
        refine::refine_and_check_among(&streaming, &Candidates::of(&report, [0.0, 0.0]), &data);
    assert_eq!(check.chosen, Chosen::Refined, "{}", check.reason);
    // The true support, no more and no less, each coefficient within 5 % (mean within 2 %).
    let refined = named(&check.model);
    let mut got: Vec<&str> = refined.iter().map(|(n, _)| n.as_str()).collect();
    let mut want: Vec<&str> = truth.iter().map(|(n, _)| n.as_str()).collect();
    got.sort_unstable();
    want.sort_unstable();
    assert_eq!(got, want, "{}", check.reason);
    let errors: Vec<f64> = truth
        .iter()
        .map(|(name, want)| {
            let (_, c) = refined
                .iter()
                .find(|(n, _)| n == name)
                .expect("a true term");
            100.0 * ((c - want) / want).abs()
        })
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    eprintln!("lost by streaming: {lost:?}; refined errors {errors:.2?} %, mean {mean:.2} %");
    assert!(errors.iter().all(|e| *e < 5.0), "{errors:?}");
    assert!(mean <= 2.0, "{errors:?}");
    // What was added is said (in the JSON's "refined" object and the text), and only then.
    let summary = Summary::of(&check, report.omega);
    let json = serde_json::to_value(&summary).expect("serialises");
    match &summary.support_changed {
        Some(change) => {
            assert_eq!(change.added, lost, "{json}");
            assert!(change.removed.is_empty(), "{json}");
            assert_eq!(json["support_changed"]["added"][0], lost[0].as_str());
            assert!(summary.render("m").contains("support changed"));
        }
        None => {
            assert!(lost.is_empty(), "{json}");
            assert!(json.get("support_changed").is_none());
        }
    }
}
