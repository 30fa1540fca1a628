//! Probing: Ω refined by phase tracking over the whole file, from probes of rows read at
//! byte offsets (see the module docs of [`super`]).

use std::fs::File;
use std::io::{self, BufReader, Seek, SeekFrom};
use std::path::Path;

use lssi_core::derivative::Taps;
use lssi_core::factor::Factor;
use lssi_core::{Config, Library, LibraryConfig};

use super::reader::{CsvStream, reader_builder};
use super::{SPREAD_PROBES, StreamOptions, debug};
use crate::identify::{IdentifyError, Options, TERM_CAPACITY, WINDOW_CAPACITY};
use crate::recording::{ColumnNames, Recording, resolve_columns};

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
/// probes read. `excerpt_bytes` is where the excerpt ends in the file `source_file`.
pub(super) fn refine_omega(
    source_file: &Path,
    excerpt: &Recording,
    config: &Config,
    options: &Options,
    excerpt_bytes: u64,
    stream: &StreamOptions,
    reference: crate::identify::Reference,
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
    let size = std::fs::metadata(source_file).map_or(0, |m| m.len());
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
        let Some(recording) = probe(source_file, &excerpt.columns, offset, stream.probe_rows)
        else {
            return false;
        };
        // Less the excerpt's reference, as the excerpt is.
        let recording = reference.shifted(&recording).unwrap_or(recording);
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
        let w = crate::identify::golden(|w| rows.rss(w), *omega - half, *omega + half, steps);
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
