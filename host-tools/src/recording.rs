//! Recordings on disk: CSV files with a header row, read into columns of f64.
//!
//! Columns `t` (seconds) and `x` (displacement) are required; `v` (velocity) and `u`
//! (excitation) are used when present; anything else is ignored. [`ColumnNames`] picks other
//! header names (`--t-col`, `--x-col`, `--v-col`, `--u-col`). A file that cannot be used is a
//! [`RecordingError`] whose message is one sentence naming the file, line and column at fault.
//!
//! The tokens `nan`, `NaN`, `inf`, `-inf` read as non-finite values and are passed through: the
//! identifier core rejects and counts such samples itself. Text that is not a number is an
//! error.
//!
//! ```
//! use lssi_host::recording::{ColumnNames, parse_csv};
//!
//! let text = "time,pos,note\n0,1.5,a\n0.01,nan,b\n";
//! let columns = ColumnNames { t: "time".into(), x: "pos".into(), ..ColumnNames::default() };
//! let recording = parse_csv("run.csv", text.as_bytes(), &columns).unwrap();
//! assert_eq!(recording.t, [0.0, 0.01]);
//! assert!(recording.x[1].is_nan());
//! assert!(recording.v.is_none());
//!
//! let error = parse_csv("run.csv", "t,x\n0,1.2.3\n".as_bytes(), &ColumnNames::default());
//! assert_eq!(
//!     error.unwrap_err().to_string(),
//!     r#"run.csv: line 2, column 'x': "1.2.3" is not a number."#
//! );
//! ```

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// Which header names hold which quantity.
///
/// `t` and `x` must be present. For `v` and `u`, `None` means "use the column named `v` (`u`)
/// if there is one", while `Some(name)` means that column must be present: a name the user
/// typed that is missing is more likely a typo than a wish to go without.
///
/// In a [`Recording`], `v` and `u` are `Some` exactly when that data was read, so the struct
/// reads the same file the same way again.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
#[command(next_help_heading = "Input")]
pub struct ColumnNames {
    /// Header name of the time column (seconds).
    #[arg(long = "t-col", value_name = "NAME", default_value = "t")]
    pub t: String,
    /// Header name of the displacement column; two names, X1,X2, for a two-degree-of-freedom
    /// harvester with an electrical column (x1'' and x2''; used if columns 'x1' and 'x2'
    /// exist and 'x' does not).
    #[arg(long = "x-col", value_name = "NAME", default_value = "x")]
    pub x: String,
    /// Header name of the velocity column [used if a column 'v' exists]; with two
    /// displacements two names, V1,V2 [used if 'v1' and 'v2' exist].
    #[arg(long = "v-col", value_name = "NAME")]
    pub v: Option<String>,
    /// Header name of the excitation column [used if a column 'u' exists].
    #[arg(long = "u-col", value_name = "NAME")]
    pub u: Option<String>,
}

impl Default for ColumnNames {
    fn default() -> Self {
        Self {
            t: "t".to_owned(),
            x: "x".to_owned(),
            v: None,
            u: None,
        }
    }
}

/// One row of a recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time, seconds.
    pub t: f64,
    /// Displacement.
    pub x: f64,
    /// Velocity, when the recording has it.
    pub v: Option<f64>,
    /// Excitation, when the recording has it.
    pub u: Option<f64>,
}

/// A recording read from a CSV file, one `Vec` per quantity, all of the same length.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// The file it was read from, as given.
    pub path: PathBuf,
    /// Sample times, seconds.
    pub t: Vec<f64>,
    /// Displacement.
    pub x: Vec<f64>,
    /// Velocity, if the file has a velocity column.
    pub v: Option<Vec<f64>>,
    /// Excitation, if the file has an excitation column.
    pub u: Option<Vec<f64>>,
    /// The header names the data came from; `v`/`u` are `Some` exactly when that data is.
    pub columns: ColumnNames,
}

