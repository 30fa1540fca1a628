//! Blemishes of a recording, found before it is identified: non-finite values, time gaps,
//! and isolated spikes.
//!
//! Each blemished sample is left out, and the identifier restarts its derivative window after
//! it, as a device does on a gap in time ([`lssi_core::Identifier`] restarts when a sample
//! comes more than 1.5 periods after the previous one, so leaving a sample out is enough).
//! The rules:
//!
//! - a sample with a NaN or infinite value (time or any channel) is left out;
//! - a time step off the sample period by more than half a period is a blemish: a step
//!   under half a period leaves the sample out (it is not after the previous one), a step
//!   over one and a half periods is a gap (the window restarts);
//! - an isolated spike is a sample whose distance from the cubic through its four neighbours,
//!   r = s − (−s₋₂ + 4s₋₁ + 4s₊₁ − s₊₂)/6, is more than [`SPIKE_MADS`] robust standard
//!   deviations (1.4826 · the median absolute deviation of r over the recording, at least the
//!   channel's quantisation step) — times how much further than a Gaussian's the channel's
//!   own noise reaches, so that heavy-tailed noise such as a laser vibrometer's is not taken
//!   for spikes (see `Limit::of`) — and at least [`SPIKE_DOMINANCE`] times the r of the samples
//!   two either side
//!   (a spike of height h gives r = h at its sample and −2h/3 at its neighbours; a step gives
//!   ±h/2 at two samples and is not a spike). A spike whose four neighbours are kept is
//!   *repaired*: the identifier is given that cubic's value instead (the other channels as
//!   measured), so its derivative window does not restart around it. Leaving it out restarts
//!   the window, and the hole that leaves in the test-function sums moved the damping of
//!   `lssi gen eveh`'s harvester by up to 2.1 % (a spike at data row 15001; 0.01 % repaired).
//!   The cubic's error is of order h⁴ times the fourth derivative, far under the noise at the
//!   sampling rates the identifier needs; its noise is √(34/36) of one sample's.
//!   The first and last two samples of a stretch (the record's ends, or beside a gap) have no
//!   two neighbours on each side: they are judged by the one-sided residual from the cubic
//!   fitted to the samples 2 to 25 away, against that stencil's own limit, so a spike there is
//!   found where it is (issue 25), not at its neighbour; such a spike is left out.
//!
//! - a burst: 2 to 5 consecutive bad samples in x or a measured v, which the spike rule does
//!   not find (no sample of it dominates its neighbours): see [`crate::identify::burst`]. It
//!   is found before the spikes, named as one blemish (its rows), and repaired with the cubic
//!   through the samples around it as a spike is (left out at a stretch's end).
//!
//! - a stuck sensor: a run of samples in which x (or a measured v) keeps exactly the same
//!   value for at least [`STUCK_PERIODS`] of its dominant period (and [`STUCK_MIN_ROWS`]
//!   samples) while it varies elsewhere. No oscillator's coordinate stays bit for bit
//!   constant over half a period; a frozen sensor or a logger that repeats its last reading
//!   does. The run's samples after its first are left out (and named, rows and times, as one
//!   blemish), so the model comes from the rest of the record; quantised data, whose turning
//!   points repeat a value for a few per cent of a period, is not taken for it.
//!
//! The excitation frequency is estimated from windows within clean stretches only, and the
//! derivative window from the clean samples (see [`crate::identify::configure`]).

use std::ops::Range;

use crate::recording::Recording;

/// Robust standard deviations of r beyond which a sample is a spike.
pub const SPIKE_MADS: f64 = 12.0;
/// How much a spike's r must exceed its neighbours' (an isolated spike: 1.5).
pub const SPIKE_DOMINANCE: f64 = 1.25;

/// Fraction of x's dominant period (samples per period of its strongest line) a run of equal
/// values must last to be a stuck sensor.
pub const STUCK_PERIODS: f64 = 0.5;
/// Samples a run of equal values must hold at least to be a stuck sensor.
pub const STUCK_MIN_ROWS: usize = 32;

/// What is wrong with a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A NaN or infinite value.
    NonFinite,
    /// The time step from the previous sample exceeds 1.5 periods (the window restarts).
    Gap,
    /// The time step from the previous sample is under half a period (left out).
    Early,
    /// An isolated spike (left out).
    Spike,
    /// The first sample of a burst of a few consecutive bad samples ([`Blemish::rows`] long;
    /// repaired or left out as a spike is).
    Burst,
    /// The first sample of a run in which a channel is stuck at one value (the rest of the
    /// run left out; [`Blemish::rows`] long).
    Stuck,
}

impl Kind {
    /// What it is, in a few words (plural).
    pub fn noun(self) -> &'static str {
        match self {
            Kind::NonFinite => "NaN or infinite values",
            Kind::Gap => "time gaps",
            Kind::Early => "samples less than half a period after the previous one",
            Kind::Spike => "isolated spikes",
            Kind::Burst => "bursts of consecutive bad samples",
            Kind::Stuck => "stretches where the sensor is stuck at one value",
        }
    }

    /// What one of it is, in a few words.
    pub fn noun_one(self) -> &'static str {
        match self {
            Kind::NonFinite => "NaN or infinite value",
            Kind::Gap => "time gap",
            Kind::Early => "sample less than half a period after the previous one",
            Kind::Spike => "isolated spike",
            Kind::Burst => "burst of consecutive bad samples",
            Kind::Stuck => "stretch where the sensor is stuck at one value",
        }
    }
}

