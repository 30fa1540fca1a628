//! `lssi log FILE`: prints a telemetry log written by `lssi replay`, as text (the default),
//! JSON lines (`--json`, one object per record) or CSV (`--csv`: model coefficients, health
//! counters and device log lines over time, one value a row).
//!
//! A log cut short by a killed writer is printed up to its last whole record, and a sentence
//! on stderr says that a partial record was skipped. A corrupt record stops the printing
//! there, with an error naming its offset. Frames are decoded here, from the raw bytes the log
//! keeps; device log lines are decoded with `--elf` (the firmware's defmt tables) or shown raw.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;
use lssi_core::Config;

use crate::error::CliError;
use crate::telemetry::decode::{Event, csv_rows, decode, entry_json, render_text, session_config};
use crate::telemetry::defmt::Tables;
use crate::telemetry::read_log;

/// Arguments of `lssi log`.
#[derive(Debug, Clone, Args)]
pub struct LogArgs {
    /// The telemetry log (written by `lssi replay --log`).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// One JSON object per record instead of text.
    #[arg(long, conflicts_with = "csv")]
    pub json: bool,
    /// CSV: session, time_s, kind, field, value (model coefficients, health, log lines).
    #[arg(long)]
    pub csv: bool,
    /// The firmware's ELF, to decode the device's defmt log lines.
    #[arg(long, value_name = "ELF")]
    pub elf: Option<PathBuf>,
}

/// A CSV writer's error as the I/O error under it (so that a closed pipe stays one and ends
/// `lssi` quietly, see [`crate::output::fail`]).
fn csv_io(error: csv::Error) -> std::io::Error {
    match error.into_kind() {
        csv::ErrorKind::Io(e) => e,
        other => std::io::Error::other(format!("{other:?}")),
    }
}

/// Why a log without a single record prints nothing: one sentence naming the file.
fn nothing_logged(file: &str, len: usize, partial: bool) -> String {
    let magic = crate::telemetry::MAGIC.len();
    if len == 0 {
        format!("{file}: the file is empty, so it holds no telemetry record.")
    } else if len < magic {
        format!(
            "{file}: the file holds only the first {len} of the log header's {magic} bytes (its writer stopped before logging anything), so it holds no telemetry record."
        )
    } else if partial {
        format!(
            "{file}: the log holds its header and one partial record ({} bytes, as a writer stopped mid-record leaves it), and no whole record.",
            len - magic
        )
    } else {
        format!("{file}: the log holds only its header, no telemetry record (nothing was logged).")
    }
}

/// Runs `lssi log`.
pub fn run(args: &LogArgs) -> Result<(), CliError> {
    let file = args.file.display().to_string();
    let bytes = std::fs::read(&args.file)
        .map_err(|e| CliError::Input(format!("{file}: cannot read the telemetry log: {e}.")))?;
    let tables = args
        .elf
        .as_deref()
        .map(Tables::load)
        .transpose()
        .map_err(|e| CliError::Input(format!("{e}.")))?;
    let (records, partial, skipped) = match read_log(&bytes) {
        Ok(contents) => (contents.records, contents.partial_tail, contents.skipped),
        Err(error) => return Err(CliError::Input(format!("{file}: {error}."))),
    };
    if records.is_empty() && skipped.is_empty() {
        return Err(CliError::Input(nothing_logged(
            &file,
            bytes.len(),
            partial.is_some(),
        )));
    }
    let entries = decode(&records, tables.as_ref());
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let written = if args.json {
        let mut session = (Config::default(), false);
        entries.iter().try_for_each(|entry| {
            if let Event::Session(value) = &entry.event {
                session = session_config(value);
            }
            writeln!(out, "{}", entry_json(entry, &session))
        })
    } else if args.csv {
        let mut writer = csv::Writer::from_writer(&mut out);
        let mut result = writer
            .write_record(["session", "time_s", "kind", "field", "value"])
            .map_err(csv_io);
        for row in csv_rows(&entries) {
            if result.is_ok() {
                result = writer.write_record(&row).map_err(csv_io);
            }
        }
        result.and_then(|()| writer.flush())
    } else {
        out.write_all(render_text(&entries).as_bytes())
    };
    // A closed pipe (`| head`) or a full disk: exit 1 (quietly for the pipe).
    if let Err(e) = written {
        crate::output::fail(&e)
    }
    if let Some(tail) = partial {
        eprintln!(
            "lssi: {file}: the last record ({} bytes at byte {}) is partial, as a stopped writer leaves it, and was skipped.",
            tail.len, tail.offset
        );
    }
    for s in &skipped {
        eprintln!(
            "lssi: {file}: {} damaged bytes at byte {} were skipped (the record there: {}); reading went on at the next whole record.",
            s.len, s.offset, s.reason
        );
    }
    if !skipped.is_empty() {
        let bytes: u64 = skipped.iter().map(|s| s.len).sum();
        return Err(CliError::Input(format!(
            "{file}: the log is damaged: {} stretch(es), {bytes} bytes, were skipped; the {} intact records were printed.",
            skipped.len(),
            records.len()
        )));
    }
    Ok(())
}