impl Recording {
    /// A few lines describing the recording (what `lssi info` prints): size, time span,
    /// columns, and non-finite values.
    pub fn describe(&self) -> String {
        let non_finite = |values: Option<&Vec<f64>>| {
            values.map_or(0, |values| values.iter().filter(|v| !v.is_finite()).count())
        };
        Summary {
            path: &self.path,
            columns: &self.columns,
            samples: self.len(),
            first: self.t.first().copied().unwrap_or(f64::NAN),
            last: self.t.last().copied().unwrap_or(f64::NAN),
            non_finite: [
                non_finite(Some(&self.t)),
                non_finite(Some(&self.x)),
                non_finite(self.v.as_ref()),
                non_finite(self.u.as_ref()),
            ],
            has_v: self.v.is_some(),
            has_u: self.u.is_some(),
            backwards: self.t.windows(2).filter(|w| w[1] <= w[0]).count(),
        }
        .render()
    }

    /// Reads the CSV file at `path`; see [`parse_csv`].
    pub fn read(path: impl AsRef<Path>, columns: &ColumnNames) -> Result<Self, RecordingError> {
        read_csv(path, columns)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there are no samples (never, for a recording read from a file).
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The samples in order, for streaming into the identifier.
    pub fn samples(&self) -> impl ExactSizeIterator<Item = Sample> + '_ {
        self.t
            .iter()
            .zip(&self.x)
            .enumerate()
            .map(|(i, (&t, &x))| Sample {
                t,
                x,
                v: self.v.as_ref().and_then(|v| v.get(i).copied()),
                u: self.u.as_ref().and_then(|u| u.get(i).copied()),
            })
    }
}

/// The longest line a recording may have, in bytes (1 MiB).
pub const MAX_LINE: usize = 1 << 20;

/// Why a recording file cannot be used. Every message is one sentence that starts with the
/// file name.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordingError {
    /// The file could not be opened or read.
    #[error("{}: cannot read the file: {source}.", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
    /// The file has no header row (it is empty or blank).
    #[error(
        "{}: the file is empty; a recording needs a header row such as 't,x,v' and then one row \
         per sample.",
        .path.display()
    )]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// A line is longer than [`MAX_LINE`] bytes (not a recording: e.g. /dev/zero, a binary).
    #[error(
        "{}: line {line} is longer than {} bytes, so the file is not a CSV recording.",
        .path.display(),
        MAX_LINE
    )]
    LineTooLong {
        /// The file.
        path: PathBuf,
        /// The line, counted from 1.
        line: usize,
    },
    /// A required column is not in the header.
    #[error("{}", missing_column(.path, *.line, .column, .found))]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the header.
        line: u64,
        /// The column asked for.
        column: String,
        /// The header's fields.
        found: Vec<String>,
    },
    /// A column name appears more than once in the header, so which one to use is unclear.
    #[error(
        "{}: line {line}, column '{column}' appears more than once in the header, so which one \
         to use is unclear.",
        .path.display()
    )]
    DuplicateColumn {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the header.
        line: u64,
        /// The repeated name.
        column: String,
    },
    /// The header is there but no data rows follow.
    #[error("{}: the header is there but no data rows follow it.", .path.display())]
    NoData {
        /// The file.
        path: PathBuf,
    },
    /// A row has a different number of fields than the header.
    #[error("{}", ragged(.path, *.line, *.fields, .header))]
    Ragged {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the row.
        line: u64,
        /// Fields in the row.
        fields: usize,
        /// The header's fields.
        header: Vec<String>,
    },
    /// A field that should hold a number is empty.
    #[error("{}: line {line}, column '{column}' is empty.", .path.display())]
    EmptyField {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// The column's header name.
        column: String,
    },
    /// A field holds text that is not a number.
    #[error("{}: line {line}, column '{column}': {} is not a number.", .path.display(), quoted(.text))]
    NotANumber {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// The column's header name.
        column: String,
        /// The offending text.
        text: String,
    },
    /// A field is not valid UTF-8 (the file is probably not a text CSV).
    #[error("{}", not_text(.path, *.line, .column.as_deref()))]
    NotText {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// The column's header name, when the header could be read.
        column: Option<String>,
    },
}

