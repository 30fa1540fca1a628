//! lssi on measured data: the bistable piezo-magneto-elastic harvester (BistableX), the
//! magneto-mechanical beam (FrID) and the Silverbox benchmark.
//!
//! ```text
//! cargo run --release -p lssi-host --example real_data -- [--data DIR]
//! ```
//!
//! `DIR` defaults to `../shared/data/real` relative to the repository root; the data are read
//! from there and never copied (their licences are in each folder's README.txt). For each
//! record the example fits the streaming identifier (f32, as on a device) on the first part,
//! then simulates the identified model freely (RK4 on the record's time grid, the measured
//! excitation interpolated) over the held-out rest from the measured initial state, and prints
//! the equation, whether it is a double well and where its wells are, and the NRMSE of the
//! free simulation (RMS error / standard deviation of the measured response); for Silverbox
//! the benchmark's RMSE in mV on its test split.
//!
//! Preprocessing and library, per record (`--only KEY` runs one):
//! - **BistableX** (`chaos`, `intrawell`; `continuous_6p5Hz/`): the tip's absolute velocity
//!   is 0.1 m/s per volt of the vibrometer; the base velocity is the integral of the base
//!   acceleration (9.81 m/s² per g). The relative velocity v = v_tip − v_base has its mean
//!   removed and is integrated (trapezoidal rule, least-squares line removed); then a centred
//!   4 s moving average is removed from x and from v (a high-pass below 0.25 Hz, 26 forcing
//!   periods: the drift of the integrals, which otherwise smears the wells). x is in metres,
//!   v is a measured channel, u the base acceleration in m/s². Library: x^k, x^(k−1)v for
//!   k = 1, 3 (`OddFamilies`, a symmetric double well), u, no sin/cos. Fit on the first 60 %,
//!   validate on the rest.
//! - **FrID beam** (`frid`): x is `strain0_response` in µε about its rest value (the mean
//!   of the noise floor after 20 s). The forced part (0–11 s) is a single-frequency steady
//!   state, on which x, x' and the command span two dimensions and cannot separate stiffness
//!   from forcing gain, so the model is fitted, as the data's authors do, on the free decay
//!   (11–15 s, the command is 0: no u) and validated on the rest of the decay (15–20 s).
//!   Library: all monomials to order 3 (the response's mean moves with its amplitude: a
//!   quadratic term).
//! - **Silverbox** (`silverbox`, `silverbox-p9`): x = V2, u = V1, means removed (the
//!   README's instruction); fit on the training multisine [40650, 105712), simulate on the
//!   test multisine [105712, 127400) and on the arrow without extrapolation [100, 32100);
//!   RMSE in mV. Library: `OddFamilies` to order 3 and u. `silverbox-p9` sets the window to
//!   15 samples at degree 9 by hand: at about 10 samples per period the shortest window is
//!   still biased at degree 7, and the data-driven choice stops at degree 7.
//!
//! The derivative window and degree are otherwise chosen from the data by `lssi identify`'s
//! rule; `LSSI_WINDOW=W,D` in the environment overrides them (W samples, degree D).
//!
//! Besides the free run, every record reports a short-horizon error: the model restarted
//! from the measured state every forcing period (or mean period) on the first held-out
//! stretch, the pieces joined. It is the meaningful figure for a chaotic record, whose free
//! run cannot track (NRMSE ≈ √2 for any model with the right attractor). The initial
//! velocity without a measured v is the derivative of the identifier's own local polynomial
//! centred on the start.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use lssi_core::PolyFamily;
use lssi_core::derivative::Taps;
use lssi_host::identify::simulate::{SimModel, nrmse, rmse, simulate};
use lssi_host::identify::{self, Options, Report};
use lssi_host::recording::{ColumnNames, Recording};

/// One column of a CSV file, by header name.
fn read_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        format!(
            "{}: cannot be read ({e}); give the folder that holds bistablex/, frid-magmech/ and silverbox/ with --data DIR.",
            path.display()
        )
    })?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| format!("{}: is empty.", path.display()))?
        .split(',')
        .collect();
    let index: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h.trim() == *n)
                .ok_or_else(|| format!("{}: has no column '{n}'.", path.display()))
        })
        .collect::<Result<_, _>>()?;
    let mut columns = vec![Vec::new(); names.len()];
    for (row, line) in lines.enumerate() {
        let fields: Vec<&str> = line.split(',').collect();
        for (c, &i) in index.iter().enumerate() {
            let value = fields
                .get(i)
                .and_then(|f| f.trim().parse::<f64>().ok())
                .ok_or_else(|| format!("{}: line {}: bad value.", path.display(), row + 2))?;
            columns[c].push(value);
        }
    }
    Ok(columns)
}

