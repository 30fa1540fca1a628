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
//!    the file is held but the gate's blocks (below).
//! 5. The quality gate ([`crate::identify::quality`]) judges the whole file in the same pass
//!    and bounded memory ([`gate`]): a second identifier in the other precision takes every
//!    sample too, and blocks of [`StreamOptions::excerpt_rows`] rows are kept at a doubling
//!    stride ([`sketch`]: between [`StreamOptions::gate_blocks`] and twice that, spread
//!    evenly from the first row, and the file's last rows). The file's held-out error is
//!    judged against its target's variance on all of them, and each is checked as a
//!    recording in memory is (free run, short-horizon simulation, collinearity, a constant x,
//!    a sweep): a part of the file the model does not explain withholds it, named by its
//!    time span (exit status 3, as for a small file). The blocks' rows are bounded
//!    ((2 · gate_blocks + 2) · excerpt_rows, 10 blocks of 65,536 rows by default), whatever
//!    the file's length. What the gate does not see: a stretch between kept blocks shorter
//!    than the stride, and a break in under about half of a block (the short-horizon check
//!    takes the median of its windows); the held-out error over every row still weighs them.
//!
//! Blemishes as in memory ([`crate::identify::blemish`]): the excerpt is scanned as a small
//! file is (NaN, time gaps and spikes left out or repaired, each named); the rest goes through
//! the burst rule block by block ([`bursts`]: 4,096 rows with 64 of context each side) and the
//! spike rule on a sliding run of seven samples, both with the excerpt's thresholds (a burst or
//! a spike is repaired by the cubic through its neighbours and named), and the identifier itself leaves
//! out non-finite samples and restarts on time gaps. The configuration and the Ω probes take
//! repaired values and clean windows only; the gate's blocks are the rows as read (the gate
//! finds their blemishes itself, as in memory).
//!
//! Standard input (`lssi identify -` or `/dev/stdin` on a pipe) is spooled to a temporary
//! file in 64 KiB chunks ([`spool`]) and then read as a file is, named as the user named it.
//!
//! A file that turns out to end within the excerpt is identified by
//! [`crate::identify::identify_recording`] itself, so the result is the in-memory one.
//! Not streamed: `--track` and `--refine` (they need the whole signal) and batches. A streamed
//! file is not refined on simulation error (the default for one file in memory): the output says
//! so (a warning naming the file), and `--refine` reads it whole.

mod bursts;
mod gate;
mod probe;
mod reader;
mod run;
mod sketch;
mod spool;

use std::path::Path;

use crate::identify::{self, IdentifyError, Options, Report, configure};
use crate::recording::{ColumnNames, RecordingError};

use probe::refine_omega;
pub use reader::{CsvStream, describe_file};
use run::run;
pub use spool::{Input, is_stdin};

/// Probes spread evenly over a large file for the last refinement of Ω (one fewer: the
/// end of the file is the doubling chain's last probe).
pub const SPREAD_PROBES: usize = 16;

/// Files larger than this (bytes) and of more than [`STREAM_ROWS`] rows are streamed by `lssi
/// identify` and `lssi info`; smaller ones are read whole (and refined), as before.
pub const STREAM_BYTES: u64 = 8 << 20;

/// Rows (estimated from the file's first MiB) up to which a file over [`STREAM_BYTES`] is still
/// read whole, so that it is refined on simulation error with ± as a short file is: what a
/// file costs is its rows, not its bytes, and a 300,000-row file with x, v, u and long numbers
/// (13 MB) was streamed, its streaming model printed without refinement or ± (hostile seed
/// 20635: a spurious x² and x·v² beside a double well 2.05 off centre, where refinement gives
/// the truth within 0.3 %). An x-only file at 8 MiB has about 400,000 rows.
pub const STREAM_ROWS: u64 = 400_000;

/// Above this (bytes) a file is streamed whatever its rows (the memory of reading it whole).
pub const STREAM_BYTES_ALWAYS: u64 = 128 << 20;

/// The rows of the file at `path` estimated from its first MiB (its length over the mean
/// length of those lines); `None` when it cannot be read.
fn estimated_rows(path: &Path, len: u64) -> Option<u64> {
    use std::io::Read;
    let mut head = Vec::with_capacity(1 << 20);
    std::fs::File::open(path)
        .ok()?
        .take(1 << 20)
        .read_to_end(&mut head)
        .ok()?;
    let lines = head.iter().filter(|&&b| b == b'\n').count().max(1) as u64;
    Some(len * lines / head.len().max(1) as u64)
}

/// How a large recording is streamed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamOptions {
    /// Rows read first and kept: the configuration (sample period, window, Ω) comes from them.
    pub excerpt_rows: usize,
    /// Rows of each probe that refines Ω over the whole file.
    pub probe_rows: usize,
    /// Blocks of `excerpt_rows` rows the quality gate keeps (at least this many, at most
    /// twice, and the file's last rows): see [`sketch`].
    pub gate_blocks: usize,
}

