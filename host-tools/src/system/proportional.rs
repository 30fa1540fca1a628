//! A harvester whose electrical channel is proportional to the velocity (an electromagnetic
//! coil of negligible inductance, V = R Φ v / (R_c + R); or any transducer whose time
//! constant is far under the forcing's radian period): its model is `x'' = f(x, v, t, u)`
//! over the mechanical library and the algebraic equation `V = c v` (issue 26: "V
//! proportional to x' when the inductance is negligible").
//!
//! Such a channel has no dynamics of its own for an equation V' to identify (V' = c x'' is a
//! copy of the mechanical equation), and the coupling χ V in x'' is c χ v: indistinguishable
//! from the beam's damping. What a harvester designer can use is therefore
//!
//! - x'' as `lssi identify` gives it for the mechanical channels alone (the single-equation
//!   pipeline: its streaming identifier, refinement and quality gate), its v coefficient the
//!   beam's damping and the electrical damping together (only their sum acts on the motion,
//!   and the report says so); and
//! - `V = (c ± se) v`, the least-squares proportion over the standard errors' regression rows
//!   (Savitzky–Golay estimates over disjoint derivative windows, [`super::report::proportional`]),
//!   printed as an algebraic equation (target `V`, no prime; `--json`'s `"equations"` keeps
//!   its contract: `{"target": "V", "terms": [{"term": "v", "coef": c, "se": se}]}`).
//!
//! The system's gate then runs on this model ([`super::quality::assess`]: bounded free run,
//! every recorded state followed over the record's second half, V computed from the simulated
//! v), after the single equation's own gate; either failing withholds the model. A channel
//! is taken as proportional when the proportion leaves at most
//! [`super::quality::PROPORTIONAL_NRMSE`] of its RMS (a lag under 3°), on every electrical
//! channel of a one-displacement recording with x recorded (a velocity alone, integrated, is
//! withheld as before: see [`follows_velocity`]); anything else (an inductive coil, a piezo)
//! takes the system's path unchanged.

use serde::Serialize;

use super::report::{EquationReport, SystemReport};
use super::{Outcome, SystemArgs, SystemData};
use crate::error::CliError;
use crate::identify::pipeline::{self, Failure, Refine};
use crate::identify::{Options, SolutionReport, TermReport};

/// An electrical channel as a multiple of the velocity.
#[derive(Clone, Debug, PartialEq)]
pub struct Proportion {
    /// Its index among the recording's electrical channels.
    pub channel: usize,
    /// c in `V = c v`.
    pub coef: f64,
    /// c's standard error.
    pub se: f64,
    /// The fit's residual RMS over the channel's RMS (0.01 = 1 %).
    pub nrmse: f64,
}

/// What the report says of an algebraic electrical equation (`--json`'s `"algebraic"`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Algebraic {
    /// The channel: `V` or `i`.
    pub channel: String,
    /// The proportion's residual RMS, % of the channel's RMS.
    pub nrmse_percent: f64,
    /// What x''s v coefficient holds, in one sentence.
    pub damping: String,
}

/// Each electrical channel's proportion to the (first) velocity, over the standard errors'
/// rows; `None` for a channel without rows.
pub fn proportions(dt: f64, data: &SystemData) -> Vec<Option<Proportion>> {
    data.electrical
        .iter()
        .enumerate()
        .take(2)
        .map(|(k, _)| {
            let (coef, se, nrmse) = super::report::proportional(dt, data, 2 + k, 1)?;
            Some(Proportion {
                channel: k,
                coef,
                se,
                nrmse,
            })
        })
        .collect()
}

/// The proportions when every electrical channel of a one-displacement recording follows the
/// velocity within [`super::quality::PROPORTIONAL_NRMSE`]; else `None`.
pub fn follows_velocity(dt: f64, data: &SystemData) -> Option<Vec<Proportion>> {
    // A velocity recorded without a displacement stays on the system's path (withheld with
    // the proportion): x integrated from v, its drift removed, gives the single equation
    // spurious terms (v², x², a sine of the forcing) that its gate passes (`lssi gen
    // electromagnetic --coil negligible --observe v`, seeds 200-235: 5 of 12 such models
    // wrong, every one with x recorded right or withheld).
    if data.second.is_some() || data.electrical.is_empty() || data.x_from_v.is_some() {
        return None;
    }
    proportions(dt, data)
        .into_iter()
        .map(|p| p.filter(|p| p.nrmse <= super::quality::PROPORTIONAL_NRMSE))
        .collect()
}