/// One blemish.
#[derive(Clone, Debug, PartialEq)]
pub struct Blemish {
    /// What.
    pub kind: Kind,
    /// The sample (0-based; data row `index + 1`).
    pub index: usize,
    /// Its time (NaN if that is what is wrong).
    pub t: f64,
    /// The gap's length in seconds, the spike's value, or the non-finite value.
    pub value: f64,
    /// A spike given to the identifier as the cubic through its neighbours (see
    /// [`Scan::repairs`]) rather than left out.
    pub repaired: bool,
    /// Samples it covers: 1, or a burst's or a stuck run's length.
    pub rows: usize,
    /// The time of its last sample (its own time but for a stuck run).
    pub t_end: f64,
    /// The column it is in: "t" for a time gap, an early sample or a non-finite time; the
    /// channel ("x", "v", "u") of a spike, a stuck run or a non-finite value.
    pub channel: &'static str,
}

impl Blemish {
    /// One sentence (without the file name and the final period).
    pub fn sentence(&self) -> String {
        let row = self.index + 1;
        match self.kind {
            Kind::NonFinite => format!(
                "data row {row} (t = {}): a NaN or infinite value in {}; it was left out and the window restarted",
                self.t, self.channel
            ),
            Kind::Gap => format!(
                "data row {row} (t = {}): a gap of {:.6} s in {} before it; the window restarted",
                self.t, self.value, self.channel
            ),
            Kind::Early => format!(
                "data row {row} (t = {}): {} only {:.3e} s after the previous sample's (under half a period); it was left out",
                self.t, self.channel, self.value
            ),
            Kind::Spike if self.repaired => format!(
                "data row {row} (t = {}): an isolated spike in {} ({:e}); it was replaced by the cubic through its four neighbours",
                self.t, self.channel, self.value
            ),
            Kind::Spike => format!(
                "data row {row} (t = {}): an isolated spike in {} ({:e}); it was left out and the window restarted",
                self.t, self.channel, self.value
            ),
            Kind::Burst => format!(
                "data rows {row}–{} (t = {}–{} s): a burst of {} bad samples in {} (the first {:e}); {}",
                row + self.rows - 1,
                self.t,
                self.t_end,
                self.rows,
                self.channel,
                self.value,
                if self.repaired {
                    "they were replaced by the cubic through the samples around them"
                } else {
                    "they were left out and the window restarted"
                }
            ),
            Kind::Stuck => format!(
                "data rows {row}–{} (t = {}–{} s): {} is stuck at {} (the same value in {} samples in a row: a sensor that froze, or a logger repeating its last reading); they were left out after the first and the window restarted",
                row + self.rows - 1,
                self.t,
                self.t_end,
                self.channel,
                self.value,
                self.rows
            ),
        }
    }
}

/// The blemishes of a recording and what the identifier is to leave out.
#[derive(Clone, Debug, Default)]
pub struct Scan {
    /// Median sample period (the identifier's), seconds; 0 when unknown.
    pub dt: f64,
    /// Per sample: left out.
    pub skip: Vec<bool>,
    /// Per sample: the window restarts before it (a gap, or a left-out sample before it).
    pub restart: Vec<bool>,
    /// Missing sample periods before each sample (a gap of Δt leaves round(Δt/dt) − 1).
    pub missing: Vec<usize>,
    /// Every blemish, in order.
    pub blemishes: Vec<Blemish>,
    /// Repaired spikes: per sample, its values (x, v, u) with the spiking channel replaced
    /// by the cubic through its four neighbours. These samples are in `skip` too (their
    /// measured values are not used: not for the window choice nor for Ω), but the identifier
    /// is given the repaired values and does not restart its window ([`Scan::feed`]).
    pub repairs: std::collections::BTreeMap<usize, Repaired>,
}

/// A repaired sample's values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Repaired {
    /// x.
    pub x: f64,
    /// v, when measured.
    pub v: Option<f64>,
    /// u, when measured.
    pub u: Option<f64>,
}

/// What the identifier is given for one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feed {
    /// The sample as measured.
    AsIs,
    /// The sample with a spike repaired.
    Repaired(Repaired),
    /// Nothing: the sample is left out.
    Skip,
}

/// The median of a slice (sorted in place); 0 when empty.
fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

