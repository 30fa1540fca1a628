//! The figures themselves: each is drawn once for a PNG and once for an SVG through the same
//! generic code, with one shared style (sizes in pixels, colours, number format).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use lssi_core::{RestoringForce, Term};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use super::Written;
use super::data::{History, Neighbours, Reconstruction, envelope};
use crate::identify::Report;
use crate::identify::simulate::{SimModel, nrmse, simulate};
use crate::recording::Recording;

/// The font every figure uses (DejaVu Sans; licence beside it).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";
const CAPTION: u32 = 30;
const DESC: u32 = 24;
const LABEL: u32 = 20;
const LEGEND: u32 = 21;
/// Points per line before envelope decimation (per panel).
const BUCKETS: usize = 1500;

const RECORDING: RGBColor = RGBColor(90, 90, 90);
const MODEL: RGBColor = RGBColor(213, 94, 0);
const ACCENT: RGBColor = RGBColor(0, 114, 178);
const SELECTED: RGBColor = RGBColor(204, 0, 0);
const GOOD: RGBColor = RGBColor(0, 140, 70);

/// Why a figure was not written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlotError {
    /// The data do not support this figure (a sentence saying why).
    #[error("{0}")]
    Skipped(String),
    /// Drawing or writing failed.
    #[error("cannot draw the figure: {0}.")]
    Draw(String),
}

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for PlotError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        PlotError::Draw(e.to_string())
    }
}

/// Registers the shipped font as plotters' `sans-serif` (once per process).
pub(super) fn register_font() -> Result<(), PlotError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(PlotError::Draw("the embedded font cannot be read".into()))
    }
}

/// The units the axes are labelled with.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Units {
    /// Unit of the displacement x (e.g. `m`, `mm`); `None`: the recording's own unit, unnamed.
    pub x: Option<String>,
}

impl Units {
    /// The unit of x, or `u` (the recording's unit, named in the captions) when unknown.
    fn x_unit(&self) -> String {
        self.x.clone().unwrap_or_else(|| "u".into())
    }
    fn x(&self) -> String {
        format!("displacement x [{}]", self.x_unit())
    }
    fn v(&self) -> String {
        format!("velocity v = x′ [{}/s]", self.x_unit())
    }
    fn error(&self) -> String {
        format!("mean error of x″ [({}/s²)²]", self.x_unit())
    }
    /// A note for titles when the unit is unknown.
    fn note(&self) -> &'static str {
        if self.x.is_some() {
            ""
        } else {
            "   (u: the recording's unit of x)"
        }
    }
}

/// A tick label: 3 significant digits, scientific notation for very large or small values.
fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        let e = a.log10().floor() as i32;
        let m = v / 10f64.powi(e);
        let m = format!("{m:.1}");
        let m = m.trim_end_matches(".0");
        format!("{m}e{e}").replace('-', "−")
    } else {
        let decimals = (2 - a.log10().floor() as i32).clamp(0, 4) as usize;
        let s = format!("{v:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        s.replace('-', "−")
    }
}

/// Tick labels for a linear axis over `[lo, hi]`: as many decimals as the tick step needs,
/// scientific notation with one exponent for very large or small values.
fn ticker(lo: f64, hi: f64) -> impl Fn(&f64) -> String {
    let step = ((hi - lo).abs() / 12.0).max(f64::MIN_POSITIVE);
    let big = lo.abs().max(hi.abs()).max(f64::MIN_POSITIVE);
    move |v: &f64| {
        let v = *v;
        if v.abs() <= 1e-9 * big {
            return "0".into();
        }
        let text = if !(1e-3..1e5).contains(&big) {
            let e = big.log10().floor() as i32;
            let scale = 10f64.powi(e);
            let d = (-(step / scale).log10().floor()).clamp(0.0, 6.0) as usize;
            format!("{:.d$}e{e}", v / scale)
        } else {
            let d = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
            format!("{v:.d$}")
        };
        text.replace('-', "−")
    }
}

