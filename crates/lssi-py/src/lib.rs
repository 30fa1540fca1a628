//! The compiled part of the `lssi` Python package (`lssi._lssi`): the identification that
//! `lssi identify` runs (its one pipeline: refined on simulation error unless asked not to),
//! from NumPy arrays, a reader for its recording files, and a streaming identifier. The
//! Python layer (`python/lssi/__init__.py`) adds the PySINDy-like `Model` and `Stream`
//! classes, input checks and pandas support on top of it.
//!
//! Nothing here panics into Python: every entry point runs under [`guarded`], which turns a
//! panic of the Rust code (a bug, for inputs that got past the checks) into a `RuntimeError`
//! with a sentence, and inputs that would index out of bounds (columns of unequal lengths)
//! are `ValueError`s before they reach the host library. Error sentences from the host
//! library name the command's flags; [`python_words`] names the Python arguments instead.

mod host;

use std::cell::RefCell;
use std::panic::{self, AssertUnwindSafe};

use lssi_core::{Config, PolyFamily, Real};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

use host::{Columns, HostIdentifier, Options, Reference, Report, SimModel, Summary};

/// What went wrong on the Rust side: bad input (a sentence for a `ValueError`) or a panic
/// (a bug: a sentence for a `RuntimeError`).
enum Error {
    Input(String),
    Panic(String),
}

impl From<String> for Error {
    fn from(s: String) -> Self {
        Error::Input(s)
    }
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::Input(s) => PyValueError::new_err(python_words(&s)),
            Error::Panic(s) => PyRuntimeError::new_err(s),
        }
    }
}

thread_local! {
    /// Where the last panic on this thread happened, recorded by the module's panic hook.
    static PANIC_AT: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Runs `f`, a panic in it becoming [`Error::Panic`] with a sentence (what was being done,
/// the panic's message and where it happened) instead of a `pyo3_runtime.PanicException`.
fn guarded<R>(doing: &str, f: impl FnOnce() -> Result<R, String>) -> Result<R, Error> {
    match panic::catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result.map_err(Error::Input),
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "no message".into());
            let at = PANIC_AT
                .with(|p| p.borrow_mut().take())
                .map(|at| format!(" at {at}"))
                .unwrap_or_default();
            Err(Error::Panic(format!(
                "lssi failed while {doing}: an internal error ({message}{at}); this is a bug, please report it with the data and options that caused it."
            )))
        }
    }
}

/// The host library's sentences with the command's flags replaced by the Python arguments
/// (`give --omega.` → `give omega=… (rad/s).`, `--omega 50 rad/s` → `omega=50 rad/s`).
fn python_words(message: &str) -> String {
    const FLAGS: [(&str, &str); 12] = [
        ("give --omega", "give omega=… (rad/s)"),
        (" (--u-col)", " (u=…)"),
        ("--omega ", "omega="),
        ("--omega", "omega"),
        ("--poly-order", "poly_order"),
        ("--harmonics", "harmonics"),
        ("--family", "family"),
        ("--memory", "memory"),
        ("--no-smoothing", "smoothing=False"),
        ("--f64", "f32=False"),
        ("--load-ohms", "load_ohms"),
        ("--coupling-order", "coupling_order"),
    ];
    // A header's hint names the command's column options, which Python has not got: the
    // columns are renamed instead.
    const RENAME: &str = "rename the file's columns to t, x or v, u, and V or i (or read it with pandas, rename them and pass the DataFrame).";
    const CASE: &str = "differs only in case (names are case-sensitive): give ";
    let message = match message
        .find("; if '")
        .or_else(|| message.find("; name the motion's"))
    {
        Some(at) if message.contains("--x-col or --v-col") => {
            format!("{}; {RENAME}", &message[..at])
        }
        // `column 'T' differs only in case …: give --t-col T --x-col X.`
        _ => match message.find(CASE) {
            Some(at) => format!(
                "{}differs only in case (names are case-sensitive): {RENAME}",
                &message[..at]
            ),
            None => message.to_string(),
        },
    };
    let mut out = message;
    for (flag, argument) in FLAGS {
        out = out.replace(flag, argument);
    }
    out.replace("--f32", "f32=True")
}