impl Default for StreamOptions {
    fn default() -> Self {
        Self {
            excerpt_rows: 1 << 16,
            probe_rows: 1 << 13,
            gate_blocks: 4,
        }
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
    /// The quality gate ([`crate::identify::quality`]) over the whole file ([`gate`]: the
    /// held-out error over every row, the other precision's model over every row, and the
    /// checks on the signal on blocks spread over the file); a failure withholds the file's
    /// model.
    pub quality: crate::identify::quality::Quality,
    /// Rows the gate's signal checks saw (all of the blocks).
    pub gated_rows: usize,
    /// Blocks the gate checked (1 when the file was not streamed).
    pub gated_blocks: usize,
}

/// Identifies the recording at `path` without holding it: see the module docs. `progress` is
/// called now and then with the bytes read so far and the file's size.
pub fn identify_file(
    path: impl AsRef<Path>,
    columns: &ColumnNames,
    options: &Options,
    stream: &StreamOptions,
    progress: impl FnMut(u64, u64),
) -> Result<(Report, StreamSummary), StreamError> {
    let path = path.as_ref();
    identify_file_named(path, path, columns, options, stream, progress)
}

/// [`identify_file`] on the file at `file`, named `name` in messages and in the report (a
/// spooled standard input is read from a temporary file and named `-`).
pub fn identify_file_named(
    file: &Path,
    name: &Path,
    columns: &ColumnNames,
    options: &Options,
    stream: &StreamOptions,
    mut progress: impl FnMut(u64, u64),
) -> Result<(Report, StreamSummary), StreamError> {
    let mut csv = CsvStream::open_named(file, name, columns)?;
    let excerpt = csv.read_rows(stream.excerpt_rows.max(1))?;
    if excerpt.is_empty() {
        return Err(RecordingError::NoData {
            path: name.to_owned(),
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
            gated_blocks: 1,
        };
        return Ok((report, summary));
    }
    let clock = std::time::Instant::now();
    // A large offset removed (in f64) for the configuration and Ω, as in memory; the run
    // subtracts the same reference from every sample.
    let reference = identify::Reference::of(&excerpt);
    let shifted = reference.shifted(&excerpt);
    let (mut config, estimated) = configure(shifted.as_ref().unwrap_or(&excerpt), options)?;
    debug(&format!("configure {:?}", clock.elapsed()));
    let mut summary = StreamSummary {
        streamed: true,
        excerpt_omega: None,
        probes: 0,
        gated_rows: 0,
        gated_blocks: 0,
        quality: crate::identify::quality::Quality {
            unexplained: None,
            stable: None,
            precisions_agree: None,
            failures: Vec::new(),
            simulation_failures: 0,
        },
    };
    if estimated {
        summary.excerpt_omega = Some(config.omega);
        let (omega, probes) = refine_omega(
            file,
            shifted.as_ref().unwrap_or(&excerpt),
            &config,
            options,
            csv.bytes_read(),
            stream,
            reference,
        )?;
        config.omega = omega;
        summary.probes = probes;
        debug(&format!(
            "refine {:?} omega {omega} probes {probes}",
            clock.elapsed()
        ));
    }
    drop(shifted);
    let pass = run(
        csv,
        excerpt,
        config,
        estimated,
        options.f32,
        stream.gate_blocks,
        &mut progress,
    )?;
    debug(&format!("run {:?}", clock.elapsed()));
    summary.quality = gate::judge(
        &pass.blocks,
        &config,
        &pass.report,
        pass.other.as_ref(),
        reference,
    );
    summary.gated_rows = pass.blocks.iter().map(|b| b.rows.len()).sum();
    summary.gated_blocks = pass.blocks.len();
    debug(&format!(
        "gate {:?}: {} blocks, {} rows",
        clock.elapsed(),
        summary.gated_blocks,
        summary.gated_rows
    ));
    let mut report = pass.report;
    reference.restore(&mut report);
    Ok((report, summary))
}

fn debug(text: &str) {
    if std::env::var_os("LSSI_STREAM_DEBUG").is_some() {
        eprintln!("lssi: stream: {text}");
    }
}

/// Whether `lssi identify` and `lssi info` stream the file at `path`: it is larger than
/// [`STREAM_BYTES`] and has more than [`STREAM_ROWS`] rows, or is larger than
/// [`STREAM_BYTES_ALWAYS`].
pub fn is_large(path: &Path) -> bool {
    let Some(len) = std::fs::metadata(path)
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len())
    else {
        return false;
    };
    len > STREAM_BYTES_ALWAYS
        || (len > STREAM_BYTES && estimated_rows(path, len).is_none_or(|r| r > STREAM_ROWS))
}

/// `lssi identify FILE` for a large file: as [`crate::commands::identify::run`] prints, with a
/// progress bar on stderr when it is a terminal. `path` is the file read, `name` what the
/// messages call it (the same, or `-` for a spooled standard input).
pub fn identify_command(
    path: &Path,
    name: &Path,
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
    let result = identify_file_named(
        path,
        name,
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
    // Read in chunks, the recording is not held: the quality gate judged the whole file in
    // the same pass (see `gate`).
    let mut warnings = identify::batch::warnings(&report);
    if !summary.quality.passed() {
        warnings.extend(summary.quality.failures.iter().cloned());
        let sentence = format!(
            "no deterministic dynamics found in {} (read in chunks: the gate judged the whole file's fit and {} stretches of {} rows spread over it): {}.",
            name.display(),
            summary.gated_blocks,
            summary.gated_rows / summary.gated_blocks.max(1),
            summary.quality.failures.join("; ")
        );
        if json {
            // As for a file in memory: no "terms" at the top, the model under
            // "withheld_model" beside why.
            crate::outln!(
                "{{\"withheld\":true,\"reason\":{},\"withheld_model\":{},\"warnings\":{}}}",
                serde_json::Value::from(sentence.as_str()),
                identify::json_text(&report, None, &[]),
                serde_json::Value::from(warnings)
            );
        }
        return Err(crate::error::CliError::NoDynamics(sentence));
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
