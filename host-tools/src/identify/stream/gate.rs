//! The quality gate over a whole streamed file ([`crate::identify::quality`]), from what one
//! pass keeps: the file's model in both precisions (two identifiers fed the same samples)
//! and the blocks of [`super::sketch`], spread over the whole file.
//!
//! - Over the whole file: the held-out error of the file's model (the identifier's, over
//!   every row) against the variance of its target pooled over the kept blocks, and the other
//!   precision's choice of terms (the file's other identifier).
//! - On each kept block, as on a recording in memory: x varies, the free run stays bounded,
//!   the short-horizon simulation follows the block, the terms are not collinear on it, it is
//!   not a sweep. A block that fails withholds the model, its time span named: the file's
//!   model must explain every part of it that the gate sees, not only the first rows.
//! - The file's last rows on their own: the second half of the last block (which always ends
//!   at the file's last row), judged as a block. A break in only the file's last few per cent
//!   fills part of the last block, and the block's median window passed it; its last half
//!   is mostly broken.
//! - A sensor stuck at one value ([`crate::identify::blemish`]) past the excerpt: the stream
//!   fed those rows to the identifier (only the excerpt's stuck rows are left out), so the
//!   model is withheld, the stuck rows named.

use lssi_core::Config;

use super::sketch::Block;
use crate::identify::quality::{self, MAX_UNEXPLAINED, Quality};
use crate::identify::{Reference, Report};

/// Failing blocks named one by one in the verdict (the first ones and the last; then how many
/// more).
const NAMED_BLOCKS: usize = 2;

/// Where a block lies: "t = a–b s (rows i–j)".
fn span(block: &Block) -> String {
    let t = &block.rows.t;
    let first = t
        .iter()
        .copied()
        .find(|v| v.is_finite())
        .unwrap_or(f64::NAN);
    let last = t
        .iter()
        .rev()
        .copied()
        .find(|v| v.is_finite())
        .unwrap_or(f64::NAN);
    format!(
        "t = {first}–{last} s (data rows {}–{})",
        block.first_row + 1,
        block.first_row + block.rows.len()
    )
}

/// The second half of a block (its last rows), as a block; `None` when it is too short to
/// judge.
fn last_half(block: &Block) -> Option<Block> {
    let rows = &block.rows;
    let n = rows.t.len();
    if n < 512 {
        return None;
    }
    let from = n / 2;
    Some(Block {
        first_row: block.first_row + from,
        rows: crate::recording::Recording {
            path: rows.path.clone(),
            t: rows.t[from..].to_vec(),
            x: rows.x[from..].to_vec(),
            v: rows.v.as_ref().map(|v| v[from..].to_vec()),
            u: rows.u.as_ref().map(|u| u[from..].to_vec()),
            columns: rows.columns.clone(),
        },
    })
}

/// The gate over the whole file: see the module docs. `report` and `other` are the file's
/// models (in the precision asked for and the other one) before the reference is put back,
/// `reference` what was subtracted from every sample.
pub(super) fn judge(
    blocks: &[Block],
    config: &Config,
    report: &Report,
    other: Option<&Report>,
    reference: Reference,
) -> Quality {
    let mut quality = Quality {
        unexplained: None,
        stable: None,
        precisions_agree: None,
        failures: Vec::new(),
        simulation_failures: 0,
    };
    if report.terms.is_empty() {
        quality
            .failures
            .push("the selected model has no terms".into());
        return quality;
    }
    // Each block: the in-memory checks that need the signal itself (the held-out check is
    // the whole file's, below; the precisions are compared once). One block less the
    // reference at a time: the blocks are not copied.
    let local = Report {
        solutions: Vec::new(),
        ..report.clone()
    };
    let mut failing = Vec::new();
    let (mut pooled, mut weight) = (0.0, 0.0);
    let last_rows = blocks.last().and_then(last_half);
    for block in blocks {
        let shifted = reference.shifted(&block.rows);
        let rows = shifted.as_ref().unwrap_or(&block.rows);
        // The target's variance pooled over the blocks (within each block: the target, x''
        // over a few periods, has a mean near 0 in each).
        if let Some(variance) = quality::target_variance(rows, config) {
            pooled += variance * rows.len() as f64;
            weight += rows.len() as f64;
        }
        if block.first_row > 0 {
            let scan = crate::identify::blemish::Scan::of(rows);
            for b in scan
                .blemishes
                .iter()
                .filter(|b| b.kind == crate::identify::blemish::Kind::Stuck)
            {
                quality.failures.push(format!(
                    "{} is stuck at {} over data rows {}–{} (t = {}–{} s; a sensor that froze, or a logger repeating its last reading), which the streamed model was fitted with: cut them out",
                    b.channel,
                    b.value,
                    block.first_row + b.index + 1,
                    block.first_row + b.index + b.rows,
                    b.t,
                    b.t_end
                ));
            }
        }
        let q = quality::assess(rows, config, &local, None);
        if let Some(stable) = q.stable {
            quality.stable = Some(quality.stable.unwrap_or(true) && stable);
        }
        if !q.failures.is_empty() {
            failing.push(format!("at {}: {}", span(block), q.failures.join("; ")));
        }
    }
    // The file's last rows on their own (named unless the whole last block failed already).
    if let Some(block) = &last_rows {
        let shifted = reference.shifted(&block.rows);
        let rows = shifted.as_ref().unwrap_or(&block.rows);
        let q = quality::assess(rows, config, &local, None);
        if let Some(stable) = q.stable {
            quality.stable = Some(quality.stable.unwrap_or(true) && stable);
        }
        let last_failed = blocks.last().is_some_and(|b| {
            failing
                .last()
                .is_some_and(|f| f.starts_with(&format!("at {}:", span(b))))
        });
        if !q.failures.is_empty() && !last_failed {
            failing.push(format!(
                "at the file's last rows, {}: {}",
                span(block),
                q.failures.join("; ")
            ));
        }
    }
    // The whole file: held-out error (over every row) against the target's variance on the
    // blocks spread over it.
    let held_out = report.solutions.get(report.selected).map(|s| s.mean_error);
    let variance = (weight > 0.0).then(|| pooled / weight);
    quality.unexplained = held_out.zip(variance).map(|(e, var)| e / var);
    if let Some(r) = quality.unexplained
        && !(r <= MAX_UNEXPLAINED)
    {
        quality.failures.push(format!(
            "the model leaves {:.0} % of the variance of x'' unexplained on held-out data over the whole file (at most {:.0} % allowed)",
            100.0 * r,
            100.0 * MAX_UNEXPLAINED
        ));
    }
    if let Some(other) = other {
        let names = |r: &Report| r.terms.iter().map(|t| t.term.clone()).collect::<Vec<_>>();
        let agree = names(report) == names(other);
        quality.precisions_agree = Some(agree);
        if !agree {
            quality.failures.push(format!(
                "{} selects {} but {} selects {}",
                report.precision,
                names(report).join(", "),
                other.precision,
                names(other).join(", ")
            ));
        }
    }
    // The first and the last failing blocks named (the last is nearest where a recording
    // broke off), then how many more.
    let more = failing.len().saturating_sub(NAMED_BLOCKS);
    let checked = blocks.len();
    if more > 0 {
        let last = failing.pop();
        quality
            .failures
            .extend(failing.into_iter().take(NAMED_BLOCKS - 1));
        quality.failures.extend(last);
        quality.failures.push(format!(
            "and {more} more of the {checked} stretches the gate checked fail"
        ));
    } else {
        quality.failures.extend(failing);
    }
    quality
}
