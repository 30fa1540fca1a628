//! The record's longest clean stretch and x's RMS over parts of it: what the gate's checks
//! of a record's oscillation (its cycles, [`crate::identify::orbit`]; its quarters,
//! [`crate::identify::sweep`] and [`crate::identify::quality`]) measure it on. Each had its
//! own copy of these lines.

use std::ops::Range;

use crate::identify::blemish::Scan;
use crate::recording::Recording;

/// The recording's longest clean stretch ([`Scan::stretches`]): `None` when every sample is
/// left out.
pub fn longest(recording: &Recording) -> Option<Range<usize>> {
    Scan::of(recording)
        .stretches()
        .into_iter()
        .max_by_key(|r| r.len())
}

/// The mean of `s` (NaN when empty).
pub fn mean(s: &[f64]) -> f64 {
    s.iter().sum::<f64>() / s.len() as f64
}

/// The RMS of `s` about its mean, its standard deviation (NaN when empty).
pub fn rms(s: &[f64]) -> f64 {
    let m = mean(s);
    (s.iter().map(|v| (v - m).powi(2)).sum::<f64>() / s.len() as f64).sqrt()
}

/// x's RMS about its mean over the first and the last quarter of the record's longest clean
/// stretch (`None` when a quarter is under 16 samples).
pub fn quarters_rms(recording: &Recording) -> Option<(f64, f64)> {
    let x = &recording.x[longest(recording)?];
    let quarter = x.len() / 4;
    if quarter < 16 {
        return None;
    }
    Some((rms(&x[..quarter]), rms(&x[x.len() - quarter..])))
}

/// x's RMS about `mean` over each of the cycles between the samples `ends` (each from one
/// end to the next).
pub fn cycles_rms(x: &[f64], ends: &[usize], mean: f64) -> Vec<f64> {
    ends.windows(2)
        .map(|w| {
            let c = &x[w[0]..w[1]];
            (c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / c.len() as f64).sqrt()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rms_is_the_standard_deviation_and_cycles_split_it() {
        let x = [1.0, -1.0, 1.0, -1.0, 3.0, -3.0];
        assert!((mean(&x) - 0.0).abs() < 1e-15);
        assert!((rms(&x) - (22.0f64 / 6.0).sqrt()).abs() < 1e-12);
        let each = cycles_rms(&x, &[0, 2, 4, 6], 0.0);
        assert_eq!(each, vec![1.0, 1.0, 3.0]);
    }
}
