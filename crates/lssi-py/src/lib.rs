//! The compiled part of the `lssi` Python package (`lssi._lssi`): the identification that
//! `lssi identify` runs, from NumPy arrays or a file, and a streaming identifier. The
//! Python layer (`python/lssi/__init__.py`) adds the PySINDy-like `Model` and `Stream`
//! classes, input checks and pandas support on top of it.

mod host;

use lssi_core::{Config, PolyFamily, Real};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use host::{Columns, HostIdentifier, Options, Report};

fn value_error(message: String) -> PyErr {
    PyValueError::new_err(message)
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
    harmonics: u8,
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
    config: Config,
    omega_estimated: bool,
    /// What `lssi identify --json` ends with.
    warnings: Vec<String>,
}

#[pymethods]
impl Fit {
    /// The `lssi identify --json` object, as a string.
    fn json(&self) -> String {
        host::json(&self.report, &self.warnings)
    }

    /// The `lssi identify` text report.
    fn text(&self) -> String {
        host::text(&self.report)
    }

    /// The selected equation, one line.
    fn equation(&self) -> String {
        host::equation(&self.report)
    }

    /// The library's term names, in order.
    fn feature_names(&self) -> Vec<String> {
        host::feature_names(&self.config)
    }

    /// The selected model's active terms and coefficients (physical units).
    fn terms(&self) -> Vec<(String, f64)> {
        self.report
            .model
            .iter()
            .map(|(t, c)| (t.name(self.report.omega).to_string(), *c))
            .collect()
    }

    /// Free run on the grid `t` from (x0, v0); `u` the measured excitation on the same grid.
    #[pyo3(signature = (t, x0, v0, u=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArray1<'py, f64>,
        x0: f64,
        v0: f64,
        u: Option<PyReadonlyArray1<'py, f64>>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let t = t.as_array().to_vec();
        let u = vector(u);
        let report = &self.report;
        let (x, v) = py.detach(|| host::simulate(report, &t, u.as_deref(), x0, v0));
        (PyArray1::from_vec(py, x), PyArray1::from_vec(py, v))
    }
}

/// `lssi identify` on arrays (all of one length; `v` and `u` optional).
#[pyfunction]
#[pyo3(signature = (t, x, v, u, omega, harmonics, poly_order, family, f32, smoothing, memory))]
#[allow(clippy::too_many_arguments)]
fn fit(
    py: Python<'_>,
    t: PyReadonlyArray1<'_, f64>,
    x: PyReadonlyArray1<'_, f64>,
    v: Option<PyReadonlyArray1<'_, f64>>,
    u: Option<PyReadonlyArray1<'_, f64>>,
    omega: Option<f64>,
    harmonics: u8,
    poly_order: u8,
    family: &str,
    f32: bool,
    smoothing: bool,
    memory: Option<f64>,
) -> PyResult<Fit> {
    let options = options(omega, harmonics, poly_order, family, f32, smoothing, memory)?;
    let columns = Columns {
        name: "array".into(),
        t: t.as_array().to_vec(),
        x: x.as_array().to_vec(),
        v: vector(v),
        u: vector(u),
    };
    run(py, columns, &options)
}

fn run(py: Python<'_>, columns: Columns, options: &Options) -> PyResult<Fit> {
    let (report, config, warnings) = py
        .detach(|| host::fit(columns, options))
        .map_err(value_error)?;
    Ok(Fit {
        omega_estimated: report.omega_estimated,
        report,
        config,
        warnings,
    })
}

/// `lssi identify FILE` (columns t, x and, when the header has them, v and u).
#[pyfunction]
#[pyo3(signature = (path, omega, harmonics, poly_order, family, f32, smoothing, memory))]
#[allow(clippy::too_many_arguments)]
fn identify_file(
    py: Python<'_>,
    path: &str,
    omega: Option<f64>,
    harmonics: u8,
    poly_order: u8,
    family: &str,
    f32: bool,
    smoothing: bool,
    memory: Option<f64>,
) -> PyResult<Fit> {
    let options = options(omega, harmonics, poly_order, family, f32, smoothing, memory)?;
    let columns = py.detach(|| host::read(path)).map_err(value_error)?;
    run(py, columns, &options)
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
    let c = py.detach(|| host::read(path)).map_err(value_error)?;
    Ok((
        PyArray1::from_vec(py, c.t),
        PyArray1::from_vec(py, c.x),
        c.v.map(|v| PyArray1::from_vec(py, v)),
        c.u.map(|u| PyArray1::from_vec(py, u)),
    ))
}

