//! Many recordings, identified in parallel on every core (rayon), one result per file in the
//! order given, and each result as `lssi identify FILE...` prints it: a JSON line (the report
//! of `lssi identify --json` with "file" first and "warnings" last), a CSV row (file, equation,
//! terms, coefficients, the selected model's held-out error, samples, rejected, warnings,
//! error), or the text report under the file's name. A file that fails gets its error in its
//! row; the others go on.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::CliError;
use crate::identify::{self, Options, Report, identify_recording};
use crate::recording::{ColumnNames, Recording};

/// The files named: each path as given, a folder as its `*.csv` files in name order.
pub fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>, CliError> {
    let mut files = Vec::new();
    for path in paths {
        if path.is_dir() {
            let entries = std::fs::read_dir(path).map_err(|e| {
                CliError::Input(format!(
                    "{}: the folder cannot be read ({e}).",
                    path.display()
                ))
            })?;
            let mut found: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "csv") && p.is_file())
                .collect();
            found.sort();
            if found.is_empty() {
                return Err(CliError::Input(format!(
                    "{}: the folder holds no .csv recording.",
                    path.display()
                )));
            }
            files.extend(found);
        } else {
            files.push(path.clone());
        }
    }
    Ok(files)
}

/// One recording's report, or its error as a sentence.
pub type Outcome = Result<Report, String>;

fn one(path: &Path, columns: &ColumnNames, options: &Options) -> Outcome {
    let recording = Recording::read(path, columns).map_err(|e| e.to_string())?;
    identify_recording(&recording, options).map_err(|e| e.to_string())
}

/// Identifies every file in parallel, calling `done` as each finishes; the results come in the
/// order of `files`.
pub fn identify_all(
    files: &[PathBuf],
    columns: &ColumnNames,
    options: &Options,
    done: impl Fn() + Sync,
) -> Vec<Outcome> {
    files
        .par_iter()
        .map(|path| {
            let result = one(path, columns, options);
            done();
            result
        })
        .collect()
}

fn equation(report: &Report) -> String {
    identify::render(report)
        .lines()
        .next()
        .unwrap_or_default()
        .to_owned()
}

/// The rejected samples as `lssi identify` warns of them: the first five, then a count.
pub fn warnings(report: &Report) -> Vec<String> {
    const NAMED: usize = 5;
    let mut out: Vec<String> = report.rejections.iter().take(NAMED).cloned().collect();
    if report.rejections.len() > NAMED {
        out.push(format!(
            "{} more samples were left out ({} in all)",
            report.rejections.len() - NAMED,
            report.rejections.len()
        ));
    }
    out
}

fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}

/// The header row of the CSV table (`--csv`).
pub const CSV_HEADER: &str =
    "file,equation,terms,coefficients,held_out_error,samples,rejected,warnings,error\n";

/// One file's JSON line (`--json`), with its newline.
pub fn json_line(file: &str, outcome: &Outcome) -> String {
    match outcome {
        Ok(report) => {
            // "file" first, then the report's fields in the order `lssi identify --json`
            // prints them, then the warnings (rejected samples) it prints on stderr.
            let mut body = serde_json::to_string(report).unwrap_or_default();
            body.pop();
            format!(
                "{{\"file\":{},{},\"warnings\":{}}}\n",
                serde_json::Value::from(file),
                body.get(1..).unwrap_or_default(),
                serde_json::Value::from(warnings(report))
            )
        }
        Err(error) => format!("{}\n", serde_json::json!({ "file": file, "error": error })),
    }
}

/// One file's row of the CSV table (`--csv`), with its newline.
pub fn csv_row(file: &str, outcome: &Outcome) -> String {
    match outcome {
        Ok(report) => {
            let terms: Vec<&str> = report.terms.iter().map(|t| t.term.as_str()).collect();
            let coefficients: Vec<String> =
                report.terms.iter().map(|t| t.coef.to_string()).collect();
            let fit = report
                .solutions
                .get(report.selected)
                .map(|s| s.mean_error.to_string())
                .unwrap_or_default();
            format!(
                "{},{},{},{},{},{},{},{},\n",
                csv_field(file),
                csv_field(&equation(report)),
                csv_field(&terms.join(" ")),
                csv_field(&coefficients.join(" ")),
                fit,
                report.samples,
                report.rejected,
                csv_field(&warnings(report).join(" "))
            )
        }
        Err(error) => format!("{},,,,,,,,{}\n", csv_field(file), csv_field(error)),
    }
}

/// One file's text report under its name.
pub fn text_block(file: &str, outcome: &Outcome) -> String {
    match outcome {
        Ok(report) => format!("== {file}\n{}\n", identify::render(report)),
        Err(error) => format!("== {file}\nlssi: {error}\n\n"),
    }
}
