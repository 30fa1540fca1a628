//! Large recordings: read in chunks, configured from an excerpt, identified in one pass.
//!
//! [`crate::recording::Recording::read`] holds a whole file (its text and its columns) and
//! [`crate::identify::configure`] estimates Ω on all of it: fine for the shipped recordings,
//! not for 10⁷ rows. Above [`STREAM_BYTES`] `lssi identify` and `lssi info` come here instead:
//!
//! 1. [`CsvStream`] reads the file with the `csv` crate's reader in 64 KiB chunks, one sample
//!    at a time, with the errors (and line numbers) of [`crate::recording::parse_csv`].
//! 2. The first [`StreamOptions::excerpt_rows`] rows are kept as a [`Recording`] and
//!    [`crate::identify::configure`] decides on it, as it would on a small file: the sample
//!    period, the derivative window and test function, and Ω.
//! 3. Ω, when it is estimated, is refined on probes of [`StreamOptions::probe_rows`] rows read
//!    at byte offsets 2, 4, 8, … times the excerpt's and at the end of the file (phase
//!    tracking): each step doubles the span of the fit of the polynomial library plus
//!    sin/cos(Ωt), and looks for the best Ω within a quarter of the ambiguity 2π/span of the
//!    last one. Then [`SPREAD_PROBES`] − 1 more probes spread evenly over the file, and a last
//!    search on all of them. Ω must be close: the damping term takes up what a phase drift of
//!    the forcing leaves (10⁻⁵ rad/s on 100 s moves it by 2 %); on 10⁷ rows the error is
//!    ~10⁻⁸ rad/s where the excerpt alone leaves ~10⁻⁴.
//! 4. The identifier takes the excerpt, then the rest of the file chunk by chunk; nothing of
//!    the file is held but the excerpt.
//!
//! Blemishes as in memory ([`crate::identify::blemish`]): the excerpt is scanned as a small
//! file is (NaN, time gaps and spikes left out or repaired, each named); the rest goes through
//! the spike rule on a sliding run of seven samples with the excerpt's thresholds (a spike is
//! repaired by the cubic through its neighbours and named), and the identifier itself leaves
//! out non-finite samples and restarts on time gaps. The configuration and the Ω probes take
//! repaired values and clean windows only. The quality gate ([`crate::identify::quality`])
//! runs on the excerpt (its own model, configured as the file's; the whole file is not held):
//! a failure withholds the file's model, exit status 3, as for a small file.
//!
//! A file that turns out to end within the excerpt is identified by
//! [`crate::identify::identify_recording`] itself, so the result is the in-memory one.
//! Not streamed: `--track` and `--refine` (they need the whole signal) and batches. A streamed
//! file is not refined on simulation error (the default for one file in memory): the output says
//! so (a warning naming the file), and `--refine` reads it whole.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use lssi_core::derivative::Taps;
use lssi_core::factor::Factor;
use lssi_core::{Config, Identifier, Library, LibraryConfig, Real};

use crate::identify::blemish::Feed;
use crate::identify::{
    self, IdentifyError, Options, Report, TERM_CAPACITY, WINDOW_CAPACITY, configure,
};
use crate::recording::{
    ColumnNames, MAX_LINE, Positions, Recording, RecordingError, Sample, resolve_columns,
};

/// Probes spread evenly over a large file for the last refinement of Ω (one fewer: the
/// end of the file is the doubling chain's last probe).
pub const SPREAD_PROBES: usize = 16;

/// Files larger than this (bytes) are streamed by `lssi identify` and `lssi info`; smaller
/// ones are read whole, as before.
pub const STREAM_BYTES: u64 = 8 << 20;

/// How a large recording is streamed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamOptions {
    /// Rows read first and kept: the configuration (sample period, window, Ω) comes from them.
    pub excerpt_rows: usize,
    /// Rows of each probe that refines Ω over the whole file.
    pub probe_rows: usize,
}

impl Default for StreamOptions {
    fn default() -> Self {
        Self {
            excerpt_rows: 1 << 16,
            probe_rows: 1 << 13,
        }
    }
}

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
    path: PathBuf,
    csv: csv::Reader<LineLimit<BufReader<File>>>,
    header: Vec<String>,
    positions: Positions,
    columns: ColumnNames,
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

