//! A batch of samples, carrying only the channels the recording has.
//!
//! ```
//! use lssi_proto::{Channels, SampleBatch, WireSample, MAX_BATCH};
//!
//! let mut batch = SampleBatch::new(0, Channels::X);
//! let mut next = 0;
//! for i in 0..100u32 {
//!     let sample = WireSample { t: f64::from(i) * 1e-3, x: 0.5, v: None, u: None };
//!     if let Err(sample) = batch.push(sample) {
//!         // Full (or the channels changed): send this batch, start the next with `sample`.
//!         next += 1;
//!         batch = SampleBatch::new(next, Channels::of(&sample));
//!         batch.push(sample).unwrap();
//!     }
//! }
//! assert_eq!(batch.len(), 100 % MAX_BATCH);
//! assert_eq!(batch.iter().next().map(|s| s.t), Some(96e-3));
//! ```
//!
//! On the wire a sample is a postcard tuple of exactly the present channels: `t` as 8 bytes,
//! then `x`, and `v`, `u` if the batch's [`Channels`] say so, 4 bytes each (IEEE 754, little
//! endian, bit for bit). An x-only sample is 12 bytes, with no per-sample tag.

mod codec;
mod in_place;

pub(crate) use in_place::BatchHeader;
pub use in_place::{BatchRef, BatchSamples};

use crate::MAX_BATCH;
use crate::size::varint_len;
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Deserializer, Serialize, Serializer, de};

/// One sample as it crosses the link.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireSample {
    /// Time in seconds; the device sees exactly these 64 bits.
    pub t: f64,
    /// Displacement.
    pub x: f32,
    /// Measured velocity, when the recording has one.
    pub v: Option<f32>,
    /// Measured excitation, when the recording has one.
    pub u: Option<f32>,
}

/// Which optional channels every sample of a batch carries; `t` and `x` always travel.
///
/// On the wire: one byte, bit 0 = v, bit 1 = u; other bits set are a decode error.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Channels(u8);

impl Channels {
    /// Bit of the velocity channel.
    pub const V_BIT: u8 = 0b01;
    /// Bit of the excitation channel.
    pub const U_BIT: u8 = 0b10;
    /// t and x only.
    pub const X: Channels = Channels(0);
    /// t, x and v.
    pub const XV: Channels = Channels(Self::V_BIT);
    /// t, x and u.
    pub const XU: Channels = Channels(Self::U_BIT);
    /// t, x, v and u.
    pub const XVU: Channels = Channels(Self::V_BIT | Self::U_BIT);

    /// The channels with v and/or u present.
    pub const fn new(v: bool, u: bool) -> Self {
        let v = if v { Self::V_BIT } else { 0 };
        let u = if u { Self::U_BIT } else { 0 };
        Channels(v | u)
    }

    /// The channels `sample` has.
    pub const fn of(sample: &WireSample) -> Self {
        Self::new(sample.v.is_some(), sample.u.is_some())
    }

    /// The channels of a mask byte; `None` if it has bits other than v and u.
    pub const fn from_bits(bits: u8) -> Option<Self> {
        if bits & !(Self::V_BIT | Self::U_BIT) == 0 {
            Some(Channels(bits))
        } else {
            None
        }
    }

    /// The mask byte.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// Whether samples carry v.
    pub const fn has_v(self) -> bool {
        self.0 & Self::V_BIT != 0
    }

    /// Whether samples carry u.
    pub const fn has_u(self) -> bool {
        self.0 & Self::U_BIT != 0
    }

    /// Number of values per sample on the wire: t, x and the optional channels.
    pub const fn values_per_sample(self) -> usize {
        2 + self.has_v() as usize + self.has_u() as usize
    }

    /// Wire bytes per sample (postcard, before framing): 12, 16 or 20.
    pub const fn bytes_per_sample(self) -> usize {
        8 + 4 * (self.values_per_sample() - 1)
    }
}

impl Serialize for Channels {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_u8(self.0)
    }
}