impl RecordingError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            RecordingError::Io { path, .. }
            | RecordingError::Empty { path }
            | RecordingError::LineTooLong { path, .. }
            | RecordingError::MissingColumn { path, .. }
            | RecordingError::DuplicateColumn { path, .. }
            | RecordingError::NoData { path }
            | RecordingError::Ragged { path, .. }
            | RecordingError::EmptyField { path, .. }
            | RecordingError::NotANumber { path, .. }
            | RecordingError::NotText { path, .. } => path,
        }
    }
}

/// The longest stretch of offending text quoted in a message.
const QUOTE_LIMIT: usize = 40;

/// `text` in double quotes, cut short (with an ellipsis) if it is long.
fn quoted(text: &str) -> String {
    if text.chars().count() <= QUOTE_LIMIT {
        format!("{text:?}")
    } else {
        let head: String = text.chars().take(QUOTE_LIMIT).collect();
        format!("{head:?}…")
    }
}

/// `text` cut short (with an ellipsis) if it is long.
fn shortened(text: &str) -> String {
    if text.chars().count() <= QUOTE_LIMIT {
        text.to_owned()
    } else {
        let head: String = text.chars().take(QUOTE_LIMIT).collect();
        format!("{head}…")
    }
}

fn looks_like_numbers(fields: &[String]) -> bool {
    !fields.is_empty() && fields.iter().all(|f| f.parse::<f64>().is_ok())
}

/// The sentence of [`RecordingError::MissingColumn`].
fn missing_column(path: &Path, line: u64, column: &str, found: &[String]) -> String {
    let list = found
        .iter()
        .map(|name| shortened(name))
        .collect::<Vec<_>>()
        .join(", ");
    let mut text = format!(
        "{}: no column named '{column}' in the header (found: {list})",
        path.display()
    );
    if looks_like_numbers(found) {
        text.push_str(&format!(
            "; line {line} looks like data, so the file seems to have no header row: \
             add one such as 't,x,v'."
        ));
    } else if let Some(hint) = header_hint(column, found) {
        text.push_str("; ");
        text.push_str(&hint);
        text.push('.');
    } else {
        text.push('.');
    }
    text
}

/// A hint for a header without `column`: another delimiter than the comma (one field holding
/// `;`, a tab or `|`), or a name that differs only in case (`T` for `t`: the option to give).
fn header_hint(column: &str, found: &[String]) -> Option<String> {
    if let [only] = found {
        let delimiters = [
            (';', "semicolons (';')"),
            ('\t', "tabs"),
            ('|', "bars ('|')"),
        ];
        if let Some((_, name)) = delimiters.iter().find(|(d, _)| only.contains(*d)) {
            return Some(format!(
                "the header seems to be separated by {name}, but lssi reads comma-separated files: \
                 replace the delimiter with commas (e.g. tr ';\\t' ',,' < in > out.csv), after \
                 turning any decimal commas (0,5) into points (e.g. sed 's/,/./g')"
            ));
        }
    }
    let Some(other) = found.iter().find(|f| f.eq_ignore_ascii_case(column)) else {
        return unit_suffix_hint(column, found);
    };
    // Every default name the header has in another case: all the options needed at once.
    let flags: Vec<String> = ["t", "x", "v", "u"]
        .iter()
        .filter(|name| !found.iter().any(|f| f == *name))
        .filter_map(|name| {
            found
                .iter()
                .find(|f| f.eq_ignore_ascii_case(name))
                .map(|f| format!("--{name}-col {f}"))
        })
        .collect();
    let give = if flags.is_empty() {
        format!("the matching --t-col, --x-col, --v-col or --u-col {other}")
    } else {
        flags.join(" ")
    };
    Some(format!(
        "column '{other}' differs only in case (names are case-sensitive): give {give}"
    ))
}

