//! Coefficient error against measurement noise, from x alone, on the harvester of eq. 19
//! (`lssi gen eveh --observe x --delta D --seed S [--wells monostable]`, 20 s at 2 kHz): the streaming
//! model (f32, as on a device; `lssi identify --family odd`) and the model refined on
//! simulation error as `lssi identify` refines it (`lssi_host::identify::refine`: the
//! streaming support and the sweep's solutions one term away from it, the sparsest that
//! predicts the held-out half as well as the best), over seeds 1–5 at each noise level.
//!
//!     cargo run --release -p lssi-host --example refine_noise
//!
//! Mean coefficient error in % over the true terms (100 for a missed one), spurious terms,
//! the share of coefficients whose refined value lies within 3 standard errors of the truth,
//! and the median of |refined − true| ÷ standard error (about 0.67 when the errors are
//! calibrated: far under it they are inflated, far over it too small).
//!
//! `LSSI_DELTAS=0.01,0.02` runs some noise levels, `LSSI_WELLS=bistable` one configuration,
//! `LSSI_SEEDS=6,7,8` runs other seeds than 1–5. `LSSI_VERBOSE=1` prints each seed's truth, streaming and refined models, and every support
//! refined with its held-out simulation error and the significance (|coefficient| ÷ standard
//! error) of the terms it adds.

use lssi_core::PolyFamily;
use lssi_host::identify::refine::{self, Chosen, Data};
use lssi_host::identify::simulate::SimModel;
use lssi_host::identify::supports::Candidates;
use lssi_host::identify::{self, Options};
use lssi_host::synth::eveh::{EvehOptions, Wells, generate_eveh};

struct Score {
    mean: f64,
    spurious: usize,
}

/// Terms named at the truth's Ω (an estimated Ω of 21.4001 rad/s is the same cos term).
fn score(model: &SimModel, truth: &[(String, f64)], omega: f64) -> Score {
    let named: Vec<(String, f64)> = model
        .terms
        .iter()
        .filter(|(_, c)| *c != 0.0)
        .map(|(t, c)| (t.name(omega).to_string(), *c))
        .collect();
    let errors: Vec<f64> = truth
        .iter()
        .map(|(name, want)| {
            named
                .iter()
                .find(|(n, _)| n == name)
                .map_or(100.0, |(_, got)| 100.0 * ((got - want) / want).abs())
        })
        .collect();
    Score {
        mean: errors.iter().sum::<f64>() / errors.len() as f64,
        spurious: named
            .iter()
            .filter(|(n, _)| !truth.iter().any(|(t, _)| t == n))
            .count(),
    }
}

fn main() {
    let wells_wanted = std::env::var("LSSI_WELLS").ok();
    for wells in [Wells::Monostable, Wells::Bistable] {
        if wells_wanted
            .as_deref()
            .is_some_and(|w| !format!("{wells:?}").eq_ignore_ascii_case(w))
        {
            continue;
        }
        println!("\n{wells:?}:\n");
        println!(
            "| noise δ | streaming f32: mean % (worst seed), spurious | refined: mean % (worst seed), spurious | refined taken | truth within 3 se | median \\|error\\|/se |"
        );
        println!("|---:|---|---|---:|---:|---:|");
        // `LSSI_DELTAS=0.05,0.1` for a part of the table.
        let deltas: Vec<f64> = std::env::var("LSSI_DELTAS")
            .ok()
            .map(|s| s.split(',').filter_map(|d| d.parse().ok()).collect())
            .unwrap_or_else(|| vec![0.0, 0.01, 0.02, 0.05, 0.10]);
        // `LSSI_SEEDS=6,7,8` for other seeds than the table's 1–5 (a check that the
        // choice's thresholds, set looking at seeds 1–5, hold on others).
        let seeds: Vec<u64> = std::env::var("LSSI_SEEDS")
            .ok()
            .map(|s| s.split(',').filter_map(|d| d.parse().ok()).collect())
            .unwrap_or_else(|| (1..=5).collect());
        for &delta in &deltas {
            let (mut s_all, mut r_all) = (Vec::new(), Vec::new());
            let (mut s_sp, mut r_sp, mut taken, mut inside, mut counted) = (0, 0, 0, 0, 0);
            let mut ratios: Vec<f64> = Vec::new();
            for &seed in &seeds {
                let options = EvehOptions {
                    delta,
                    seed,
                    wells,
                    ..EvehOptions::default()
                };
                let generated = generate_eveh(&options);
                let truth = generated.generated.truth.named_terms();
                let recording = generated.to_recording(format!("eveh-{delta}-{seed}"));
                let id_options = Options {
                    family: PolyFamily::OddFamilies,
                    f32: true,
                    ..Options::default()
                };
                let report = match identify::identify_recording(&recording, &id_options) {
                    Ok(report) => report,
                    Err(e) => {
                        println!("seed {seed}, δ {delta}: no model: {e}");
                        continue;
                    }
                };
                let streaming = SimModel::from_report(&report);
                let data = Data {
                    t: &recording.t,
                    x: &recording.x,
                    u: None,
                };
                let candidates = Candidates::of(&report, [0.0, 0.0]);
                let check = refine::refine_and_check_among(&streaming, &candidates, &data);
                let omega = generated.generated.truth.omega;
                let s = score(&streaming, &truth, omega);
                let r = score(&check.model, &truth, omega);
                if std::env::var_os("LSSI_VERBOSE").is_some() {
                    let names = |m: &SimModel| -> Vec<String> {
                        m.terms
                            .iter()
                            .filter(|(_, c)| *c != 0.0)
                            .map(|(t, c)| format!("{}={c:.4}", t.name(omega)))
                            .collect()
                    };
                    println!(
                        "seed {seed}: truth {truth:?}\n  streaming {:.2} % {:?}\n  refined {:.2} % {:?} ({})",
                        s.mean,
                        names(&streaming),
                        r.mean,
                        names(&check.model),
                        check.reason
                    );
                    for tried in &check.supports {
                        let names: Vec<String> = tried
                            .terms
                            .iter()
                            .map(|t| t.name(omega).to_string())
                            .collect();
                        let sig = &tried.added_significance;
                        match tried.held_out {
                            Some(f) => println!("  {:.5} % {names:?} {sig:.1?}", f.nrmse_percent),
                            None => println!("  no fit {names:?}"),
                        }
                    }
                }
                s_all.push(s.mean);
                r_all.push(r.mean);
                s_sp += s.spurious;
                r_sp += r.spurious;
                if check.chosen == Chosen::Refined {
                    taken += 1;
                }
                if let Some(se) = &check.standard_errors {
                    for ((term, c), se) in check.model.terms.iter().zip(se) {
                        let name = term.name(omega).to_string();
                        if let Some((_, want)) = truth.iter().find(|(n, _)| *n == name) {
                            counted += 1;
                            ratios.push((c - want).abs() / se);
                            if (c - want).abs() <= 3.0 * se {
                                inside += 1;
                            }
                        }
                    }
                }
            }
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
            let worst = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
            ratios.sort_by(f64::total_cmp);
            let median = match ratios.len() {
                0 => "–".to_owned(),
                m => format!("{:.2}", 0.5 * (ratios[(m - 1) / 2] + ratios[m / 2])),
            };
            println!(
                "| {:.0} % | {:.3} ({:.3}), {} | {:.3} ({:.3}), {} | {}/{} | {}/{} | {} |",
                100.0 * delta,
                mean(&s_all),
                worst(&s_all),
                s_sp,
                mean(&r_all),
                worst(&r_all),
                r_sp,
                taken,
                seeds.len(),
                inside,
                counted,
                median
            );
        }
    }
}
