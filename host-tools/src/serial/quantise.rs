//! The compact sample encoding's quantisation (`lssi replay --encoding i16`,
//! `lssi identify --quantise i16`): every time put on a uniform grid, every value rounded to
//! an i16 number of quanta, one scale per channel.
//!
//! The quantisation is part of the recording: what the device receives is exactly
//! [`Quantised::recording`] (times `t0 + k·dt` in f64, values `q·scale` in f32, held as f64),
//! so `lssi identify --quantise i16` (which identifies that recording) is what a replay in
//! the compact encoding must equal, bit for bit.

use lssi_proto::{
    Channels, CompactBatch, HostMsg, I16Encoding, MAX_COMPACT_BATCH, MAX_HOST_FRAME_LEN,
    NOT_A_NUMBER, encode,
};
use serde::Serialize;

use crate::recording::Recording;
use crate::serial::link::BatchSource;

/// Largest number of quanta a value may have (±32767; −32768 stands for not a number).
const FULL_SCALE: f64 = 32767.0;

/// A recording quantised for the compact encoding.
#[derive(Clone, Debug)]
pub struct Quantised {
    /// The grid and the scales, as `Configure` carries them.
    pub encoding: I16Encoding,
    /// The channels after x.
    pub channels: Channels,
    /// Grid index of each sample (strictly increasing).
    pub index: Vec<u32>,
    /// Quanta of each sample: x, then v and u when present.
    pub quanta: Vec<[i16; 3]>,
    /// The recording as the device receives it.
    pub recording: Recording,
    /// What the quantisation did, for the report.
    pub summary: Quantisation,
}

/// What the quantisation did to the recording (`"quantisation"` in `lssi replay --json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Quantisation {
    /// The encoding's name: `"i16"`.
    pub encoding: &'static str,
    /// Grid step in seconds.
    pub dt: f64,
    /// Value of one quantum of x, v and u (absent channels: null).
    pub scale: [Option<f32>; 3],
    /// Largest |recorded − received| of x, v and u over the finite values.
    pub max_error: [Option<f64>; 3],
    /// Largest |recorded − received| time, seconds.
    pub max_time_error: f64,
}

impl Quantisation {
    /// One line for the human output.
    pub fn render(&self) -> String {
        let names = ["x", "v", "u"];
        let channels: Vec<String> = (0..3)
            .filter_map(|i| {
                let scale = self.scale[i]?;
                let error = self.max_error[i].unwrap_or(0.0);
                Some(format!(
                    "{} scale {scale:e} (max error {error:.3e})",
                    names[i]
                ))
            })
            .collect();
        format!(
            "quantised: samples as {} ({}), times on a {:e} s grid (max error {:.3e} s); the model is that of the quantised recording (lssi identify --quantise i16)\n",
            self.encoding,
            channels.join(", "),
            self.dt,
            self.max_time_error
        )
    }
}

/// Quantises `recording` for the compact encoding, or says in a sentence why it cannot be
/// (times that are not finite, or not increasing on a grid).
pub fn quantise(recording: &Recording) -> Result<Quantised, String> {
    let file = recording.path.display();
    let t = &recording.t;
    if t.len() < 2 {
        return Err(format!("{file}: too few samples for the compact encoding."));
    }
    if let Some(i) = t.iter().position(|t| !t.is_finite()) {
        return Err(format!(
            "{file}: row {} has no finite time, so the compact encoding (times on a grid) cannot carry it; use --encoding f32.",
            i + 1
        ));
    }
    // The grid step: the median interval, then stretched so the last sample lies on it.
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let median = steps[steps.len() / 2];
    if !(median > 0.0) {
        return Err(format!(
            "{file}: the times do not increase, so the compact encoding cannot carry them; use --encoding f32."
        ));
    }
    let t0 = t[0];
    let last = ((t[t.len() - 1] - t0) / median).round();
    if !(last > 0.0 && last < f64::from(u32::MAX)) {
        return Err(format!(
            "{file}: the recording spans more grid steps than the compact encoding counts; use --encoding f32."
        ));
    }
    let dt = (t[t.len() - 1] - t0) / last;
    let columns: [Option<&[f64]>; 3] = [
        Some(&recording.x),
        recording.v.as_deref(),
        recording.u.as_deref(),
    ];
    let mut scale = [1.0f32; 3];
    for (slot, column) in scale.iter_mut().zip(columns) {
        let peak = column
            .into_iter()
            .flatten()
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max(v.abs()));
        if peak > 0.0 {
            *slot = (peak / FULL_SCALE) as f32;
            // The f32 rounding must not push the peak past full scale.
            while peak / f64::from(*slot) > FULL_SCALE + 0.5 {
                *slot = f32::from_bits(slot.to_bits() + 1);
            }
        }
    }
    let encoding = I16Encoding { t0, dt, scale };
    let channels = Channels::new(recording.v.is_some(), recording.u.is_some());

    let mut index = Vec::with_capacity(t.len());
    let mut max_time_error = 0.0f64;
    for (i, &time) in t.iter().enumerate() {
        let k = ((time - t0) / dt).round();
        let previous = index.last().map_or(-1.0, |&k: &u32| f64::from(k));
        if !(k > previous) || k > f64::from(u32::MAX) {
            return Err(format!(
                "{file}: row {} (t = {time}) falls on the same point of the {dt:e} s grid as the row before, so the compact encoding cannot carry it; use --encoding f32.",
                i + 1
            ));
        }
        // In range: checked above.
        let k = k as u32;
        max_time_error = max_time_error.max((encoding.time(k) - time).abs());
        index.push(k);
    }

    let mut quanta = Vec::with_capacity(t.len());
    let mut received: [Vec<f64>; 3] = Default::default();
    let mut max_error: [Option<f64>; 3] = [None; 3];
    for i in 0..t.len() {
        let mut q = [0i16; 3];
        for (c, column) in columns.iter().enumerate() {
            let Some(column) = column else { continue };
            let value = column[i];
            q[c] = encoding.quantise(value, c);
            let back = encoding.value(q[c], c);
            if value.is_finite() && q[c] != NOT_A_NUMBER {
                let error = (f64::from(back) - value).abs();
                max_error[c] = Some(max_error[c].map_or(error, |m: f64| m.max(error)));
            }
            received[c].push(f64::from(back));
        }
        quanta.push(q);
    }
    let [x, v, u] = received;
    let recording = Recording {
        t: index.iter().map(|&k| encoding.time(k)).collect(),
        x,
        v: recording.v.is_some().then_some(v),
        u: recording.u.is_some().then_some(u),
        ..recording.clone()
    };
    let present = [true, channels.has_v(), channels.has_u()];
    let summary = Quantisation {
        encoding: "i16",
        dt,
        scale: std::array::from_fn(|c| present[c].then_some(scale[c])),
        max_error: std::array::from_fn(|c| {
            if present[c] {
                max_error[c].or(Some(0.0))
            } else {
                None
            }
        }),
        max_time_error,
    };
    Ok(Quantised {
        encoding,
        channels,
        index,
        quanta,
        recording,
        summary,
    })
}