/// Trapezoidal running integral, starting at 0.
fn integrate(t: &[f64], y: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(y.len());
    let mut sum = 0.0;
    out.push(0.0);
    for i in 1..y.len() {
        sum += 0.5 * (y[i] + y[i - 1]) * (t[i] - t[i - 1]);
        out.push(sum);
    }
    out
}

/// `y` minus its least-squares straight line in `t`.
fn detrend(t: &[f64], y: &[f64]) -> Vec<f64> {
    let n = y.len() as f64;
    let (mt, my) = (t.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut stt, mut sty) = (0.0, 0.0);
    for (a, b) in t.iter().zip(y) {
        stt += (a - mt) * (a - mt);
        sty += (a - mt) * (b - my);
    }
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    t.iter()
        .zip(y)
        .map(|(a, b)| b - my - slope * (a - mt))
        .collect()
}

/// `y` minus its mean.
fn demean(y: &[f64]) -> Vec<f64> {
    let m = y.iter().sum::<f64>() / y.len().max(1) as f64;
    y.iter().map(|v| v - m).collect()
}

/// Slope of the least-squares line through the 11 samples centred on `i`.
fn slope_at(t: &[f64], x: &[f64], i: usize) -> f64 {
    let lo = i.saturating_sub(5);
    let hi = (i + 6).min(x.len());
    detrend_slope(&t[lo..hi], &x[lo..hi])
}

fn detrend_slope(t: &[f64], y: &[f64]) -> f64 {
    let n = y.len() as f64;
    let (mt, my) = (t.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut stt, mut sty) = (0.0, 0.0);
    for (a, b) in t.iter().zip(y) {
        stt += (a - mt) * (a - mt);
        sty += (a - mt) * (b - my);
    }
    if stt > 0.0 { sty / stt } else { 0.0 }
}

/// A recording in memory.
fn recording(name: &str, t: &[f64], x: &[f64], v: Option<&[f64]>, u: Option<&[f64]>) -> Recording {
    Recording {
        path: PathBuf::from(name),
        t: t.to_vec(),
        x: x.to_vec(),
        v: v.map(<[f64]>::to_vec),
        u: u.map(<[f64]>::to_vec),
        columns: ColumnNames {
            v: v.map(|_| "v".to_owned()),
            u: u.map(|_| "u".to_owned()),
            ..ColumnNames::default()
        },
    }
}

