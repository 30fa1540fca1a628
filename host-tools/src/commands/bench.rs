//! `lssi bench accuracy`: the accuracy table of the paper's Table 3, on the paper's eq. 17
//! protocol, for lssi in f32 (streaming, end of file), in f64, and without the k-neighbour
//! smoothing (the ablation); and the identification throughput on 10⁶ samples.
//!
//! One default configuration for every row: only the recording's own facts differ (sample
//! period, which channels it has), and the library is the paper's eq. 18 — constant,
//! monomials of (x, v) to order 3, sin/cos(kt) for k = 1..3 (Ω = 1 given, H = 3).

use std::time::Instant;

use clap::{Args, Subcommand};

use crate::error::CliError;
use crate::identify::Options;
use crate::identify::identify_recording;
use crate::synth::Observe;
use crate::synth::noise::NoiseKind;
use crate::synth::paper::{PaperOptions, generate_paper};
use crate::synth::truth::score;

/// Arguments of `lssi bench`.
#[derive(Debug, Clone, Args)]
pub struct BenchArgs {
    /// Which benchmark.
    #[command(subcommand)]
    pub which: Which,
}

/// The benchmarks.
#[derive(Debug, Clone, Subcommand)]
pub enum Which {
    /// Replay throughput over firmware-sim's pty at 115 200 and 921 600 baud, against the
    /// line's bound.
    Replay(crate::commands::replay::ReplayBenchArgs),
    /// The eq. 17 accuracy table and the throughput on 10⁶ samples.
    Accuracy {
        /// Only ε = 1 and the paper's noise (a quick look).
        #[arg(long)]
        quick: bool,
        /// Noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

/// The true coefficients of eq. 17 (Table 1) at strength ε.
fn truth(epsilon: f64) -> [(&'static str, f64); 6] {
    [
        ("x", -1.0),
        ("v", epsilon),
        ("x^2", 2.0 * epsilon),
        ("x^3", -4.0 * epsilon),
        ("x^2*v", -2.0 * epsilon),
        ("cos(2t)", 5.0 * epsilon),
    ]
}

fn options(f32: bool, smoothing: bool) -> Options {
    Options {
        omega: Some(1.0),
        harmonics: Some(3),
        poly_order: 3,
        f32,
        smoothing,
        ..Options::default()
    }
}

/// Runs `lssi bench`.
pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let (quick, seed) = match &args.which {
        Which::Accuracy { quick, seed } => (*quick, *seed),
        Which::Replay(replay) => return crate::commands::replay::bench(replay),
    };
    let epsilons: &[f64] = if quick { &[1.0] } else { &[1.0, 0.3] };
    let kinds: &[NoiseKind] = if quick {
        &[NoiseKind::Paper]
    } else {
        &[NoiseKind::Paper, NoiseKind::Uniform0]
    };
    crate::outln!(
        "eq. 17, t in [0, 100] s, dt = 0.001 s, seed {seed}; library: 1, monomials of (x, v) to order 3, sin/cos(kt) k = 1..3"
    );
    crate::outln!(
        "errors in % of each true coefficient (100 = term missed); spurious = terms not in eq. 17\n"
    );
    crate::outln!(
        "| case | x | v | x^2 | x^3 | x^2*v | cos(2t) | f32 mean | f32 spurious | f64 mean | f64 spurious | no smoothing mean | no smoothing spurious |"
    );
    crate::outln!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for &epsilon in epsilons {
        for &kind in kinds {
            for delta in [0.001, 0.01, 0.1] {
                for observe in [Observe::Xv, Observe::X] {
                    let opts = PaperOptions {
                        epsilon,
                        delta,
                        noise: kind,
                        observe,
                        seed,
                        ..PaperOptions::default()
                    };
                    let generated = generate_paper(&opts);
                    let recording = generated.to_recording("eq17.csv");
                    let t = truth(epsilon);
                    let mut cells = Vec::new();
                    let mut per_term = Vec::new();
                    for (f32, smoothing) in [(true, true), (false, true), (true, false)] {
                        let report = identify_recording(&recording, &options(f32, smoothing))?;
                        let (errors, spurious) = score(&report, &t);
                        if per_term.is_empty() {
                            per_term = errors.clone();
                        }
                        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
                        cells.push(format!("{mean:.3} | {spurious}"));
                    }
                    let noise = match kind {
                        NoiseKind::Paper => "eq. 16",
                        NoiseKind::Uniform0 => "zero-mean uniform",
                        NoiseKind::Gauss => "Gaussian",
                    };
                    let channels = match observe {
                        Observe::Xv => "x and x'",
                        Observe::X => "x only",
                    };
                    crate::outln!(
                        "| ε = {epsilon}, {noise}, δ = {delta}, {channels} | {} | {} |",
                        per_term
                            .iter()
                            .map(|e| format!("{e:.3}"))
                            .collect::<Vec<_>>()
                            .join(" | "),
                        cells.join(" | ")
                    );
                }
            }
        }
    }
    // Throughput: 10⁶ samples of eq. 17 (x and x', δ = 0.01), one core.
    let opts = PaperOptions {
        delta: 0.01,
        t_end: 999.999,
        seed,
        ..PaperOptions::default()
    };
    let generated = generate_paper(&opts);
    let recording = generated.to_recording("eq17-1e6.csv");
    let (config, _) = crate::identify::configure(&recording, &options(true, true))?;
    let start = Instant::now();
    let report = crate::identify::run::<f32>(&recording, config, false)?;
    let streaming = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let _ = identify_recording(&recording, &options(true, true))?;
    let whole = start.elapsed().as_secs_f64();
    crate::outln!(
        "\nthroughput, {} samples, f32, one core: streaming identifier {:.2} M samples/s ({:.3} s); with the window choice from the data {:.2} M samples/s ({:.3} s)",
        report.samples,
        report.samples as f64 / streaming / 1e6,
        streaming,
        report.samples as f64 / whole / 1e6,
        whole
    );
    Ok(())
}