/// A coefficient as text (4 significant digits).
fn coefficient(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}").replace('-', "−")
    } else {
        let decimals = if a == 0.0 {
            0
        } else {
            (3 - a.log10().floor() as i32).clamp(0, 6) as usize
        };
        format!("{v:.decimals$}").replace('-', "−")
    }
}

/// The range of finite values, padded by 5 % each side (and widened when flat).
fn padded(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.into_iter().filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    let span = hi - lo;
    let pad = if span > 0.0 {
        0.05 * span
    } else {
        0.5 * lo.abs().max(1e-12)
    };
    (lo - pad, hi + pad)
}

fn font(size: u32) -> TextStyle<'static> {
    (FAMILY, size).into_font().into()
}

/// Something drawn the same way on any backend.
trait Figure {
    /// Pixel size.
    fn size(&self) -> (u32, u32);
    /// Draws on a white root area.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError>;
}

/// Writes `figure` as `<base>-<name>.png` and `.svg`.
fn write(base: &Path, name: &str, figure: &impl Figure) -> Result<Written, PlotError> {
    let file = |ext: &str| {
        let mut s = base.as_os_str().to_owned();
        s.push(format!("-{name}.{ext}"));
        PathBuf::from(s)
    };
    let (png, svg) = (file("png"), file("svg"));
    let size = figure.size();
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present()?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present()?;
    }
    Ok(Written {
        figure: name.into(),
        png,
        svg,
    })
}

/// The legend box every chart uses.
fn legend<'a, DB: DrawingBackend + 'a, X: Ranged, Y: Ranged>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    position: SeriesLabelPosition,
) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.5))
        .label_font(font(LEGEND))
        .margin(12)
        .draw()?;
    Ok(())
}

fn line_legend(color: RGBColor, width: u32) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 28, y)], color.stroke_width(width))
}

// ---------------------------------------------------------------------------------------
// Recording against the model's free simulation (Fig. 7).

struct ModelFigure<'a> {
    t: &'a [f64],
    x: &'a [f64],
    sim: Vec<f64>,
    /// The upper panel's span and caption (the whole record, or its start when the record
    /// holds too many periods to see).
    overview: ((f64, f64), &'static str),
    zoom: (f64, f64),
    title: String,
    /// identify's short-horizon figure, in the upper panel's caption.
    prediction: Option<String>,
    units: &'a Units,
}

impl Figure for ModelFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1500, 1050)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(&self.title, font(CAPTION))?;
        let (top, bottom) = root.split_vertically(480);
        let panels = [
            (&top, self.overview.0, self.overview.1),
            (&bottom, self.zoom, "close-up: the end of the free run"),
        ];
        for (area, (t0, t1), label) in panels {
            let inside = |t: f64| t >= t0 && t <= t1;
            let (ts, xs, ss): (Vec<f64>, Vec<f64>, Vec<f64>) = {
                let mut a = (Vec::new(), Vec::new(), Vec::new());
                for ((t, x), s) in self.t.iter().zip(self.x).zip(&self.sim) {
                    if inside(*t) {
                        a.0.push(*t);
                        a.1.push(*x);
                        a.2.push(*s);
                    }
                }
                a
            };
            let (lo, hi) = padded(xs.iter().chain(ss.iter()).copied());
            // Head room for the legend.
            let hi = hi + 0.3 * (hi - lo);
            let caption = match (&self.prediction, t0 == self.overview.0.0) {
                (Some(p), true) => format!("{label}; {p}"),
                _ => label.to_owned(),
            };
            let mut chart = ChartBuilder::on(area)
                .caption(caption, font(DESC))
                .margin(15)
                .margin_right(40)
                .x_label_area_size(60)
                .y_label_area_size(110)
                .build_cartesian_2d(t0..t1, lo..hi)?;
            chart
                .configure_mesh()
                .x_desc("time t [s]")
                .y_desc(self.units.x())
                .label_style(font(LABEL))
                .axis_desc_style(font(DESC))
                .x_label_formatter(&ticker(t0, t1))
                .y_label_formatter(&ticker(lo, hi))
                .light_line_style(BLACK.mix(0.06))
                .draw()?;
            if label == "whole record" && self.zoom.0 > t0 {
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(self.zoom.0, lo), (self.zoom.1, hi)],
                    ACCENT.mix(0.12).filled(),
                )))?;
            }
            chart
                .draw_series(LineSeries::new(
                    envelope(&ts, &xs, BUCKETS),
                    RECORDING.mix(0.45).stroke_width(6),
                ))?
                .label("recording")
                .legend(line_legend(RECORDING, 6));
            chart
                .draw_series(LineSeries::new(
                    envelope(&ts, &ss, BUCKETS),
                    MODEL.stroke_width(2),
                ))?
                .label("identified model, free run")
                .legend(line_legend(MODEL, 3));
            legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        }
        Ok(())
    }
}