/// A hint for a header whose names carry units or words (`t_s`, `time`, `x [mm]`,
/// `base_acc_g`): the column that looks like `column` (its name, then `_`, a space, `(` or
/// `[`; or `time…` for `t`) as the option to give, and the options naming the channels.
fn unit_suffix_hint(column: &str, found: &[String]) -> Option<String> {
    let looks_like = |f: &&String| {
        let lower = f.to_ascii_lowercase();
        lower
            .strip_prefix(column)
            .is_some_and(|rest| rest.starts_with(['_', ' ', '(', '[']))
            || (column == "t" && lower.starts_with("time"))
    };
    if !["t", "x", "v", "u"].contains(&column) {
        return None;
    }
    let flag = format!("--{column}-col");
    let channels = "name the motion's column with --x-col or --v-col, a measured excitation's with --u-col, and the load's voltage or current with --V-col or --i-col";
    Some(match found.iter().find(looks_like) {
        Some(name) => format!("if '{name}' is {column}, give {flag} {name}; {channels}"),
        None => channels.to_owned(),
    })
}

/// The sentence of [`RecordingError::Ragged`].
fn ragged(path: &Path, line: u64, fields: usize, header: &[String]) -> String {
    let mut text = format!(
        "{}: line {line} has {fields} field{} but the header has {}",
        path.display(),
        if fields == 1 { "" } else { "s" },
        header.len()
    );
    match header.get(fields) {
        Some(missing) if fields < header.len() => text.push_str(&format!(
            ", so column '{missing}' is missing (perhaps the line was cut short)."
        )),
        _ => match header.last() {
            Some(last) => text.push_str(&format!(", so it has fields beyond column '{last}'.")),
            None => text.push('.'),
        },
    }
    text
}

/// The sentence of [`RecordingError::NotText`].
fn not_text(path: &Path, line: u64, column: Option<&str>) -> String {
    match column {
        Some(column) => format!(
            "{}: line {line}, column '{column}' is not UTF-8 text, so this is probably not a CSV \
             file.",
            path.display()
        ),
        None => format!(
            "{}: line {line} is not UTF-8 text, so this is probably not a CSV file.",
            path.display()
        ),
    }
}

/// Reads the CSV file at `path`; see [`parse_csv`].
pub fn read_csv(
    path: impl AsRef<Path>,
    columns: &ColumnNames,
) -> Result<Recording, RecordingError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|source| RecordingError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_csv(path, file, columns)
}

/// Where each wanted quantity sits in a row.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Positions {
    pub(crate) t: usize,
    pub(crate) x: usize,
    pub(crate) v: Option<usize>,
    pub(crate) u: Option<usize>,
}

/// Which columns of `header` (on line `header_line`) hold which quantity: the required ones
/// present once, an optional one named by the user required too, a default name taken when
/// present. Shared by [`parse_csv`] and the chunked reader (`identify::stream`).
pub(crate) fn resolve_columns(
    path: &Path,
    header: &[String],
    header_line: u64,
    columns: &ColumnNames,
) -> Result<Positions, RecordingError> {
    let find = |name: &str, required: bool| -> Result<Option<usize>, RecordingError> {
        let mut hits = header
            .iter()
            .enumerate()
            .filter(|(_, h)| h.as_str() == name);
        match (hits.next(), hits.next()) {
            (Some(_), Some(_)) => Err(RecordingError::DuplicateColumn {
                path: path.to_owned(),
                line: header_line,
                column: name.to_owned(),
            }),
            (Some((index, _)), None) => Ok(Some(index)),
            (None, _) if required => Err(RecordingError::MissingColumn {
                path: path.to_owned(),
                line: header_line,
                column: name.to_owned(),
                found: header.to_vec(),
            }),
            (None, _) => Ok(None),
        }
    };
    let required = |name: &str| -> Result<usize, RecordingError> {
        find(name, true)?.ok_or_else(|| RecordingError::MissingColumn {
            path: path.to_owned(),
            line: header_line,
            column: name.to_owned(),
            found: header.to_vec(),
        })
    };
    let optional = |name: &Option<String>, default: &str| match name {
        Some(name) => required(name).map(Some),
        None => find(default, false),
    };
    Ok(Positions {
        t: required(&columns.t)?,
        x: required(&columns.x)?,
        v: optional(&columns.v, "v")?,
        u: optional(&columns.u, "u")?,
    })
}