impl Scan {
    /// Scans a recording.
    pub fn of(recording: &Recording) -> Self {
        let n = recording.len();
        let t = &recording.t;
        let mut channels: Vec<&[f64]> = vec![&recording.x];
        channels.extend(recording.v.as_deref());
        channels.extend(recording.u.as_deref());
        // The channels' names, in the same order.
        let mut channel_names: Vec<&'static str> = vec!["x"];
        channel_names.extend(recording.v.as_ref().map(|_| "v"));
        channel_names.extend(recording.u.as_ref().map(|_| "u"));
        let mut steps: Vec<f64> = t
            .iter()
            .copied()
            .filter(|t| t.is_finite())
            .collect::<Vec<_>>()
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 0.0)
            .collect();
        let dt = median(&mut steps);
        let mut scan = Scan {
            dt,
            skip: vec![false; n],
            restart: vec![false; n],
            missing: vec![0; n],
            blemishes: Vec::new(),
            repairs: std::collections::BTreeMap::new(),
        };
        let finite = |i: usize| t[i].is_finite() && channels.iter().all(|c| c[i].is_finite());
        let mut found: Vec<Blemish> = Vec::new();
        for i in 0..n {
            if !finite(i) {
                scan.skip[i] = true;
                let (value, channel) = channels
                    .iter()
                    .zip(&channel_names)
                    .map(|(c, name)| (c[i], *name))
                    .find(|(v, _)| !v.is_finite())
                    .filter(|_| t[i].is_finite())
                    .unwrap_or((t[i], "t"));
                found.push(Blemish {
                    kind: Kind::NonFinite,
                    index: i,
                    t: t[i],
                    value,
                    repaired: false,
                    rows: 1,
                    t_end: t[i],
                    channel,
                });
            }
        }
        let mut names: Vec<&'static str> = vec!["x"];
        names.extend(recording.v.as_ref().map(|_| "v"));
        for (c, name) in names.into_iter().enumerate() {
            for run in stuck(channels[c], &scan) {
                for j in run.start + 1..run.end {
                    scan.skip[j] = true;
                }
                found.push(Blemish {
                    kind: Kind::Stuck,
                    index: run.start,
                    t: t[run.start],
                    value: channels[c][run.start],
                    repaired: false,
                    rows: run.len(),
                    t_end: t[run.end - 1],
                    channel: name,
                });
            }
        }
        if dt > 0.0 {
            // Time steps, from the last sample with a finite time.
            let mut last: Option<f64> = None;
            for i in 0..n {
                if !t[i].is_finite() {
                    continue;
                }
                if let Some(prev) = last {
                    let step = t[i] - prev;
                    if step < 0.5 * dt {
                        if !scan.skip[i] {
                            scan.skip[i] = true;
                            found.push(Blemish {
                                kind: Kind::Early,
                                index: i,
                                t: t[i],
                                value: step,
                                repaired: false,
                                rows: 1,
                                t_end: t[i],
                                channel: "t",
                            });
                        }
                        continue;
                    }
                    if step > 1.5 * dt {
                        scan.restart[i] = true;
                        scan.missing[i] = ((step / dt).round() as usize).saturating_sub(1);
                        found.push(Blemish {
                            kind: Kind::Gap,
                            index: i,
                            t: t[i],
                            value: step,
                            repaired: false,
                            rows: 1,
                            t_end: t[i],
                            channel: "t",
                        });
                    }
                }
                last = Some(t[i]);
            }
            // Bursts, before the spikes (whose rule would take a burst's clean neighbours
            // for spikes): each sample of one left out, or repaired when every bursting
            // channel at it has a prediction.
            let mut predicted: std::collections::BTreeMap<usize, Vec<(usize, Option<f64>)>> =
                std::collections::BTreeMap::new();
            let searched = 1 + usize::from(recording.v.is_some());
            for c in 0..searched {
                for burst in crate::identify::burst::bursts(channels[c], &scan) {
                    let (a, b) = (burst.rows.start, burst.rows.end - 1);
                    for (k, j) in burst.rows.clone().enumerate() {
                        scan.skip[j] = true;
                        let value = burst.repair.as_ref().map(|v| v[k]);
                        predicted.entry(j).or_default().push((c, value));
                    }
                    found.push(Blemish {
                        kind: Kind::Burst,
                        index: a,
                        t: t[a],
                        value: channels[c][a],
                        repaired: burst.repair.is_some(),
                        rows: burst.rows.len(),
                        t_end: t[b],
                        channel: channel_names[c],
                    });
                }
            }
            for (&j, values) in &predicted {
                if values.iter().any(|(_, v)| v.is_none()) || !finite(j) {
                    continue;
                }
                let value = |c: usize| {
                    values
                        .iter()
                        .find(|(k, _)| *k == c)
                        .and_then(|(_, v)| *v)
                        .unwrap_or(channels[c][j])
                };
                let v = recording.v.is_some().then(|| value(1));
                let u = recording
                    .u
                    .is_some()
                    .then(|| value(if recording.v.is_some() { 2 } else { 1 }));
                scan.repairs.insert(j, Repaired { x: value(0), v, u });
            }
            // A burst whose samples are not all repaired (another channel's left out) is
            // left out.
            for b in found.iter_mut().filter(|b| b.kind == Kind::Burst) {
                b.repaired = (b.index..b.index + b.rows).all(|j| scan.repairs.contains_key(&j));
            }
            let mut spiking: Vec<(usize, usize)> = Vec::new();
            for (c, channel) in channels.iter().enumerate() {
                for i in spikes(channel, &scan) {
                    spiking.push((i, c));
                    if !scan.skip[i] {
                        scan.skip[i] = true;
                        found.push(Blemish {
                            kind: Kind::Spike,
                            index: i,
                            t: t[i],
                            value: channel[i],
                            repaired: false,
                            rows: 1,
                            t_end: t[i],
                            channel: channel_names[c],
                        });
                    }
                }
            }
            // Repairs: a spike whose four neighbours are all kept (so not another spike, a
            // NaN or a gap), each spiking channel replaced by the cubic through them.
            for b in found.iter_mut().filter(|b| b.kind == Kind::Spike) {
                let i = b.index;
                let neighbours_kept = i >= 2
                    && i + 2 < n
                    && [i - 2, i - 1, i + 1, i + 2]
                        .iter()
                        .all(|&j| !scan.skip[j] && !scan.restart[j] && finite(j))
                    && !scan.restart[i];
                if !neighbours_kept {
                    continue;
                }
                let value = |c: usize| {
                    let s = channels[c];
                    if spiking.contains(&(i, c)) {
                        -(s[i - 2] / 6.0) + s[i - 1] / 1.5 + s[i + 1] / 1.5 - s[i + 2] / 6.0
                    } else {
                        s[i]
                    }
                };
                // Channel order: x, then v and u when measured.
                let v = recording.v.is_some().then(|| value(1));
                let u = recording
                    .u
                    .is_some()
                    .then(|| value(if recording.v.is_some() { 2 } else { 1 }));
                let repaired = Repaired { x: value(0), v, u };
                if repaired.x.is_finite()
                    && repaired.v.is_none_or(f64::is_finite)
                    && repaired.u.is_none_or(f64::is_finite)
                {
                    scan.repairs.insert(i, repaired);
                    b.repaired = true;
                }
            }
        }
        for i in 1..n {
            if scan.skip[i - 1] {
                scan.restart[i] = true;
            }
        }
        found.sort_by_key(|b| b.index);
        scan.blemishes = found;
        scan
    }

    /// What the identifier is given for sample `i`: as measured, repaired, or nothing.
    pub fn feed(&self, i: usize) -> Feed {
        match self.repairs.get(&i) {
            Some(r) => Feed::Repaired(*r),
            None if self.skip.get(i).copied().unwrap_or(false) => Feed::Skip,
            None => Feed::AsIs,
        }
    }

    /// This scan with the repaired spikes kept (not skipped, no restart after them): for
    /// what reads the repaired values ([`Scan::repaired`]), such as the estimate of Ω, which
    /// a hole of a few windows moved by 3·10⁻⁵ rad/s (and the damping by 1 %).
    pub fn with_repairs_kept(&self) -> Scan {
        let mut scan = self.clone();
        for &i in self.repairs.keys() {
            scan.skip[i] = false;
            if i + 1 < scan.restart.len() {
                let gap = self
                    .blemishes
                    .iter()
                    .any(|b| b.index == i + 1 && b.kind == Kind::Gap);
                scan.restart[i + 1] = gap;
            }
        }
        scan
    }

    /// Channel `c` (0: x, 1: v, 2: u, of those present) with the repaired spikes' values.
    pub fn repaired(&self, recording: &Recording, c: usize) -> Option<Vec<f64>> {
        let mut channels: Vec<&Vec<f64>> = vec![&recording.x];
        channels.extend(recording.v.as_ref());
        channels.extend(recording.u.as_ref());
        let mut out = channels.get(c)?.to_vec();
        for (&i, r) in &self.repairs {
            let mut values = vec![r.x];
            values.extend(r.v);
            values.extend(r.u);
            if let Some(v) = values.get(c) {
                out[i] = *v;
            }
        }
        Some(out)
    }

    /// No blemish at all.
    pub fn is_clean(&self) -> bool {
        self.blemishes.is_empty()
    }

    /// Samples left out.
    pub fn skipped(&self) -> usize {
        self.skip.iter().filter(|s| **s).count()
    }

    /// The clean stretches: runs of samples that are kept, without a restart inside.
    pub fn stretches(&self) -> Vec<Range<usize>> {
        let mut out = Vec::new();
        let mut start: Option<usize> = None;
        for i in 0..self.skip.len() {
            if (self.skip[i] || self.restart[i])
                && let Some(s) = start.take()
            {
                out.push(s..i);
            }
            if !self.skip[i] && start.is_none() {
                start = Some(i);
            }
        }
        if let Some(s) = start {
            out.push(s..self.skip.len());
        }
        out
    }

    /// The length L such that the stretches at least L long hold half of the kept samples
    /// (a weighted median): the stretch length the identifier typically sees.
    pub fn typical_stretch(&self) -> usize {
        let mut lengths: Vec<usize> = self.stretches().iter().map(|r| r.len()).collect();
        lengths.sort_unstable_by(|a, b| b.cmp(a));
        let total: usize = lengths.iter().sum();
        let mut sum = 0;
        for l in lengths {
            sum += l;
            if 2 * sum >= total {
                return l;
            }
        }
        0
    }

    /// One sentence per kind of blemish: how many, and the first rows.
    pub fn summary(&self) -> Vec<String> {
        let kinds = [
            Kind::NonFinite,
            Kind::Gap,
            Kind::Early,
            Kind::Spike,
            Kind::Burst,
            Kind::Stuck,
        ];
        kinds
            .iter()
            .filter_map(|&k| {
                let rows: Vec<usize> = self
                    .blemishes
                    .iter()
                    .filter(|b| b.kind == k)
                    .map(|b| b.index + 1)
                    .collect();
                if rows.is_empty() {
                    return None;
                }
                if k == Kind::Burst {
                    let bursts: Vec<String> = self
                        .blemishes
                        .iter()
                        .filter(|b| b.kind == k)
                        .map(|b| {
                            format!(
                                "a burst of {} bad samples in {} at data rows {}–{} (t = {}–{} s)",
                                b.rows,
                                b.channel,
                                b.index + 1,
                                b.index + b.rows,
                                b.t,
                                b.t_end
                            )
                        })
                        .collect();
                    return Some(bursts.join(", "));
                }
                if k == Kind::Stuck {
                    let runs: Vec<String> = self
                        .blemishes
                        .iter()
                        .filter(|b| b.kind == k)
                        .map(|b| {
                            format!(
                                "{} stuck at {} over data rows {}–{} (t = {}–{} s)",
                                b.channel,
                                b.value,
                                b.index + 1,
                                b.index + b.rows,
                                b.t,
                                b.t_end
                            )
                        })
                        .collect();
                    return Some(runs.join(", "));
                }
                // The columns they are in, each once, in the order found.
                let mut columns: Vec<&str> = Vec::new();
                for b in self.blemishes.iter().filter(|b| b.kind == k) {
                    if !columns.contains(&b.channel) {
                        columns.push(b.channel);
                    }
                }
                Some(format!(
                    "{} {} in {} ({})",
                    rows.len(),
                    if rows.len() == 1 {
                        k.noun_one()
                    } else {
                        k.noun()
                    },
                    columns.join(" and "),
                    where_text(&rows)
                ))
            })
            .collect()
    }
}