fn reader_builder() -> csv::ReaderBuilder {
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
        let path = path.as_ref().to_owned();
        let io_error = |source| RecordingError::Io {
            path: path.clone(),
            source,
        };
        let file = File::open(&path).map_err(io_error)?;
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
            Err(error) => return Err(stream_error(&path, &csv, error, None)),
        };
        if header.iter().all(String::is_empty) {
            return Err(RecordingError::Empty { path });
        }
        let header_line = line_at_file(&path, 0);
        let positions = resolve_columns(&path, &header, header_line, columns)?;
        let columns = ColumnNames {
            t: header[positions.t].clone(),
            x: header[positions.x].clone(),
            v: positions.v.map(|i| header[i].clone()),
            u: positions.u.map(|i| header[i].clone()),
        };
        Ok(Self {
            path,
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
                    line: line_at_file(&self.path, start),
                    path: self.path.clone(),
                    fields: record.len(),
                    header: self.header.clone(),
                });
            }
            let number = |index: usize| number(&self.path, &self.header, record, start, index);
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
    path: &Path,
    header: &[String],
    record: &csv::StringRecord,
    start: u64,
    index: usize,
) -> Result<f64, RecordingError> {
    let text = record.get(index).unwrap_or_default();
    if text.is_empty() {
        return Err(RecordingError::EmptyField {
            path: path.to_owned(),
            line: line_at_file(path, start),
            column: header.get(index).cloned().unwrap_or_default(),
        });
    }
    text.parse::<f64>().map_err(|_| RecordingError::NotANumber {
        path: path.to_owned(),
        line: line_at_file(path, start),
        column: header.get(index).cloned().unwrap_or_default(),
        text: text.to_owned(),
    })
}

fn stream_error(
    path: &Path,
    csv: &csv::Reader<LineLimit<BufReader<File>>>,
    error: csv::Error,
    header: Option<&[String]>,
) -> RecordingError {
    let path = path.to_owned();
    if csv.get_ref().too_long {
        let line = csv.get_ref().line;
        return RecordingError::LineTooLong { path, line };
    }
    let line = line_at_file(&path, error.position().map_or(0, csv::Position::byte));
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

/// Why a large recording could not be identified.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// The file cannot be read as a recording.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The recording cannot be identified.
    #[error(transparent)]
    Identify(#[from] IdentifyError),
}

/// The most rejected samples named one by one in [`Report::rejections`] (the count is
/// [`Report::rejected`]).
pub const NAMED_REJECTIONS: usize = 100;

/// What [`identify_file`] did besides the report.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamSummary {
    /// Whether the file was streamed (false: it ended within the excerpt and was identified
    /// in memory).
    pub streamed: bool,
    /// Ω from the excerpt alone, when it was estimated.
    pub excerpt_omega: Option<f64>,
    /// Probes read to refine Ω.
    pub probes: usize,
    /// The quality gate ([`crate::identify::quality`]) on the excerpt (the whole file when it
    /// was not streamed): the whole file is not held, so the gate's checks (which run the
    /// identifier again in the other precision and simulate the model) are made on the
    /// excerpt's own model, configured as the file's; a failure withholds the file's model.
    pub quality: crate::identify::quality::Quality,
    /// Rows the gate saw.
    pub gated_rows: usize,
}