fn value_error(message: String) -> PyErr {
    Error::Input(message).into()
}

fn family(name: &str) -> PyResult<PolyFamily> {
    match name {
        "all" => Ok(PolyFamily::All),
        "families" => Ok(PolyFamily::Families),
        "odd" => Ok(PolyFamily::OddFamilies),
        other => Err(value_error(format!(
            "family must be 'all', 'families' or 'odd', not {other:?}."
        ))),
    }
}

#[allow(clippy::too_many_arguments)]
fn options(
    omega: Option<f64>,
    harmonics: Option<u8>,
    poly_order: u8,
    family_name: &str,
    f32: bool,
    smoothing: bool,
    memory: Option<f64>,
) -> PyResult<Options> {
    Ok(Options {
        omega,
        harmonics,
        poly_order,
        family: family(family_name)?,
        f32,
        smoothing,
        memory,
        noise_correction: false,
    })
}

fn vector(a: Option<PyReadonlyArray1<'_, f64>>) -> Option<Vec<f64>> {
    a.map(|a| a.as_array().to_vec())
}

/// A fitted model: what `lssi identify` reports, and the configuration it ran with.
#[pyclass(module = "lssi._lssi", frozen)]
struct Fit {
    report: Report,
    /// The refinement's summary, when it ran (`None`: `--no-refine`, or a stream's model).
    refined: Option<Summary>,
    config: Config,
    omega_estimated: bool,
    /// What `lssi identify --json` ends with.
    warnings: Vec<String>,
    /// The reported model (the refined one when it was taken), to simulate.
    model: SimModel,
    /// The references subtracted from x and v before identifying (a stream like this fit
    /// subtracts them too).
    reference: Reference,
}

/// Two NumPy arrays: a simulation's x and v.
type Pair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

fn named(terms: &[lssi_host::identify::TermReport]) -> Vec<(String, f64)> {
    terms.iter().map(|t| (t.term.clone(), t.coef)).collect()
}

#[pymethods]
impl Fit {
    /// The `lssi identify --json` object, as a string (`--no-refine` when not refined).
    fn json(&self) -> String {
        host::json(&self.report, self.refined.as_ref(), &self.warnings)
    }

    /// The `lssi identify` text report, x in `unit` (the command's `--unit`).
    #[pyo3(signature = (unit=host::DEFAULT_UNIT))]
    fn text(&self, unit: &str) -> String {
        host::text(&self.report, self.refined.as_ref(), unit)
    }

    /// The reported equation, one line (the text report's first).
    fn equation(&self) -> String {
        self.text(host::DEFAULT_UNIT)
            .lines()
            .next()
            .unwrap_or_default()
            .to_string()
    }

    /// The library's term names, in order.
    fn feature_names(&self) -> Vec<String> {
        host::feature_names(&self.config)
    }

    /// The reported model's active terms and coefficients (physical units): the JSON's
    /// `terms`.
    fn terms(&self) -> Vec<(String, f64)> {
        named(&self.report.terms)
    }

    /// The streaming identifier's model (a device's): the JSON's `streaming_terms`.
    fn streaming_terms(&self) -> Vec<(String, f64)> {
        named(&self.report.streaming_terms)
    }

