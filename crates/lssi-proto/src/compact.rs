//! Compact samples: i16 fixed point on a uniform time grid, negotiated in `Configure`
//! ([`WireConfig::encoding`](crate::WireConfig)), and the model sent in parts.
//!
//! With [`SampleEncoding::I16`] a sample is its grid index and one `i16` per channel: the
//! time is `t0 + index · dt` (f64, computed the same way on both sides) and a value is
//! `q · scale` (f32, one scale per channel); `q = i16::MIN` stands for a value that is not a
//! number (NaN or infinite on the host), which the device receives as NaN and rejects as
//! `lssi identify` rejects it. A [`CompactBatch`] holds up to [`MAX_COMPACT_BATCH`]
//! consecutive grid points: its first index, then 2 bytes per channel per sample (little
//! endian), no per-sample time. An x-only sample costs 2 bytes instead of 12.
//!
//! ```
//! # #[cfg(feature = "std")] {
//! use lssi_proto::{Channels, CompactBatch, I16Encoding, HostMsg, encode, decode_host_frame,
//!                  HostCommand, MAX_HOST_FRAME_LEN};
//!
//! let enc = I16Encoding { t0: 0.0, dt: 1e-3, scale: [1e-4, 1.0, 1.0] };
//! let mut batch = CompactBatch::new(0, 100, Channels::X);
//! batch.push(&[enc.quantise(0.25, 0)]).unwrap();
//! let mut frame = [0u8; MAX_HOST_FRAME_LEN];
//! let len = encode(&HostMsg::Compact(batch), &mut frame).unwrap();
//! let HostCommand::Compact(batch) = decode_host_frame(&mut frame[..len - 1]).unwrap() else {
//!     panic!()
//! };
//! let sample = batch.samples(&enc).next().unwrap();
//! assert_eq!((sample.t, sample.x), (0.1, 2500.0 * 1e-4));
//! # }
//! ```

use crate::size::{varint_len, vec_max_size};
use crate::{Channels, ModelSnapshot, WireSample};
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

/// Most samples in one [`CompactBatch`]: 64 samples of x, v and u are 384 bytes, so the
/// host frame stays under 512 bytes.
pub const MAX_COMPACT_BATCH: usize = 64;
/// Most value bytes in one [`CompactBatch`].
pub const MAX_COMPACT_BYTES: usize = MAX_COMPACT_BATCH * 2 * 3;
/// Most snapshot bytes in one [`DeviceMsg::ModelPart`](crate::DeviceMsg::ModelPart): short
/// enough that a part crosses a line that damages 2 % of its bytes more often than not.
pub const MODEL_PART_LEN: usize = 24;

/// How sample batches travel, chosen by the host in `Configure`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SampleEncoding {
    /// [`HostMsg::Samples`](crate::HostMsg::Samples): t as f64, the channels as f32.
    F32,
    /// [`HostMsg::Compact`](crate::HostMsg::Compact): i16 fixed point on a time grid.
    I16(I16Encoding),
}

/// The parameters of [`SampleEncoding::I16`]: the time grid and one scale per channel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct I16Encoding {
    /// Time of grid index 0, in seconds.
    pub t0: f64,
    /// Grid step in seconds.
    pub dt: f64,
    /// Value of one quantum of x, v and u.
    pub scale: [f32; 3],
}

/// The `q` that stands for a value that is not a number.
pub const NOT_A_NUMBER: i16 = i16::MIN;

impl I16Encoding {
    /// The time of grid point `index`: `t0 + index · dt` in f64.
    pub fn time(&self, index: u32) -> f64 {
        self.t0 + f64::from(index) * self.dt
    }

    /// The value of `q` quanta of channel `channel` (0 = x, 1 = v, 2 = u): `q · scale` in f32,
    /// NaN for [`NOT_A_NUMBER`].
    pub fn value(&self, q: i16, channel: usize) -> f32 {
        if q == NOT_A_NUMBER {
            return f32::NAN;
        }
        let scale = self.scale.get(channel).copied().unwrap_or(0.0);
        f32::from(q) * scale
    }

    /// `value` rounded to the nearest quantum of `channel`, saturating at ±32767;
    /// [`NOT_A_NUMBER`] for NaN and infinities (a host's job: with the `std` feature).
    #[cfg(any(test, feature = "std"))]
    pub fn quantise(&self, value: f64, channel: usize) -> i16 {
        let scale = f64::from(self.scale.get(channel).copied().unwrap_or(0.0));
        let q = (value / scale).round();
        if !q.is_finite() || !value.is_finite() {
            return NOT_A_NUMBER;
        }
        // In range after the clamp: the cast is exact.
        q.clamp(-32767.0, 32767.0) as i16
    }
}

/// Up to [`MAX_COMPACT_BATCH`] consecutive grid points under one sequence number (the
/// compact [`SampleBatch`](crate::SampleBatch)): numbered, applied and acknowledged alike.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CompactBatch {
    /// Sequence number of the batch.
    pub seq: u32,
    /// Grid index of the first sample.
    pub start: u32,
    /// Which channels follow x in every sample.
    pub channels: Channels,
    /// The values, sample after sample, x then v and u if present, i16 little endian.
    values: heapless::Vec<u8, MAX_COMPACT_BYTES>,
}

impl CompactBatch {
    /// An empty batch numbered `seq` starting at grid index `start`.
    pub const fn new(seq: u32, start: u32, channels: Channels) -> Self {
        Self {
            seq,
            start,
            channels,
            values: heapless::Vec::new(),
        }
    }