/// Identifies the recording at `path` without holding it: see the module docs. `progress` is
/// called now and then with the bytes read so far and the file's size.
pub fn identify_file(
    path: impl AsRef<Path>,
    columns: &ColumnNames,
    options: &Options,
    stream: &StreamOptions,
    mut progress: impl FnMut(u64, u64),
) -> Result<(Report, StreamSummary), StreamError> {
    let path = path.as_ref();
    let mut csv = CsvStream::open(path, columns)?;
    let excerpt = csv.read_rows(stream.excerpt_rows.max(1))?;
    if excerpt.is_empty() {
        return Err(RecordingError::NoData {
            path: path.to_owned(),
        }
        .into());
    }
    if excerpt.len() < stream.excerpt_rows {
        let (report, quality) = identify::quality::identify_checked(&excerpt, options)?;
        let summary = StreamSummary {
            streamed: false,
            excerpt_omega: None,
            probes: 0,
            quality,
            gated_rows: excerpt.len(),
        };
        return Ok((report, summary));
    }
    let (_, quality) = identify::quality::identify_checked(&excerpt, options)?;
    let clock = std::time::Instant::now();
    let (mut config, estimated) = configure(&excerpt, options)?;
    debug(&format!("configure {:?}", clock.elapsed()));
    let mut summary = StreamSummary {
        streamed: true,
        excerpt_omega: None,
        probes: 0,
        gated_rows: excerpt.len(),
        quality,
    };
    if estimated {
        summary.excerpt_omega = Some(config.omega);
        let (omega, probes) = refine_omega(&excerpt, &config, options, csv.bytes_read(), stream)?;
        config.omega = omega;
        summary.probes = probes;
        debug(&format!(
            "refine {:?} omega {omega} probes {probes}",
            clock.elapsed()
        ));
    }
    let report = if options.f32 {
        run::<f32>(csv, excerpt, config, estimated, &mut progress)
    } else {
        run::<f64>(csv, excerpt, config, estimated, &mut progress)
    }?;
    Ok((report, summary))
}

fn debug(text: &str) {
    if std::env::var_os("LSSI_STREAM_DEBUG").is_some() {
        eprintln!("lssi: stream: {text}");
    }
}

/// The identifier over the excerpt, then over the rest of the stream.
fn run<T: Real>(
    mut csv: CsvStream,
    excerpt: Recording,
    config: Config,
    omega_estimated: bool,
    progress: &mut impl FnMut(u64, u64),
) -> Result<Report, StreamError> {
    let file = excerpt.path.display().to_string();
    let mut identifier: Identifier<T, WINDOW_CAPACITY, TERM_CAPACITY> =
        Identifier::new(config).map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    let mut rejections = Vec::new();
    let mut push = |i: usize, s: Sample| {
        let sample = lssi_core::Sample {
            t: s.t,
            x: T::from_f64(s.x),
            v: s.v.map(T::from_f64),
            u: s.u.map(T::from_f64),
        };
        if let Err(why) = identifier.push(sample)
            && rejections.len() < NAMED_REJECTIONS
        {
            rejections.push(format!(
                "{file}: data row {} (t = {}): {why}; it was left out",
                i + 1,
                s.t
            ));
        }
    };
    // The excerpt as in memory: its blemishes found by the scan, spikes repaired, the other
    // blemished samples left out (each named).
    let scan = crate::identify::blemish::Scan::of(&excerpt);
    let mut blemished = scan.skipped() as u64;
    let mut notes: Vec<String> = scan
        .blemishes
        .iter()
        .take(NAMED_REJECTIONS)
        .map(|b| format!("{file}: {}", b.sentence()))
        .collect();
    for (i, s) in excerpt.samples().enumerate() {
        match scan.feed(i) {
            Feed::Skip => {}
            Feed::AsIs => push(i, s),
            Feed::Repaired(r) => push(
                i,
                Sample {
                    x: r.x,
                    v: r.v,
                    u: r.u,
                    ..s
                },
            ),
        }
    }
    // The rest: the spike rule with the excerpt's thresholds, on a sliding run of seven
    // samples (a spike's residual against its neighbours'); a spike is repaired as in memory.
    // (Non-finite values and time gaps the identifier itself leaves out and restarts on.)
    let mut channels = vec![excerpt.x.clone()];
    channels.extend(excerpt.v.clone());
    channels.extend(excerpt.u.clone());
    let limits: Vec<Option<(f64, f64)>> = channels
        .iter()
        .map(|c| crate::identify::blemish::spike_limit(c, &scan))
        .collect();
    drop(channels);
    let mut spikes = SpikeRepair::new(limits, scan.dt);
    let mut i = excerpt.len();
    drop(excerpt);
    while let Some(s) = csv.next_sample()? {
        if let Some((j, out, spike)) = spikes.push(i, s) {
            if let Some(value) = spike {
                blemished += 1;
                if notes.len() < NAMED_REJECTIONS {
                    notes.push(format!(
                        "{file}: data row {} (t = {}): an isolated spike ({value:e}); it was replaced by the cubic through its four neighbours",
                        j + 1,
                        out.t
                    ));
                }
            }
            push(j, out);
        }
        i += 1;
        if i.is_multiple_of(1 << 16) {
            progress(csv.bytes_read(), csv.size());
        }
    }
    for (j, out) in spikes.finish() {
        push(j, out);
    }
    progress(csv.size(), csv.size());
    identifier.screen();
    let counters = *identifier.counters();
    let model = identifier.model().ok_or_else(|| {
        IdentifyError(format!(
            "{file}: no model: {} samples were accepted and {} rejected, too few regression rows for the {}-term library.",
            counters.accepted,
            counters.rejected(),
            identifier.library().len()
        ))
    })?;
    let mut report = identify::report(
        model,
        &config,
        omega_estimated,
        counters.rejected() + blemished,
        std::any::type_name::<T>(),
    );
    notes.extend(rejections);
    report.rejections = notes;
    Ok(report)
}