/// "data row 12" / "data rows 12 and 30" / "data rows 101, 301, 501, … 39901, every 200 rows".
pub fn where_text(rows: &[usize]) -> String {
    match rows {
        [] => String::new(),
        [r] => format!("data row {r}"),
        [a, b] => format!("data rows {a} and {b}"),
        _ => {
            let shown: Vec<String> = rows.iter().take(3).map(|r| r.to_string()).collect();
            let last = rows[rows.len() - 1];
            let step = rows[1] - rows[0];
            let regular = rows.windows(2).all(|w| w[1] - w[0] == step);
            let tail = if rows.len() > 3 {
                format!(", … {last}")
            } else {
                String::new()
            };
            let every = if regular && rows.len() > 3 {
                format!(", every {step} rows")
            } else {
                String::new()
            };
            format!("data rows {}{tail}{every}", shown.join(", "))
        }
    }
}

/// The Gaussian value of q₉₉/q₉₅ of |r| (2.5758/1.9600), as a power-law exponent:
/// ln 5 / ln(2.5758/1.9600) ≈ 5.89 (see [`Limit::of`]).
fn gaussian_alpha() -> f64 {
    5f64.ln() / (2.5758f64 / 1.9600).ln()
}

/// Samples of the one-sided cubic fit that judges the first and last two samples of a stretch
/// (offsets 2 to 25 from the sample, skipping its neighbour so that a spike there does not
/// move it). 24 samples give a noise gain of 1.63 (the centred stencil's: 1.39; 8 samples:
/// 5.3), so a spike at the end is found from 20 noise σ on.
pub(crate) const EDGE_FIT: usize = 24;