    /// Which model `terms` is: "refined" or "streaming".
    fn reported(&self) -> &'static str {
        match self.report.reported {
            lssi_host::identify::refine::Chosen::Refined => "refined",
            lssi_host::identify::refine::Chosen::Streaming => "streaming",
        }
    }

    /// The reported model's standard errors, term by term, when it is the refined one.
    fn standard_errors(&self) -> Option<Vec<(String, f64)>> {
        // The refined model's, or a kept streaming model's (its support refined, each
        // widened to the distance between the two estimates); none with refine=False.
        self.report.terms.iter().any(|t| t.se.is_some()).then(|| {
            self.report
                .terms
                .iter()
                .map(|t| (t.term.clone(), t.se.unwrap_or(f64::NAN)))
                .collect()
        })
    }

    /// Whether the reported model has an excitation term `u` (a simulation needs u).
    fn uses_input(&self) -> bool {
        self.model.uses_input()
    }

    /// The channels the identifier was configured for: (velocity v, excitation u).
    fn channels(&self) -> (bool, bool) {
        (self.config.channels.velocity, self.config.channels.input)
    }

    /// Free run of the reported model on the grid `t` from (x0, v0); `u` the measured
    /// excitation on the same grid.
    #[pyo3(signature = (t, x0, v0, u=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArray1<'py, f64>,
        x0: f64,
        v0: f64,
        u: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<Pair<'py>> {
        let t = t.as_array().to_vec();
        let u = vector(u);
        let model = &self.model;
        let (x, v) = py.detach(|| {
            guarded("simulating", || {
                if let Some(u) = &u
                    && u.len() != t.len()
                {
                    return Err(format!("u has {} samples but t has {}.", u.len(), t.len()));
                }
                Ok(host::simulate(model, &t, u.as_deref(), x0, v0))
            })
        })?;
        Ok((PyArray1::from_vec(py, x), PyArray1::from_vec(py, v)))
    }
}

fn columns(
    name: String,
    t: PyReadonlyArray1<'_, f64>,
    x: PyReadonlyArray1<'_, f64>,
    v: Option<PyReadonlyArray1<'_, f64>>,
    u: Option<PyReadonlyArray1<'_, f64>>,
) -> Columns {
    Columns {
        name,
        t: t.as_array().to_vec(),
        x: x.as_array().to_vec(),
        v: vector(v),
        u: vector(u),
    }
}

/// `lssi identify` on arrays (all of one length; `v` and `u` optional), `name` standing for
/// the file in its sentences; refined on simulation error unless `refine` is false
/// (`--no-refine`).
#[pyfunction]
#[pyo3(signature = (t, x, v, u, omega, harmonics, poly_order, family, f32, smoothing, memory, refine=true, name="array"))]
#[allow(clippy::too_many_arguments)]
fn fit(
    py: Python<'_>,
    t: PyReadonlyArray1<'_, f64>,
    x: PyReadonlyArray1<'_, f64>,
    v: Option<PyReadonlyArray1<'_, f64>>,
    u: Option<PyReadonlyArray1<'_, f64>>,
    omega: Option<f64>,
    harmonics: Option<u8>,
    poly_order: u8,
    family: &str,
    f32: bool,
    smoothing: bool,
    memory: Option<f64>,
    refine: bool,
    name: &str,
) -> PyResult<Fit> {
    let options = options(omega, harmonics, poly_order, family, f32, smoothing, memory)?;
    let columns = columns(name.to_string(), t, x, v, u);
    let fitted = py.detach(|| guarded("identifying", || host::fit(columns, &options, refine)))?;
    Ok(Fit {
        omega_estimated: fitted.report.omega_estimated,
        report: fitted.report,
        refined: fitted.refined,
        config: fitted.config,
        warnings: fitted.warnings,
        model: fitted.model,
        reference: fitted.reference,
    })
}

/// Reads a recording file: (t, x, v or None, u or None).
#[pyfunction]
#[allow(clippy::type_complexity)]
fn read_recording<'py>(
    py: Python<'py>,
    path: &str,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    Option<Bound<'py, PyArray1<f64>>>,
)> {
    let c = py.detach(|| guarded("reading the recording", || host::read(path)))?;
    Ok((
        PyArray1::from_vec(py, c.t),
        PyArray1::from_vec(py, c.x),
        c.v.map(|v| PyArray1::from_vec(py, v)),
        c.u.map(|u| PyArray1::from_vec(py, u)),
    ))
}

/// A system's model (a recording with an electrical column): what `lssi identify` reports
/// for it, and the model to simulate.
#[pyclass(module = "lssi._lssi", frozen)]
struct SystemFit {
    fitted: host::SystemFitted,
}

