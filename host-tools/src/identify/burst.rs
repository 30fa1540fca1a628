//! Bursts: a few consecutive bad samples (2 to [`BURST_MAX`]) in x or a measured v, found
//! before the isolated spikes ([`crate::identify::blemish`]).
//!
//! The spike rule does not find them: a burst of height h over two samples gives the centred
//! cubic residual h/6, −h/2, h/3, h/3, −h/2, h/6 around it, so no sample dominates its
//! neighbours (and the clean samples beside it have the largest residual); a logger glitch of
//! three rows at 10× the amplitude went unnamed, and the identifier failed with "damping
//! lost" or "diverges". The rule here:
//!
//! - the candidates are the samples whose centred residual is beyond the spike rule's limit
//!   (the same [`Limit`], so a clean record, whose residuals stay under it, has none); nearby
//!   candidates (at most 4 apart) make a cluster (a burst may begin up to [`BURST_MAX`] + 1
//!   before it: only some of the residuals it moves may be beyond the limit), and a cluster longer than [`BURST_MAX`] + 6
//!   samples is not a burst;
//! - a burst a..=b is a hypothesis: its samples predicted by the least-squares cubic through
//!   [`CONTEXT`] kept samples on each side (or, at the record's end or beside a gap, through the
//!   [`EDGE_FIT`] samples on the side that has them); it explains the cluster if both its end
//!   samples are beyond the limit from the prediction (the limit scaled by the prediction's
//!   own noise gain, √(1 + Σ w²), over the centred stencil's) and the centred residuals of the
//!   record with the burst replaced by the prediction, from two before to two after it, are
//!   all within the limit;
//! - the shortest hypothesis that explains the cluster is taken; if that is a single sample,
//!   the cluster is a spike and left to the spike rule (its behaviour unchanged).
//!
//! A burst with kept context on both sides is *repaired*, as a spike is: the identifier is
//! given the prediction (the other channels as measured); one at an end of a stretch is left
//! out and the window restarts. u is not searched: a commanded input may step or switch.
//! At 2000 Hz and Ω = 21.4 rad/s (`lssi gen eveh`, 590 samples a period) the cubic's error
//! across five samples is far under the noise.

use std::ops::Range;

use crate::identify::blemish::{
    EDGE_FIT, Limit, Scan, centred, centred_gain, cubic_fit_at, quantum,
};

/// The most consecutive bad samples that make a burst.
pub const BURST_MAX: usize = 5;
/// Kept samples each side whose cubic predicts a burst inside a stretch.
pub const CONTEXT: usize = 4;

/// One burst of a channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Burst {
    /// Its samples.
    pub rows: Range<usize>,
    /// The prediction of each, when it is repaired (context on both sides); `None` at the
    /// end of a stretch (left out).
    pub repair: Option<Vec<f64>>,
}

/// A burst hypothesis's prediction: values and noise gains, and whether both sides gave it.
struct Fill {
    values: Vec<f64>,
    gains: Vec<f64>,
    both_sides: bool,
}

/// The prediction of samples `a..=b` of `s` from the kept samples around them (see the module
/// docs); `None` when the burst's samples are not all kept and finite, a gap is inside it, or
/// no side has enough context.
fn fill(s: &[f64], scan: &Scan, a: usize, b: usize) -> Option<Fill> {
    let n = s.len();
    let ok = |j: usize| !scan.skip[j] && s[j].is_finite();
    if b >= n || !(a..=b).all(ok) || (a + 1..=b).any(|j| scan.restart[j]) {
        return None;
    }
    // Contiguous kept samples before a and after b, nearest first (restart[j]: a gap before j).
    let mut left: Vec<usize> = Vec::new();
    let mut j = a;
    while left.len() < EDGE_FIT && j > 0 && !scan.restart[j] && ok(j - 1) {
        j -= 1;
        left.push(j);
    }
    let mut right: Vec<usize> = Vec::new();
    let mut j = b;
    while right.len() < EDGE_FIT && j + 1 < n && !scan.restart[j + 1] && ok(j + 1) {
        j += 1;
        right.push(j);
    }
    let (context, both_sides): (Vec<usize>, bool) = if left.len() >= 3 && right.len() >= 3 {
        let mut c: Vec<usize> = left.iter().take(CONTEXT).copied().collect();
        c.extend(right.iter().take(CONTEXT));
        (c, true)
    } else if right.len() >= EDGE_FIT {
        (right, false)
    } else if left.len() >= EDGE_FIT {
        (left, false)
    } else {
        return None;
    };
    let offset = |j: usize| j as f64 - a as f64;
    let points: Vec<(f64, f64)> = context.iter().map(|&j| (offset(j), s[j])).collect();
    let mut values = Vec::with_capacity(b - a + 1);
    let mut gains = Vec::with_capacity(b - a + 1);
    for i in a..=b {
        values.push(cubic_fit_at(&points, offset(i))?);
        // The prediction's weights: the fit of each unit vector.
        let mut sum = 1.0;
        for k in 0..context.len() {
            let unit: Vec<(f64, f64)> = context
                .iter()
                .enumerate()
                .map(|(m, &j)| (offset(j), if m == k { 1.0 } else { 0.0 }))
                .collect();
            let w = cubic_fit_at(&unit, offset(i))?;
            sum += w * w;
        }
        gains.push(sum.sqrt());
    }
    Some(Fill {
        values,
        gains,
        both_sides,
    })
}