/// The recording against its model's free simulation from the first sample with a velocity.
pub(super) fn model(
    base: &Path,
    recording: &Recording,
    velocity: &[Option<f64>],
    report: &Report,
    prediction: Option<&str>,
    units: &Units,
) -> Result<Written, PlotError> {
    let start = (0..recording.len())
        .find(|&i| {
            recording.x[i].is_finite() && recording.t[i].is_finite() && velocity[i].is_some()
        })
        .ok_or_else(|| PlotError::Skipped("no sample has both x and a velocity.".into()))?;
    let t = &recording.t[start..];
    let x = &recording.x[start..];
    if t.len() < 2 {
        return Err(PlotError::Skipped("too few samples to simulate.".into()));
    }
    let v0 = velocity[start].unwrap_or(0.0);
    let model = SimModel::from_report(report);
    let u = recording.u.as_ref().map(|u| &u[start..]);
    let run = simulate(&model, t, u, (x[0], v0), 2);
    let score = match (run.diverged_at, nrmse(&run.x, x)) {
        (Some(i), _) => format!("the simulation diverged at t = {} s", tick(t[i])),
        (None, Some(e)) => format!("NRMSE {:.1} %", 100.0 * e),
        (None, None) => "NRMSE not defined".into(),
    };
    let span = t[t.len() - 1] - t[0];
    // Close-up: four periods of the excitation (or of the linear resonance), at the end.
    let forced = model
        .terms
        .iter()
        .any(|(term, c)| matches!(term, Term::Sin(_) | Term::Cos(_)) && *c != 0.0);
    // The strongest sin/cos term sets the period of the forced response.
    let strongest = model
        .terms
        .iter()
        .filter_map(|(term, c)| match term {
            Term::Sin(k) | Term::Cos(k) if *c != 0.0 => Some((*k, c.abs())),
            _ => None,
        })
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let period = if let (true, Some((k, _))) = (forced && report.omega > 0.0, strongest) {
        Some(2.0 * std::f64::consts::PI / (f64::from(k) * report.omega))
    } else {
        report
            .resonance_hz
            .or(report.well_resonance_hz)
            .map(|f| 1.0 / f)
    };
    let width = period.map_or(0.1 * span, |p| 3.0 * p).min(span);
    let end = t[t.len() - 1];
    let overview = match period {
        Some(p) if span > 30.0 * p => ((t[0], t[0] + 10.0 * p), "start of the free run"),
        _ => ((t[0], end), "whole record"),
    };
    let figure = ModelFigure {
        t,
        x,
        sim: run.x,
        overview,
        zoom: (end - width, end),
        title: format!(
            "Recording vs. the model, free run from the first sample: {score}{}",
            units.note()
        ),
        prediction: prediction.map(str::to_owned),
        units,
    };
    write(base, "model", &figure)
}

// ---------------------------------------------------------------------------------------
// Mean error of every solution (Figs. 6 and 12).

struct ScreeningFigure<'a> {
    report: &'a Report,
    units: &'a Units,
}