#[pymethods]
impl SystemFit {
    /// The `lssi identify --json` object, as a string.
    fn json(&self) -> String {
        self.fitted.report.json()
    }

    /// The `lssi identify` text report.
    fn text(&self) -> String {
        self.fitted.report.render()
    }

    /// The states, in order: `x`, `v`, then the electrical ones (`V`, `i`).
    fn states(&self) -> Vec<String> {
        self.fitted.report.states.clone()
    }

    /// Each equation's target (`x''`, `V'`, `i'`) and its terms with their coefficients.
    fn equations(&self) -> Vec<(String, Vec<(String, f64)>)> {
        self.fitted
            .report
            .equations
            .iter()
            .map(|e| (e.target.clone(), named(&e.terms)))
            .collect()
    }

    /// Whether the model has an excitation term `u` (a simulation needs u).
    fn uses_input(&self) -> bool {
        self.fitted.model.uses_input()
    }

    /// The shared library's term names, in column order (every equation is sparse over it).
    fn feature_names(&self) -> Vec<String> {
        self.fitted.library.clone()
    }

    /// Free run of the model on the grid `t` from `x0` (one value per state, in `states()`
    /// order); `u` the excitation on the same grid. One array per state.
    #[pyo3(signature = (t, x0, u=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArray1<'py, f64>,
        x0: Vec<f64>,
        u: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<Vec<Bound<'py, PyArray1<f64>>>> {
        let t = t.as_array().to_vec();
        let u = vector(u);
        let fitted = &self.fitted;
        let states = fitted.report.states.len();
        let columns = py.detach(|| {
            guarded("simulating the system", || {
                if x0.len() != states {
                    return Err(format!(
                        "x0 has {} values but the model has {states} states.",
                        x0.len()
                    ));
                }
                if let Some(u) = &u
                    && u.len() != t.len()
                {
                    return Err(format!("u has {} samples but t has {}.", u.len(), t.len()));
                }
                if u.is_none() && fitted.model.uses_input() {
                    return Err("u: the model has an excitation term u, so a simulation needs u on the same grid as t.".into());
                }
                let u = u.unwrap_or_default();
                let targets: Vec<String> = fitted
                    .report
                    .equations
                    .iter()
                    .map(|e| e.target.clone())
                    .collect();
                Ok(host::simulate_system(
                    &fitted.model,
                    &t,
                    &u,
                    &x0,
                    &host::state_layout(&targets),
                    fitted.bound,
                ))
            })
        })?;
        Ok(columns
            .into_iter()
            .map(|c| PyArray1::from_vec(py, c))
            .collect())
    }
}

/// `lssi identify FILE` when the file is a system's recording (it has an electrical column,
/// `V` or `i`): its model; `None` for a single-equation recording.
#[pyfunction]
#[pyo3(signature = (path, omega, harmonics, poly_order, family, f32, smoothing, memory, coupling_order=1, load_ohms=None, refine=true))]
#[allow(clippy::too_many_arguments)]
fn identify_system(
    py: Python<'_>,
    path: &str,
    omega: Option<f64>,
    harmonics: Option<u8>,
    poly_order: u8,
    family: &str,
    f32: bool,
    smoothing: bool,
    memory: Option<f64>,
    coupling_order: u8,
    load_ohms: Option<f64>,
    refine: bool,
) -> PyResult<Option<SystemFit>> {
    let options = options(omega, harmonics, poly_order, family, f32, smoothing, memory)?;
    let fitted = py.detach(|| {
        guarded("identifying the system", || {
            match host::read_system(path)? {
                Some(data) => {
                    host::fit_system(&data, &options, coupling_order, load_ohms, refine).map(Some)
                }
                None => Ok(None),
            }
        })
    })?;
    Ok(fitted.map(|fitted| SystemFit { fitted }))
}