impl Quantised {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// The batch numbered `seq` of at most `max` samples from sample `from`: consecutive grid
    /// points only (a gap in the recording ends the batch). Returns it and how many samples
    /// it took (at least one when `from` is a sample).
    pub fn batch(&self, seq: u32, from: usize, max: usize) -> (CompactBatch, usize) {
        let max = max.clamp(1, MAX_COMPACT_BATCH);
        let start = self.index.get(from).copied().unwrap_or(0);
        let mut batch = CompactBatch::new(seq, start, self.channels);
        let width = self.channels.values_per_sample() - 1;
        let mut taken = 0;
        while taken < max && from + taken < self.len() {
            let i = from + taken;
            if self.index[i] != start.wrapping_add(taken as u32) {
                break;
            }
            if batch.push(&self.quanta[i][..width]).is_err() {
                break;
            }
            taken += 1;
        }
        (batch, taken)
    }
}

impl BatchSource for Quantised {
    fn len(&self) -> usize {
        self.index.len()
    }

    fn max_batch(&self) -> usize {
        MAX_COMPACT_BATCH
    }

    fn bytes_per_sample(&self) -> usize {
        2 * (self.channels.values_per_sample() - 1)
    }

    fn frame(&self, seq: u32, from: usize, max: usize) -> (Vec<u8>, usize) {
        let (batch, taken) = self.batch(seq, from, max);
        let mut frame = vec![0u8; MAX_HOST_FRAME_LEN];
        let len = encode(&HostMsg::Compact(batch), &mut frame).unwrap_or(0);
        frame.truncate(len);
        (frame, taken)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::ColumnNames;

    fn recording(t: Vec<f64>, x: Vec<f64>) -> Recording {
        Recording {
            path: "r.csv".into(),
            t,
            x,
            v: None,
            u: None,
            columns: ColumnNames::default(),
        }
    }

    #[test]
    fn values_round_to_the_nearest_quantum_and_times_to_the_grid() {
        let t: Vec<f64> = (0..100).map(|i| f64::from(i) * 0.1).collect();
        let x: Vec<f64> = (0..100)
            .map(|i| (f64::from(i) * 0.37).sin() * 2e-3)
            .collect();
        let q = quantise(&recording(t.clone(), x.clone())).unwrap();
        let scale = f64::from(q.encoding.scale[0]);
        for i in 0..100 {
            assert!((q.recording.x[i] - x[i]).abs() <= 0.51 * scale);
            assert!((q.recording.t[i] - t[i]).abs() < 1e-12);
            assert_eq!(q.recording.x[i], f64::from(q.recording.x[i] as f32));
        }
        let peak = q.quanta.iter().map(|s| s[0].unsigned_abs()).max().unwrap();
        assert!(peak >= 32760, "full scale used: {peak}");
        assert!(q.summary.max_error[0].unwrap() <= 0.51 * scale);
    }

    #[test]
    fn a_gap_ends_a_batch_and_nan_crosses_as_nan() {
        let t = vec![0.0, 1.0, 2.0, 5.0, 6.0, 7.0];
        let x = vec![1.0, f64::NAN, 3.0, 4.0, 5.0, 6.0];
        let q = quantise(&recording(t, x)).unwrap();
        assert_eq!(q.index, vec![0, 1, 2, 5, 6, 7]);
        assert!(q.recording.x[1].is_nan());
        let (batch, taken) = q.batch(0, 0, 64);
        assert_eq!((batch.len(), taken), (3, 3));
        let (batch, taken) = q.batch(1, 3, 2);
        assert_eq!((batch.start, taken), (5, 2));
    }

    #[test]
    fn two_rows_on_one_grid_point_are_refused() {
        let t = vec![0.0, 1.0, 1.1, 2.0, 3.0];
        let error = quantise(&recording(t, vec![0.0; 5])).unwrap_err();
        assert!(error.contains("row 3"), "{error}");
    }
}