/// The spike rule on a stream: samples go through a run of seven; the middle one is a spike
/// when its cubic residual r (against its four neighbours) is beyond the channel's limit and
/// [`crate::identify::blemish::SPIKE_DOMINANCE`] times its neighbours' r, all seven finite and
/// evenly spaced. A spike is replaced by the cubic's value.
struct SpikeRepair {
    limits: Vec<Option<(f64, f64)>>,
    dt: f64,
    run: std::collections::VecDeque<(usize, Sample)>,
    /// Repaired spikes still in the run: (index, measured value).
    judged: Vec<(usize, f64)>,
}

impl SpikeRepair {
    fn new(limits: Vec<Option<(f64, f64)>>, dt: f64) -> Self {
        Self {
            limits,
            dt,
            run: std::collections::VecDeque::with_capacity(8),
            judged: Vec::new(),
        }
    }

    fn channel(s: &Sample, c: usize) -> Option<f64> {
        match c {
            0 => Some(s.x),
            1 => s.v.or(s.u),
            _ => s.u,
        }
    }

    fn set(s: &mut Sample, c: usize, value: f64) {
        match c {
            0 => s.x = value,
            1 if s.v.is_some() => s.v = Some(value),
            _ => s.u = Some(value),
        }
    }

    /// Takes sample `i`; gives back the sample leaving the run (its index, the sample,
    /// and the spike's measured value when it was repaired).
    fn push(&mut self, i: usize, s: Sample) -> Option<(usize, Sample, Option<f64>)> {
        self.run.push_back((i, s));
        let mut spike = None;
        if self.run.len() == 7 && self.dt > 0.0 {
            let even = self.run.iter().zip(self.run.iter().skip(1)).all(|(a, b)| {
                let step = b.1.t - a.1.t;
                step > 0.5 * self.dt && step < 1.5 * self.dt
            });
            if even {
                for c in 0..self.limits.len() {
                    let Some((centre, limit)) = self.limits[c] else {
                        continue;
                    };
                    let v: Vec<f64> = self
                        .run
                        .iter()
                        .map(|(_, s)| Self::channel(s, c).unwrap_or(f64::NAN))
                        .collect();
                    let cubic = |k: usize| {
                        -(v[k - 2] / 6.0) + v[k - 1] / 1.5 + v[k + 1] / 1.5 - v[k + 2] / 6.0
                    };
                    let size = |k: usize| {
                        let r = v[k] - cubic(k) - centre;
                        if r.is_finite() {
                            r.abs()
                        } else {
                            f64::INFINITY
                        }
                    };
                    let around = v.iter().all(|x| x.is_finite());
                    if !around {
                        continue;
                    }
                    let here = size(3);
                    let neighbours = size(2).max(size(4));
                    if here > limit
                        && here >= crate::identify::blemish::SPIKE_DOMINANCE * neighbours
                    {
                        let value = cubic(3);
                        if value.is_finite() {
                            spike = Some(v[3]);
                            Self::set(&mut self.run[3].1, c, value);
                        }
                    }
                }
            }
        }
        // The middle one was just judged; it leaves the run three samples later.
        if let Some(value) = spike {
            self.judged.push((self.run[3].0, value));
        }
        if self.run.len() < 7 {
            return None;
        }
        let (j, out) = self.run.pop_front()?;
        let verdict = self
            .judged
            .iter()
            .position(|(k, _)| *k == j)
            .map(|p| self.judged.remove(p).1);
        Some((j, out, verdict))
    }