/// At most this many positions measure the one-sided stencil's limit (evenly spread).
const EDGE_SAMPLE: usize = 100_000;

/// The runs of a channel stuck at one value (see the module docs): runs of exactly equal
/// finite samples, not left out already, at least [`STUCK_MIN_ROWS`] long and
/// [`STUCK_PERIODS`] of the channel's dominant period, while the channel varies elsewhere
/// (a constant channel is the quality gate's to name).
fn stuck(s: &[f64], scan: &Scan) -> Vec<Range<usize>> {
    let n = s.len();
    let mut runs: Vec<Range<usize>> = Vec::new();
    let mut start = 0;
    for i in 1..=n {
        let same = i < n && !scan.skip[i] && s[i].is_finite() && s[i] == s[i - 1];
        if !same {
            if i - start >= STUCK_MIN_ROWS && !scan.skip[start] && s[start].is_finite() {
                runs.push(start..i);
            }
            start = i;
        }
    }
    if runs.is_empty() {
        return runs;
    }
    // A channel constant but for a few samples is not a stuck stretch of a varying one.
    let held: usize = runs.iter().map(|r| r.len()).sum();
    if n - held < STUCK_MIN_ROWS {
        return Vec::new();
    }
    // The dominant period from the samples outside the runs (each run's first kept).
    let mut rest: Vec<f64> = Vec::with_capacity(n);
    let mut k = 0;
    for (i, v) in s.iter().enumerate() {
        while k < runs.len() && runs[k].end <= i {
            k += 1;
        }
        if (k < runs.len() && runs[k].start < i && i < runs[k].end) || !v.is_finite() {
            continue;
        }
        rest.push(*v);
    }
    let Some(period) = crate::identify::refine::mean_period_samples(&rest) else {
        return Vec::new();
    };
    runs.retain(|r| r.len() as f64 >= STUCK_PERIODS * period);
    runs
}

/// The centre of a residual and the limit of |r − centre| beyond which a sample is a spike.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Limit {
    pub(crate) centre: f64,
    pub(crate) limit: f64,
}

