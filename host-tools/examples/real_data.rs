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
//! Preprocessing, per record:
//! - **BistableX** (`continuous_6p5Hz/`): the tip's absolute velocity is 0.1 m/s per volt of
//!   the vibrometer; the base velocity is the integral of the base acceleration (9.81 m/s² per
//!   g). The relative velocity v = v_tip − v_base has its mean removed, is integrated with the
//!   trapezoidal rule, and the least-squares straight line of the result is removed (the drift
//!   of integrating a velocity offset; a line, not a high-pass filter, so that the time spent
//!   in either well is kept). x is that relative displacement in metres, v the relative velocity
//!   (a measured channel), u the base acceleration in m/s²; no sin/cos terms.
//! - **FrID magneto-mechanical beam**: x is the strain gauge `strain0_response` (strain), u
//!   the commanded forcing voltage (2 V sine at 42.05 Hz until 11 s, then 0); fit on 0–14 s
//!   (forced response and the start of the free decay), validate on the decay from 14 to 20 s
//!   (after 20 s it is noise floor).
//! - **Silverbox**: x = V2, u = V1, both with their means removed (the README's instruction);
//!   fit on the benchmark's training multisine, samples [40650, 105712), simulate on its test
//!   multisine [105712, 127400); the RMSE is in mV.
//!
//! The derivative window and degree are chosen from the data by `lssi identify`'s rule;
//! `LSSI_WINDOW=W,D` in the environment overrides them (W samples, degree D), for diagnosis.
//!
//! The initial velocity of a free simulation without a measured velocity is the slope of a
//! least-squares line through the 11 samples centred on the start.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use lssi_core::PolyFamily;
use lssi_host::identify::{self, Options, Report};
use lssi_host::recording::{ColumnNames, Recording};
use lssi_host::simulate::{SimModel, nrmse, rmse, simulate};

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

/// What one case reports.
struct Outcome {
    report: Report,
    nrmse: Option<f64>,
    rmse: Option<f64>,
    diverged_at: Option<f64>,
}

/// Fits on `fit`, simulates on `[split, end)`.
#[allow(clippy::too_many_arguments)]
fn fit_and_validate(
    name: &str,
    t: &[f64],
    x: &[f64],
    v: Option<&[f64]>,
    u: Option<&[f64]>,
    fit: (usize, usize),
    validate: (usize, usize),
    options: &Options,
    window: Option<(usize, u8)>,
) -> Result<Outcome, String> {
    let (a, b) = fit;
    let train = recording(
        name,
        &t[a..b],
        &x[a..b],
        v.map(|v| &v[a..b]),
        u.map(|u| &u[a..b]),
    );
    let (mut config, estimated) = identify::configure(&train, options).map_err(|e| e.0)?;
    if let Some((w, d)) = window.or_else(|| {
        std::env::var("LSSI_WINDOW").ok().and_then(|s| {
            let (w, d) = s.split_once(',')?;
            Some((w.parse().ok()?, d.parse().ok()?))
        })
    }) {
        config.window = w;
        config.derivative_degree = d;
    }
    let report = identify::run::<f32>(&train, config, estimated).map_err(|e| e.0)?;
    let model = SimModel::from_report(&report);
    let (c, d) = validate;
    let v0 = match v {
        Some(v) => v[c],
        None => slope_at(t, x, c),
    };
    let run = simulate(&model, &t[c..d], u.map(|u| &u[c..d]), (x[c], v0), 4);
    Ok(Outcome {
        nrmse: nrmse(&run.x, &x[c..d]),
        rmse: rmse(&run.x, &x[c..d]),
        diverged_at: run.diverged_at.map(|i| t[c + i]),
        report,
    })
}

fn print_outcome(title: &str, o: &Outcome, unit: &str, scale: f64) {
    println!("== {title}");
    let text = identify::render(&o.report);
    print!(
        "{}",
        text.lines()
            .take(2)
            .map(|l| format!("{l}\n"))
            .collect::<String>()
    );
    let ox = o.report.offsets[0];
    match o.report.wells {
        Some(w) => println!(
            "double well: yes, wells at {:.4e} and {:.4e} {unit} (x = {:.4e} ± {:.4e}), {:.3} Hz in a well",
            ox - w,
            ox + w,
            ox,
            w,
            o.report.well_resonance_hz.unwrap_or(f64::NAN)
        ),
        None => match o.report.resonance_hz {
            Some(f) => println!("double well: no (single well, linear resonance {f:.3} Hz)"),
            None => println!("double well: no (the linear term is not restoring, no well found)"),
        },
    }
    match (o.nrmse, o.diverged_at) {
        (Some(e), _) => println!(
            "free simulation on the held-out part: NRMSE = {e:.3}, RMSE = {:.4e} {unit}",
            o.rmse.unwrap_or(f64::NAN) * scale
        ),
        (None, Some(t)) => {
            println!("free simulation on the held-out part: diverged at t = {t:.3} s")
        }
        (None, None) => {
            println!("free simulation on the held-out part: no error (constant record)")
        }
    }
    println!();
}