/// The 1-based line of the record that csv reports at byte offset `start`.
///
/// csv's own `Position::line` is wrong after blank lines (rust-csv issue 208), and its byte
/// offset can point at the line ends before a record, so skip those and count.
fn line_at(bytes: &[u8], start: u64) -> u64 {
    let start = usize::try_from(start)
        .unwrap_or(usize::MAX)
        .min(bytes.len());
    let skipped = bytes[start..]
        .iter()
        .take_while(|&&b| b == b'\n' || b == b'\r')
        .count();
    let newlines = bytes[..start + skipped]
        .iter()
        .filter(|&&b| b == b'\n')
        .count();
    newlines as u64 + 1
}

/// Parses CSV text from `reader` as a recording; `path` names it in the result and in errors.
///
/// Fields are trimmed of surrounding spaces, blank lines are skipped (so trailing blank lines
/// are fine), a UTF-8 byte-order mark is ignored, and every row must have as many fields as
/// the header.
pub fn parse_csv(
    path: impl Into<PathBuf>,
    mut reader: impl Read,
    columns: &ColumnNames,
) -> Result<Recording, RecordingError> {
    let path = path.into();
    // The whole text stays at hand so an error can name its true line (see `line_at`); the
    // parsed columns are about as large anyway.
    let mut bytes = Vec::new();
    // Read in chunks, so that a line without end (/dev/zero, a binary file) is refused after
    // MAX_LINE bytes instead of filling the memory.
    let mut chunk = vec![0u8; 1 << 16];
    let (mut lines, mut since_newline) = (1usize, 0usize);
    loop {
        let n = match reader.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(source) => return Err(RecordingError::Io { path, source }),
        };
        for &b in &chunk[..n] {
            if b == b'\n' {
                lines += 1;
                since_newline = 0;
            } else {
                since_newline += 1;
                if since_newline > MAX_LINE {
                    return Err(RecordingError::LineTooLong { path, line: lines });
                }
            }
        }
        bytes.extend_from_slice(&chunk[..n]);
    }
    let mut csv = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());

    let header: Vec<String> = match csv.headers() {
        Ok(record) => record.iter().map(str::to_owned).collect(),
        Err(error) => return Err(from_csv_error(&path, &bytes, error, None)),
    };
    if header.iter().all(String::is_empty) {
        return Err(RecordingError::Empty { path });
    }
    let header_line = line_at(&bytes, 0);

    let positions = resolve_columns(&path, &header, header_line, columns)?;

    let mut t = Vec::new();
    let mut x = Vec::new();
    let mut v = positions.v.map(|_| Vec::new());
    let mut u = positions.u.map(|_| Vec::new());
    let mut record = csv::StringRecord::new();
    loop {
        match csv.read_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(error) => return Err(from_csv_error(&path, &bytes, error, Some(&header))),
        }
        let start = record.position().map_or(0, csv::Position::byte);
        // With trimming, a line of spaces is one empty field: as blank as an empty line.
        if record.len() == 1 && record.get(0).is_some_and(str::is_empty) && header.len() > 1 {
            continue;
        }
        if record.len() != header.len() {
            return Err(RecordingError::Ragged {
                line: line_at(&bytes, start),
                path,
                fields: record.len(),
                header,
            });
        }
        let number = |index: usize| -> Result<f64, RecordingError> {
            let text = record.get(index).unwrap_or_default();
            if text.is_empty() {
                return Err(RecordingError::EmptyField {
                    path: path.clone(),
                    line: line_at(&bytes, start),
                    column: header[index].clone(),
                });
            }
            text.parse::<f64>().map_err(|_| RecordingError::NotANumber {
                path: path.clone(),
                line: line_at(&bytes, start),
                column: header[index].clone(),
                text: text.to_owned(),
            })
        };
        t.push(number(positions.t)?);
        x.push(number(positions.x)?);
        if let (Some(values), Some(index)) = (v.as_mut(), positions.v) {
            values.push(number(index)?);
        }
        if let (Some(values), Some(index)) = (u.as_mut(), positions.u) {
            values.push(number(index)?);
        }
    }
    if t.is_empty() {
        return Err(RecordingError::NoData { path });
    }

    let columns = ColumnNames {
        t: header[positions.t].clone(),
        x: header[positions.x].clone(),
        v: positions.v.map(|i| header[i].clone()),
        u: positions.u.map(|i| header[i].clone()),
    };
    Ok(Recording {
        path,
        t,
        x,
        v,
        u,
        columns,
    })
}