impl Limit {
    /// The limit of one stencil's residuals over a channel: [`SPIKE_MADS`] robust standard
    /// deviations σ (1.4826 · MAD, at least `floor`, the quantisation step through the
    /// stencil), times how much further than a Gaussian's the channel's own noise reaches.
    ///
    /// The reach extrapolates the tail as a power law through the 95th and 99th percentiles
    /// q₉₅, q₉₉ of |r − centre|: P(|r| > q) ∝ q^(−α), α = ln 5 / ln(q₉₉/q₉₅), to the largest of
    /// 100 such records, q₉₉ m^(1/α) for m residuals. The same extrapolation of Gaussian noise
    /// (q₉₉ = 2.576 σ, α = 5.89) is the reference: Gaussian noise keeps about 12 σ at any length
    /// (the ratio of the two reaches is 1 up to the percentiles' scatter),
    /// while heavy-tailed noise, such as a laser vibrometer's (speckle dropouts: BistableX's
    /// velocity has q₉₉ = 5–10 σ, α ≈ 2, and single-sample excursions up to 140 σ, like
    /// Student's t with 2–3 degrees of freedom), gets a limit beyond what its own excursions
    /// reach, so a noisy channel is not taken for a spiky one. A spike moves five residuals,
    /// so the percentiles hold while fewer than one sample in 500 is a spike. q₉₅ is taken at
    /// least 1.96 σ, its Gaussian value, so that a quantised channel whose residuals are
    /// mostly zero does not extrapolate from nothing.
    pub(crate) fn of(residuals: &[Option<f64>], floor: f64) -> Option<Self> {
        let mut values: Vec<f64> = residuals
            .iter()
            .flatten()
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        let m = values.len();
        if m < 16 {
            return None;
        }
        let centre = median(&mut values);
        let mut deviations: Vec<f64> = values.iter().map(|v| (v - centre).abs()).collect();
        let sigma = (1.4826 * median(&mut deviations)).max(floor);
        if !(sigma > 0.0) {
            return None;
        }
        let mut quantile = |p: f64| {
            let k = ((p * m as f64) as usize).min(m - 1);
            *deviations.select_nth_unstable_by(k, f64::total_cmp).1
        };
        let q95 = quantile(0.95).max(1.96 * sigma);
        let q99 = quantile(0.99);
        let reach = if q99 > q95 {
            let alpha = 5f64.ln() / (q99 / q95).ln();
            q99 * (m as f64).powf(1.0 / alpha)
        } else {
            q99
        };
        let gaussian = 2.5758 * sigma * (m as f64).powf(1.0 / gaussian_alpha());
        let limit = SPIKE_MADS * sigma * (reach / gaussian).max(1.0);
        limit.is_finite().then_some(Self { centre, limit })
    }

    /// |r − centre|.
    pub(crate) fn size(&self, r: f64) -> f64 {
        if r.is_finite() {
            (r - self.centre).abs()
        } else {
            f64::INFINITY
        }
    }
}

/// The noise gain of the centred stencil, √(1 + 2 (2/3)² + 2 (1/6)²) ≈ 1.394: the quantisation
/// step through it.
pub(crate) fn centred_gain() -> f64 {
    (1.0f64 + 8.0 / 9.0 + 1.0 / 18.0).sqrt()
}

/// The quantisation step of a channel: the smallest non-zero difference of consecutive
/// samples (0 when there is none).
pub(crate) fn quantum(s: &[f64]) -> f64 {
    let q = s
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| d.is_finite() && *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    if q.is_finite() { q } else { 0.0 }
}

/// The centred cubic residual r = s − (−s₋₂ + 4s₋₁ + 4s₊₁ − s₊₂)/6 of every sample whose four
/// neighbours are kept and evenly spaced.
pub(crate) fn centred(s: &[f64], scan: &Scan) -> Vec<Option<f64>> {
    let n = s.len();
    let usable = |i: usize| {
        i >= 2
            && i + 2 < n
            && (i - 2..=i + 2).all(|j| !scan.skip[j] && s[j].is_finite())
            && (i - 1..=i + 2).all(|j| !scan.restart[j])
    };
    (0..n)
        .map(|i| {
            usable(i).then(|| {
                s[i] - (-(s[i - 2] / 6.0) + s[i - 1] / 1.5 + s[i + 1] / 1.5 - s[i + 2] / 6.0)
            })
        })
        .collect()
}

/// The value at `at` of the least-squares cubic through `points` (offset, value); `None` with
/// fewer than five points or a singular fit.
pub(crate) fn cubic_fit_at(points: &[(f64, f64)], at: f64) -> Option<f64> {
    cubic_fit_slope_at(points, at).map(|(value, _)| value)
}

/// The value and the slope at `at` of the least-squares cubic through `points` (offset,
/// value); `None` as [`cubic_fit_at`].
pub(crate) fn cubic_fit_slope_at(points: &[(f64, f64)], at: f64) -> Option<(f64, f64)> {
    if points.len() < 5 {
        return None;
    }
    let mean = points.iter().map(|p| p.0).sum::<f64>() / points.len() as f64;
    let spread = points
        .iter()
        .map(|p| (p.0 - mean).abs())
        .fold(0.0f64, f64::max);
    if !(spread > 0.0) {
        return None;
    }
    let basis = |k: f64| {
        let z = (k - mean) / spread;
        [1.0, z, z * z, z * z * z]
    };
    // Normal equations A c = b, solved by Gaussian elimination with partial pivoting.
    let mut a = [[0.0f64; 5]; 4];
    for &(k, value) in points {
        let phi = basis(k);
        for r in 0..4 {
            for c in 0..4 {
                a[r][c] += phi[r] * phi[c];
            }
            a[r][4] += phi[r] * value;
        }
    }
    for col in 0..4 {
        let pivot = (col..4).max_by(|&p, &q| a[p][col].abs().total_cmp(&a[q][col].abs()))?;
        a.swap(col, pivot);
        if !(a[col][col].abs() > 1e-12) {
            return None;
        }
        for r in col + 1..4 {
            let f = a[r][col] / a[col][col];
            for c in col..5 {
                a[r][c] -= f * a[col][c];
            }
        }
    }
    let mut coef = [0.0f64; 4];
    for r in (0..4).rev() {
        let tail: f64 = (r + 1..4).map(|c| a[r][c] * coef[c]).sum();
        coef[r] = (a[r][4] - tail) / a[r][r];
    }
    let phi = basis(at);
    let z = (at - mean) / spread;
    let slope = (coef[1] + 2.0 * coef[2] * z + 3.0 * coef[3] * z * z) / spread;
    Some(((0..4).map(|r| coef[r] * phi[r]).sum(), slope))
}

