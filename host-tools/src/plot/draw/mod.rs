//! The figures themselves: each is drawn once for a PNG and once for an SVG through the same
//! generic code, with one shared style (sizes in pixels, colours, number format).

mod coefficients;
mod model;
mod neighbours;
mod phase;
mod screening;
mod system;

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
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");
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
    /// Drawing failed.
    #[error("cannot draw the figure: {0}.")]
    Draw(String),
    /// The figure's file cannot be written.
    #[error("{}: cannot write the figure: {reason}.", .path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong (what the operating system said).
        reason: String,
    },
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
    // Each file is created first, so that a path that cannot be written (a missing or
    // read-only folder, a folder in the file's place) fails with what the system says; a
    // failure to save the figure is named with its file too. (A figure the data cannot be
    // drawn from stays a `Draw` error: skipped with a note.)
    let failed = |path: &Path, reason: String| PlotError::Write {
        path: path.to_path_buf(),
        reason,
    };
    std::fs::File::create(&png).map_err(|e| failed(&png, e.to_string()))?;
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present().map_err(|e| failed(&png, e.to_string()))?;
    }
    std::fs::File::create(&svg).map_err(|e| failed(&svg, e.to_string()))?;
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present().map_err(|e| failed(&svg, e.to_string()))?;
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

pub(super) use coefficients::coefficients;
pub(super) use model::model;
pub(super) use neighbours::neighbours;
pub(super) use phase::phase;
pub(super) use screening::screening;
pub(super) use system::{power_frequency, power_load, voltage};

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