/// The sentence saying what x''s v coefficient holds.
fn damping_sentence(names: &str) -> String {
    format!(
        "the v coefficient of x'' is the beam's damping and the electrical damping together (the coupling's reaction χ {names} is a multiple of v, so only their sum acts on the motion and the record cannot part them)"
    )
}

/// A recording whose electrical channels follow the velocity: x'' over the mechanical library
/// (the single-equation pipeline), each channel's algebraic equation, the system's gate and,
/// with `--load-ohms`, the harvester's analysis. `None` when a channel does not follow the
/// velocity (the system's path then goes on). `streaming` is the system identifier's report,
/// for its sample period and counts.
pub fn identify(
    data: &SystemData,
    options: &Options,
    args: &SystemArgs,
    no_refine: bool,
    streaming: &SystemReport,
) -> Result<Option<Outcome>, CliError> {
    let Some(found) = follows_velocity(streaming.sample_period, data) else {
        return Ok(None);
    };
    let refine = if no_refine {
        Refine::No("not refined (--no-refine)")
    } else {
        Refine::Yes
    };
    let (single, refined, warnings, withheld) =
        match pipeline::identify(&data.recording, options, refine) {
            Ok(done) => (done.report, done.refined, done.warnings, None),
            Err(Failure::Withheld(sentence, reasons, report)) => {
                (*report, None, reasons, Some(sentence))
            }
            Err(Failure::Error(e)) => return Err(CliError::Identify(e)),
        };
    let mut report = of_single(&single, refined.as_ref(), &found, data, streaming);
    report.coupling_order = args.coupling_order;
    report.warnings.extend(warnings);
    let names = found
        .iter()
        .map(|p| data.electrical[p.channel].kind.symbol())
        .collect::<Vec<_>>()
        .join(" and ");
    if let Some(sentence) = withheld {
        // The mechanical equation failed its own gate: the harvester's model is withheld,
        // saying which channel was found proportional.
        let sentence = format!(
            "{} ({names} is proportional to v on this recording, {}; x'' is the single equation of the mechanical channels, and that is withheld)",
            sentence.trim_end_matches('.'),
            proportions_text(&found, data)
        );
        return Ok(Some(Outcome::Withheld(
            format!("{sentence}."),
            Box::new(report),
        )));
    }
    let mut quality = super::quality::assess(&report, data);
    // x'' about one well of a double well: about its centre of symmetry where that predicts
    // as well (super::symmetric).
    if let Some((symmetric, q)) = super::symmetric::recentre(&report, &quality, data) {
        report = symmetric;
        quality = q;
    }
    report.warnings.extend(quality.warnings.iter().cloned());
    if !quality.passed() {
        let sentence = super::quality::refusal(data, &quality);
        report.warnings.extend(quality.failures.iter().cloned());
        report.quality = Some(quality);
        return Ok(Some(Outcome::Withheld(sentence, Box::new(report))));
    }
    report.quality = Some(quality);
    if let Some(r) = args.load_ohms {
        report.harvester = Some(super::power::harvester(&report, data, r, args.coil_ohms));
    }
    Ok(Some(Outcome::Passed(Box::new(report))))
}

