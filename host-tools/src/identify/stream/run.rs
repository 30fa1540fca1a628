//! Running: the identifier over the excerpt, then over the rest of the stream chunk by
//! chunk, searched for bursts block by block ([`super::bursts`]) and then for spikes on a
//! sliding run of seven samples.

use lssi_core::{Config, Identifier, Real};

use super::bursts::{BurstRepair, MARGIN};
use super::sketch::{Block, Sketch};
use super::{CsvStream, NAMED_REJECTIONS, StreamError};
use crate::identify::blemish::Feed;
use crate::identify::{self, IdentifyError, Report, TERM_CAPACITY, WINDOW_CAPACITY};
use crate::recording::{Recording, Sample};

/// What one pass over the file gives: the model in the precision asked for and in the other
/// one (both before the reference is put back: see [`identify::Reference::restore`]), and
/// the blocks the gate judges.
pub(super) struct Pass {
    pub(super) report: Report,
    pub(super) other: Option<Report>,
    pub(super) blocks: Vec<Block>,
}

type Id<T> = Identifier<T, WINDOW_CAPACITY, TERM_CAPACITY>;

/// One precision's identifier fed a sample less the reference.
fn feed<T: Real>(
    identifier: &mut Id<T>,
    s: &Sample,
    reference: identify::Reference,
) -> Result<bool, lssi_core::Rejection> {
    identifier.push(lssi_core::Sample {
        t: s.t,
        x: T::from_f64(s.x - reference.x),
        v: s.v.map(|v| T::from_f64(v - reference.v)),
        u: s.u.map(T::from_f64),
    })
}

/// The model of one identifier, reported.
fn finish<T: Real>(
    identifier: &mut Id<T>,
    file: &str,
    config: &Config,
    omega_estimated: bool,
    blemished: u64,
) -> Result<Report, IdentifyError> {
    identifier.screen();
    let counters = *identifier.counters();
    let model = identifier.model().ok_or_else(|| {
        IdentifyError(format!(
            "{file}: no model: {} samples were accepted and {} rejected, too few regression rows for the {}-term library{}.",
            counters.accepted,
            counters.rejected(),
            identifier.library().len(),
            identify::memory_hint(config, counters.accepted)
        ))
    })?;
    Ok(identify::report(
        model,
        config,
        omega_estimated,
        counters.rejected() + blemished,
        std::any::type_name::<T>(),
    ))
}