impl Figure for ScreeningFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1500, 1050)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let report = self.report;
        let n = report.solutions.len();
        let selected = report.selected;
        let root = root.titled(
            "Screening of the solutions (MES): held-out mean error of each sparse solution",
            font(CAPTION),
        )?;
        let (top, bottom) = root.split_vertically(560);
        let errors: Vec<f64> = report.solutions.iter().map(|s| s.mean_error).collect();
        let positive = errors
            .iter()
            .copied()
            .filter(|e| *e > 0.0 && e.is_finite())
            .fold(f64::INFINITY, f64::min);
        let floor = if positive.is_finite() {
            positive
        } else {
            1e-12
        };
        let top_value = errors
            .iter()
            .copied()
            .filter(|e| e.is_finite())
            .fold(floor, f64::max);
        let x_range = 0.5..(n as f64 + 0.5);
        let mut chart = ChartBuilder::on(&top)
            .margin(15)
            .margin_right(40)
            .x_label_area_size(55)
            .y_label_area_size(120)
            .build_cartesian_2d(x_range.clone(), (floor / 1.6..top_value * 1.6).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("solution Sᵢ (threshold rises →, fewer terms)")
            .y_desc(self.units.error())
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_labels(n.min(20))
            .x_label_formatter(&|v| format!("S{}", v.round() as i64))
            .y_label_formatter(&|v| tick(*v))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        let points: Vec<(f64, f64)> = errors
            .iter()
            .enumerate()
            .map(|(i, e)| ((i + 1) as f64, e.max(floor)))
            .collect();
        chart
            .draw_series(LineSeries::new(points.clone(), ACCENT.stroke_width(2)))?
            .label("mean error of x″ on held-out rows")
            .legend(line_legend(ACCENT, 3));
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 6, ACCENT.filled())))?;
        if let Some(p) = points.get(selected) {
            let terms = report.solutions[selected].terms.len();
            chart
                .draw_series(std::iter::once(Circle::new(
                    *p,
                    13,
                    SELECTED.stroke_width(4),
                )))?
                .label(format!(
                    "selected: S{} ({terms} terms, error {})",
                    selected + 1,
                    tick(p.1)
                ))
                .legend(|(x, y)| Circle::new((x + 14, y), 9, SELECTED.stroke_width(3)));
        }
        legend(&mut chart, SeriesLabelPosition::UpperLeft)?;

        let max_terms = report
            .solutions
            .iter()
            .map(|s| s.terms.len())
            .max()
            .unwrap_or(1);
        let caption = report.solutions.get(selected).map_or(String::new(), |s| {
            format!("selected S{}: x″ = f({})", selected + 1, s.terms.join(", "))
        });
        let mut chart = ChartBuilder::on(&bottom)
            .caption(caption, font(DESC).color(&SELECTED))
            .margin(15)
            .margin_right(40)
            .x_label_area_size(55)
            .y_label_area_size(120)
            .build_cartesian_2d(x_range, 0.0..(max_terms as f64 + 1.0))?;
        chart
            .configure_mesh()
            .x_desc("solution Sᵢ")
            .y_desc("active terms")
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_labels(n.min(20))
            .x_label_formatter(&|v| format!("S{}", v.round() as i64))
            .y_label_formatter(&|v| format!("{}", v.round() as i64))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        chart.draw_series(report.solutions.iter().enumerate().map(|(i, s)| {
            let x = (i + 1) as f64;
            let color = if i == selected { SELECTED } else { ACCENT };
            Rectangle::new(
                [(x - 0.35, 0.0), (x + 0.35, s.terms.len() as f64)],
                color.mix(0.8).filled(),
            )
        }))?;
        Ok(())
    }
}

/// The screening curve.
pub(super) fn screening(base: &Path, report: &Report, units: &Units) -> Result<Written, PlotError> {
    if report.solutions.is_empty() {
        return Err(PlotError::Skipped("the sweep has no solutions.".into()));
    }
    write(base, "screening", &ScreeningFigure { report, units })
}

// ---------------------------------------------------------------------------------------
// ε(K) per channel (Fig. 4).

struct NeighboursFigure<'a> {
    neighbours: &'a Neighbours,
    used: (u8, u8),
    units: &'a Units,
}

