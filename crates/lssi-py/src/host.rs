//! Every call into `lssi-host` (the `lssi` command's library) is in this file, so that the
//! package follows the command when its modules move.

use std::path::PathBuf;

use lssi_core::{Config, Identifier, Real, Sample, Term};
pub use lssi_host::identify::Options;
pub use lssi_host::identify::Reference;
pub use lssi_host::identify::Report;
use lssi_host::identify::pipeline::{self, Failure, Refine};
use lssi_host::identify::refine::Chosen;
pub use lssi_host::identify::refine::Summary;
use lssi_host::identify::simulate;
pub use lssi_host::identify::simulate::SimModel;
use lssi_host::identify::{self, TERM_CAPACITY};
use lssi_host::recording::{ColumnNames, Recording};

/// The ring-buffer capacity `lssi identify` runs with.
pub use lssi_host::identify::WINDOW_CAPACITY;

/// Why a model was not refined, as `lssi identify --no-refine` says it (in its `--json`
/// warnings and its text report): the package's `refine=False`, and a stream's model.
pub const NOT_REFINED: &str = "not refined (--no-refine)";

/// The unit of x `lssi identify` writes in its text report unless `--unit` is given.
pub const DEFAULT_UNIT: &str = "[x]";

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

impl Columns {
    /// Every column has x's length (the host library indexes them together).
    pub fn check(&self) -> Result<(), String> {
        lengths(
            self.x.len(),
            &[
                ("t", Some(self.t.len())),
                ("v", self.v.as_ref().map(Vec::len)),
                ("u", self.u.as_ref().map(Vec::len)),
            ],
        )
    }
}

