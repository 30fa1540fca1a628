//! `lssi simulate MODEL.json FILE.csv`: the equation `lssi identify --json` printed, simulated
//! over a recording's time grid from its first state, driven by its `u` column when the model
//! has a `u` term: prediction from the excitation alone. Prints the error against the file's
//! `x` (RMS, NRMSE) and, with `--out`, writes the simulated x.

use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;
use crate::identify::refine::{self, Data};
use crate::identify::simulate::SimModel;
use crate::identify::supports::term_named;
use crate::recording::{ColumnNames, Recording};

/// Arguments of `lssi simulate`.
#[derive(Debug, Clone, Args)]
pub struct SimulateArgs {
    /// The model: the object `lssi identify --json` prints (its `terms`, `omega` and `offsets`).
    #[arg(value_name = "MODEL.json")]
    pub model: PathBuf,
    /// The recording whose time grid (and `u`, when the model has a `u` term) drives the
    /// simulation; its `x` is what the simulation is compared with.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
    /// The initial state "x0,v0" in the recording's units (default: x from the first row, v
    /// from the `v` column or 0).
    #[arg(long, value_name = "X0,V0", allow_hyphen_values = true)]
    pub initial: Option<String>,
    /// Writes t, the simulated x and the recorded x here (CSV).
    #[arg(long, value_name = "OUT.csv")]
    pub out: Option<PathBuf>,
    /// A system's electrical channels and load (issue 26; see crate::system).
    #[command(flatten)]
    pub system: crate::system::SimulateSystemArgs,
}

/// The model of an `lssi identify --json` object.
pub fn model_from_json(text: &str, path: &str) -> Result<SimModel, CliError> {
    let bad = |why: String| CliError::Input(format!("{path}: {why}."));
    let value: serde_json::Value = serde_json::from_str(text.lines().next().unwrap_or(""))
        .map_err(|e| bad(format!("not the JSON `lssi identify --json` prints ({e})")))?;
    if value.get("withheld").and_then(|w| w.as_bool()) == Some(true) {
        return Err(bad(
            "this model was withheld by the quality gate, so there is nothing to simulate".into(),
        ));
    }
    let omega = value
        .get("omega")
        .and_then(|w| w.as_f64())
        .ok_or_else(|| bad("it has no \"omega\"".into()))?;
    let offsets = value
        .get("offsets")
        .and_then(|o| o.as_array())
        .and_then(|o| Some([o.first()?.as_f64()?, o.get(1)?.as_f64()?]))
        .unwrap_or([0.0, 0.0]);
    let terms = value
        .get("terms")
        .and_then(|t| t.as_array())
        .ok_or_else(|| bad("it has no \"terms\" list".into()))?;
    let mut model = Vec::with_capacity(terms.len());
    for t in terms {
        let name = t
            .get("term")
            .and_then(|n| n.as_str())
            .ok_or_else(|| bad("a term has no \"term\" name".into()))?;
        let coef = t
            .get("coef")
            .and_then(|c| c.as_f64())
            .ok_or_else(|| bad(format!("the term {name} has no numeric \"coef\"")))?;
        let term = term_named(name, omega)
            .ok_or_else(|| bad(format!("the term {name:?} is not one lssi knows")))?;
        model.push((term, coef));
    }
    if model.is_empty() {
        return Err(bad("its model has no terms".into()));
    }
    Ok(SimModel {
        terms: model,
        omega,
        offsets,
    })
}

/// Runs `lssi simulate`.
pub fn run(args: &SimulateArgs) -> Result<(), CliError> {
    let text = std::fs::read_to_string(&args.model).map_err(|e| {
        CliError::Input(format!(
            "{}: cannot read the model ({e}).",
            args.model.display()
        ))
    })?;
    // A system's model (issue 26): its own free run (crate::system::simulate).
    if let Ok(value) = serde_json::from_str::<serde_json::Value>(text.lines().next().unwrap_or(""))
        && value.get("equations").is_some()
    {
        let path = args.model.display().to_string();
        if let Some(initial) = &args.initial {
            return Err(CliError::BadFlag {
                flag: "--initial",
                value: initial.clone(),
                requirement:
                    "left out for a system's model (its initial state is the file's first row)"
                        .into(),
            });
        }
        let out = args.out.as_deref();
        return crate::system::simulate::simulate_command(
            &value,
            &path,
            &args.file,
            &args.columns,
            &args.system,
            out,
        );
    }
    let model = model_from_json(&text, &args.model.display().to_string())?;
    let recording = Recording::read(&args.file, &args.columns)?;
    let file = args.file.display();
    if model.uses_input() && recording.u.is_none() {
        return Err(CliError::Input(format!(
            "{file}: the model has a u term but the file has no u column (--u-col names it)."
        )));
    }
    let n = recording.len();
    if n < 2 {
        return Err(CliError::Input(format!(
            "{file}: {n} row(s); a simulation needs two at least."
        )));
    }
    if let Some(i) = (0..n).find(|&i| {
        !recording.t[i].is_finite()
            || recording.u.as_ref().is_some_and(|u| !u[i].is_finite())
            || (i > 0 && recording.t[i] <= recording.t[i - 1])
    }) {
        return Err(CliError::Input(format!(
            "{file}: data row {} has a non-finite or non-increasing t, or a non-finite u; a simulation needs a clean time grid and input.",
            i + 1
        )));
    }
    let start = match &args.initial {
        Some(text) => {
            let parts: Vec<Option<f64>> = text
                .split(',')
                .map(|p| p.trim().parse::<f64>().ok())
                .collect();
            match parts.as_slice() {
                [Some(x), Some(v)] if x.is_finite() && v.is_finite() => (*x, *v),
                _ => {
                    return Err(CliError::BadFlag {
                        flag: "--initial",
                        value: text.clone(),
                        requirement: "two finite numbers \"x0,v0\"".into(),
                    });
                }
            }
        }
        None => (recording.x[0], recording.v.as_ref().map_or(0.0, |v| v[0])),
    };
    let data = Data {
        t: &recording.t,
        x: &recording.x,
        u: recording.u.as_deref(),
    };
    let simulated = refine::free_run(&model, &data, start).ok_or_else(|| {
        CliError::Input(format!(
            "{file}: the model's simulation diverges on this recording."
        ))
    })?;
    let finite: Vec<usize> = (0..n).filter(|&i| recording.x[i].is_finite()).collect();
    let rss: f64 = finite
        .iter()
        .map(|&i| (simulated[i] - recording.x[i]).powi(2))
        .sum();
    let count = finite.len().max(1) as f64;
    let mean = finite.iter().map(|&i| recording.x[i]).sum::<f64>() / count;
    let sd = (finite
        .iter()
        .map(|&i| (recording.x[i] - mean).powi(2))
        .sum::<f64>()
        / count)
        .sqrt();
    let rms = (rss / count).sqrt();
    crate::outln!(
        "simulated {n} samples from (x0, v0) = ({}, {}){}: RMS error {rms:.6e} [x], NRMSE {:.3} %",
        start.0,
        start.1,
        if model.uses_input() {
            ", driven by u"
        } else {
            ""
        },
        100.0 * rms / sd
    );
    if let Some(out) = &args.out {
        let mut text = String::from("t,x_simulated,x\n");
        for i in 0..n {
            text.push_str(&format!(
                "{},{},{}\n",
                recording.t[i], simulated[i], recording.x[i]
            ));
        }
        std::fs::write(out, text).map_err(|e| {
            CliError::Input(format!(
                "{}: cannot write the simulation ({e}).",
                out.display()
            ))
        })?;
    }
    Ok(())
}