impl NeighboursFigure<'_> {
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        title: &str,
        unit: &str,
        r: &Reconstruction,
        used: u8,
    ) -> Result<(), PlotError> {
        let (lo, hi) = padded(r.rms.iter().map(|p| p.1));
        let k_lo = r.rms.first().map_or(2, |p| p.0) as f64 - 0.5;
        let k_hi = r.rms.last().map_or(8, |p| p.0) as f64 + 0.5;
        let mut chart = ChartBuilder::on(area)
            .caption(title, font(DESC))
            .margin(15)
            .margin_right(30)
            .x_label_area_size(60)
            .y_label_area_size(120)
            .build_cartesian_2d(k_lo..k_hi, lo..hi)?;
        chart
            .configure_mesh()
            .x_desc("neighbours K")
            .y_desc(format!("RMS reconstruction error [{unit}]"))
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_labels(r.rms.len())
            .x_label_formatter(&|v| format!("{}", v.round() as i64))
            .y_label_formatter(&ticker(lo, hi))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        let points: Vec<(f64, f64)> = r.rms.iter().map(|(k, e)| (*k as f64, *e)).collect();
        chart
            .draw_series(LineSeries::new(points.clone(), ACCENT.stroke_width(3)))?
            .label("ε(K), leave-one-out, whole record")
            .legend(line_legend(ACCENT, 3));
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 6, ACCENT.filled())))?;
        if used > 0 {
            let k = f64::from(used);
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(k, lo), (k, hi)],
                    10,
                    6,
                    SELECTED.stroke_width(2),
                ))?
                .label(format!("K used by lssi identify: {used}"))
                .legend(line_legend(SELECTED, 2));
        }
        if let Some(p) = points.iter().find(|p| p.0 as usize == r.chosen) {
            chart
                .draw_series(std::iter::once(Circle::new(*p, 11, GOOD.stroke_width(3))))?
                .label(format!("least ε(K) (within 1 %): K = {}", r.chosen))
                .legend(|(x, y)| Circle::new((x + 14, y), 8, GOOD.stroke_width(3)));
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    }
}

impl Figure for NeighboursFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1600, 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(
            &format!(
                "k-neighbour smoothing: reconstruction error ε(K) per channel{}",
                self.units.note()
            ),
            font(CAPTION),
        )?;
        let (left, right) = root.split_horizontally(800);
        let unit = self.units.x_unit();
        self.panel(
            &left,
            "(a) displacement x",
            &unit,
            &self.neighbours.x,
            self.used.0,
        )?;
        self.panel(
            &right,
            "(b) velocity v = x′",
            &format!("{unit}/s"),
            &self.neighbours.v,
            self.used.1,
        )?;
        Ok(())
    }
}

/// ε(K) of x and v.
pub(super) fn neighbours(
    base: &Path,
    neighbours: &Neighbours,
    report: &Report,
    units: &Units,
) -> Result<Written, PlotError> {
    let figure = NeighboursFigure {
        neighbours,
        used: (report.k.x, report.k.v),
        units,
    };
    write(base, "k-neighbours", &figure)
}

// ---------------------------------------------------------------------------------------
// Coefficients after each screening.

struct CoefficientsFigure<'a> {
    history: &'a History,
    /// (name, index in the history's library, final value from the report).
    terms: Vec<(String, usize, f64)>,
    rows: usize,
    columns: usize,
}

