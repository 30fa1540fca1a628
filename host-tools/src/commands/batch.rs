//! `lssi identify FILE...`: many recordings, identified in parallel on every core (rayon),
//! one result per file in the order given: a JSON line (`--json`: the report of `lssi identify
//! --json` with "file" first and "warnings" last), a CSV row (`--csv`: file, equation, terms,
//! coefficients, the selected model's held-out error, samples, rejected, warnings, error), or
//! the text report under the file's name. A file that fails gets its error in its row; the
//! others go on, and the exit code is 2 if any failed.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;

use crate::commands::identify::{IdentifyArgs, identify_recording};
use crate::error::CliError;
use crate::identify::{self, Options, Report};
use crate::recording::Recording;

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

fn one(path: &Path, args: &IdentifyArgs, options: &Options) -> Result<Report, String> {
    let recording = Recording::read(path, &args.columns).map_err(|e| e.to_string())?;
    identify_recording(&recording, options).map_err(|e| e.to_string())
}

fn equation(report: &Report) -> String {
    identify::render(report)
        .lines()
        .next()
        .unwrap_or_default()
        .to_owned()
}

/// The rejected samples as `lssi identify` warns of them: the first five, then a count.
pub(crate) fn warnings(report: &Report) -> Vec<String> {
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

/// Identifies every file; prints in the order given.
pub fn run(args: &IdentifyArgs, options: &Options) -> Result<(), CliError> {
    if args.track {
        return Err(CliError::BadFlag {
            flag: "--track",
            value: "with several recordings".into(),
            requirement: "used with one recording only".into(),
        });
    }
    let mut paths = vec![args.file.clone()];
    paths.extend(args.more.iter().cloned());
    let files = expand(&paths)?;
    let bar = if std::io::stderr().is_terminal() {
        let bar =
            ProgressBar::with_draw_target(Some(files.len() as u64), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template("{bar:30} {pos}/{len} recordings {elapsed}")
        {
            bar.set_style(style);
        }
        bar
    } else {
        ProgressBar::hidden()
    };
    let results: Vec<Result<Report, String>> = files
        .par_iter()
        .map(|path| {
            let result = one(path, args, options);
            bar.inc(1);
            result
        })
        .collect();
    bar.finish_and_clear();
    let mut out = String::new();
    if args.csv {
        out.push_str(
            "file,equation,terms,coefficients,held_out_error,samples,rejected,warnings,error\n",
        );
    }
    for (path, result) in files.iter().zip(&results) {
        let file = path.display().to_string();
        match (result, args.json, args.csv) {
            (Ok(report), true, _) => {
                // "file" first, then the report's fields in the order `lssi identify --json`
                // prints them.
                // prints them, then the warnings (rejected samples) it prints on stderr.
                let mut body = serde_json::to_string(report).unwrap_or_default();
                body.pop();
                out.push_str(&format!(
                    "{{\"file\":{},{},\"warnings\":{}}}",
                    serde_json::Value::from(file),
                    body.get(1..).unwrap_or_default(),
                    serde_json::Value::from(warnings(report))
                ));
                out.push('\n');
            }
            (Err(error), true, _) => {
                out.push_str(&serde_json::json!({ "file": file, "error": error }).to_string());
                out.push('\n');
            }
            (Ok(report), false, true) => {
                let terms: Vec<&str> = report.terms.iter().map(|t| t.term.as_str()).collect();
                let coefficients: Vec<String> =
                    report.terms.iter().map(|t| t.coef.to_string()).collect();
                let fit = report
                    .solutions
                    .get(report.selected)
                    .map(|s| s.mean_error.to_string())
                    .unwrap_or_default();
                out.push_str(&format!(
                    "{},{},{},{},{},{},{},{},\n",
                    csv_field(&file),
                    csv_field(&equation(report)),
                    csv_field(&terms.join(" ")),
                    csv_field(&coefficients.join(" ")),
                    fit,
                    report.samples,
                    report.rejected,
                    csv_field(&warnings(report).join(" "))
                ));
            }
            (Err(error), false, true) => {
                out.push_str(&format!(
                    "{},,,,,,,,{}\n",
                    csv_field(&file),
                    csv_field(error)
                ));
            }
            (Ok(report), false, false) => {
                out.push_str(&format!("== {file}\n{}\n", identify::render(report)));
            }
            (Err(error), false, false) => out.push_str(&format!("== {file}\nlssi: {error}\n\n")),
        }
    }
    if let Err(e) = std::io::stdout().write_all(out.as_bytes()) {
        crate::output::fail(&e)
    }
    let failed = results.iter().filter(|r| r.is_err()).count();
    if failed > 0 {
        return Err(CliError::Input(format!(
            "{failed} of {} recordings could not be identified (their rows say why).",
            files.len()
        )));
    }
    Ok(())
}