/// A system's columns from arrays (`x` or `v`, and `V` or `i`, all of `t`'s length).
#[allow(clippy::too_many_arguments)]
fn system_columns(
    name: &str,
    t: PyReadonlyArray1<'_, f64>,
    x: Option<PyReadonlyArray1<'_, f64>>,
    v: Option<PyReadonlyArray1<'_, f64>>,
    u: Option<PyReadonlyArray1<'_, f64>>,
    voltage: Option<PyReadonlyArray1<'_, f64>>,
    current: Option<PyReadonlyArray1<'_, f64>>,
) -> host::SystemColumns {
    host::SystemColumns {
        name: name.to_string(),
        t: t.as_array().to_vec(),
        x: vector(x),
        v: vector(v),
        u: vector(u),
        voltage: vector(voltage),
        current: vector(current),
    }
}

/// `lssi identify` on a system's arrays, as on a file with columns t, x (or v alone:
/// integrated), v, u, V, i holding them; `name` standing for the file in its sentences.
#[pyfunction]
#[pyo3(signature = (t, x, v, u, voltage, current, omega, harmonics, poly_order, family, f32, smoothing, memory, coupling_order=1, load_ohms=None, refine=true, name="array"))]
#[allow(clippy::too_many_arguments)]
fn fit_system(
    py: Python<'_>,
    t: PyReadonlyArray1<'_, f64>,
    x: Option<PyReadonlyArray1<'_, f64>>,
    v: Option<PyReadonlyArray1<'_, f64>>,
    u: Option<PyReadonlyArray1<'_, f64>>,
    voltage: Option<PyReadonlyArray1<'_, f64>>,
    current: Option<PyReadonlyArray1<'_, f64>>,
    omega: Option<f64>,
    harmonics: Option<u8>,
    poly_order: u8,
    family: &str,
    f32: bool,
    smoothing: bool,
    memory: Option<f64>,
    coupling_order: u8,
    load_ohms: Option<f64>,
    refine: bool,
    name: &str,
) -> PyResult<SystemFit> {
    let options = options(omega, harmonics, poly_order, family, f32, smoothing, memory)?;
    let columns = system_columns(name, t, x, v, u, voltage, current);
    let fitted = py.detach(|| {
        guarded("identifying the system", || {
            let data = host::system_data(columns)?;
            host::fit_system(&data, &options, coupling_order, load_ohms, refine)
        })
    })?;
    Ok(SystemFit { fitted })
}

/// The state `lssi simulate` starts a system's free run from for a recording with these
/// columns (x, v, then the electrical states), and x (v integrated when x is None).
#[pyfunction]
#[pyo3(signature = (t, x, v, voltage, current))]
#[allow(clippy::type_complexity)]
fn system_start<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    x: Option<PyReadonlyArray1<'py, f64>>,
    v: Option<PyReadonlyArray1<'py, f64>>,
    voltage: Option<PyReadonlyArray1<'py, f64>>,
    current: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<(Vec<f64>, Bound<'py, PyArray1<f64>>)> {
    let columns = system_columns("array", t, x, v, None, voltage, current);
    let (start, x) = py.detach(|| {
        guarded("taking the first state", || {
            let data = host::system_data(columns)?;
            Ok((host::first_state(&data)?, data.recording.x))
        })
    })?;
    Ok((start, PyArray1::from_vec(py, x)))
}

/// Panics inside the guard, for the tests: what a bug in the Rust code becomes in Python
/// (a `RuntimeError` with a sentence, not a `pyo3_runtime.PanicException`).
#[pyfunction]
fn _panic_for_tests(py: Python<'_>) -> PyResult<()> {
    py.detach(|| {
        guarded("testing the guard", || -> Result<(), String> {
            panic!("a panic on purpose")
        })
    })?;
    Ok(())
}

/// A streaming identifier in either precision.
enum Precision {
    F32(Box<HostIdentifier<f32>>),
    F64(Box<HostIdentifier<f64>>),
}