    /// The samples still in the run, in order.
    fn finish(&mut self) -> Vec<(usize, Sample)> {
        self.run.drain(..).collect()
    }
}

/// Rows of the Ω fit: (time, polynomial library row, x''), every 4th sample, from a
/// derivative window over x (or v when it is measured), as `identify::estimate_omega` makes
/// them.
struct Rows {
    taps: Taps<f64, WINDOW_CAPACITY>,
    library: Library<TERM_CAPACITY>,
    rows: Vec<(f64, [f64; TERM_CAPACITY], f64)>,
}

impl Rows {
    fn add(&mut self, recording: &Recording, every: usize) {
        let n = self.taps.len();
        // As `identify::estimate_omega`: windows within clean stretches only, a repaired
        // spike with its repaired value (a spike of 1e300 in a probe took Ω off by 4e-4).
        let scan = crate::identify::blemish::Scan::of(recording);
        let clean = crate::identify::blemish::CleanWindows::new(&scan.with_repairs_kept(), n);
        let x = scan.repaired(recording, 0).unwrap_or_default();
        let v_repaired = scan
            .repaired(recording, 1)
            .filter(|_| recording.v.is_some());
        let mut start = 0;
        let mut count = 0usize;
        while start + n <= x.len() {
            if !clean.ok(start) {
                start += 4;
                continue;
            }
            let w = &x[start..start + n];
            let (xh, vh, yh) = match &v_repaired {
                Some(v) => {
                    let vw = &v[start..start + n];
                    (
                        self.taps.apply(0, w, &[]),
                        self.taps.apply(0, vw, &[]),
                        self.taps.apply(1, vw, &[]),
                    )
                }
                None => (
                    self.taps.apply(0, w, &[]),
                    self.taps.apply(1, w, &[]),
                    self.taps.apply(2, w, &[]),
                ),
            };
            let t = recording.t[start + (n - 1) / 2];
            if xh.is_finite() && vh.is_finite() && yh.is_finite() && t.is_finite() {
                if count.is_multiple_of(every) {
                    let mut row = [0.0; TERM_CAPACITY];
                    self.library.evaluate(xh, vh, 0.0, 0.0, &mut row);
                    self.rows.push((t, row, yh));
                }
                count += 1;
            }
            start += 4;
        }
    }

    /// Residual energy of the polynomial library plus sin/cos(ωt).
    fn rss(&self, w: f64) -> f64 {
        let p = self.library.len();
        let mut f: Factor<f64, TERM_CAPACITY> = Factor::new(p + 2);
        for (t, row, y) in &self.rows {
            let mut r = *row;
            r[p] = (w * t).sin();
            r[p + 1] = (w * t).cos();
            f.update(&r, *y, 1.0);
        }
        f.residual_energy()
    }
}

/// Reads `rows` samples starting at the first whole line after byte `offset`.
fn probe(path: &Path, columns: &ColumnNames, offset: u64, rows: usize) -> Option<Recording> {
    let header = CsvStream::open(path, columns).ok()?;
    let positions = resolve_columns(path, &header.header, 1, columns).ok()?;
    let mut file = File::open(path).ok()?;
    file.seek(SeekFrom::Start(offset)).ok()?;
    let mut reader = BufReader::with_capacity(1 << 16, file);
    // Skip the rest of the line the offset falls in.
    let mut skipped = Vec::new();
    io::BufRead::read_until(&mut reader, b'\n', &mut skipped).ok()?;
    let mut csv = reader_builder().has_headers(false).from_reader(reader);
    let mut recording = Recording {
        path: path.to_owned(),
        t: Vec::with_capacity(rows),
        x: Vec::with_capacity(rows),
        v: positions.v.map(|_| Vec::with_capacity(rows)),
        u: positions.u.map(|_| Vec::with_capacity(rows)),
        columns: header.columns.clone(),
    };
    let mut record = csv::StringRecord::new();
    let field = |record: &csv::StringRecord, i: usize| record.get(i)?.parse::<f64>().ok();
    while recording.t.len() < rows {
        if !csv.read_record(&mut record).ok()? {
            break;
        }
        if record.len() != header.header.len() {
            continue;
        }
        let (Some(t), Some(x)) = (field(&record, positions.t), field(&record, positions.x)) else {
            continue;
        };
        let v = positions.v.map(|i| field(&record, i));
        let u = positions.u.map(|i| field(&record, i));
        if v.is_some_and(|v| v.is_none()) || u.is_some_and(|u| u.is_none()) {
            continue;
        }
        recording.t.push(t);
        recording.x.push(x);
        if let (Some(values), Some(Some(v))) = (recording.v.as_mut(), v) {
            values.push(v);
        }
        if let (Some(values), Some(Some(u))) = (recording.u.as_mut(), u) {
            values.push(u);
        }
    }
    Some(recording)
}