/// The configuration `lssi identify` would choose for these arrays, as a `Fit`-less handle:
/// a streaming identifier configured from a calibration block.
enum Precision {
    F32(Box<HostIdentifier<f32>>),
    F64(Box<HostIdentifier<f64>>),
}

/// A streaming identifier: samples in blocks, the model at any time.
#[pyclass(module = "lssi._lssi")]
struct RawStream {
    identifier: Precision,
    omega_estimated: bool,
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
    /// A streaming identifier with the configuration a fit ran with (the same results as that
    /// fit on the same samples).
    #[staticmethod]
    fn like(fit: &Fit) -> PyResult<Self> {
        Self::with(
            fit.config,
            fit.report.precision == "f32",
            fit.omega_estimated,
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
        harmonics: u8,
        poly_order: u8,
        family: &str,
        f32: bool,
        smoothing: bool,
        memory: Option<f64>,
    ) -> PyResult<Self> {
        let options = options(omega, harmonics, poly_order, family, f32, smoothing, memory)?;
        let columns = Columns {
            name: "stream".into(),
            t: t.as_array().to_vec(),
            x: x.as_array().to_vec(),
            v: vector(v),
            u: vector(u),
        };
        let (config, estimated) = py
            .detach(|| host::configure(&columns, &options))
            .map_err(value_error)?;
        Self::with(config, f32, estimated)
    }

    /// Feeds a block; returns how many of its samples the identifier rejected.
    #[pyo3(signature = (t, x, v=None, u=None))]
    fn push(
        &mut self,
        py: Python<'_>,
        t: PyReadonlyArray1<'_, f64>,
        x: PyReadonlyArray1<'_, f64>,
        v: Option<PyReadonlyArray1<'_, f64>>,
        u: Option<PyReadonlyArray1<'_, f64>>,
    ) -> usize {
        let (t, x, v, u) = (
            t.as_array().to_vec(),
            x.as_array().to_vec(),
            vector(v),
            vector(u),
        );
        let identifier = &mut self.identifier;
        py.detach(|| match identifier {
            Precision::F32(id) => push_all(id, &t, &x, v.as_deref(), u.as_deref()),
            Precision::F64(id) => push_all(id, &t, &x, v.as_deref(), u.as_deref()),
        })
    }

    /// The model now (a screening on request: it changes nothing that follows).
    fn model(&mut self, py: Python<'_>) -> PyResult<Fit> {
        let estimated = self.omega_estimated;
        let identifier = &mut self.identifier;
        let (report, config) = py
            .detach(|| match identifier {
                Precision::F32(id) => {
                    host::report_now(id, estimated, "stream").map(|r| (r, *id.config()))
                }
                Precision::F64(id) => {
                    host::report_now(id, estimated, "stream").map(|r| (r, *id.config()))
                }
            })
            .map_err(value_error)?;
        Ok(Fit {
            warnings: host::warnings(&report),
            report,
            config,
            omega_estimated: estimated,
        })
    }
}

impl RawStream {
    fn with(config: Config, f32: bool, omega_estimated: bool) -> PyResult<Self> {
        let identifier = if f32 {
            Precision::F32(new_identifier::<f32>(config)?)
        } else {
            Precision::F64(new_identifier::<f64>(config)?)
        };
        Ok(Self {
            identifier,
            omega_estimated,
        })
    }
}

/// The compiled module.
#[pymodule]
fn _lssi(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Fit>()?;
    m.add_class::<RawStream>()?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(identify_file, m)?)?;
    m.add_function(wrap_pyfunction!(read_recording, m)?)?;
    Ok(())
}