    /// Appends a sample (its quanta: x, then v and u as the channels say); gives it back
    /// when the batch is full or it has the wrong number of values.
    pub fn push<'a>(&mut self, quanta: &'a [i16]) -> Result<(), &'a [i16]> {
        let width = self.channels.values_per_sample() - 1;
        if quanta.len() != width || self.values.len() + 2 * width > self.values.capacity() {
            return Err(quanta);
        }
        for q in quanta {
            // Cannot fail: room checked above.
            let _ = self.values.extend_from_slice(&q.to_le_bytes());
        }
        Ok(())
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.values.len() / (2 * (self.channels.values_per_sample() - 1))
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The same batch read in place.
    pub fn as_ref(&self) -> CompactRef<'_> {
        CompactRef {
            seq: self.seq,
            start: self.start,
            channels: self.channels,
            values: &self.values,
        }
    }
}

impl MaxSize for CompactBatch {
    const POSTCARD_MAX_SIZE: usize = 2 * u32::POSTCARD_MAX_SIZE
        + Channels::POSTCARD_MAX_SIZE
        + vec_max_size::<u8>(MAX_COMPACT_BYTES);
}

/// A [`CompactBatch`] read in place from a received frame.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
pub struct CompactRef<'a> {
    /// Sequence number of the batch.
    pub seq: u32,
    /// Grid index of the first sample.
    pub start: u32,
    /// Which channels follow x in every sample.
    pub channels: Channels,
    values: &'a [u8],
}

impl<'a> CompactRef<'a> {
    /// Number of whole samples.
    pub fn len(&self) -> usize {
        self.values.len() / (2 * (self.channels.values_per_sample() - 1))
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the values are whole samples and at most [`MAX_COMPACT_BATCH`] of them.
    pub fn is_well_formed(&self) -> bool {
        let width = 2 * (self.channels.values_per_sample() - 1);
        self.values.len().is_multiple_of(width) && self.values.len() <= MAX_COMPACT_BYTES
    }

    /// The same batch as a [`CompactBatch`] (a copy).
    pub fn to_batch(&self) -> CompactBatch {
        CompactBatch {
            seq: self.seq,
            start: self.start,
            channels: self.channels,
            values: heapless::Vec::from_slice(self.values).unwrap_or_default(),
        }
    }

    /// The samples as the device applies them, dequantised with `encoding`.
    pub fn samples(self, encoding: &I16Encoding) -> impl Iterator<Item = WireSample> + 'a {
        let encoding = *encoding;
        let channels = self.channels;
        let width = 2 * (channels.values_per_sample() - 1);
        let start = self.start;
        self.values
            .chunks_exact(width.max(2))
            .zip(0u32..)
            .map(move |(bytes, k)| {
                let q = |i: usize| {
                    let b = bytes.get(2 * i..2 * i + 2).unwrap_or(&[0, 0]);
                    i16::from_le_bytes([
                        b.first().copied().unwrap_or(0),
                        b.get(1).copied().unwrap_or(0),
                    ])
                };
                let mut next = 1;
                let mut channel = |present: bool, index: usize| {
                    present.then(|| {
                        let value = encoding.value(q(next), index);
                        next += 1;
                        value
                    })
                };
                let v = channel(channels.has_v(), 1);
                let u = channel(channels.has_u(), 2);
                WireSample {
                    t: encoding.time(start.wrapping_add(k)),
                    x: encoding.value(q(0), 0),
                    v,
                    u,
                }
            })
    }
}

/// One part of the current model's postcard bytes (the host asks with
/// [`HostMsg::ModelPart`](crate::HostMsg::ModelPart) when a whole `Model` frame does not cross).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModelPart {
    /// Length of the whole snapshot's postcard bytes.
    pub total: u16,
    /// Offset of `bytes` in them.
    pub offset: u16,
    /// CRC-32C of the whole snapshot's bytes: parts of different models do not mix.
    pub crc: u32,
    /// The bytes (empty past the end).
    pub bytes: heapless::Vec<u8, MODEL_PART_LEN>,
}

impl MaxSize for ModelPart {
    const POSTCARD_MAX_SIZE: usize = 2 * u16::POSTCARD_MAX_SIZE
        + u32::POSTCARD_MAX_SIZE
        + varint_len(MODEL_PART_LEN)
        + MODEL_PART_LEN;
}

/// Part `offset..` of `snapshot`'s postcard bytes, encoded in `scratch` (at least
/// `ModelSnapshot::POSTCARD_MAX_SIZE` bytes); `None` if it does not encode there.
pub fn model_part(snapshot: &ModelSnapshot, offset: u16, scratch: &mut [u8]) -> Option<ModelPart> {
    let bytes = postcard::to_slice(snapshot, scratch).ok()?;
    let total = u16::try_from(bytes.len()).ok()?;
    let from = usize::from(offset).min(bytes.len());
    let to = (from + MODEL_PART_LEN).min(bytes.len());
    Some(ModelPart {
        total,
        offset,
        crc: crc32c(bytes),
        bytes: heapless::Vec::from_slice(bytes.get(from..to)?).ok()?,
    })
}

/// The snapshot from its reassembled postcard bytes, checked against the parts' CRC.
pub fn snapshot_from_parts(bytes: &[u8], crc: u32) -> Option<ModelSnapshot> {
    if crc32c(bytes) != crc {
        return None;
    }
    postcard::from_bytes(bytes).ok()
}

/// CRC-32C of `bytes` (the frames' CRC).
pub fn crc32c(bytes: &[u8]) -> u32 {
    crate::frame::CRC32C.checksum(bytes)
}