/// `y` minus its centred moving average over `len` samples (shortened at the ends): a
/// high-pass with its first zero at 1/(`len`·dt), for the drift of an integrated velocity.
fn remove_moving_average(y: &[f64], len: usize) -> Vec<f64> {
    let mut prefix = Vec::with_capacity(y.len() + 1);
    prefix.push(0.0);
    for v in y {
        prefix.push(prefix.last().copied().unwrap_or(0.0) + v);
    }
    let half = len / 2;
    (0..y.len())
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(half), (i + half + 1).min(y.len()));
            y[i] - (prefix[hi] - prefix[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// One record as a user would run it: the preprocessed channels, the split and the options.
struct Case {
    /// Short name (`--only NAME`).
    key: &'static str,
    /// What the record is and how it is split.
    title: String,
    t: Vec<f64>,
    x: Vec<f64>,
    v: Option<Vec<f64>>,
    u: Option<Vec<f64>>,
    /// Samples the identifier is fitted on, [a, b).
    fit: (usize, usize),
    /// Held-out stretches the model is simulated on, [c, d), with a label.
    validate: Vec<(&'static str, (usize, usize))>,
    /// Library options.
    options: Options,
    /// Short-horizon restarts every `horizon` samples (for models that cannot be run freely
    /// over a long stretch: chaotic or drifting records), with a label for the horizon.
    horizon: (usize, &'static str),
    /// Unit of x and the factor from it to the unit the RMSE is reported in.
    unit: (&'static str, f64),
    /// A derivative window and degree set by hand instead of the data's choice.
    window: Option<(usize, u8)>,
}

/// The error of one simulation.
#[derive(Clone, Copy)]
enum Error {
    Ok { nrmse: f64, rmse: f64 },
    Diverged(f64),
    None,
}

/// What one case reports.
struct Outcome {
    report: Report,
    /// Free runs over each held-out stretch.
    free: Vec<(&'static str, Error)>,
    /// Short-horizon restarts over the first held-out stretch.
    short: Error,
}

/// x' at sample `i`: the measured v, or the derivative of the identifier's own local
/// polynomial (its window and degree) centred on `i` (the slope of a short line is no
/// estimate at 10 samples per period, as on Silverbox).
fn velocity_at(case: &Case, report: &Report, i: usize) -> f64 {
    if let Some(v) = &case.v {
        return v[i];
    }
    let half = (report.window - 1) / 2;
    let taps: Option<Taps<f64, { identify::WINDOW_CAPACITY }>> = Taps::design(
        report.window,
        usize::from(report.degree),
        report.sample_period,
    )
    .ok();
    match taps {
        Some(taps) if i >= half && i + half < case.x.len() => {
            taps.apply(1, &case.x[i - half..=i + half], &[])
        }
        _ => slope_at(&case.t, &case.x, i),
    }
}

fn error_of(
    case: &Case,
    sim: &lssi_host::identify::simulate::Simulation,
    c: usize,
    d: usize,
) -> Error {
    match (
        nrmse(&sim.x, &case.x[c..d]),
        rmse(&sim.x, &case.x[c..d]),
        sim.diverged_at,
    ) {
        (Some(nrmse), Some(rmse), _) => Error::Ok { nrmse, rmse },
        (_, _, Some(i)) => Error::Diverged(case.t[c + i]),
        _ => Error::None,
    }
}

/// Fits on `case.fit`, then simulates on each held-out stretch, freely and restarted from the
/// measured state every `case.horizon` samples.
fn run_case(case: &Case) -> Result<Outcome, String> {
    let (a, b) = case.fit;
    let train = recording(
        case.key,
        &case.t[a..b],
        &case.x[a..b],
        case.v.as_deref().map(|v| &v[a..b]),
        case.u.as_deref().map(|u| &u[a..b]),
    );
    let (mut config, estimated) = identify::configure(&train, &case.options).map_err(|e| e.0)?;
    if let Some((w, d)) = std::env::var("LSSI_WINDOW")
        .ok()
        .and_then(|s| {
            let (w, d) = s.split_once(',')?;
            Some((w.parse().ok()?, d.parse().ok()?))
        })
        .or(case.window)
    {
        config.window = w;
        config.derivative_degree = d;
    }
    let report = identify::run::<f32>(&train, config, estimated).map_err(|e| e.0)?;
    let model = SimModel::from_report(&report);
    let u = case.u.as_deref();
    let free = case
        .validate
        .iter()
        .map(|&(label, (c, d))| {
            let sim = simulate(
                &model,
                &case.t[c..d],
                u.map(|u| &u[c..d]),
                (case.x[c], velocity_at(case, &report, c)),
                4,
            );
            (label, error_of(case, &sim, c, d))
        })
        .collect();
    // Restarted every `horizon` samples from the measured state; the pieces are joined.
    let (c, d) = case.validate[0].1;
    let h = case.horizon.0.max(1);
    let mut joined = lssi_host::identify::simulate::Simulation {
        x: Vec::with_capacity(d - c),
        v: Vec::with_capacity(d - c),
        diverged_at: None,
    };
    let mut start = c;
    while start < d {
        let end = (start + h).min(d);
        let piece = simulate(
            &model,
            &case.t[start..end],
            u.map(|u| &u[start..end]),
            (case.x[start], velocity_at(case, &report, start)),
            4,
        );
        if joined.diverged_at.is_none() {
            joined.diverged_at = piece.diverged_at.map(|i| start - c + i);
        }
        joined.x.extend(piece.x);
        joined.v.extend(piece.v);
        start = end;
    }
    Ok(Outcome {
        short: error_of(case, &joined, c, d),
        free,
        report,
    })
}

/// The selected equation with 3 significant digits, for the table.
fn equation(report: &Report) -> String {
    let mut out = String::from("x'' =");
    for (i, t) in report.terms.iter().enumerate() {
        let value = format!("{:.3e}", t.coef.abs());
        let value = match value.split_once('e') {
            Some((m, "0")) => m.to_string(),
            Some((m, e)) => format!("{m}e{e}"),
            None => value,
        };
        let term = if t.term == "1" {
            String::new()
        } else {
            format!(" {}", t.term)
        };
        let sign = match (i, t.coef < 0.0) {
            (0, true) => " −",
            (0, false) => " ",
            (_, true) => " − ",
            (_, false) => " + ",
        };
        out.push_str(&format!("{sign}{value}{term}"));
    }
    if report.terms.is_empty() {
        out.push_str(" 0");
    }
    out
}

fn wells(report: &Report, unit: &str, scale: f64) -> String {
    let ox = report.offsets[0];
    match report.wells {
        Some(w) => format!(
            "yes: {:.3} and {:.3} {unit} ({:.2} Hz in a well)",
            (ox - w) * scale,
            (ox + w) * scale,
            report.well_resonance_hz.unwrap_or(f64::NAN)
        ),
        None => match report.resonance_hz {
            Some(f) => format!("no: single well, {f:.2} Hz"),
            None => "no well (linear term not restoring)".into(),
        },
    }
}

fn describe(e: Error, unit: &str, scale: f64) -> String {
    match e {
        Error::Ok { nrmse, rmse } => format!("NRMSE {nrmse:.3} (RMSE {:.3} {unit})", rmse * scale),
        Error::Diverged(t) => format!("diverged at {t:.2} s"),
        Error::None => "no error (constant record)".into(),
    }
}

fn print_case(case: &Case, o: &Outcome) {
    let (unit, scale) = case.unit;
    println!("== {}", case.title);
    let text = identify::render(&o.report);
    for line in text.lines().take(2) {
        println!("{line}");
    }
    println!("double well: {}", wells(&o.report, unit, scale));
    for (label, e) in &o.free {
        println!("free simulation, {label}: {}", describe(*e, unit, scale));
    }
    println!(
        "restarted from the measured state every {}: {}",
        case.horizon.1,
        describe(o.short, unit, scale)
    );
    println!();
}

/// Index of the first time ≥ `s`.
fn at(t: &[f64], s: f64) -> usize {
    t.iter().position(|&v| v >= s).unwrap_or(t.len())
}

fn bistablex(dir: &Path, key: &'static str, file: &str, fit_fraction: f64) -> Result<Case, String> {
    let path = dir.join("bistablex/continuous_6p5Hz").join(file);
    let c = read_columns(&path, &["t_s", "base_acc_g", "vibrometer_velocity_V_raw"])?;
    let (t, acc_g, vib) = (&c[0], &c[1], &c[2]);
    let a_base: Vec<f64> = acc_g.iter().map(|a| 9.81 * a).collect();
    let v_base = detrend(t, &integrate(t, &demean(&a_base)));
    let v_rel: Vec<f64> = vib.iter().zip(&v_base).map(|(a, b)| 0.1 * a - b).collect();
    let v_rel = demean(&v_rel);
    let x = detrend(t, &integrate(t, &v_rel));
    // The drift of the integrals is slower than 0.25 Hz: remove a 4 s moving average from x
    // and (consistently) from v.
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    let len = (4.0 / dt) as usize | 1;
    let (x, v_rel) = (
        remove_moving_average(&x, len),
        remove_moving_average(&v_rel, len),
    );
    let n = t.len();
    let split = (fit_fraction * n as f64) as usize;
    let period = (1.0 / (6.5 * dt)).round() as usize;
    Ok(Case {
        key,
        title: format!(
            "BistableX {file}: fit 0–{:.1} s, validate {:.1}–{:.1} s (x in m, u = base acceleration in m/s²)",
            t[split],
            t[split],
            t[n - 1]
        ),
        t: t.clone(),
        x,
        v: Some(v_rel),
        u: Some(demean(&a_base)),
        fit: (0, split),
        validate: vec![("held-out part", (split, n))],
        options: Options {
            harmonics: Some(0),
            poly_order: 3,
            family: PolyFamily::OddFamilies,
            ..Options::default()
        },
        horizon: (period, "forcing period (1/6.5 s)"),
        unit: ("mm", 1e3),
        window: None,
    })
}

fn frid(dir: &Path) -> Result<Case, String> {
    let path = dir.join("frid-magmech/decay_f_42p05_ampl_2p0.csv");
    let c = read_columns(&path, &["t_s", "strain0_response"])?;
    let t = &c[0];
    // Strain in µε about the gauge's rest value (the mean of the noise floor after 20 s).
    let rest = at(t, 20.0);
    let offset = c[1][rest..].iter().sum::<f64>() / (c[1].len() - rest).max(1) as f64;
    let x: Vec<f64> = c[1].iter().map(|v| (v - offset) * 1e6).collect();
    let (start, split, end) = (at(t, 11.0), at(t, 15.0), at(t, 20.0));
    Ok(Case {
        key: "frid",
        title: "FrID magneto-mechanical beam: fit the free decay 11–15 s, validate its rest 15–20 s (x = strain in µε, no input: the command is 0 after 11 s)".into(),
        validate: vec![("free decay 15–20 s", (split, end))],
        fit: (start, split),
        t: t.clone(),
        x,
        v: None,
        u: None,
        options: Options {
            harmonics: Some(0),
            poly_order: 3,
            family: PolyFamily::All,
            ..Options::default()
        },
        horizon: (24, "24 samples (one period)"),
        unit: ("µε", 1.0),
        window: None,
    })
}

fn silverbox(dir: &Path, window: Option<(usize, u8)>) -> Result<Case, String> {
    let path = dir.join("silverbox/SNLS80mV.csv");
    let c = read_columns(&path, &["t_s", "V1_input_V", "V2_output_V"])?;
    let (t, u, x) = (&c[0], demean(&c[1]), demean(&c[2]));
    Ok(Case {
        key: if window.is_some() {
            "silverbox-p9"
        } else {
            "silverbox"
        },
        title: format!(
            "Silverbox SNLS80mV{}: fit on the training multisine [40650, 105712), simulate on the test multisine [105712, 127400) and the arrow [100, 32100) (x = V2, u = V1, in V)",
            if window.is_some() {
                " (window 15, degree 9 by hand)"
            } else {
                ""
            }
        ),
        t: t.clone(),
        x,
        v: None,
        u: Some(u),
        fit: (40650, 105712),
        validate: vec![
            ("test multisine [105712, 127400)", (105712, 127400)),
            ("arrow, no extrapolation [100, 32100)", (100, 32100)),
        ],
        options: Options {
            harmonics: Some(0),
            poly_order: 3,
            family: PolyFamily::OddFamilies,
            ..Options::default()
        },
        horizon: (10, "10 samples (one mean period)"),
        unit: ("mV", 1e3),
        window,
    })
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real");
    let mut only: Option<String> = None;
    let mut rest = args.iter();
    while let Some(a) = rest.next() {
        match (a.as_str(), rest.next()) {
            ("--data", Some(d)) => dir = PathBuf::from(d),
            ("--only", Some(k)) => only = Some(k.clone()),
            _ => {
                eprintln!("real_data: usage: real_data [--data DIR] [--only KEY]");
                return ExitCode::from(2);
            }
        }
    }
    type Load<'a> = Box<dyn Fn() -> Result<Case, String> + 'a>;
    let loads: [(&str, Load); 5] = [
        (
            "chaos",
            Box::new(|| bistablex(&dir, "chaos", "chaos_symmetric.csv", 0.6)),
        ),
        (
            "intrawell",
            Box::new(|| bistablex(&dir, "intrawell", "mono_symmetric_left.csv", 0.6)),
        ),
        ("frid", Box::new(|| frid(&dir))),
        ("silverbox", Box::new(|| silverbox(&dir, None))),
        // At 10 samples per period even the shortest window is biased at degree 7, and the
        // chooser's degrees stop at 7 (its reference needs p + 2 ≤ 9): degree 9 by hand.
        ("silverbox-p9", Box::new(|| silverbox(&dir, Some((15, 9))))),
    ];
    let mut failed = false;
    let mut rows = Vec::new();
    for (key, load) in loads.iter() {
        if only.as_deref().is_some_and(|o| o != *key) {
            continue;
        }
        match load().and_then(|case| run_case(&case).map(|o| (case, o))) {
            Ok((case, o)) => {
                print_case(&case, &o);
                let (unit, scale) = case.unit;
                let errors: Vec<String> = o
                    .free
                    .iter()
                    .map(|(label, e)| format!("free, {label}: {}", describe(*e, unit, scale)))
                    .chain(std::iter::once(format!(
                        "restarted every {}: {}",
                        case.horizon.1,
                        describe(o.short, unit, scale)
                    )))
                    .collect();
                rows.push(format!(
                    "| {} | `{}` | {} | {} | `cargo run --release -p lssi-host --example real_data -- --only {key}` |",
                    case.title.split(':').next().unwrap_or(key),
                    equation(&o.report),
                    wells(&o.report, unit, scale),
                    errors.join("; "),
                ));
            }
            Err(e) => {
                eprintln!("real_data: {key}: {e}");
                failed = true;
            }
        }
    }
    println!("| record | identified equation | double well? | error on held-out data | command |");
    println!("|---|---|---|---|---|");
    for r in rows {
        println!("{r}");
    }
    if failed {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    }
}
