//! `lssi gen MODEL [OPTIONS] OUT.csv`: writes a synthetic recording and, beside it, its truth.
//!
//! `OUT.csv` gets the observed columns (`t,x` or `t,x,v`) and `OUT.json` the [`Truth`]: the
//! equation's terms and coefficients, every option, and the noise that was added.
//!
//! [`Truth`]: crate::truth::Truth

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};

use crate::error::CliError;
use crate::generators::paper::{PaperOptions, PaperParams, generate_paper};
use crate::generators::{Generated, Observe};
use crate::noise::NoiseKind;
use crate::recording::write_csv;

/// Arguments of `lssi gen`.
#[derive(Debug, Clone, Args)]
pub struct GenArgs {
    /// Which model to simulate.
    #[command(subcommand)]
    pub model: GenModel,
}

/// The models `lssi gen` can simulate.
#[derive(Debug, Clone, Subcommand)]
pub enum GenModel {
    /// The paper's eq. (17) with Table 1's parameters and eq. (16) noise.
    Paper(PaperArgs),
}

/// Arguments of `lssi gen paper`.
#[derive(Debug, Clone, Args)]
pub struct PaperArgs {
    /// Nonlinear perturbation strength ε.
    #[arg(long, value_name = "E", default_value_t = PaperOptions::default().epsilon,
          allow_negative_numbers = true)]
    pub eps: f64,
    /// Noise level δ: the noise has 2-norm δ times the signal's (eq. 16).
    #[arg(long, value_name = "D", default_value_t = PaperOptions::default().delta,
          allow_negative_numbers = true)]
    pub delta: f64,
    /// Raw noise distribution: paper = uniform (0,1) as in the paper (biased), uniform0 =
    /// uniform (-1,1), gauss = standard normal; all scaled to the same norm.
    #[arg(long, value_enum, default_value_t = PaperOptions::default().noise)]
    pub noise: NoiseKind,
    /// Channels to write: x, or x and v.
    #[arg(long, value_enum, default_value_t = PaperOptions::default().observe)]
    pub observe: Observe,
    /// Last sample time, seconds.
    #[arg(long = "t-end", value_name = "T", default_value_t = PaperOptions::default().t_end,
          allow_negative_numbers = true)]
    pub t_end: f64,
    /// Sampling interval, seconds.
    #[arg(long, value_name = "DT", default_value_t = PaperOptions::default().dt,
          allow_negative_numbers = true)]
    pub dt: f64,
    /// Seed of the noise generator; the same seed gives the same file.
    #[arg(long, value_name = "S", default_value_t = PaperOptions::default().seed)]
    pub seed: u64,
    /// The CSV file to write; the truth goes beside it with the extension .json.
    #[arg(value_name = "OUT.csv")]
    pub out: PathBuf,
}

impl PaperArgs {
    /// The generator options these flags ask for.
    pub fn options(&self) -> PaperOptions {
        PaperOptions {
            params: PaperParams::default(),
            epsilon: self.eps,
            delta: self.delta,
            noise: self.noise,
            observe: self.observe,
            t_end: self.t_end,
            dt: self.dt,
            seed: self.seed,
        }
    }
}

/// Runs `lssi gen`.
pub fn run(args: &GenArgs) -> Result<(), CliError> {
    match &args.model {
        GenModel::Paper(paper) => run_paper(paper),
    }
}

fn run_paper(args: &PaperArgs) -> Result<(), CliError> {
    let options = args.options();
    options.validate().map_err(|error| {
        let flag = match error.field {
            "epsilon" => "--eps",
            "delta" => "--delta",
            "t_end" => "--t-end",
            "dt" => "--dt",
            // Table 1's fields have no flags (and their defaults are valid).
            other => other,
        };
        CliError::from_option(error, flag)
    })?;
    let json = truth_path(&args.out)?;
    let generated = generate_paper(&options);
    if let Some(t) = generated.diverged_at() {
        return Err(CliError::Diverged {
            model: generated.truth.model.clone(),
            t,
        });
    }
    write_generated(&args.out, &json, &generated)?;
    println!(
        "wrote {} ({} samples of {} over {} s) and {}",
        args.out.display(),
        generated.t.len(),
        generated.csv_columns().0.join(","),
        options.t_end,
        json.display()
    );
    Ok(())
}

/// The truth file that goes beside `csv`: same stem, extension `.json`.
pub fn truth_path(csv: &Path) -> Result<PathBuf, CliError> {
    if csv.file_name().is_none() {
        return Err(CliError::BadOutput {
            path: csv.to_owned(),
            reason: "this is not a file name; give the CSV file to write, such as out.csv"
                .to_owned(),
        });
    }
    if csv
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        return Err(CliError::BadOutput {
            path: csv.to_owned(),
            reason: "the recording cannot end in .json, because the truth file is written \
                     beside it under that name; use .csv"
                .to_owned(),
        });
    }
    Ok(csv.with_extension("json"))
}

/// Writes a generated recording to `csv` and its truth, pretty-printed, to `json`.
pub fn write_generated(csv: &Path, json: &Path, generated: &Generated) -> Result<(), CliError> {
    let (header, columns) = generated.csv_columns();
    write_csv(csv, &header, &columns).map_err(|source| CliError::Write {
        path: csv.to_owned(),
        source,
    })?;
    let write_json = || -> std::io::Result<()> {
        let mut writer = BufWriter::new(File::create(json)?);
        serde_json::to_writer_pretty(&mut writer, &generated.truth)?;
        writeln!(writer)?;
        writer.flush()
    };
    write_json().map_err(|source| CliError::Write {
        path: json.to_owned(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_goes_beside_the_csv() {
        assert_eq!(
            truth_path(Path::new("dir/run.csv")).ok(),
            Some(PathBuf::from("dir/run.json"))
        );
        assert_eq!(
            truth_path(Path::new("run")).ok(),
            Some(PathBuf::from("run.json"))
        );
        assert!(truth_path(Path::new("run.json")).is_err());
        assert!(truth_path(Path::new("..")).is_err());
    }

    #[test]
    fn flag_defaults_are_the_library_defaults() {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrapper {
            #[command(flatten)]
            args: PaperArgs,
        }
        let wrapper = Wrapper::parse_from(["test", "out.csv"]);
        assert_eq!(wrapper.args.options(), PaperOptions::default());
    }
}
