//! Reading: [`CsvStream`], a CSV recording one sample at a time (the same checks and error
//! sentences as [`crate::recording::parse_csv`]), and [`describe_file`], what `lssi info`
//! prints from one pass over a large file.

use std::fs::File;
use std::io::{self, BufReader, Read};
use std::path::{Path, PathBuf};

use crate::recording::{
    ColumnNames, MAX_LINE, Positions, Recording, RecordingError, Sample, resolve_columns,
};

/// Counts bytes since the last newline and refuses a line longer than [`MAX_LINE`].
struct LineLimit<R> {
    inner: R,
    line: usize,
    since_newline: usize,
    too_long: bool,
}

impl<R: Read> Read for LineLimit<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.too_long {
            return Err(io::Error::other("line too long"));
        }
        let n = self.inner.read(buf)?;
        for &b in &buf[..n] {
            if b == b'\n' {
                self.line += 1;
                self.since_newline = 0;
            } else {
                self.since_newline += 1;
                if self.since_newline > MAX_LINE {
                    self.too_long = true;
                    return Err(io::Error::other("line too long"));
                }
            }
        }
        Ok(n)
    }
}

/// A CSV recording read one sample at a time; the same format, checks and error sentences as
/// [`crate::recording::parse_csv`] (a line longer than [`MAX_LINE`] is found when it is reached,
/// not before the first row).
pub struct CsvStream {
    /// The name in messages and in the recordings read (the file's path, or what it stands
    /// for: `-` for standard input spooled to a temporary file).
    path: PathBuf,
    /// The file read.
    file: PathBuf,
    csv: csv::Reader<LineLimit<BufReader<File>>>,
    pub(super) header: Vec<String>,
    positions: Positions,
    pub(super) columns: ColumnNames,
    record: csv::StringRecord,
    rows: u64,
    size: u64,
}

impl std::fmt::Debug for CsvStream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CsvStream")
            .field("path", &self.path)
            .field("rows", &self.rows)
            .finish_non_exhaustive()
    }
}

pub(super) fn reader_builder() -> csv::ReaderBuilder {
    let mut builder = csv::ReaderBuilder::new();
    builder
        .flexible(true)
        .trim(csv::Trim::All)
        .buffer_capacity(1 << 16);
    builder
}

/// The 1-based line of the record that csv reports at byte offset `start` of the file (see
/// `line_at` in [`crate::recording`]): the newlines before it, and those of blank lines
/// right at it. Read again from the file, as this is only needed for an error.
fn line_at_file(path: &Path, start: u64) -> u64 {
    let Ok(file) = File::open(path) else {
        return 0;
    };
    let mut reader = BufReader::with_capacity(1 << 16, file);
    let mut buffer = vec![0u8; 1 << 16];
    let (mut offset, mut newlines, mut skipping) = (0u64, 0u64, false);
    loop {
        let n = match reader.read(&mut buffer) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        for &b in &buffer[..n] {
            if offset >= start {
                skipping = true;
            }
            if skipping && b != b'\n' && b != b'\r' {
                return newlines + 1;
            }
            if b == b'\n' {
                newlines += 1;
            }
            offset += 1;
        }
    }
    newlines + 1
}

impl CsvStream {
    /// Opens the file at `path` and reads its header.
    pub fn open(path: impl AsRef<Path>, columns: &ColumnNames) -> Result<Self, RecordingError> {
        Self::open_named(path.as_ref(), path.as_ref(), columns)
    }

    /// Opens the file at `file` and reads its header; messages (and the recordings read) name
    /// it `name`.
    pub fn open_named(
        file: &Path,
        name: &Path,
        columns: &ColumnNames,
    ) -> Result<Self, RecordingError> {
        let source = file.to_owned();
        let path = name.to_owned();
        let io_error = |source| RecordingError::Io {
            path: path.clone(),
            source,
        };
        let file = File::open(&source).map_err(io_error)?;
        let size = file.metadata().map_err(io_error)?.len();
        let limit = LineLimit {
            inner: BufReader::with_capacity(1 << 16, file),
            line: 1,
            since_newline: 0,
            too_long: false,
        };
        let mut csv = reader_builder().has_headers(true).from_reader(limit);
        let header: Vec<String> = match csv.headers() {
            Ok(record) => record.iter().map(str::to_owned).collect(),
            Err(error) => return Err(stream_error(&path, &source, &csv, error, None)),
        };
        if header.iter().all(String::is_empty) {
            return Err(RecordingError::Empty { path });
        }
        let header_line = line_at_file(&source, 0);
        let positions = resolve_columns(&path, &header, header_line, columns)?;
        let columns = ColumnNames {
            t: header[positions.t].clone(),
            x: header[positions.x].clone(),
            v: positions.v.map(|i| header[i].clone()),
            u: positions.u.map(|i| header[i].clone()),
        };
        Ok(Self {
            path,
            file: source,
            csv,
            header,
            positions,
            columns,
            record: csv::StringRecord::new(),
            rows: 0,
            size,
        })
    }

    /// The header names the samples come from (`v`/`u` are `Some` exactly when present).
    pub fn columns(&self) -> &ColumnNames {
        &self.columns
    }

    /// The file read (its path; [`Recording::path`] of what it reads is the name in messages).
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// The file's size in bytes.
    pub fn size(&self) -> u64 {
        self.size
    }

