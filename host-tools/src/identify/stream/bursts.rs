//! Bursts past the excerpt ([`crate::identify::burst`]): a streamed file's rows go through
//! blocks of [`BLOCK`] rows, each searched for bursts in x (and a measured v) as a recording
//! in memory is, against the excerpt's limit, with [`MARGIN`] rows of context on each side
//! (the block before's last rows, already repaired, and the next block's first). A burst
//! whose first row is in the block is repaired there (the cubic through the samples around
//! it) or, without context on both sides (beside a time gap or a non-finite value, or at the
//! file's end), left out: its rows are not given to the identifier, which restarts its window
//! on the gap they leave.
//! Before this stage a three-row logger glitch past the file's first 65,536 rows went into
//! the identifier as measured, and the gate withheld the whole file with "no deterministic
//! dynamics found", not naming the glitch.

use std::collections::VecDeque;

use crate::identify::blemish::{Blemish, EDGE_FIT, Kind, Limit, Scan};
use crate::identify::burst::{BURST_MAX, CONTEXT, bursts_within};
use crate::recording::Sample;

/// Rows searched at once.
pub(super) const BLOCK: usize = 4096;
/// Rows of context kept on each side of a block: a burst's cluster, its candidates up to
/// [`BURST_MAX`] + 1 before it, the cubic's [`EDGE_FIT`] samples.
pub(super) const MARGIN: usize = 64;

const _: () = assert!(MARGIN >= EDGE_FIT + 2 * (BURST_MAX + 6) + 2 && CONTEXT <= EDGE_FIT);

/// The burst stage of a stream: rows in, the same rows out (repaired) a block later.
pub(super) struct BurstRepair {
    /// Per searched channel (x, then v when measured): the excerpt's limit.
    limits: Vec<Option<Limit>>,
    names: Vec<&'static str>,
    dt: f64,
    /// Rows held: up to [`MARGIN`] already given out (context), then the rows not yet given out.
    rows: VecDeque<(usize, Sample)>,
    /// How many of `rows` were given out already.
    given: usize,
    /// Rows searched and ready to give out (a left-out burst's rows are not).
    ready: VecDeque<(usize, Sample)>,
    /// Indices of `rows` in a burst left out (their x is NaN in `rows`: the search's context
    /// skips them).
    left_out: Vec<usize>,
    /// Bursts found, in order.
    pub(super) found: Vec<Blemish>,
}

impl BurstRepair {
    /// `limits`: the excerpt's (centre, limit) of the centred residuals of x and (when
    /// measured) v; `context`: the excerpt's last rows, as given to the identifier.
    pub(super) fn new(
        limits: Vec<Option<(f64, f64)>>,
        names: Vec<&'static str>,
        dt: f64,
        context: Vec<(usize, Sample)>,
    ) -> Self {
        let given = context.len();
        Self {
            limits: limits
                .into_iter()
                .map(|l| l.map(|(centre, limit)| Limit { centre, limit }))
                .collect(),
            names,
            dt,
            rows: context.into_iter().collect(),
            given,
            ready: VecDeque::new(),
            left_out: Vec::new(),
            found: Vec::new(),
        }
    }

    /// Takes row `i`; the rows searched since are given out by [`BurstRepair::next`].
    pub(super) fn push(&mut self, i: usize, s: Sample) {
        self.rows.push_back((i, s));
        if self.rows.len() - self.given >= BLOCK + MARGIN {
            self.search(self.given + BLOCK);
        }
    }

    /// A row searched, ready for the spike stage.
    pub(super) fn next(&mut self) -> Option<(usize, Sample)> {
        self.ready.pop_front()
    }

    /// Searches what is left (the file ended) and gives out every row.
    pub(super) fn finish(&mut self) {
        self.search(self.rows.len());
    }

    fn value(s: &Sample, c: usize) -> f64 {
        match c {
            0 => s.x,
            _ => s.v.unwrap_or(f64::NAN),
        }
    }

    /// Searches the rows `given..end` of `rows` (with the context around them), repairs
    /// the bursts that start there, and gives them out, keeping [`MARGIN`] as context.
    fn search(&mut self, end: usize) {
        let n = self.rows.len();
        let (from, end) = (self.given, end.min(n));
        if self.dt > 0.0 && end > from {
            let mut scan = Scan {
                dt: self.dt,
                skip: vec![false; n],
                restart: vec![false; n],
                missing: vec![0; n],
                ..Scan::default()
            };
            for (j, (_, s)) in self.rows.iter().enumerate() {
                let finite = s.t.is_finite()
                    && s.x.is_finite()
                    && s.v.is_none_or(f64::is_finite)
                    && s.u.is_none_or(f64::is_finite);
                scan.skip[j] = !finite;
                if j > 0 {
                    let step = s.t - self.rows[j - 1].1.t;
                    scan.restart[j] = !(step > 0.5 * self.dt && step < 1.5 * self.dt);
                }
            }
            for c in 0..self.limits.len() {
                let Some(limit) = &self.limits[c] else {
                    continue;
                };
                let channel: Vec<f64> = self.rows.iter().map(|(_, s)| Self::value(s, c)).collect();
                for burst in bursts_within(&channel, &scan, limit) {
                    let (a, b) = (burst.rows.start, burst.rows.end - 1);
                    if a < from || a >= end {
                        continue;
                    }
                    let repaired = burst.repair.is_some();
                    self.found.push(Blemish {
                        kind: Kind::Burst,
                        index: self.rows[a].0,
                        t: self.rows[a].1.t,
                        value: channel[a],
                        repaired,
                        rows: b - a + 1,
                        t_end: self.rows[b].1.t,
                        channel: self.names[c],
                    });
                    for (k, j) in (a..=b).enumerate() {
                        let s = &mut self.rows[j].1;
                        match (&burst.repair, c) {
                            (Some(values), 0) => s.x = values[k],
                            (Some(values), _) => s.v = Some(values[k]),
                            (None, _) => {
                                s.x = f64::NAN;
                                self.left_out.push(self.rows[j].0);
                            }
                        }
                        scan.skip[j] = true;
                    }
                }
            }
        }
        let left_out = &self.left_out;
        self.ready.extend(
            self.rows
                .range(from..end)
                .filter(|(i, _)| !left_out.contains(i))
                .copied(),
        );
        self.left_out.clear();
        self.given = end;
        let drop = self.given.saturating_sub(MARGIN);
        self.rows.drain(..drop);
        self.given -= drop;
    }
}
