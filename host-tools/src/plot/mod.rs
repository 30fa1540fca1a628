//! Pictures of a recording and its identified model, as PNG and SVG (`lssi plot`).
//!
//! Five figures, each written as `<stem>-<name>.png` and `.svg`:
//!
//! | name | shows | paper |
//! |---|---|---|
//! | `model` | the recording against the identified model's free simulation (RK4 from the first sample), whole record and a close-up | Fig. 7 |
//! | `screening` | held-out mean error of every solution of the threshold sweep, the one MES selected, and the terms per solution | Figs. 6, 12 |
//! | `k-neighbours` | the k-neighbour reconstruction error ε(K) of x and of v, and the K chosen | Fig. 4 |
//! | `coefficients` | each selected term's coefficient as identified from the record up to time t (the streaming view) | — |
//! | `phase` | the phase portrait (x, v) with the unforced model's equilibria; for a double well the wells and the saddle | — |
//!
//! A harvester's recording (an electrical channel: [`crate::system`]) gets its own figures
//! ([`plot_system`]): `voltage` (or `current`), the measured channel against the identified
//! system's free run from the excitation alone, and with `--load-ohms` `power-load` (the
//! predicted mean power against the load, the measured power and the optimal load) and
//! `power-frequency` (against the forcing frequency).
//!
//! Text is drawn with DejaVu Sans, shipped in `assets/fonts` and embedded in the binary, so
//! the PNGs look the same on any machine and nothing depends on the system's fonts.

mod data;
mod draw;

use std::path::{Path, PathBuf};

use crate::error::CliError;
use crate::identify::{Options, Report};
use crate::recording::Recording;

pub use data::{History, Neighbours, Reconstruction, envelope, history, neighbours, velocity};
pub use draw::{PlotError, Units};

/// One figure written to disk.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Written {
    /// Short name (`model`, `screening`, …).
    pub figure: String,
    /// The PNG file.
    pub png: PathBuf,
    /// The SVG file.
    pub svg: PathBuf,
}

/// What [`plot_all`] did: the figures written, those the data could not support (a sentence
/// each, as `name: why`) and those whose files could not be written ([`PlotError::Write`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Figures {
    /// The figures written.
    pub written: Vec<Written>,
    /// `name: why` for each figure the data could not support.
    pub skipped: Vec<String>,
    /// Each figure whose file could not be written (an error naming the file).
    pub failed: Vec<PlotError>,
}

/// Draws every figure of `recording`, identified as `report` says (with the options that made
/// it), into `dir` (created if missing); `prediction` is the short-horizon figure `lssi
/// identify` reports, named in the model figure's title beside the free run's. Returns the
/// files written, for each figure the data could not support a sentence saying why, and the
/// figures whose files could not be written.
pub fn plot_all(
    recording: &Recording,
    options: &Options,
    report: &Report,
    prediction: Option<&str>,
    dir: &Path,
    units: &Units,
) -> Result<Figures, CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::CreateDir {
        path: dir.to_path_buf(),
        source: e,
    })?;
    draw::register_font().map_err(|e| CliError::Identify(e.to_string()))?;
    let (config, _) = crate::identify::configure(recording, options)?;
    let stem = recording
        .path
        .file_stem()
        .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
    let mut figures = Figures::default();
    let mut emit = |name: &str, result: Result<Written, PlotError>| match result {
        Ok(w) => figures.written.push(w),
        Err(e @ PlotError::Write { .. }) => figures.failed.push(e),
        Err(PlotError::Skipped(why)) => figures.skipped.push(format!("{name}: {why}")),
        Err(e) => figures.skipped.push(format!("{name}: {e}")),
    };
    let base = dir.join(&stem);
    let velocity = data::velocity(recording, &config);
    emit(
        "model",
        draw::model(&base, recording, &velocity, report, prediction, units),
    );
    emit("screening", draw::screening(&base, report, units));
    emit(
        "k-neighbours",
        match data::neighbours(recording, &config) {
            Some(n) => draw::neighbours(&base, &n, report, units),
            None => Err(PlotError::Skipped(
                "too few regression rows for ε(K).".into(),
            )),
        },
    );
    let history = if options.f32 {
        data::history::<f32>(recording, &config)
    } else {
        data::history::<f64>(recording, &config)
    };
    emit(
        "coefficients",
        match history {
            Some(h) => draw::coefficients(&base, &h, report),
            None => Err(PlotError::Skipped("the identifier cannot be built.".into())),
        },
    );
    emit(
        "phase",
        draw::phase(&base, recording, &velocity, report, units),
    );
    Ok(figures)
}

/// Draws a harvester's figures (see the module's documentation) into `dir`: the measured
/// electrical channel against the free run of `report`'s system, and with its
/// `harvester` (`--load-ohms`) the power against load and frequency.
pub fn plot_system(
    data: &crate::system::SystemData,
    report: &crate::system::SystemReport,
    dir: &Path,
) -> Result<Figures, CliError> {
    use crate::system::simulate::{SystemSim, first_state, nrmse};
    std::fs::create_dir_all(dir).map_err(|e| CliError::CreateDir {
        path: dir.to_path_buf(),
        source: e,
    })?;
    draw::register_font().map_err(|e| CliError::Identify(e.to_string()))?;
    let r = &data.recording;
    let stem = r
        .path
        .file_stem()
        .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
    let base = dir.join(&stem);
    let mut figures = Figures::default();
    let mut emit = |name: &str, result: Result<Written, PlotError>| match result {
        Ok(w) => figures.written.push(w),
        Err(e @ PlotError::Write { .. }) => figures.failed.push(e),
        Err(PlotError::Skipped(why)) => figures.skipped.push(format!("{name}: {why}")),
        Err(e) => figures.skipped.push(format!("{name}: {e}")),
    };
    match SystemSim::of_report(report) {
        Some(sim) => {
            let u = r.u.as_deref().unwrap_or(&[]);
            let scale = r.x.iter().fold(0.0f64, |m, q| m.max(q.abs()));
            let run = sim.run(&r.t, u, first_state(data), scale + 1.0);
            for (k, e) in data.electrical.iter().enumerate().take(2) {
                let predicted: Vec<f64> = run.iter().map(|s| s[2 + k]).collect();
                let error = 100.0 * nrmse(&predicted, &e.values);
                let name = if e.kind.symbol() == "V" {
                    "voltage"
                } else {
                    "current"
                };
                emit(
                    name,
                    draw::voltage(&base, &r.t, &e.values, &predicted, e.kind.symbol(), error),
                );
            }
        }
        None => emit(
            "voltage",
            Err(PlotError::Skipped(
                "the model has a term the simulator does not know.".into(),
            )),
        ),
    }
    match &report.harvester {
        Some(h) => {
            emit("power-load", draw::power_load(&base, h));
            emit(
                "power-frequency",
                draw::power_frequency(&base, h, report.omega),
            );
        }
        None => emit(
            "power-load, power-frequency",
            Err(PlotError::Skipped(
                "give the load the voltage was recorded across (--load-ohms R).".into(),
            )),
        ),
    }
    Ok(figures)
}
