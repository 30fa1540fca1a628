//! Many recordings, identified in parallel on every core (rayon), one result per file in the
//! order given, and each result as `lssi identify FILE...` prints it: a JSON line (the report
//! of `lssi identify --json` with "file" first and "warnings" last), a CSV row (file, equation,
//! terms, coefficients, the selected model's held-out error, samples, rejected, warnings,
//! error), or the text report under the file's name. A file that fails gets its error in its
//! row; the others go on. Each file goes through the quality gate as one recording does (a
//! withheld model is a row with the refusal); models are the streaming identifier's unless
//! `--refine` asks for refinement (10–30 times the identification's time per file), and a
//! warning says so.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::CliError;
use crate::identify::pipeline::Refine;
use crate::identify::{self, Options, Report};
use crate::recording::{ColumnNames, Recording};

/// The files named: each path as given, a folder as its `*.csv` files in name order. A folder
/// that cannot be read or holds no `.csv` file stays in the list as itself, so that it gets a
/// row with its error (see [`folder_problem`]) while the other files are still identified.
pub fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>, CliError> {
    let mut files = Vec::new();
    for path in paths {
        if path.is_dir() {
            match csv_files(path) {
                Ok(found) if !found.is_empty() => files.extend(found),
                _ => files.push(path.clone()),
            }
        } else {
            files.push(path.clone());
        }
    }
    Ok(files)
}

/// The `*.csv` files of a folder, in name order.
fn csv_files(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "csv") && p.is_file())
        .collect();
    found.sort();
    Ok(found)
}

/// Why a folder named in a batch gave no recording (one sentence naming it), or `None` when
/// `path` is not a folder or holds `.csv` files.
pub fn folder_problem(path: &Path) -> Option<String> {
    if !path.is_dir() {
        return None;
    }
    match csv_files(path) {
        Err(e) => Some(format!(
            "{}: the folder cannot be read ({e}).",
            path.display()
        )),
        Ok(found) if found.is_empty() => Some(format!(
            "{}: the folder holds no .csv recording.",
            path.display()
        )),
        Ok(_) => None,
    }
}

/// A list of names for a sentence: "a", "a and b", "a, b and c", the first `named` then
/// "and N more".
fn name_list(names: &[String], named: usize) -> String {
    let shown: Vec<&str> = names.iter().take(named).map(String::as_str).collect();
    let more = names.len().saturating_sub(named);
    match (shown.split_last(), more) {
        (None, _) => String::new(),
        (Some((last, [])), 0) => (*last).to_owned(),
        (Some((last, rest)), 0) => format!("{} and {last}", rest.join(", ")),
        (Some(_), more) => format!("{} and {more} more", shown.join(", ")),
    }
}

/// The batch's closing sentence when some inputs gave no model for a reason other than the
/// gate (exit status 2): how many of the recordings could not be identified, and each folder
/// that gave no recording (it holds no `.csv` file, or cannot be read), named, not counted as
/// a recording. `None` when every input gave a recording and none failed.
pub fn failure_sentence(files: &[PathBuf], results: &[Outcome]) -> Option<String> {
    const NAMED: usize = 5;
    let (mut empty, mut unreadable, mut failed) = (Vec::new(), Vec::new(), Vec::new());
    let mut recordings = 0usize;
    for (path, result) in files.iter().zip(results) {
        let name = path.display().to_string();
        if path.is_dir() {
            match csv_files(path) {
                Err(_) => unreadable.push(name),
                Ok(found) if found.is_empty() => empty.push(name),
                Ok(_) => {}
            }
            continue;
        }
        recordings += 1;
        if matches!(result, Err(Failure::Error(_))) {
            failed.push(name);
        }
    }
    let mut parts = Vec::new();
    if !failed.is_empty() {
        parts.push(format!(
            "{} of {recordings} recording{} could not be identified: {}",
            failed.len(),
            if recordings == 1 { "" } else { "s" },
            name_list(&failed, NAMED)
        ));
    }
    let folders = |names: &[String], one: &str, many: &str| match names.len() {
        0 => None,
        1 => Some(format!("the folder {} {one}", names[0])),
        _ => Some(format!("the folders {} {many}", name_list(names, NAMED))),
    };
    parts.extend(folders(
        &empty,
        "holds no .csv recording",
        "hold no .csv recording",
    ));
    parts.extend(folders(&unreadable, "cannot be read", "cannot be read"));
    if parts.is_empty() {
        return None;
    }
    let rows = if failed.len() + empty.len() + unreadable.len() == 1 {
        "its row says why"
    } else {
        "their rows say why"
    };
    Some(format!("{} ({rows}).", parts.join("; ")))
}

pub use crate::identify::pipeline::{Failure, Identified, Outcome, warnings};

/// Why a model in a batch is the streaming one: refinement is not run on several recordings
/// at once unless `--refine` asks for it.
pub const NOT_REFINED: &str =
    "not refined: several recordings are identified at once (--refine refines each)";

fn one(path: &Path, columns: &ColumnNames, options: &Options, refine: bool) -> Outcome {
    if let Some(problem) = folder_problem(path) {
        return Err(Failure::Error(problem));
    }
    let recording = Recording::read(path, columns).map_err(|e| Failure::Error(e.to_string()))?;
    let refine = if refine {
        Refine::Yes
    } else {
        Refine::No(NOT_REFINED)
    };
    crate::identify::pipeline::identify(&recording, options, refine)
}

/// Identifies every file in parallel (each through the quality gate, and refined when
/// `refine`), calling `done` as each finishes; the results come in the order of `files`.
pub fn identify_all(
    files: &[PathBuf],
    columns: &ColumnNames,
    options: &Options,
    refine: bool,
    done: impl Fn() + Sync,
) -> Vec<Outcome> {
    files
        .par_iter()
        .map(|path| {
            let result = one(path, columns, options, refine);
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

/// One file's JSON line (`--json`), with its newline: `"file"` first, then the object `lssi
/// identify --json` prints; or the file, its error and, for a withheld model, `"withheld":
/// true` and the gate's reasons as `"warnings"`.
pub fn json_line(file: &str, outcome: &Outcome) -> String {
    match outcome {
        Ok(done) => {
            let body = identify::json_text(&done.report, done.refined.as_ref(), &done.warnings);
            format!(
                "{{\"file\":{},{}\n",
                serde_json::Value::from(file),
                body.get(1..).unwrap_or_default(),
            )
        }
        Err(Failure::Error(error)) => {
            format!("{}\n", serde_json::json!({ "file": file, "error": error }))
        }
        Err(Failure::Withheld(error, reasons, _)) => format!(
            "{}\n",
            serde_json::json!({ "file": file, "error": error, "withheld": true, "warnings": reasons })
        ),
    }
}

/// One file's row of the CSV table (`--csv`), with its newline.
pub fn csv_row(file: &str, outcome: &Outcome) -> String {
    match outcome {
        Ok(done) => {
            let report = &done.report;
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
                csv_field(&done.warnings.join(" "))
            )
        }
        Err(failure) => format!(
            "{},,,,,,,,{}\n",
            csv_field(file),
            csv_field(failure.sentence())
        ),
    }
}

/// One file's text report under its name.
pub fn text_block(file: &str, outcome: &Outcome, unit: &str) -> String {
    match outcome {
        Ok(done) => {
            let note = done.refined.is_none().then_some(NOT_REFINED);
            format!(
                "== {file}\n{}\n",
                identify::render_reported(&done.report, done.refined.as_ref(), note, unit)
            )
        }
        Err(failure) => format!("== {file}\nlssi: {}\n\n", failure.sentence()),
    }
}