/// The identifiers (f32 and f64) over the excerpt, then over the rest of the stream, and the
/// gate's blocks kept on the way (see [`super::sketch`]). `f32`: the precision asked for.
pub(super) fn run(
    mut csv: CsvStream,
    excerpt: Recording,
    config: Config,
    omega_estimated: bool,
    f32: bool,
    gate_blocks: usize,
    progress: &mut impl FnMut(u64, u64),
) -> Result<Pass, StreamError> {
    let file = excerpt.path.display().to_string();
    let new_error = |e: lssi_core::ConfigError| IdentifyError(format!("{file}: {e}."));
    let mut single: Box<Id<f32>> = Box::new(Identifier::new(config).map_err(new_error)?);
    let mut double: Box<Id<f64>> = Box::new(Identifier::new(config).map_err(new_error)?);
    let mut rejections = Vec::new();
    // A large offset removed in f64 before the conversion to T, as in memory (the excerpt's
    // first rows give the reference).
    let reference = identify::Reference::of(&excerpt);
    let mut push = |i: usize, s: Sample| {
        // Both precisions take every sample; the one asked for names what it rejects.
        let (a, b) = (
            feed(&mut single, &s, reference),
            feed(&mut double, &s, reference),
        );
        if let Err(why) = if f32 { a } else { b }
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
    // The excerpt's last rows as given to the identifier: the burst stage's first context.
    let mut context: std::collections::VecDeque<(usize, Sample)> =
        std::collections::VecDeque::with_capacity(MARGIN + 1);
    for (i, s) in excerpt.samples().enumerate() {
        let given = match scan.feed(i) {
            Feed::Skip => None,
            Feed::AsIs => Some(s),
            Feed::Repaired(r) => Some(Sample {
                x: r.x,
                v: r.v,
                u: r.u,
                ..s
            }),
        };
        if let Some(given) = given {
            push(i, given);
        }
        // A row left out is context the burst search skips (x non-finite).
        context.push_back((i, given.unwrap_or(Sample { x: f64::NAN, ..s })));
        if context.len() > MARGIN {
            context.pop_front();
        }
    }
    // The rest: the spike rule with the excerpt's thresholds, on a sliding run of seven
    // samples (a spike's residual against its neighbours'); a spike is repaired as in memory.
    // (Non-finite values and time gaps the identifier itself leaves out and restarts on.)
    let mut channels = vec![excerpt.x.clone()];
    channels.extend(excerpt.v.clone());
    channels.extend(excerpt.u.clone());
    let mut names: Vec<&'static str> = vec!["x"];
    names.extend(excerpt.v.as_ref().map(|_| "v"));
    names.extend(excerpt.u.as_ref().map(|_| "u"));
    let limits: Vec<Option<(f64, f64)>> = channels
        .iter()
        .map(|c| crate::identify::blemish::spike_limit(c, &scan))
        .collect();
    drop(channels);
    // Bursts in x and a measured v, before the spikes (as in memory).
    let searched = 1 + usize::from(excerpt.v.is_some());
    let mut bursts = BurstRepair::new(
        limits[..searched].to_vec(),
        names[..searched].to_vec(),
        scan.dt,
        context.into_iter().collect(),
    );
    let mut spikes = SpikeRepair::new(limits, names, scan.dt);
    // The gate's blocks: the excerpt is the first; the rows as read (the gate finds their
    // blemishes itself, as in memory).
    let mut sketch = Sketch::new(&excerpt, excerpt.len(), gate_blocks);
    let mut i = excerpt.len();
    drop(excerpt);
    let mut named_bursts = 0;
    // The rows the burst stage gave out, through the spike stage to the identifiers.
    let mut drain = |bursts: &mut BurstRepair,
                     spikes: &mut SpikeRepair,
                     notes: &mut Vec<String>,
                     blemished: &mut u64| {
        for b in &bursts.found[named_bursts..] {
            *blemished += b.rows as u64;
            if notes.len() < NAMED_REJECTIONS {
                notes.push(format!("{file}: {}", b.sentence()));
            }
        }
        named_bursts = bursts.found.len();
        while let Some((k, s)) = bursts.next() {
            if let Some((j, out, spike)) = spikes.push(k, s) {
                if let Some((value, channel)) = spike {
                    *blemished += 1;
                    if notes.len() < NAMED_REJECTIONS {
                        notes.push(format!(
                            "{file}: data row {} (t = {}): an isolated spike in {channel} ({value:e}); it was replaced by the cubic through its four neighbours",
                            j + 1,
                            out.t
                        ));
                    }
                }
                push(j, out);
            }
        }
    };
    while let Some(s) = csv.next_sample()? {
        sketch.push(s);
        bursts.push(i, s);
        drain(&mut bursts, &mut spikes, &mut notes, &mut blemished);
        i += 1;
        if i.is_multiple_of(1 << 16) {
            progress(csv.bytes_read(), csv.size());
        }
    }
    bursts.finish();
    drain(&mut bursts, &mut spikes, &mut notes, &mut blemished);
    for (j, out) in spikes.finish() {
        push(j, out);
    }
    progress(csv.size(), csv.size());
    let a = finish(&mut single, &file, &config, omega_estimated, blemished);
    let b = finish(&mut double, &file, &config, omega_estimated, blemished);
    let (report, other) = if f32 { (a, b) } else { (b, a) };
    let mut report = report?;
    notes.extend(rejections);
    report.rejections = notes;
    Ok(Pass {
        report,
        other: other.ok(),
        blocks: sketch.finish(),
    })
}

/// A repaired spike's measured value and its channel's name.
type Spike = (f64, &'static str);

/// The spike rule on a stream: samples go through a run of seven; the middle one is a spike
/// when its cubic residual r (against its four neighbours) is beyond the channel's limit and
/// [`crate::identify::blemish::SPIKE_DOMINANCE`] times its neighbours' r, all seven finite and
/// evenly spaced. A spike is replaced by the cubic's value.
struct SpikeRepair {
    limits: Vec<Option<(f64, f64)>>,
    dt: f64,
    run: std::collections::VecDeque<(usize, Sample)>,
    /// The channels' names ("x", then "v" and "u" when measured).
    names: Vec<&'static str>,
    /// Repaired spikes still in the run: (index, (measured value, channel)).
    judged: Vec<(usize, Spike)>,
}

impl SpikeRepair {
    fn new(limits: Vec<Option<(f64, f64)>>, names: Vec<&'static str>, dt: f64) -> Self {
        Self {
            limits,
            names,
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
    /// and the spike's measured value and channel when it was repaired).
    fn push(&mut self, i: usize, s: Sample) -> Option<(usize, Sample, Option<Spike>)> {
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
                        && !crate::identify::blemish::level_step(&v, 3)
                    {
                        let value = cubic(3);
                        if value.is_finite() {
                            spike = Some((v[3], self.names[c]));
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
