//! Every call into `lssi-host` (the `lssi` command's library) is in this file, so that the
//! package follows the command when its modules move.

use std::path::PathBuf;

use lssi_core::{Config, Identifier, Real, Sample};
pub use lssi_host::identify::Options;
pub use lssi_host::identify::Report;
use lssi_host::identify::simulate::{self, SimModel};
use lssi_host::identify::{self, TERM_CAPACITY};
use lssi_host::recording::{ColumnNames, Recording};

/// The ring-buffer capacity `lssi identify` runs with.
pub use lssi_host::identify::WINDOW_CAPACITY;

/// The columns of a recording held in memory.
pub struct Columns {
    /// Name the error messages give the data (a file name, or "array").
    pub name: String,
    /// Times, seconds.
    pub t: Vec<f64>,
    /// Displacement.
    pub x: Vec<f64>,
    /// Velocity, when measured.
    pub v: Option<Vec<f64>>,
    /// Excitation, when measured.
    pub u: Option<Vec<f64>>,
}

fn recording(c: Columns) -> Recording {
    let columns = ColumnNames {
        t: "t".into(),
        x: "x".into(),
        v: c.v.as_ref().map(|_| "v".into()),
        u: c.u.as_ref().map(|_| "u".into()),
    };
    Recording {
        path: PathBuf::from(c.name),
        t: c.t,
        x: c.x,
        v: c.v,
        u: c.u,
        columns,
    }
}

/// Reads a recording file as `lssi identify` does (columns t, x and, when present, v and u).
pub fn read(path: &str) -> Result<Columns, String> {
    // v and u are taken when the header has them, as the command does by default.
    let r = Recording::read(path, &ColumnNames::default()).map_err(|e| e.to_string())?;
    Ok(Columns {
        name: path.to_string(),
        t: r.t,
        x: r.x,
        v: r.v,
        u: r.u,
    })
}

/// `lssi identify`'s configuration for these columns and options, and whether Ω was estimated.
pub fn configure(c: &Columns, options: &Options) -> Result<(Config, bool), String> {
    let r = recording(Columns {
        name: c.name.clone(),
        t: c.t.clone(),
        x: c.x.clone(),
        v: c.v.clone(),
        u: c.u.clone(),
    });
    identify::configure(&r, options).map_err(|e| e.0)
}

/// `lssi identify` on columns: its report (the `--json` object), the configuration and the
/// warnings `--json` ends with. A model that fails the quality gate is an error, with the
/// sentence `lssi identify` prints ("no deterministic dynamics found in …").
pub fn fit(c: Columns, options: &Options) -> Result<(Report, Config, Vec<String>), String> {
    let r = recording(c);
    let (config, _) = identify::configure(&r, options).map_err(|e| e.0)?;
    let (report, quality) = identify::quality::identify_checked(&r, options).map_err(|e| e.0)?;
    if !quality.passed() {
        return Err(identify::quality::refusal(&r, &quality));
    }
    let warnings = warnings(&report);
    Ok((report, config, warnings))
}

/// The warnings `lssi identify --json` ends with for a report that passed the gate: the
/// left-out samples.
pub fn warnings(report: &Report) -> Vec<String> {
    identify::batch::warnings(report)
}

/// The identifier `lssi identify` streams through, in precision `T`.
pub type HostIdentifier<T> = Identifier<T, WINDOW_CAPACITY, TERM_CAPACITY>;

/// The report of an identifier's model now (a screening on request: it changes nothing that
/// follows), as `lssi identify` reports it.
pub fn report_now<T: Real>(
    identifier: &mut HostIdentifier<T>,
    omega_estimated: bool,
    name: &str,
) -> Result<Report, String> {
    identifier.screen();
    let config = *identifier.config();
    let counters = *identifier.counters();
    let model = identifier.model().ok_or_else(|| {
        format!(
            "{name}: no model yet: {} samples were accepted and {} rejected, too few regression rows for the {}-term library.",
            counters.accepted,
            counters.rejected(),
            identifier.library().len()
        )
    })?;
    Ok(identify::report(
        model,
        &config,
        omega_estimated,
        counters.rejected(),
        std::any::type_name::<T>(),
    ))
}

/// One sample in precision `T`.
pub fn sample<T: Real>(t: f64, x: f64, v: Option<f64>, u: Option<f64>) -> Sample<T> {
    Sample {
        t,
        x: T::from_f64(x),
        v: v.map(T::from_f64),
        u: u.map(T::from_f64),
    }
}

/// The JSON `lssi identify --json` prints for a report and its warnings.
pub fn json(report: &Report, warnings: &[String]) -> String {
    let mut text = serde_json::to_string(report).unwrap_or_default();
    text.pop();
    text.push_str(",\"warnings\":");
    text.push_str(&serde_json::Value::from(warnings.to_vec()).to_string());
    text.push('}');
    text
}

/// The text `lssi identify` prints for a report.
pub fn text(report: &Report) -> String {
    identify::render(report)
}

/// The selected model's equation as one line (the first line of the text report).
pub fn equation(report: &Report) -> String {
    text(report).lines().next().unwrap_or_default().to_string()
}

/// The library's term names in order, for the report's Ω.
pub fn feature_names(config: &Config) -> Vec<String> {
    match lssi_core::Library::<TERM_CAPACITY>::new(&config.library) {
        Ok(library) => library
            .terms()
            .iter()
            .map(|t| t.name(config.omega).to_string())
            .collect(),
        Err(_) => Vec::new(),
    }
}

/// A free run of the report's model on the grid `t` from (x0, v0), with the excitation `u`
/// interpolated between samples when the model has a `u` term.
pub fn simulate(
    report: &Report,
    t: &[f64],
    u: Option<&[f64]>,
    x0: f64,
    v0: f64,
) -> (Vec<f64>, Vec<f64>) {
    let model = SimModel::from_report(report);
    let s = simulate::simulate(&model, t, u, (x0, v0), 4);
    (s.x, s.v)
}