impl Figure for CoefficientsFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1600, 90 + 330 * self.rows as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(
            "Coefficients identified from the record up to time t (dashed: the whole record)",
            font(CAPTION),
        )?;
        let areas = root.split_evenly((self.rows, self.columns));
        let points = &self.history.points;
        let (_, t1) = padded(points.iter().map(|p| p.0));
        let t0 = 0.0;
        for (area, (name, j, last)) in areas.iter().zip(&self.terms) {
            let series: Vec<(f64, f64)> = points
                .iter()
                .filter_map(|(t, c)| c.get(*j).map(|c| (*t, *c)))
                .collect();
            // The range covers the later half of the run and ±2 % of the final value;
            // early excursions beyond it are drawn at the edge (hollow markers).
            let later = series.len() / 2;
            let (lo, hi) = padded(
                series[later..]
                    .iter()
                    .map(|p| p.1)
                    .chain([last * 0.98, last * 1.02]),
            );
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!("{name}   (whole record: {})", coefficient(*last)),
                    font(DESC),
                )
                .margin(12)
                .margin_right(30)
                .x_label_area_size(50)
                .y_label_area_size(110)
                .build_cartesian_2d(t0..t1, lo..hi)?;
            chart
                .configure_mesh()
                .x_desc("time t [s]")
                .label_style(font(LABEL))
                .axis_desc_style(font(LABEL))
                .x_label_formatter(&ticker(t0, t1))
                .y_label_formatter(&ticker(lo, hi))
                .y_labels(5)
                .light_line_style(BLACK.mix(0.06))
                .draw()?;
            chart.draw_series(DashedLineSeries::new(
                vec![(t0, *last), (t1, *last)],
                10,
                6,
                MODEL.stroke_width(2),
            ))?;
            let clipped: Vec<(f64, f64)> =
                series.iter().map(|(t, c)| (*t, c.clamp(lo, hi))).collect();
            chart.draw_series(LineSeries::new(clipped.clone(), ACCENT.stroke_width(2)))?;
            chart.draw_series(series.iter().zip(&clipped).map(|(raw, p)| {
                let style = if raw.1 == p.1 {
                    ACCENT.filled()
                } else {
                    ACCENT.stroke_width(2)
                };
                Circle::new(*p, 5, style)
            }))?;
        }
        Ok(())
    }
}

/// The selected terms' coefficients as the record grows.
pub(super) fn coefficients(
    base: &Path,
    history: &History,
    report: &Report,
) -> Result<Written, PlotError> {
    if history.points.is_empty() {
        return Err(PlotError::Skipped(
            "no prefix of the record gave a model.".into(),
        ));
    }
    let terms: Vec<(String, usize, f64)> = report
        .terms
        .iter()
        .filter_map(|t| {
            history
                .names
                .iter()
                .position(|n| *n == t.term)
                .map(|j| (t.term.clone(), j, t.coef))
        })
        .collect();
    if terms.is_empty() {
        return Err(PlotError::Skipped(
            "the selected model has no terms.".into(),
        ));
    }
    let columns = if terms.len() > 3 { 2 } else { 1 };
    let rows = terms.len().div_ceil(columns);
    let figure = CoefficientsFigure {
        history,
        terms,
        rows,
        columns,
    };
    write(base, "coefficients", &figure)
}

// ---------------------------------------------------------------------------------------
// Phase portrait with the equilibria (wells) of the unforced model.

struct PhaseFigure<'a> {
    points: Vec<(f64, f64)>,
    /// (x, stable) of each equilibrium in the recording's coordinates.
    equilibria: Vec<(f64, bool)>,
    v_origin: f64,
    title: String,
    units: &'a Units,
}

