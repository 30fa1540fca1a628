//! What `lssi gen` writes: a generated recording as CSV and, beside it with the extension
//! `.json`, its truth, pretty-printed.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::CliError;
use crate::recording::write_csv;
use crate::synth::Generated;
use crate::synth::eveh::EvehGenerated;
use crate::synth::harvester::HarvesterGenerated;

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
    write_truth(json, generated)
}

/// Writes the truth of a generated recording, pretty-printed, to `json`.
fn write_truth(json: &Path, generated: &Generated) -> Result<(), CliError> {
    write_json(json, &generated.truth)
}

/// Writes `value`, pretty-printed, to `json`.
fn write_json(json: &Path, value: &impl serde::Serialize) -> Result<(), CliError> {
    let write_json = || -> std::io::Result<()> {
        let mut writer = BufWriter::new(File::create(json)?);
        serde_json::to_writer_pretty(&mut writer, value)?;
        writeln!(writer)?;
        writer.flush()
    };
    write_json().map_err(|source| CliError::Write {
        path: json.to_owned(),
        source,
    })
}

/// Writes a generated harvester recording (with its `u` column, if any) and its truth.
pub fn write_eveh(csv: &Path, json: &Path, generated: &EvehGenerated) -> Result<(), CliError> {
    let (header, columns) = generated.csv_columns();
    write_csv(csv, &header, &columns).map_err(|source| CliError::Write {
        path: csv.to_owned(),
        source,
    })?;
    write_truth(json, &generated.generated)
}

/// Writes a generated harvester-with-circuit recording (`t`, the chosen channels) and its
/// truth (both equations).
pub fn write_harvester(
    csv: &Path,
    json: &Path,
    generated: &HarvesterGenerated,
) -> Result<(), CliError> {
    let (header, columns) = generated.csv_columns();
    write_csv(csv, &header, &columns).map_err(|source| CliError::Write {
        path: csv.to_owned(),
        source,
    })?;
    write_json(json, &generated.truth)
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
}