/// The weights of the one-sided stencil: sᵢ predicted by the least-squares cubic through
/// sᵢ₊₂ … sᵢ₊₂₅ (index 0 is offset 2); the same weights, mirrored, predict from sᵢ₋₂₅ … sᵢ₋₂.
fn edge_weights() -> [f64; EDGE_FIT] {
    let mut w = [0.0; EDGE_FIT];
    for (k, wk) in w.iter_mut().enumerate() {
        let points: Vec<(f64, f64)> = (0..EDGE_FIT)
            .map(|j| ((j + 2) as f64, if j == k { 1.0 } else { 0.0 }))
            .collect();
        *wk = cubic_fit_at(&points, 0.0).unwrap_or(0.0);
    }
    w
}

/// The sample at offset `k` (2 ≤ k ≤ 25) from `i` in the stencil's direction.
fn edge_at(i: usize, k: usize, forward: bool) -> usize {
    if forward { i + k } else { i - k }
}

/// Whether the samples at offsets 2..=25 from `i` (ahead, or behind) are all in the
/// recording, kept and finite, and evenly spaced from `i` on.
fn edge_usable(s: &[f64], scan: &Scan, i: usize, forward: bool) -> bool {
    let last = EDGE_FIT + 1;
    let inside = if forward {
        i + last < s.len()
    } else {
        i >= last
    };
    inside
        && (2..=last).all(|k| {
            let j = edge_at(i, k, forward);
            !scan.skip[j] && s[j].is_finite()
        })
        // restart[j]: a gap between j − 1 and j.
        && (1..=last).all(|k| {
            let j = edge_at(i, k, forward);
            !scan.restart[if forward { j } else { j + 1 }]
        })
}

/// The one-sided residual sᵢ − (the stencil's prediction) at a sample, if usable.
fn one_sided_at(
    s: &[f64],
    scan: &Scan,
    w: &[f64; EDGE_FIT],
    i: usize,
    forward: bool,
) -> Option<f64> {
    if scan.skip[i] || !s[i].is_finite() || !edge_usable(s, scan, i, forward) {
        return None;
    }
    let predicted: f64 = (0..EDGE_FIT)
        .map(|k| w[k] * s[edge_at(i, k + 2, forward)])
        .sum();
    Some(s[i] - predicted)
}

/// The spike rule's threshold on one channel, from a stretch of it: the centre of the cubic
/// residual r and the limit |r − centre| beyond which a sample is a spike (with
/// [`SPIKE_DOMINANCE`] over its neighbours). For a reader that sees the recording a sample at a
/// time after this stretch (`crate::identify::stream`).
pub fn spike_limit(s: &[f64], scan: &Scan) -> Option<(f64, f64)> {
    let limit = Limit::of(&centred(s, scan), quantum(s) * centred_gain())?;
    Some((limit.centre, limit.limit))
}

/// The isolated spikes of one channel (see the module docs), among samples that `scan` keeps
/// so far.
///
/// A sample with its four neighbours kept and evenly spaced is judged by the centred cubic
/// residual; the first and last two samples of a stretch (the record's ends, or beside a gap
/// or a left-out sample) by the one-sided residual from the cubic fitted to the samples 2 to
/// 25 away on the side that has them, against that stencil's own limit measured over the
/// channel. That fit leaves out the samples whose centred residual is beyond its limit (a
/// spike there, and its neighbours), so a spike near the end does not make one at the end.
/// A spike must exceed the residuals of the samples two either side, whichever stencil judges
/// them, by [`SPIKE_DOMINANCE`]: an interior spike of height h gives h there, 2h/3 one away and
/// h/6 two away; one at the first sample gives h there and h/6 at the third.
fn spikes(s: &[f64], scan: &Scan) -> Vec<usize> {
    let n = s.len();
    let q = quantum(s);
    let r = centred(s, scan);
    let Some(lc) = Limit::of(&r, q * centred_gain()) else {
        return Vec::new();
    };
    let w = edge_weights();
    let edge_floor = q * (1.0 + w.iter().map(|x| x * x).sum::<f64>()).sqrt();
    let stride = n.div_ceil(EDGE_SAMPLE).max(1);
    let measured = |forward: bool| {
        let sample: Vec<Option<f64>> = (0..n)
            .step_by(stride)
            .map(|i| one_sided_at(s, scan, &w, i, forward))
            .collect();
        Limit::of(&sample, edge_floor)
    };
    let (lf, lb) = (measured(true), measured(false));
    let candidate = |j: usize| r[j].is_some_and(|v| lc.size(v) > lc.limit);
    // The edge samples' residual and limit: forward where the span ahead is usable, else
    // backward; refitted without candidate spikes in the span.
    let edge: Vec<Option<(f64, Limit)>> = (0..n)
        .map(|i| {
            if r[i].is_some() || scan.skip[i] || !s[i].is_finite() {
                return None;
            }
            let (forward, limit) = match (edge_usable(s, scan, i, true), lf, lb) {
                (true, Some(l), _) => (true, l),
                (_, _, Some(l)) if edge_usable(s, scan, i, false) => (false, l),
                _ => return None,
            };
            let points: Vec<(f64, f64)> = (2..=EDGE_FIT + 1)
                .map(|k| (k, edge_at(i, k, forward)))
                .filter(|&(_, j)| !candidate(j))
                .map(|(k, j)| (k as f64, s[j]))
                .collect();
            let value = if points.len() == EDGE_FIT {
                one_sided_at(s, scan, &w, i, forward)?
            } else {
                s[i] - cubic_fit_at(&points, 0.0)?
            };
            Some((value, limit))
        })
        .collect();
    let size = |i: usize| match (r.get(i).copied().flatten(), edge.get(i).copied().flatten()) {
        (Some(v), _) => lc.size(v),
        (None, Some((v, l))) => l.size(v),
        (None, None) => 0.0,
    };
    (0..n)
        .filter(|&i| {
            let beyond = match (r[i], edge[i]) {
                (Some(v), _) => lc.size(v) > lc.limit,
                (None, Some((v, l))) => l.size(v) > l.limit,
                (None, None) => false,
            };
            let neighbours = (i.saturating_sub(2)..=i + 2)
                .filter(|&j| j != i)
                .map(size)
                .fold(0.0, f64::max);
            beyond && size(i) >= SPIKE_DOMINANCE * neighbours && !level_step(s, i)
        })
        .collect()
}