/// Ω refined by phase tracking over the whole file (see the module docs); the number of
/// probes read. `excerpt_bytes` is where the excerpt ends in the file.
fn refine_omega(
    excerpt: &Recording,
    config: &Config,
    options: &Options,
    excerpt_bytes: u64,
    stream: &StreamOptions,
) -> Result<(f64, usize), IdentifyError> {
    let file = excerpt.path.display();
    let omega0 = config.omega;
    // The window `configure` estimated Ω with (rows as they are; the weak form's short window
    // is chosen after).
    let dt = config.sample_period;
    // The clean samples, a repaired spike with its repaired value (as `configure` takes them).
    let scan = crate::identify::blemish::Scan::of(excerpt);
    let kept = scan.with_repairs_kept();
    let channel = usize::from(excerpt.v.is_some());
    let values = scan
        .repaired(excerpt, channel)
        .unwrap_or_else(|| excerpt.x.clone());
    let source: Vec<f64> = values
        .iter()
        .zip(&kept.skip)
        .filter(|(s, skip)| s.is_finite() && !**skip)
        .map(|(s, _)| *s)
        .collect();
    let order = 2 - channel;
    drop(values);
    let memory_samples = options
        .memory
        .map_or(source.len(), |m| ((m / dt) as usize).min(source.len()));
    let Some(choice) = lssi_core::tuning::choose_window::<f64, WINDOW_CAPACITY>(
        &source,
        order,
        dt,
        memory_samples,
    ) else {
        return Ok((omega0, 0));
    };
    drop(source);
    debug(&format!("refine: window {} chosen", choice.window));
    let clock = std::time::Instant::now();
    let taps = Taps::design(choice.window, usize::from(choice.degree), dt)
        .map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    let library = Library::new(&LibraryConfig {
        harmonics: 0,
        input: false,
        ..config.library
    })
    .map_err(|e| IdentifyError(format!("{file}: {e}.")))?;
    let mut rows = Rows {
        taps,
        library,
        rows: Vec::new(),
    };
    rows.add(excerpt, 4);
    let Some(&t0) = excerpt.t.iter().find(|t| t.is_finite()) else {
        return Ok((omega0, 0));
    };
    let size = std::fs::metadata(&excerpt.path).map_or(0, |m| m.len());
    let row_bytes = excerpt_bytes as f64 / excerpt.len() as f64;
    let probe_bytes = (row_bytes * stream.probe_rows as f64 * 1.1) as u64;
    if excerpt_bytes == 0 || size <= excerpt_bytes + probe_bytes {
        return Ok((omega0, 0));
    }
    // The doubling chain makes Ω unambiguous over the whole file; then probes spread evenly
    // over it weigh the far end as the in-memory estimate's every row does.
    let mut chain = Vec::new();
    let mut offset = 2 * excerpt_bytes;
    let last = size - probe_bytes;
    while offset < last {
        chain.push(offset);
        offset *= 2;
    }
    chain.push(last);
    let spread = (1..SPREAD_PROBES as u64)
        .map(|k| excerpt_bytes + (last - excerpt_bytes) * k / SPREAD_PROBES as u64);
    let mut omega = omega0;
    let mut probes = 0;
    let mut t_end = t0;
    let add = |offset: u64, rows: &mut Rows, t_end: &mut f64| -> bool {
        let Some(recording) = probe(&excerpt.path, &excerpt.columns, offset, stream.probe_rows)
        else {
            return false;
        };
        let Some(&end) = recording.t.iter().rev().find(|t| t.is_finite()) else {
            return false;
        };
        if !(end > *t_end) || recording.len() < rows.taps.len() + 16 {
            return false;
        }
        rows.add(&recording, 1);
        *t_end = t_end.max(end);
        true
    };
    let search = |rows: &Rows, omega: &mut f64, t_end: f64, steps: usize| {
        // The fit cannot tell ω from ω ± 2π/span; the last estimate is far closer than that.
        let half = 0.25 * std::f64::consts::TAU / (t_end - t0);
        let w = super::golden(|w| rows.rss(w), *omega - half, *omega + half, steps);
        if rows.rss(w) <= rows.rss(*omega) {
            *omega = w;
        }
    };
    for offset in chain {
        if !add(offset, &mut rows, &mut t_end) {
            return Ok((omega, probes));
        }
        probes += 1;
        // 12 steps leave 0.3 % of the interval, well inside the next one (half as wide).
        search(&rows, &mut omega, t_end, 12);
        debug(&format!(
            "probe {probes}: {:?} rows {} omega {omega}",
            clock.elapsed(),
            rows.rows.len()
        ));
    }
    let mut spread_end = t0;
    for offset in spread {
        if add(offset, &mut rows, &mut spread_end) {
            probes += 1;
        }
    }
    // 32 steps leave 2·10⁻⁷ of the interval (10⁻⁸ rad/s on 100 s): the damping term takes up
    // what a phase drift of Ω leaves, so Ω must be closer than the fit alone needs.
    search(&rows, &mut omega, t_end, 32);
    debug(&format!(
        "spread: {:?} rows {} omega {omega}",
        clock.elapsed(),
        rows.rows.len()
    ));
    Ok((omega, probes))
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

/// Whether `lssi identify` and `lssi info` stream the file at `path` (it is larger than
/// [`STREAM_BYTES`]).
pub fn is_large(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() > STREAM_BYTES)
}

