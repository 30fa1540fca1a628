use lssi_core::PolyFamily;
use lssi_host::generators::eveh::{EvehOptions, generate_eveh};
use lssi_host::identify::{self, Options};
use lssi_host::refine::{self, Data};
use lssi_host::simulate::SimModel;
fn main() {
    let delta: f64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.05);
    let seed: u64 = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let wells = if std::env::var("MONO").is_ok() {
        lssi_host::generators::eveh::Wells::Monostable
    } else {
        lssi_host::generators::eveh::Wells::Bistable
    };
    let g = generate_eveh(&EvehOptions {
        delta,
        seed,
        wells,
        ..EvehOptions::default()
    });
    let rec = g.to_recording("x");
    let (config, est) = identify::configure(
        &rec,
        &Options {
            family: PolyFamily::OddFamilies,
            ..Options::default()
        },
    )
    .unwrap();
    let report = identify::run::<f32>(&rec, config, est).unwrap();
    let s = SimModel::from_report(&report);
    println!("streaming {:?} offsets {:?}", s.terms, s.offsets);
    let data = Data {
        t: &rec.t,
        x: &rec.x,
        u: None,
    };
    let n = rec.t.len();
    let settings = refine::Settings::for_data(&data);
    println!(
        "settings segment {} period {:?}",
        settings.segment,
        refine::mean_period_samples(&rec.x)
    );
    let truth = SimModel {
        terms: s.terms.iter().map(|(t, _)| (*t, 0.0)).collect(),
        ..s.clone()
    };
    let _ = truth;
    for (a, b) in [(0, n / 2), (0, n)] {
        let r = refine::refine(&s, &data.slice(a, b), &settings).unwrap();
        println!(
            "refined [{a},{b}) {:?} se {:?} rms {} it {}",
            r.model.terms.iter().map(|x| x.1).collect::<Vec<_>>(),
            r.standard_errors,
            r.rms,
            r.iterations
        );
    }
    let held = data.slice(n / 2, n);
    let r = refine::refine(&s, &data.slice(0, n / 2), &settings).unwrap();
    for mult in [1, 4, 16] {
        println!(
            "x{mult} held streaming {:?} refined {:?}",
            refine::prediction_fit(&s, &held, settings.segment * mult),
            refine::prediction_fit(&r.model, &held, settings.segment * mult)
        );
    }
}