/// A streaming identifier: samples in blocks, the model at any time.
#[pyclass(module = "lssi._lssi")]
struct RawStream {
    identifier: Precision,
    omega_estimated: bool,
    /// The references subtracted from x and v before they are fed in, added back to the
    /// model's offsets (as `lssi identify` does).
    reference: Reference,
    /// Set when a call panicked: the identifier may be half-updated, so it is not used again.
    broken: bool,
}

fn new_identifier<T: Real>(config: Config) -> PyResult<Box<HostIdentifier<T>>> {
    HostIdentifier::<T>::new(config)
        .map(Box::new)
        .map_err(|e| value_error(format!("the configuration is not usable: {e}.")))
}

fn push_all<T: Real>(
    identifier: &mut HostIdentifier<T>,
    t: &[f64],
    x: &[f64],
    v: Option<&[f64]>,
    u: Option<&[f64]>,
) -> usize {
    let mut rejected = 0;
    for i in 0..t.len() {
        let sample = host::sample::<T>(t[i], x[i], v.map(|v| v[i]), u.map(|u| u[i]));
        if identifier.push(sample).is_err() {
            rejected += 1;
        }
    }
    rejected
}

#[pymethods]
impl RawStream {
    /// A streaming identifier with the configuration a fit ran with (the same streaming
    /// model as that fit on the same samples).
    #[staticmethod]
    fn like(fit: &Fit) -> PyResult<Self> {
        Self::with(
            fit.config,
            fit.report.precision == "f32",
            fit.omega_estimated,
            fit.reference,
        )
    }

    /// A streaming identifier configured as `lssi identify` would configure it for a
    /// calibration block (which is not fed in: push it).
    #[staticmethod]
    #[pyo3(signature = (t, x, v, u, omega, harmonics, poly_order, family, f32, smoothing, memory))]
    #[allow(clippy::too_many_arguments)]
    fn calibrated(
        py: Python<'_>,
        t: PyReadonlyArray1<'_, f64>,
        x: PyReadonlyArray1<'_, f64>,
        v: Option<PyReadonlyArray1<'_, f64>>,
        u: Option<PyReadonlyArray1<'_, f64>>,
        omega: Option<f64>,
        harmonics: Option<u8>,
        poly_order: u8,
        family: &str,
        f32: bool,
        smoothing: bool,
        memory: Option<f64>,
    ) -> PyResult<Self> {
        let options = options(omega, harmonics, poly_order, family, f32, smoothing, memory)?;
        let columns = columns("stream".into(), t, x, v, u);
        let (config, estimated, reference) = py.detach(|| {
            guarded("configuring the stream", || {
                host::configure(&columns, &options)
            })
        })?;
        Self::with(config, f32, estimated, reference)
    }

    /// The channels the identifier takes besides x: (velocity v, excitation u).
    fn channels(&self) -> (bool, bool) {
        let channels = match &self.identifier {
            Precision::F32(id) => id.config().channels,
            Precision::F64(id) => id.config().channels,
        };
        (channels.velocity, channels.input)
    }

    /// Feeds a block (t, x and the channels the identifier takes, all of one length);
    /// returns how many of its samples the identifier rejected.
    #[pyo3(signature = (t, x, v=None, u=None))]
    fn push(
        &mut self,
        py: Python<'_>,
        t: PyReadonlyArray1<'_, f64>,
        x: PyReadonlyArray1<'_, f64>,
        v: Option<PyReadonlyArray1<'_, f64>>,
        u: Option<PyReadonlyArray1<'_, f64>>,
    ) -> PyResult<usize> {
        self.usable()?;
        let reference = self.reference;
        let (t, x, v, u) = (
            t.as_array().to_vec(),
            x.as_array()
                .iter()
                .map(|x| x - reference.x)
                .collect::<Vec<_>>(),
            vector(v).map(|v| v.iter().map(|v| v - reference.v).collect::<Vec<_>>()),
            vector(u),
        );
        let (velocity, input) = self.channels();
        let identifier = &mut self.identifier;
        let result = py.detach(|| {
            guarded("feeding the stream", || {
                host::lengths(
                    x.len(),
                    &[
                        ("t", Some(t.len())),
                        ("v", v.as_ref().map(Vec::len)),
                        ("u", u.as_ref().map(Vec::len)),
                    ],
                )?;
                channel("v", "a measured velocity", velocity, v.is_some())?;
                channel("u", "an excitation", input, u.is_some())?;
                Ok(match identifier {
                    Precision::F32(id) => push_all(id, &t, &x, v.as_deref(), u.as_deref()),
                    Precision::F64(id) => push_all(id, &t, &x, v.as_deref(), u.as_deref()),
                })
            })
        });
        self.broken = matches!(result, Err(Error::Panic(_)));
        Ok(result?)
    }