fn from_csv_error(
    path: &Path,
    bytes: &[u8],
    error: csv::Error,
    header: Option<&[String]>,
) -> RecordingError {
    let path = path.to_owned();
    let line = line_at(bytes, error.position().map_or(0, csv::Position::byte));
    match error.into_kind() {
        csv::ErrorKind::Io(source) => RecordingError::Io { path, source },
        csv::ErrorKind::Utf8 { err, .. } => RecordingError::NotText {
            path,
            line,
            column: header.and_then(|h| h.get(err.field())).cloned(),
        },
        // Reading with `flexible` set, the remaining kinds (unequal lengths, serde, seek) do
        // not arise; report them as unreadable rather than panic.
        other => RecordingError::Io {
            path,
            source: io::Error::other(format!("{other:?}")),
        },
    }
}

/// Formats a value with the shortest decimal that reads back as the same f64 (`0.1`, `1e-7`,
/// `NaN`, `inf`), so a CSV round trip is exact.
pub fn format_value(value: f64) -> String {
    // `{:?}` is the shortest round-trip form and switches to exponents for very large or small
    // magnitudes, where `{}` would print hundreds of digits.
    format!("{value:?}")
}

/// Writes columns of equal length as CSV with a header row to `writer`.
///
/// Values are written with [`format_value`]. Columns of different lengths are an
/// `InvalidInput` error, as is a header whose length differs from the number of columns.
pub fn write_csv_to(writer: impl Write, header: &[&str], columns: &[&[f64]]) -> io::Result<()> {
    if header.len() != columns.len() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} header names for {} columns",
                header.len(),
                columns.len()
            ),
        ));
    }
    let rows = columns.first().map_or(0, |c| c.len());
    if columns.iter().any(|c| c.len() != rows) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "columns of different lengths",
        ));
    }
    let mut csv = csv::Writer::from_writer(writer);
    csv.write_record(header)?;
    let mut fields: Vec<String> = Vec::with_capacity(columns.len());
    for row in 0..rows {
        fields.clear();
        fields.extend(columns.iter().map(|c| format_value(c[row])));
        csv.write_record(&fields)?;
    }
    csv.flush()
}

/// Writes columns of equal length as a CSV file at `path`; see [`write_csv_to`].
pub fn write_csv(path: impl AsRef<Path>, header: &[&str], columns: &[&[f64]]) -> io::Result<()> {
    let file = File::create(path)?;
    let mut writer = BufWriter::new(file);
    write_csv_to(&mut writer, header, columns)?;
    writer.flush()
}

/// What `lssi info` says of a recording, counted in one pass over it: in memory
/// ([`Recording::describe`]) or streamed (`identify::stream::describe_file`).
pub struct Summary<'a> {
    /// The file.
    pub path: &'a Path,
    /// Its columns, as resolved.
    pub columns: &'a ColumnNames,
    /// Rows read.
    pub samples: usize,
    /// The first time.
    pub first: f64,
    /// The last time.
    pub last: f64,
    /// Non-finite values of t, x, v and u.
    pub non_finite: [usize; 4],
    /// Whether v is in the recording.
    pub has_v: bool,
    /// Whether u is in the recording.
    pub has_u: bool,
    /// Rows whose time does not increase.
    pub backwards: usize,
}

