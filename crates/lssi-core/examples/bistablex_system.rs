//! A first look (not a bench, no claim): a BistableX record (../shared/data/real/bistablex,
//! never copied into the repository) through the system identifier, f64.
//!
//! `cargo run --release -p lssi-core --example bistablex_system -- FILE.csv [COUPLING_ORDER]`
//!
//! v: the vibrometer's velocity (X3/10 m/s) minus the base's (the base acceleration
//! integrated), each with its drift removed by a centred moving average of 4 s; x: v
//! integrated, the same; V: the piezo voltage as recorded; u: the base acceleration in m/s².
//! The window and the weak form's width are the tuning module's choice on v.
use lssi_core::library::{Electrical, LibraryConfig, PolyFamily};
use lssi_core::{Channels, Config, SystemConfig, SystemIdentifier, SystemSample};

fn high_pass(s: &[f64], width: usize) -> Vec<f64> {
    let n = s.len();
    let mut prefix = vec![0.0; n + 1];
    for i in 0..n {
        prefix[i + 1] = prefix[i] + s[i];
    }
    (0..n)
        .map(|i| {
            let a = i.saturating_sub(width / 2);
            let b = (i + width / 2 + 1).min(n);
            s[i] - (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect()
}

fn integrate(s: &[f64], dt: f64) -> Vec<f64> {
    let mut out = vec![0.0; s.len()];
    for i in 1..s.len() {
        out[i] = out[i - 1] + 0.5 * dt * (s[i] + s[i - 1]);
    }
    out
}

fn main() {
    let path = std::env::args().nth(1).expect("a CSV");
    let coupling: u8 = std::env::args()
        .nth(2)
        .map_or(1, |s| s.parse().expect("order"));
    let text = std::fs::read_to_string(&path).expect("readable");
    let rows: Vec<[f64; 4]> = text
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().expect("a number")).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    let dt = rows[1][0] - rows[0][0];
    let width = (4.0 / dt) as usize;
    let a: Vec<f64> = rows.iter().map(|r| r[1] * 9.81).collect();
    let vb = high_pass(&integrate(&high_pass(&a, width), dt), width);
    let va: Vec<f64> = rows.iter().map(|r| r[3] / 10.0).collect();
    let v: Vec<f64> = high_pass(&va, width)
        .iter()
        .zip(&vb)
        .map(|(p, q)| p - q)
        .collect();
    let x = high_pass(&integrate(&v, dt), width);
    let e: Vec<f64> = rows.iter().map(|r| r[2]).collect();
    let choice =
        lssi_core::tuning::choose_window::<f64, 256>(&v, 1, dt, v.len()).expect("a window");
    let mut base = Config {
        sample_period: dt,
        window: choice.window,
        derivative_degree: choice.degree,
        library: LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: 0,
            input: true,
        },
        channels: Channels {
            velocity: true,
            input: true,
        },
        screening_period: u32::MAX,
        ..Config::default()
    };
    if let Some(w) = lssi_core::tuning::choose_test_rows::<256>(choice.period, v.len()) {
        base.test_rows = w.test_rows;
        base.window = w.window;
        base.derivative_degree = w.degree;
        base.row_stride = 1;
    }
    let config = SystemConfig {
        base,
        electrical: [Some(Electrical::Voltage), None],
        coupling_order: coupling,
        displacements: 1,
    };
    let mut id: Box<SystemIdentifier<f64, 256, 16, 2, 4>> =
        Box::new(SystemIdentifier::new(config).expect("valid"));
    for i in 0..rows.len() {
        let ev = [e[i]];
        let _ = id.push(&SystemSample {
            x2: None,
            v2: None,
            t: rows[i][0],
            x: x[i],
            v: Some(v[i]),
            u: Some(a[i]),
            electrical: &ev,
        });
    }
    id.screen();
    let rms = |s: &[f64]| (s.iter().map(|q| q * q).sum::<f64>() / s.len() as f64).sqrt();
    println!(
        "{path}: window {} degree {} test_rows {}; rms x {:.3e} m, v {:.3e} m/s, V {:.3e} V, u {:.3e} m/s²",
        base.window,
        base.derivative_degree,
        base.test_rows,
        rms(&x),
        rms(&v),
        rms(&e),
        rms(&a)
    );
    let model = id.model().expect("a model");
    for k in 0..model.equations.len() {
        let mut s = String::new();
        model
            .write_equation(k, 5, &mut s)
            .expect("a String takes any text");
        let e = &model.equations[k];
        let error = e.selected_solution().map_or(f64::NAN, |s| s.mean_error);
        println!(
            "  {s}   (held-out mean squared error {error:.3e}, {} solutions)",
            e.solutions.len()
        );
    }
}