/// `V = (c ± se) v, within n % of V's RMS`, for each channel.
fn proportions_text(found: &[Proportion], data: &SystemData) -> String {
    found
        .iter()
        .map(|p| {
            let name = data.electrical[p.channel].kind.symbol();
            format!(
                "{name} = ({:.4e} ± {:.1e}) v within {:.1} % of {name}'s RMS",
                p.coef,
                p.se,
                100.0 * p.nrmse
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The system's report of the single equation `single` and the algebraic equations `found`.
fn of_single(
    single: &crate::identify::Report,
    refined: Option<&crate::identify::refine::Summary>,
    found: &[Proportion],
    data: &SystemData,
    streaming: &SystemReport,
) -> SystemReport {
    let mut equations = vec![EquationReport {
        target: "x''".into(),
        terms: Vec::new(),
        solutions: single.solutions.clone(),
        selected: single.selected,
    }];
    for p in found {
        let name = data.electrical[p.channel].kind.symbol();
        equations.push(EquationReport {
            target: name.to_owned(),
            terms: vec![TermReport {
                term: "v".into(),
                coef: p.coef,
                se: p.se.is_finite().then_some(p.se),
            }],
            solutions: vec![SolutionReport {
                threshold: 0.0,
                mean_error: p.nrmse * p.nrmse,
                terms: vec!["v".into()],
            }],
            selected: 0,
        });
    }
    let names = found
        .iter()
        .map(|p| data.electrical[p.channel].kind.symbol())
        .collect::<Vec<_>>()
        .join(" and ");
    let chosen = match refined {
        Some(s) if s.chosen == crate::identify::refine::Chosen::Refined => "refined",
        _ => "streaming",
    };
    let note = match refined {
        Some(s) => format!(
            "x'' is the single equation of the mechanical channels, as `lssi identify` gives it without {names} ({}); {names} by least squares on v",
            s.reason.trim_end_matches('.')
        ),
        None => format!(
            "x'' is the single equation of the mechanical channels, as `lssi identify` gives it without {names} (not refined: the streaming identifier's model); {names} by least squares on v"
        ),
    };
    let rows = "a least-squares fit on rows a derivative window apart (Savitzky–Golay estimates over disjoint windows), σ² (AᵀA)⁻¹";
    let mut mechanical = single.terms.clone();
    let standard_errors = if mechanical.iter().all(|t| t.se.is_some()) {
        format!(
            "x'': standard errors of the refinement on simulation error; {names}: {rows}; they do not cover the selection"
        )
    } else if least_squares_se(&mut mechanical, data, single.sample_period) {
        format!("every equation's: {rows}; they do not cover the selection")
    } else {
        format!("x'': none (too few rows or collinear terms); {names}: {rows}")
    };
    let warnings: Vec<String> = data.x_from_v.iter().cloned().collect();

    equations[0].terms = mechanical;
    SystemReport {
        equations,
        model: chosen.into(),
        refinement: None,
        note,
        states: streaming.states.clone(),
        x_from_v: data.x_from_v.clone(),
        omega: single.omega,
        omega_estimated: single.omega_estimated,
        samples: single.samples,
        rejected: single.rejected,
        window: single.window,
        degree: single.degree,
        test_rows: single.test_rows,
        sample_period: single.sample_period,
        precision: single.precision.clone(),
        coupling_order: streaming.coupling_order,
        standard_errors,
        harvester: None,
        quality: None,
        offsets: (single.offsets != [0.0, 0.0]).then_some(single.offsets),
        reference: None,
        algebraic: Some(Algebraic {
            channel: names.clone(),
            nrmse_percent: 100.0 * found.iter().map(|p| p.nrmse).fold(0.0, f64::max),
            damping: damping_sentence(&names),
        }),
        one_way: None,
        warnings,
        rejections: single.rejections.clone(),
    }
}

/// Fills in the standard errors of x'''s `terms` from a least-squares fit on the system's
/// regression rows ([`super::report::refit`]); false when there is none.
pub fn least_squares_se(terms: &mut [TermReport], data: &SystemData, dt: f64) -> bool {
    use super::simulate::SimTerm;
    let parsed: Option<Vec<SimTerm>> = terms.iter().map(|t| SimTerm::parse(&t.term, &[])).collect();
    let Some((_, se)) = parsed.and_then(|p| super::report::refit(dt, data, 0, &p)) else {
        return false;
    };
    for (t, s) in terms.iter_mut().zip(se) {
        t.se = s.is_finite().then_some(s);
    }
    true
}