/// Samples of one value that make the level a channel steps to (or from) at a sample.
pub const STEP_ROWS: usize = 3;

/// Whether sample `i` of `s` is the last (or first) of its stretch beside a level change
/// that stays, not a spike: the next (or previous) [`STEP_ROWS`] samples hold one value
/// other than its own, and it lies nearer its own side's linear continuation than that
/// level (by half). A commanded sine cut to 0 (FrID's magneto-mechanical record at row
/// 11000: u = 0.43, −0.10, then 0) leaves such a sample, which the cubic through its
/// neighbours took for a spike of −0.23 and "repaired" to 0.13; a spike beside a flat run
/// (a quantised turning point) is as far from both sides and is still one.
pub fn level_step(s: &[f64], i: usize) -> bool {
    let n = s.len();
    let flat = |from: usize| (from..from + STEP_ROWS).all(|j| s[j] == s[from]);
    let near_own = |level: f64, continued: f64| {
        let (own, other) = ((s[i] - continued).abs(), (s[i] - level).abs());
        own.is_finite() && other.is_finite() && own < 0.5 * other
    };
    let after = i >= 2
        && i + STEP_ROWS < n
        && flat(i + 1)
        && s[i] != s[i + 1]
        && near_own(s[i + 1], 2.0 * s[i - 1] - s[i - 2]);
    let before = i >= STEP_ROWS
        && i + 2 < n
        && flat(i - STEP_ROWS)
        && s[i] != s[i - 1]
        && near_own(s[i - 1], 2.0 * s[i + 1] - s[i + 2]);
    after || before
}

/// Which derivative windows lie within one clean stretch (no sample left out, no restart
/// inside), and the missing periods before each sample: for the excitation's estimate.
pub struct CleanWindows {
    /// Prefix counts of left-out samples.
    skipped: Vec<usize>,
    /// Prefix counts of restarts.
    restarts: Vec<usize>,
    /// Prefix sums of missing periods.
    missing: Vec<usize>,
    n: usize,
}

impl CleanWindows {
    /// For windows of `n` samples.
    pub fn new(scan: &Scan, n: usize) -> Self {
        let prefix = |f: &dyn Fn(usize) -> usize| {
            let mut out = vec![0; scan.skip.len() + 1];
            for i in 0..scan.skip.len() {
                out[i + 1] = out[i] + f(i);
            }
            out
        };
        Self {
            skipped: prefix(&|i| usize::from(scan.skip[i])),
            restarts: prefix(&|i| usize::from(scan.restart[i])),
            missing: prefix(&|i| scan.missing[i]),
            n,
        }
    }

    /// Whether the window of samples `start..start + n` is clean.
    pub fn ok(&self, start: usize) -> bool {
        let end = start + self.n;
        end < self.skipped.len()
            && self.skipped[end] == self.skipped[start]
            && self.restarts[end] == self.restarts[start + 1]
    }

    /// Sample periods missing (in gaps) up to sample `i`.
    pub fn missing_before(&self, i: usize) -> usize {
        self.missing[(i + 1).min(self.missing.len() - 1)]
    }
}

/// Refuses a recording whose clean stretches are too short for the configuration: shorter
/// than the derivative window plus a test function (or 64 rows), so that every test-function
/// sum would have a hole (measured: a NaN every 200 samples of `data/eveh-bistable.csv`,
/// with a test function of 196, lost the damping term and a shorter test function did too). The refusal names the blemishes and where they are.
pub fn refuse_if_broken(
    scan: &Scan,
    config: &lssi_core::Config,
    path: &std::path::Path,
) -> Result<(), crate::identify::IdentifyError> {
    if scan.is_clean() {
        return Ok(());
    }
    let needed = config.window + usize::from(config.test_rows).max(64);
    let typical = scan.typical_stretch();
    if typical >= needed {
        return Ok(());
    }
    Err(crate::identify::IdentifyError(format!(
        "{}: too broken to identify: {}; they leave clean stretches of typically {typical} samples ({:.4} s), and the identifier needs {needed} in a row (a derivative window of {} samples and a test function of {} rows).",
        path.display(),
        scan.summary().join(", "),
        typical as f64 * scan.dt,
        config.window,
        usize::from(config.test_rows).max(64),
    )))
}

/// For a refusal: " (the recording has …, left out)" naming the blemishes, or nothing.
pub fn because(scan: &Scan) -> String {
    if scan.is_clean() {
        String::new()
    } else {
        format!(
            " (the recording has {}, left out)",
            scan.summary().join(", ")
        )
    }
}