impl Summary<'_> {
    /// The lines `lssi info` prints.
    pub fn render(&self) -> String {
        let (n, first, last) = (self.samples, self.first, self.last);
        let mut text = format!(
            "{}: {n} sample{}, t from {first} to {last} s",
            self.path.display(),
            if n == 1 { "" } else { "s" }
        );
        if n > 1 {
            text.push_str(&format!(
                " (mean interval {} s)",
                (last - first) / (n - 1) as f64
            ));
        }
        text.push('\n');
        let c = self.columns;
        let optional = |name: &Option<String>| match name {
            Some(name) => format!("'{name}'"),
            None => "absent".to_owned(),
        };
        text.push_str(&format!(
            "columns: t = '{}', x = '{}', v = {}, u = {}\n",
            c.t,
            c.x,
            optional(&c.v),
            optional(&c.u)
        ));
        let mut counts = vec![
            format!("t {}", self.non_finite[0]),
            format!("x {}", self.non_finite[1]),
        ];
        if self.has_v {
            counts.push(format!("v {}", self.non_finite[2]));
        }
        if self.has_u {
            counts.push(format!("u {}", self.non_finite[3]));
        }
        text.push_str(&format!("non-finite values: {}\n", counts.join(", ")));
        if self.backwards > 0 {
            text.push_str(&format!(
                "warning: t fails to increase at {} row{}\n",
                self.backwards,
                if self.backwards == 1 { "" } else { "s" }
            ));
        }
        text
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Recording, RecordingError> {
        parse_csv("data.csv", text.as_bytes(), &ColumnNames::default())
    }

    #[test]
    fn optional_columns_and_extras() {
        let r = parse("u, t ,x,v,other\n1,0,2,3,x\n4,0.5,5,6,y\n\n\n").unwrap();
        assert_eq!(r.t, [0.0, 0.5]);
        assert_eq!(r.x, [2.0, 5.0]);
        assert_eq!(r.v, Some(vec![3.0, 6.0]));
        assert_eq!(r.u, Some(vec![1.0, 4.0]));
        assert_eq!(r.columns.v.as_deref(), Some("v"));
        let samples: Vec<Sample> = r.samples().collect();
        assert_eq!(
            samples[1],
            Sample {
                t: 0.5,
                x: 5.0,
                v: Some(6.0),
                u: Some(4.0)
            }
        );
    }

    #[test]
    fn non_finite_tokens_pass_through() {
        let r = parse("t,x\n0,nan\n1,NaN\n2,inf\n3,-inf\n").unwrap();
        assert!(r.x[0].is_nan() && r.x[1].is_nan());
        assert_eq!(r.x[2], f64::INFINITY);
        assert_eq!(r.x[3], f64::NEG_INFINITY);
    }

    #[test]
    fn values_format_for_an_exact_round_trip() {
        for value in [0.1, 1.0 / 3.0, 1e-7, -2.5e300, 100.0] {
            assert_eq!(format_value(value).parse::<f64>(), Ok(value));
        }
        assert_eq!(format_value(0.003), "0.003");
    }

    #[test]
    fn writer_rejects_mismatched_columns() {
        let mut out = Vec::new();
        let error = write_csv_to(&mut out, &["t", "x"], &[&[0.0, 1.0], &[0.0]]).unwrap_err();
        assert_eq!(error.kind(), io::ErrorKind::InvalidInput);
        let error = write_csv_to(&mut out, &["t"], &[&[0.0], &[0.0]]).unwrap_err();
        assert_eq!(error.kind(), io::ErrorKind::InvalidInput);
    }

    #[test]
    fn describes_a_small_recording() {
        let text = "t,x,v\n0,1,nan\n0.5,2,0\n0.5,inf,1\n";
        let recording = parse_csv("r.csv", text.as_bytes(), &ColumnNames::default()).unwrap();
        assert_eq!(
            recording.describe(),
            "r.csv: 3 samples, t from 0 to 0.5 s (mean interval 0.25 s)\n\
             columns: t = 't', x = 'x', v = 'v', u = absent\n\
             non-finite values: t 0, x 1, v 1\n\
             warning: t fails to increase at 1 row\n"
        );
    }
}