    /// The model now (a screening on request: it changes nothing that follows).
    fn model(&mut self, py: Python<'_>) -> PyResult<Fit> {
        self.usable()?;
        let estimated = self.omega_estimated;
        let reference = self.reference;
        let identifier = &mut self.identifier;
        let result = py.detach(|| {
            guarded("screening the stream", || {
                let (report, config) = match identifier {
                    Precision::F32(id) => {
                        host::report_now(id, estimated, "stream").map(|r| (r, *id.config()))
                    }
                    Precision::F64(id) => {
                        host::report_now(id, estimated, "stream").map(|r| (r, *id.config()))
                    }
                }?;
                let mut report = report;
                reference.restore(&mut report);
                let model = host::reported_model(&report, &config)?;
                Ok((report, config, model))
            })
        });
        self.broken = matches!(result, Err(Error::Panic(_)));
        let (report, config, model) = result?;
        let mut warnings = host::warnings(&report);
        warnings.push(host::NOT_REFINED.to_string());
        Ok(Fit {
            warnings,
            report,
            refined: None,
            config,
            omega_estimated: estimated,
            model,
            reference,
        })
    }
}

/// `Err` when a block's channel does not match the identifier's.
fn channel(name: &str, what: &str, configured: bool, given: bool) -> Result<(), String> {
    match (configured, given) {
        (false, true) => Err(format!(
            "{name}: this stream was configured without {what} {name}, so a block with {name} cannot be fed in (the identifier would reject every sample); push the block without {name}, or start a stream whose calibration block (or model) has {name}."
        )),
        (true, false) => Err(format!(
            "{name}: this stream was configured with {what} {name}, so every block needs {name} (the identifier would reject every sample without it)."
        )),
        _ => Ok(()),
    }
}

impl RawStream {
    fn with(
        config: Config,
        f32: bool,
        omega_estimated: bool,
        reference: Reference,
    ) -> PyResult<Self> {
        let identifier = if f32 {
            Precision::F32(new_identifier::<f32>(config)?)
        } else {
            Precision::F64(new_identifier::<f64>(config)?)
        };
        Ok(Self {
            identifier,
            omega_estimated,
            reference,
            broken: false,
        })
    }

    fn usable(&self) -> PyResult<()> {
        if self.broken {
            return Err(PyRuntimeError::new_err(
                "this stream failed earlier with an internal error and cannot be used again; start a new one.",
            ));
        }
        Ok(())
    }
}

/// The compiled module. Its panic hook records where a panic happened (for [`guarded`]'s
/// sentence) instead of printing it: the sentence reaches Python as the exception.
#[pymodule]
fn _lssi(m: &Bound<'_, PyModule>) -> PyResult<()> {
    panic::set_hook(Box::new(|info| {
        let at = info
            .location()
            .map(|l| format!("{}:{}", l.file(), l.line()));
        PANIC_AT.with(|p| *p.borrow_mut() = at);
    }));
    m.add_class::<Fit>()?;
    m.add_class::<RawStream>()?;
    m.add_class::<SystemFit>()?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(read_recording, m)?)?;
    m.add_function(wrap_pyfunction!(identify_system, m)?)?;
    m.add_function(wrap_pyfunction!(fit_system, m)?)?;
    m.add_function(wrap_pyfunction!(system_start, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    Ok(())
}