/// The largest |r − centre| of the centred residuals from `a − 2` to `b + 2` (and over the
/// whole `cluster`: a burst of 3 is not explained by a burst of 2 beside it) of `s` with
/// `a..=b` replaced by `values`, over the samples whose stencil is kept and evenly spaced;
/// `None` when there is none.
fn after_repair(
    s: &[f64],
    scan: &Scan,
    limit: &Limit,
    a: usize,
    values: &[f64],
    cluster: &Range<usize>,
) -> Option<f64> {
    let n = s.len();
    let b = a + values.len() - 1;
    let at = |j: usize| {
        if (a..=b).contains(&j) {
            values[j - a]
        } else {
            s[j]
        }
    };
    let usable = |i: usize| {
        i >= 2
            && i + 2 < n
            && (i - 2..=i + 2).all(|j| (a..=b).contains(&j) || (!scan.skip[j] && s[j].is_finite()))
            && (i - 1..=i + 2).all(|j| !scan.restart[j])
    };
    (a.min(cluster.start).saturating_sub(2)..=b.max(cluster.end - 1) + 2)
        .filter(|&i| usable(i))
        .map(|i| {
            let r =
                at(i) - (-(at(i - 2) / 6.0) + at(i - 1) / 1.5 + at(i + 1) / 1.5 - at(i + 2) / 6.0);
            limit.size(r)
        })
        .reduce(f64::max)
}

/// Whether the burst `a..=b` explains what is around it: its end samples beyond the limit
/// from the prediction, and the record with the prediction in its place clean from two
/// before to two after it. The fill and the largest residual after the repair.
fn explains(
    s: &[f64],
    scan: &Scan,
    limit: &Limit,
    cluster: &Range<usize>,
    a: usize,
    b: usize,
) -> Option<(Fill, f64)> {
    let fill = fill(s, scan, a, b)?;
    let unit = limit.limit / centred_gain();
    let beyond = |i: usize| {
        let k = i - a;
        (s[i] - fill.values[k]).abs() > unit * fill.gains[k]
    };
    if !(beyond(a) && beyond(b)) {
        return None;
    }
    let worst = after_repair(s, scan, limit, a, &fill.values, cluster)?;
    (worst <= limit.limit).then_some((fill, worst))
}

/// The bursts of one channel (see the module docs), among samples that `scan` keeps so far.
pub fn bursts(s: &[f64], scan: &Scan) -> Vec<Burst> {
    match Limit::of(&centred(s, scan), quantum(s) * centred_gain()) {
        Some(limit) => bursts_within(s, scan, &limit),
        None => Vec::new(),
    }
}

/// The bursts of one channel against a given limit of its centred residuals (a streamed
/// file's: the excerpt's, [`crate::identify::blemish::spike_limit`]).
pub(crate) fn bursts_within(s: &[f64], scan: &Scan, limit: &Limit) -> Vec<Burst> {
    let n = s.len();
    let r = centred(s, scan);
    let candidates: Vec<usize> = (0..n)
        .filter(|&i| r[i].is_some_and(|v| limit.size(v) > limit.limit))
        .collect();
    let mut clusters: Vec<Range<usize>> = Vec::new();
    for &i in &candidates {
        match clusters.last_mut() {
            // At most 4 apart: a burst of 5 of height h moves them by h/2, h/2, h/6, 0, h/6,
            // h/2, h/2.
            Some(c) if i <= c.end + 3 => c.end = i + 1,
            _ => clusters.push(i..i + 1),
        }
    }
    let mut out: Vec<Burst> = Vec::new();
    for c in clusters {
        if c.len() > BURST_MAX + 6 {
            continue;
        }
        // A burst moves the residuals from two before to two after it, and only some of
        // them may be beyond the limit (a burst of 3 of height h: h/6, h/2, h/2, h/3, h/2,
        // h/2, h/6), so it may start up to BURST_MAX + 1 before the cluster's first.
        let first = c.start.saturating_sub(BURST_MAX + 1);
        let last = (c.end + BURST_MAX).min(n - 1);
        let mut found: Option<(usize, Fill, f64)> = None;
        let mut shortest = 0;
        for k in 1..=BURST_MAX {
            for a in first..=last {
                let b = a + k - 1;
                if b > last {
                    break;
                }
                if let Some((fill, worst)) = explains(s, scan, limit, &c, a, b)
                    && found.as_ref().is_none_or(|f| worst < f.2)
                {
                    found = Some((a, fill, worst));
                }
            }
            if found.is_some() {
                shortest = k;
                break;
            }
        }
        let Some((a, fill, _)) = found else {
            continue;
        };
        if shortest < 2 {
            // A spike: the spike rule's.
            continue;
        }
        if out.last().is_some_and(|o| o.rows.end > a) {
            continue;
        }
        out.push(Burst {
            rows: a..a + shortest,
            repair: fill.both_sides.then_some(fill.values),
        });
    }
    out
}