    /// Bytes of the file parsed so far.
    pub fn bytes_read(&self) -> u64 {
        self.csv.position().byte()
    }

    /// Data rows read so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// The next sample, or `None` at the end of the file.
    pub fn next_sample(&mut self) -> Result<Option<Sample>, RecordingError> {
        loop {
            match self.csv.read_record(&mut self.record) {
                Ok(true) => {}
                Ok(false) => return Ok(None),
                Err(error) => {
                    return Err(stream_error(
                        &self.path,
                        &self.file,
                        &self.csv,
                        error,
                        Some(&self.header),
                    ));
                }
            }
            let record = &self.record;
            if record.len() == 1
                && record.get(0).is_some_and(str::is_empty)
                && self.header.len() > 1
            {
                continue;
            }
            let start = record.position().map_or(0, csv::Position::byte);
            if record.len() != self.header.len() {
                return Err(RecordingError::Ragged {
                    line: line_at_file(&self.file, start),
                    path: self.path.clone(),
                    fields: record.len(),
                    header: self.header.clone(),
                });
            }
            let number =
                |index: usize| number((&self.path, &self.file), &self.header, record, start, index);
            let p = self.positions;
            let sample = Sample {
                t: number(p.t)?,
                x: number(p.x)?,
                v: p.v.map(number).transpose()?,
                u: p.u.map(number).transpose()?,
            };
            self.rows += 1;
            return Ok(Some(sample));
        }
    }

    /// Reads up to `rows` samples into a [`Recording`] (named by the file, with its columns).
    /// The result is shorter when the file ends first, and empty at its end.
    pub fn read_rows(&mut self, rows: usize) -> Result<Recording, RecordingError> {
        let mut recording = Recording {
            path: self.path.clone(),
            t: Vec::new(),
            x: Vec::new(),
            v: self.columns.v.as_ref().map(|_| Vec::new()),
            u: self.columns.u.as_ref().map(|_| Vec::new()),
            columns: self.columns.clone(),
        };
        while recording.t.len() < rows {
            let Some(s) = self.next_sample()? else { break };
            recording.t.push(s.t);
            recording.x.push(s.x);
            if let (Some(values), Some(v)) = (recording.v.as_mut(), s.v) {
                values.push(v);
            }
            if let (Some(values), Some(u)) = (recording.u.as_mut(), s.u) {
                values.push(u);
            }
        }
        Ok(recording)
    }
}

/// One field as a number, or the sentence saying why not.
fn number(
    (path, file): (&Path, &Path),
    header: &[String],
    record: &csv::StringRecord,
    start: u64,
    index: usize,
) -> Result<f64, RecordingError> {
    let text = record.get(index).unwrap_or_default();
    if text.is_empty() {
        return Err(RecordingError::EmptyField {
            path: path.to_owned(),
            line: line_at_file(file, start),
            column: header.get(index).cloned().unwrap_or_default(),
        });
    }
    text.parse::<f64>().map_err(|_| RecordingError::NotANumber {
        path: path.to_owned(),
        line: line_at_file(file, start),
        column: header.get(index).cloned().unwrap_or_default(),
        text: text.to_owned(),
    })
}

fn stream_error(
    path: &Path,
    file: &Path,
    csv: &csv::Reader<LineLimit<BufReader<File>>>,
    error: csv::Error,
    header: Option<&[String]>,
) -> RecordingError {
    let path = path.to_owned();
    if csv.get_ref().too_long {
        let line = csv.get_ref().line;
        return RecordingError::LineTooLong { path, line };
    }
    let line = line_at_file(file, error.position().map_or(0, csv::Position::byte));
    match error.into_kind() {
        csv::ErrorKind::Io(source) => RecordingError::Io { path, source },
        csv::ErrorKind::Utf8 { err, .. } => RecordingError::NotText {
            path,
            line,
            column: header.and_then(|h| h.get(err.field())).cloned(),
        },
        other => RecordingError::Io {
            path,
            source: io::Error::other(format!("{other:?}")),
        },
    }
}
/// What `lssi info` prints, from one pass over the file: see [`Recording::describe`].
pub fn describe_file(
    path: impl AsRef<Path>,
    columns: &ColumnNames,
) -> Result<String, RecordingError> {
    let mut csv = CsvStream::open(path, columns)?;
    let (mut n, mut first, mut last) = (0usize, f64::NAN, f64::NAN);
    let mut non_finite = [0usize; 4];
    let mut backwards = 0usize;
    let mut previous: Option<f64> = None;
    while let Some(s) = csv.next_sample()? {
        if n == 0 {
            first = s.t;
        }
        last = s.t;
        n += 1;
        for (count, value) in non_finite.iter_mut().zip([Some(s.t), Some(s.x), s.v, s.u]) {
            if value.is_some_and(|v| !v.is_finite()) {
                *count += 1;
            }
        }
        if let Some(p) = previous
            && s.t <= p
        {
            backwards += 1;
        }
        previous = Some(s.t);
    }
    if n == 0 {
        return Err(RecordingError::NoData {
            path: csv.path.clone(),
        });
    }
    let c = csv.columns();
    let text = crate::recording::Summary {
        path: &csv.path,
        columns: c,
        samples: n,
        first,
        last,
        non_finite,
        has_v: c.v.is_some(),
        has_u: c.u.is_some(),
        backwards,
    }
    .render();
    Ok(text)
}
