//! A chaotic record's one-way x'' calibrated on the record's electrical mean square (issue
//! 26, `system::calibrate`): a free run of a chaotic record samples its attractor, whose
//! energy the damping sets.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use lssi_host::recording::ColumnNames;
use lssi_host::system::calibrate::{TOLERANCE, calibrate_damping, ensemble_mean_square};
use lssi_host::system::simulate::{SimTerm, SystemSim};
use lssi_host::system::{ElectricalColumns, read_if_system};

use crate::common::{generate, truth};

/// A bistable piezo harvester driven into chaotic interwell motion (8 Hz, 2 m/s²: about 3
/// hops a second), 30 s at 1 kHz. Its true model with four times its damping (BistableX's
/// asymmetric record: the energy balance's damping 3.3 times the calibrated one, its free
/// runs harvesting half the recorded power) harvests 60 % of the record's ⟨V²⟩ in its free
/// runs; calibrated, the damping comes back towards the truth's and the free
/// runs' mean ⟨V²⟩ within the tolerance of the record's. (Not monotone: twice the truth's
/// damping harvests 8 % more than the truth's 1.05.)
#[test]
fn a_chaotic_records_damping_is_calibrated_on_its_harvested_power() {
    let dir = tempfile::tempdir().unwrap();
    let path = generate(
        dir.path(),
        "c.csv",
        &[
            "piezo",
            "--wells",
            "bistable",
            "--input",
            "--observe",
            "xv",
            "--amplitude",
            "2.0",
            "--rate",
            "1000",
            "--t-end",
            "30",
            "--seed",
            "3",
        ],
    );
    let data = read_if_system(
        &path,
        &ColumnNames::default(),
        &ElectricalColumns::default(),
    )
    .unwrap()
    .unwrap();
    let truth_sim = SystemSim::from_json(&truth(&path), "truth").unwrap();
    let v = SimTerm::Monomial([0, 1, 0, 0, 0, 0]);
    let at = truth_sim.equations[0]
        .iter()
        .position(|(t, _)| *t == v)
        .unwrap();
    let c_true = truth_sim.equations[0][at].1;
    let recorded = {
        let e = &data.electrical[0].values;
        e.iter().map(|q| q * q).sum::<f64>() / e.len() as f64
    };
    // The truth's free runs: within sampling error of the record (30 s, about 90 hops).
    let truth_ratio = ensemble_mean_square(&truth_sim, &data).unwrap() / recorded;
    assert!(
        (truth_ratio - 1.0).abs() < 0.1,
        "the truth's free runs: {truth_ratio}"
    );

    let mut damped = truth_sim.clone();
    damped.equations[0][at].1 = 4.0 * c_true;
    let c = calibrate_damping(&damped, &data).unwrap();
    assert!(c.ratio_before < 1.0 - TOLERANCE, "{c:?}");
    assert!((c.ratio_after - 1.0).abs() <= TOLERANCE, "{c:?}");
    assert!(
        (c.after - c_true).abs() < 0.5 * (c.before - c_true).abs(),
        "{c:?}, truth {c_true}"
    );
}