impl Figure for PhaseFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1300, 1050)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let root = root.titled(&self.title, font(CAPTION))?;
        let (x0, x1) = padded(
            self.points
                .iter()
                .map(|p| p.0)
                .chain(self.equilibria.iter().map(|e| e.0)),
        );
        let (v0, v1) = padded(self.points.iter().map(|p| p.1).chain([self.v_origin]));
        let mut chart = ChartBuilder::on(&root)
            .margin(20)
            .margin_right(40)
            .x_label_area_size(65)
            .y_label_area_size(120)
            .build_cartesian_2d(x0..x1, v0..v1)?;
        chart
            .configure_mesh()
            .x_desc(self.units.x())
            .y_desc(self.units.v())
            .label_style(font(LABEL))
            .axis_desc_style(font(DESC))
            .x_label_formatter(&ticker(x0, x1))
            .y_label_formatter(&ticker(v0, v1))
            .light_line_style(BLACK.mix(0.06))
            .draw()?;
        chart
            .draw_series(LineSeries::new(
                self.points.clone(),
                ACCENT.mix(0.45).stroke_width(1),
            ))?
            .label("recording")
            .legend(line_legend(ACCENT, 3));
        let wells: Vec<(f64, f64)> = self
            .equilibria
            .iter()
            .filter(|e| e.1)
            .map(|e| (e.0, self.v_origin))
            .collect();
        let saddles: Vec<(f64, f64)> = self
            .equilibria
            .iter()
            .filter(|e| !e.1)
            .map(|e| (e.0, self.v_origin))
            .collect();
        let double = wells.len() > 1;
        if !wells.is_empty() {
            for w in wells.iter().filter(|_| double) {
                chart.draw_series(DashedLineSeries::new(
                    vec![(w.0, v0), (w.0, v1)],
                    10,
                    6,
                    GOOD.mix(0.8).stroke_width(2),
                ))?;
            }
            chart
                .draw_series(wells.iter().map(|p| Circle::new(*p, 12, GOOD.filled())))?
                .label(format!(
                    "{} at x = {}",
                    if double {
                        "wells (stable equilibria)"
                    } else {
                        "stable equilibrium"
                    },
                    wells
                        .iter()
                        .map(|w| tick(w.0))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
                .legend(|(x, y)| Circle::new((x + 14, y), 9, GOOD.filled()));
        }
        if !saddles.is_empty() {
            chart
                .draw_series(
                    saddles
                        .iter()
                        .map(|p| Cross::new(*p, 12, SELECTED.stroke_width(4))),
                )?
                .label(format!(
                    "saddle (unstable equilibrium) at x = {}",
                    saddles
                        .iter()
                        .map(|w| tick(w.0))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
                .legend(|(x, y)| Cross::new((x + 14, y), 9, SELECTED.stroke_width(3)));
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    }
}

/// Real roots of the model's unforced restoring force p(x) = Σ c₍ₐ,₀₎ (x − offset)ᵃ within
/// `[lo, hi]`, with whether each is stable (p′ < 0): [`RestoringForce::equilibria`].
fn equilibria(report: &Report, lo: f64, hi: f64) -> Vec<(f64, bool)> {
    let force = RestoringForce::from_terms(report.model.iter().copied(), report.offsets[0]);
    let mut out = Vec::new();
    force.equilibria(lo, hi, |e| out.push((e.x, e.stable)));
    out
}

/// The phase portrait.
pub(super) fn phase(
    base: &Path,
    recording: &Recording,
    velocity: &[Option<f64>],
    report: &Report,
    units: &Units,
) -> Result<Written, PlotError> {
    let all: Vec<(f64, f64)> = recording
        .x
        .iter()
        .zip(velocity)
        .filter_map(|(x, v)| v.filter(|_| x.is_finite()).map(|v| (*x, v)))
        .collect();
    if all.len() < 2 {
        return Err(PlotError::Skipped(
            "no sample has both x and a velocity.".into(),
        ));
    }
    let step = all.len().div_ceil(40_000).max(1);
    let points: Vec<(f64, f64)> = all.iter().step_by(step).copied().collect();
    let (lo, hi) = padded(points.iter().map(|p| p.0));
    let equilibria = equilibria(report, lo, hi);
    let title = match (report.wells, report.well_resonance_hz) {
        (Some(w), Some(f)) => format!(
            "Phase portrait: double well, wells at x = {} ± {} (in-well resonance {} Hz)",
            tick(report.offsets[0]),
            tick(w),
            tick(f)
        ),
        _ => match report.resonance_hz {
            Some(f) => format!(
                "Phase portrait: single well, linear resonance {} Hz",
                tick(f)
            ),
            None => "Phase portrait".into(),
        },
    };
    let figure = PhaseFigure {
        points,
        equilibria,
        v_origin: report.offsets[1],
        title: format!("{title}{}", units.note()),
        units,
    };
    write(base, "phase", &figure)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(2.5), "2.5");
        assert_eq!(tick(-0.125), "−0.125");
        assert_eq!(tick(1.0e7), "1e7");
        assert_eq!(tick(2.5e-4), "2.5e−4");
        assert_eq!(tick(40.0), "40");
    }

    #[test]
    fn padding_widens_a_flat_range() {
        let (lo, hi) = padded([3.0, 3.0]);
        assert!(lo < 3.0 && hi > 3.0);
        assert_eq!(padded([f64::NAN]), (-1.0, 1.0));
    }
}