fn bistablex(dir: &Path, file: &str, fit_fraction: f64) -> Result<(), String> {
    let path = dir.join("bistablex/continuous_6p5Hz").join(file);
    let c = read_columns(&path, &["t_s", "base_acc_g", "vibrometer_velocity_V_raw"])?;
    let (t, acc_g, vib) = (&c[0], &c[1], &c[2]);
    let a_base: Vec<f64> = acc_g.iter().map(|a| 9.81 * a).collect();
    let v_base = detrend(t, &integrate(t, &demean(&a_base)));
    let v_tip: Vec<f64> = vib.iter().map(|v| 0.1 * v).collect();
    let v_rel = demean(
        &v_tip
            .iter()
            .zip(&v_base)
            .map(|(a, b)| a - b)
            .collect::<Vec<f64>>(),
    );
    let x = detrend(t, &integrate(t, &v_rel));
    let u = demean(&a_base);
    let n = t.len();
    let split = (fit_fraction * n as f64) as usize;
    let options = Options {
        harmonics: 0,
        ..Options::default()
    };
    let o = fit_and_validate(
        file,
        t,
        &x,
        Some(&v_rel),
        Some(&u),
        (0, split),
        (split, n),
        &options,
        None,
    )?;
    print_outcome(
        &format!(
            "BistableX {file}: fit 0–{:.1} s, validate {:.1}–{:.1} s (x in m, u = base acceleration in m/s²)",
            t[split],
            t[split],
            t[n - 1]
        ),
        &o,
        "m",
        1.0,
    );
    Ok(())
}

fn frid(dir: &Path) -> Result<(), String> {
    let path = dir.join("frid-magmech/decay_f_42p05_ampl_2p0.csv");
    let c = read_columns(&path, &["t_s", "strain0_response", "forcing_command_sine"])?;
    let (t, x, u) = (&c[0], &c[1], &c[2]);
    let at = |s: f64| t.iter().position(|&v| v >= s).unwrap_or(t.len());
    let options = Options {
        harmonics: 0,
        ..Options::default()
    };
    let o = fit_and_validate(
        "frid-magmech",
        t,
        x,
        None,
        Some(u),
        (0, at(14.0)),
        (at(14.0), at(20.0)),
        &options,
        None,
    )?;
    print_outcome(
        "FrID magneto-mechanical beam: fit 0–14 s (forced at 42.05 Hz, decay from 11 s), validate the free decay 14–20 s (x = strain, u = command in V)",
        &o,
        "strain",
        1.0,
    );
    Ok(())
}

fn silverbox(dir: &Path) -> Result<(), String> {
    let path = dir.join("silverbox/SNLS80mV.csv");
    let c = read_columns(&path, &["t_s", "V1_input_V", "V2_output_V"])?;
    let (t, u, x) = (&c[0], demean(&c[1]), demean(&c[2]));
    let options = Options {
        harmonics: 0,
        poly_order: 3,
        family: PolyFamily::All,
        ..Options::default()
    };
    let o = fit_and_validate(
        "silverbox",
        t,
        &x,
        None,
        Some(&u),
        (40650, 105712),
        (105712, 127400),
        &options,
        None,
    )?;
    print_outcome(
        "Silverbox SNLS80mV: fit on the training multisine [40650, 105712), simulate on the test multisine [105712, 127400) (x = V2, u = V1, in V)",
        &o,
        "mV",
        1e3,
    );
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = match args.as_slice() {
        [] => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real"),
        [flag, dir] if flag == "--data" => PathBuf::from(dir),
        _ => {
            eprintln!("real_data: usage: real_data [--data DIR]");
            return ExitCode::from(2);
        }
    };
    let mut failed = false;
    type Case<'a> = Box<dyn Fn() -> Result<(), String> + 'a>;
    let cases: [(&str, Case); 4] = [
        (
            "bistablex chaos",
            Box::new(|| bistablex(&dir, "chaos_symmetric.csv", 0.6)),
        ),
        (
            "bistablex intrawell",
            Box::new(|| bistablex(&dir, "mono_symmetric_left.csv", 0.6)),
        ),
        ("frid", Box::new(|| frid(&dir))),
        ("silverbox", Box::new(|| silverbox(&dir))),
    ];
    for (name, case) in cases.iter() {
        if let Err(e) = case() {
            eprintln!("real_data: {name}: {e}");
            failed = true;
        }
    }
    if failed {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    }
}