impl<'de> Deserialize<'de> for Channels {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let bits = u8::deserialize(deserializer)?;
        Channels::from_bits(bits).ok_or_else(|| {
            de::Error::invalid_value(
                de::Unexpected::Unsigned(u64::from(bits)),
                &"a channel mask with only bit 0 (v) and bit 1 (u)",
            )
        })
    }
}

impl MaxSize for Channels {
    const POSTCARD_MAX_SIZE: usize = 1;
}

/// A sample as the batch stores it: absent channels hold 0.0 and are not sent.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Record {
    t: f64,
    x: f32,
    v: f32,
    u: f32,
}

/// Up to [`MAX_BATCH`] samples with the same [`Channels`], under one sequence number.
///
/// The device applies each `seq` once, in order, and acks it; the host resends the same
/// batch (same `seq`) on a nak or a timeout.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SampleBatch {
    /// Sequence number of the batch.
    pub seq: u32,
    channels: Channels,
    records: heapless::Vec<Record, MAX_BATCH>,
}

impl SampleBatch {
    /// An empty batch numbered `seq` whose samples will carry `channels`.
    pub const fn new(seq: u32, channels: Channels) -> Self {
        Self {
            seq,
            channels,
            records: heapless::Vec::new(),
        }
    }

    /// Appends `sample`, or hands it back if the batch is full or the sample's channels are
    /// not the batch's; either way the batch is ready to send and the sample starts the next.
    pub fn push(&mut self, sample: WireSample) -> Result<(), WireSample> {
        if Channels::of(&sample) != self.channels {
            return Err(sample);
        }
        let record = Record {
            t: sample.t,
            x: sample.x,
            v: sample.v.unwrap_or(0.0),
            u: sample.u.unwrap_or(0.0),
        };
        self.records.push(record).map_err(|_| sample)
    }

    /// The channels every sample carries.
    pub const fn channels(&self) -> Channels {
        self.channels
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Whether another sample would be handed back.
    pub fn is_full(&self) -> bool {
        self.records.is_full()
    }

    /// Removes every sample; `seq` and the channels stay.
    pub fn clear(&mut self) {
        self.records.clear();
    }

    /// The `index`-th sample.
    pub fn get(&self, index: usize) -> Option<WireSample> {
        self.records.get(index).map(|record| self.sample(record))
    }

    /// The samples in order.
    pub fn iter(&self) -> Samples<'_> {
        Samples {
            channels: self.channels,
            records: self.records.iter(),
        }
    }

    fn sample(&self, record: &Record) -> WireSample {
        to_sample(self.channels, record)
    }
}

fn to_sample(channels: Channels, record: &Record) -> WireSample {
    WireSample {
        t: record.t,
        x: record.x,
        v: channels.has_v().then_some(record.v),
        u: channels.has_u().then_some(record.u),
    }
}

impl<'a> IntoIterator for &'a SampleBatch {
    type Item = WireSample;
    type IntoIter = Samples<'a>;

    fn into_iter(self) -> Samples<'a> {
        self.iter()
    }
}

/// The samples of a [`SampleBatch`], in order.
#[derive(Clone, Debug)]
pub struct Samples<'a> {
    channels: Channels,
    records: core::slice::Iter<'a, Record>,
}

impl Iterator for Samples<'_> {
    type Item = WireSample;

    fn next(&mut self) -> Option<WireSample> {
        self.records
            .next()
            .map(|record| to_sample(self.channels, record))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.records.size_hint()
    }
}

impl DoubleEndedIterator for Samples<'_> {
    fn next_back(&mut self) -> Option<WireSample> {
        self.records
            .next_back()
            .map(|record| to_sample(self.channels, record))
    }
}

impl ExactSizeIterator for Samples<'_> {}

impl core::iter::FusedIterator for Samples<'_> {}

impl MaxSize for SampleBatch {
    // seq (varint u32), the mask byte, the sample count, then the widest samples.
    const POSTCARD_MAX_SIZE: usize = u32::POSTCARD_MAX_SIZE
        + Channels::POSTCARD_MAX_SIZE
        + varint_len(MAX_BATCH)
        + MAX_BATCH * Channels::XVU.bytes_per_sample();
}