/// `Err` naming the first column whose length is not `n` (x's).
pub fn lengths(n: usize, columns: &[(&str, Option<usize>)]) -> Result<(), String> {
    for (name, len) in columns {
        if let Some(len) = len
            && *len != n
        {
            return Err(format!("{name} has {len} samples but x has {n}."));
        }
    }
    Ok(())
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

/// `lssi identify`'s configuration for these columns and options, whether Ω was estimated,
/// and the references it subtracts from x and v ([`Reference`]: the configuration is the
/// shifted recording's, as the command's).
pub fn configure(c: &Columns, options: &Options) -> Result<(Config, bool, Reference), String> {
    c.check()?;
    let r = recording(Columns {
        name: c.name.clone(),
        t: c.t.clone(),
        x: c.x.clone(),
        v: c.v.clone(),
        u: c.u.clone(),
    });
    let reference = Reference::of(&r);
    let shifted = reference.shifted(&r);
    let (config, estimated) =
        identify::configure(shifted.as_ref().unwrap_or(&r), options).map_err(|e| e.0)?;
    Ok((config, estimated, reference))
}

/// What `lssi identify` reports for a recording, and what the package needs besides.
pub struct Fitted {
    /// The report (`terms` the reported model: refined when refinement ran and was taken).
    pub report: Report,
    /// The refinement's summary, when it ran.
    pub refined: Option<Summary>,
    /// The warnings `--json` ends with.
    pub warnings: Vec<String>,
    /// The configuration the identifier ran with.
    pub config: Config,
    /// The reported model, to simulate.
    pub model: SimModel,
    /// The references subtracted from x and v before identifying ([`Reference`]).
    pub reference: Reference,
}

/// `lssi identify` on columns through the command's one pipeline
/// ([`lssi_host::identify::pipeline::identify`]): refined on simulation error when `refine`
/// (the command's default), else the streaming model with the `--no-refine` warning. A model
/// the quality gate withholds is an error, with the sentence `lssi identify` prints ("no
/// deterministic dynamics found in …").
pub fn fit(c: Columns, options: &Options, refine: bool) -> Result<Fitted, String> {
    c.check()?;
    let r = recording(c);
    // The configuration of the recording less its references, as the pipeline's.
    let reference = Reference::of(&r);
    let shifted = reference.shifted(&r);
    let (config, _) =
        identify::configure(shifted.as_ref().unwrap_or(&r), options).map_err(|e| e.0)?;
    let refine = if refine {
        Refine::Yes
    } else {
        Refine::No(NOT_REFINED)
    };
    let done = pipeline::identify(&r, options, refine).map_err(|failure| match failure {
        Failure::Error(sentence) | Failure::Withheld(sentence, ..) => sentence,
    })?;
    let model = reported_model(&done.report, &config)?;
    Ok(Fitted {
        report: done.report,
        refined: done.refined,
        warnings: done.warnings,
        config,
        model,
        reference,
    })
}

/// The reported model as a [`SimModel`]. `Report::model` is the streaming model's (the
/// refined one is reported by name only, in `Report::terms`), so a refined model's terms are
/// found by name in the library; refinement keeps Ω and the offsets.
pub fn reported_model(report: &Report, config: &Config) -> Result<SimModel, String> {
    let streaming = SimModel::from_report(report);
    if report.reported != Chosen::Refined {
        return Ok(streaming);
    }
    let library = lssi_core::Library::<TERM_CAPACITY>::new(&config.library)
        .map_err(|e| format!("the library of the configuration is not usable: {e}."))?;
    let named: Vec<(String, Term)> = library
        .terms()
        .iter()
        .map(|t| (t.name(report.omega).to_string(), *t))
        .collect();
    let terms = report
        .terms
        .iter()
        .map(|reported| {
            let mut found = named.iter().filter(|(name, _)| *name == reported.term);
            match (found.next(), found.next()) {
                (Some((_, term)), None) => Ok((*term, reported.coef)),
                _ => Err(format!(
                    "internal error: the refined model's term {} is not one term of the library; please report it.",
                    reported.term
                )),
            }
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok(SimModel { terms, ..streaming })
}

/// The warnings `lssi identify --json` ends with for a report that passed the gate: the
/// left-out samples.
pub fn warnings(report: &Report) -> Vec<String> {
    pipeline::warnings(report)
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

/// The JSON `lssi identify --json` prints (`--no-refine` when `refined` is `None`).
pub fn json(report: &Report, refined: Option<&Summary>, warnings: &[String]) -> String {
    identify::json_text(report, refined, warnings)
}

/// The text `lssi identify` prints (`--no-refine` when `refined` is `None`), x in `unit`.
pub fn text(report: &Report, refined: Option<&Summary>, unit: &str) -> String {
    let note = refined.is_none().then_some(NOT_REFINED);
    identify::render_reported(report, refined, note, unit)
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

/// A free run of `model` on the grid `t` from (x0, v0), with the excitation `u` interpolated
/// between samples when the model has a `u` term.
pub fn simulate(
    model: &SimModel,
    t: &[f64],
    u: Option<&[f64]>,
    x0: f64,
    v0: f64,
) -> (Vec<f64>, Vec<f64>) {
    let s = simulate::simulate(model, t, u, (x0, v0), 4);
    (s.x, s.v)
}

/// A recording with an electrical column (`V` or `i`), read as `lssi identify` reads it.
pub use lssi_host::system::SystemData;
/// A system's report (`lssi identify --json` for a recording with an electrical column).
pub use lssi_host::system::SystemReport;
/// A system model, ready to simulate.
pub use lssi_host::system::simulate::SystemSim;

/// Reads `path` as a system when it has an electrical column (`V` or `i`), as `lssi
/// identify FILE` decides; `Ok(None)`: a single-equation recording.
pub fn read_system(path: &str) -> Result<Option<SystemData>, String> {
    lssi_host::system::read_if_system(
        std::path::Path::new(path),
        &ColumnNames::default(),
        &lssi_host::system::ElectricalColumns::default(),
    )
    .map_err(|e| e.to_string())
}

/// The columns of a system's recording held in memory: the mechanical ones (x may be absent
/// when v is given: it is then v integrated, as `lssi identify` integrates it) and the
/// electrical ones (`V`, the voltage across the load; `i`, the current).
pub struct SystemColumns {
    /// Name the error messages give the data (a file name, or "array").
    pub name: String,
    /// Times, seconds.
    pub t: Vec<f64>,
    /// Displacement, when measured.
    pub x: Option<Vec<f64>>,
    /// Velocity, when measured.
    pub v: Option<Vec<f64>>,
    /// Excitation, when measured.
    pub u: Option<Vec<f64>>,
    /// The voltage across the load, when measured.
    pub voltage: Option<Vec<f64>>,
    /// The current, when measured.
    pub current: Option<Vec<f64>>,
}

/// The sentence `lssi identify` warns with when x is v integrated (`lssi_host::system`'s
/// reader words it so; the package's tests compare the two reports).
fn x_from_v_sentence(width: usize) -> String {
    format!(
        "x is v integrated, its drift removed (the least-squares line, then a centred moving average of {width} samples, two hundred periods of v): the model is in x about its mean"
    )
}

/// The system's data as `lssi identify FILE` reads it from a file with these columns.
pub fn system_data(c: SystemColumns) -> Result<SystemData, String> {
    use lssi_core::library::Electrical;
    use lssi_host::system::ElectricalChannel;
    let n = c.t.len();
    lengths(
        n,
        &[
            ("x", c.x.as_ref().map(Vec::len)),
            ("v", c.v.as_ref().map(Vec::len)),
            ("u", c.u.as_ref().map(Vec::len)),
            ("V", c.voltage.as_ref().map(Vec::len)),
            ("i", c.current.as_ref().map(Vec::len)),
        ],
    )
    .map_err(|e| e.replace("but x has", "but t has"))?;
    if c.voltage.is_none() && c.current.is_none() {
        return Err("a system needs an electrical channel: give V (the voltage across the load) or i (the current).".into());
    }
    let (x, x_from_v) = match (c.x, &c.v) {
        (Some(x), _) => (x, None),
        (None, Some(v)) => {
            let (x, width) = lssi_host::system::integrate_velocity(&c.t, v);
            (x, Some(x_from_v_sentence(width)))
        }
        (None, None) => {
            return Err(
                "a system needs a displacement x or a velocity v beside its electrical channel."
                    .into(),
            );
        }
    };
    let mut electrical = Vec::new();
    if let Some(values) = c.voltage {
        electrical.push(ElectricalChannel {
            kind: Electrical::Voltage,
            name: "V".into(),
            values,
        });
    }
    if let Some(values) = c.current {
        electrical.push(ElectricalChannel {
            kind: Electrical::Current,
            name: "i".into(),
            values,
        });
    }
    let columns = ColumnNames {
        t: "t".into(),
        x: "x".into(),
        v: c.v.as_ref().map(|_| "v".into()),
        u: c.u.as_ref().map(|_| "u".into()),
    };
    Ok(SystemData {
        recording: Recording {
            path: PathBuf::from(c.name),
            t: c.t,
            x,
            v: c.v,
            u: c.u,
            columns,
        },
        second: None,
        electrical,
        x_from_v,
    })
}

/// What `lssi identify FILE` reports for a system, the model to simulate, and the bound on
/// the free run (`lssi simulate`'s: the RMS of the recording's x, plus 1).
pub struct SystemFitted {
    /// The report (`--json`, the text report).
    pub report: SystemReport,
    /// The reported model.
    pub model: SystemSim,
    /// The divergence bound of a free run.
    pub bound: f64,
    /// The shared library's term names, in column order.
    pub library: Vec<String>,
}

/// `lssi identify FILE` for a system, as the command runs it
/// ([`lssi_host::system::identify_command`]): `coupling_order` its `--coupling-order`,
/// `load_ohms` its `--load-ohms` (the harvester in physical terms).
pub fn fit_system(
    data: &SystemData,
    options: &Options,
    coupling_order: u8,
    load_ohms: Option<f64>,
    refine: bool,
) -> Result<SystemFitted, String> {
    use lssi_host::system;
    if let Some(r) = load_ohms
        && !(r.is_finite() && r > 0.0)
    {
        return Err(format!(
            "load_ohms must be a positive resistance in ohms, not {r}."
        ));
    }
    let (config, _) =
        system::configure(data, options, coupling_order).map_err(|e| e.to_string())?;
    // The command's one path: the streaming identifier, refinement (unless `refine` is false:
    // `--no-refine`), the system's gate and,
    // for a model that passes, the harvester in physical terms. A withheld model is an error
    // with the sentence `lssi identify` prints.
    let args = system::SystemArgs {
        columns: system::ElectricalColumns::default(),
        load_ohms,
        coil_ohms: None,
        coupling_order,
    };
    let report =
        match system::identify_system(data, options, &args, !refine).map_err(|e| e.to_string())? {
            system::Outcome::Passed(report) => *report,
            system::Outcome::Withheld(sentence, _) => return Err(sentence),
        };
    let model = SystemSim::of_report(&report).ok_or_else(|| {
        "internal error: a term of the system's report is not one lssi can simulate; please report it."
            .to_string()
    })?;
    let library =
        match lssi_core::library::StateLibrary::<{ system::TERM_CAPACITY }>::new(&config.library())
        {
            Ok(library) => library
                .terms()
                .iter()
                .map(|t| t.name(report.omega, &config.electrical).to_string())
                .collect(),
            Err(e) => {
                return Err(format!(
                    "internal error: the system's library is not usable ({e:?}); please report it."
                ));
            }
        };
    let bound = system::simulate::rms(&data.recording.x) + 1.0;
    Ok(SystemFitted {
        report,
        model,
        bound,
        library,
    })
}

/// The first state (x, v, then the electrical states) `lssi simulate` starts a system's
/// free run from, for a recording: v measured, or x's slope over its first samples.
pub fn first_state(data: &SystemData) -> Result<Vec<f64>, String> {
    if data.recording.t.is_empty() {
        return Err("t has no samples: the first state needs one.".into());
    }
    let s = lssi_host::system::simulate::first_state(data);
    Ok(s[..2 + data.electrical.len()].to_vec())
}

/// A system model's free run on the grid `t` from `start` (x, v, then the electrical
/// states), driven by `u` (empty: 0): one column per state, NaN after a divergence.
pub fn simulate_system(
    model: &SystemSim,
    t: &[f64],
    u: &[f64],
    start: &[f64],
    layout: &[usize],
    bound: f64,
) -> Vec<Vec<f64>> {
    // The simulator's state is (x, v, e₁, e₂, x2, v2); `layout` says where each of the
    // report's states (x, v[, x2, v2], then the electrical ones) sits in it.
    let mut s = [0.0; 6];
    for (q, &k) in start.iter().zip(layout) {
        s[k] = *q;
    }
    let states = model.run(t, u, s, bound);
    layout
        .iter()
        .map(|&k| states.iter().map(|s| s[k]).collect())
        .collect()
}

/// Where each of a system report's states sits in the simulator's state (x, v, e₁, e₂, x2,
/// v2): the first displacement and its velocity (0, 1), a second's (4, 5), then the
/// electrical states (2, 3), for a report whose equations are `targets` (`x''` or `x1''`,
/// `x2''`, then `V'` or `i'`).
pub fn state_layout(targets: &[String]) -> Vec<usize> {
    let mechanical = targets.iter().filter(|t| t.ends_with("''")).count();
    let electrical = targets.len() - mechanical;
    let mut layout = vec![0, 1];
    if mechanical > 1 {
        layout.extend([4, 5]);
    }
    layout.extend((0..electrical).map(|k| 2 + k));
    layout
}