/// `lssi identify FILE` for a large file: as [`crate::commands::identify::run`] prints, with a
/// progress bar on stderr when it is a terminal.
pub fn identify_command(
    path: &Path,
    columns: &ColumnNames,
    options: &Options,
    json: bool,
    note: Option<&str>,
) -> Result<(), crate::error::CliError> {
    use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
    use std::io::IsTerminal;
    let size = std::fs::metadata(path).map_or(0, |m| m.len());
    let bar = if std::io::stderr().is_terminal() {
        let bar = ProgressBar::with_draw_target(Some(size), ProgressDrawTarget::stderr());
        if let Ok(style) =
            ProgressStyle::with_template("{bar:30} {bytes}/{total_bytes} {elapsed} (eta {eta})")
        {
            bar.set_style(style);
        }
        bar
    } else {
        ProgressBar::hidden()
    };
    let result = identify_file(
        path,
        columns,
        options,
        &StreamOptions::default(),
        |read, _| bar.set_position(read),
    );
    bar.finish_and_clear();
    let (report, summary) = result.map_err(|e| match e {
        StreamError::Recording(e) => crate::error::CliError::from(e),
        StreamError::Identify(e) => crate::error::CliError::from(e),
    })?;
    const NAMED: usize = 5;
    for warning in report.rejections.iter().take(NAMED) {
        eprintln!("lssi: warning: {warning}.");
    }
    let rejected = usize::try_from(report.rejected).unwrap_or(usize::MAX);
    if rejected > NAMED {
        eprintln!(
            "lssi: warning: {} more samples were left out ({} in all).",
            rejected - NAMED,
            rejected
        );
    }
    // Read in chunks, the recording is not held: the quality gate ran on the excerpt.
    let mut warnings = identify::batch::warnings(&report);
    if !summary.quality.passed() {
        warnings.extend(summary.quality.failures.iter().cloned());
        if json {
            crate::outln!("{}", identify::json_text(&report, None, &warnings));
        }
        return Err(crate::error::CliError::NoDynamics(format!(
            "no deterministic dynamics found in {} (its first {} rows, on which the quality gate of a file read in chunks runs): {}.",
            path.display(),
            summary.gated_rows,
            summary.quality.failures.join("; ")
        )));
    }
    if let Some(note) = note {
        eprintln!("lssi: warning: {note}.");
    }
    if json {
        warnings.extend(note.map(str::to_owned));
        crate::outln!("{}", identify::json_text(&report, None, &warnings));
    } else {
        crate::out!("{}", identify::render_reported(&report, None, note, "[x]"));
    }
    Ok(())
}
