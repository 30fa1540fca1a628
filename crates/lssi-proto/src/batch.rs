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

use crate::MAX_BATCH;
use crate::size::varint_len;
use core::fmt;
use core::marker::PhantomData;
use postcard::experimental::max_size::MaxSize;
use serde::de::{self, DeserializeSeed, SeqAccess, Visitor};
use serde::ser::{SerializeSeq, SerializeStruct, SerializeTuple};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

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

/// A sample batch read in place from a decoded frame ([`crate::decode_host_frame`]): its
/// sequence number and channels, and its samples as the wire bytes, decoded one at a time as
/// they are iterated. The same samples, bit for bit, as the [`SampleBatch`] that
/// [`crate::decode_frame`] would build from the frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatchRef<'a> {
    /// Sequence number of the batch.
    pub seq: u32,
    channels: Channels,
    /// `len · channels.bytes_per_sample()` bytes, checked by postcard.
    samples: &'a [u8],
}

impl<'a> BatchRef<'a> {
    pub(crate) const fn new(seq: u32, channels: Channels, samples: &'a [u8]) -> Self {
        Self {
            seq,
            channels,
            samples,
        }
    }

    /// The channels every sample carries.
    pub const fn channels(&self) -> Channels {
        self.channels
    }

    /// Number of samples.
    pub const fn len(&self) -> usize {
        self.samples.len() / self.channels.bytes_per_sample()
    }

    /// Whether there are no samples.
    pub const fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The samples in order, decoded from the bytes as they come.
    pub fn iter(&self) -> BatchSamples<'a> {
        BatchSamples {
            channels: self.channels,
            bytes: self.samples,
        }
    }

    /// The same batch as a [`SampleBatch`] (a copy).
    pub fn to_batch(&self) -> SampleBatch {
        let mut batch = SampleBatch::new(self.seq, self.channels);
        for sample in self.iter() {
            // Cannot fail: at most MAX_BATCH samples of the batch's channels.
            let _ = batch.push(sample);
        }
        batch
    }
}

impl<'a> IntoIterator for &BatchRef<'a> {
    type Item = WireSample;
    type IntoIter = BatchSamples<'a>;

    fn into_iter(self) -> BatchSamples<'a> {
        self.iter()
    }
}

/// The samples of a [`BatchRef`], in order.
#[derive(Clone, Debug)]
pub struct BatchSamples<'a> {
    channels: Channels,
    bytes: &'a [u8],
}

impl BatchSamples<'_> {
    /// The next `N` bytes (postcard writes f64 and f32 as their little-endian bytes).
    fn take<const N: usize>(&mut self) -> [u8; N] {
        match self.bytes.split_first_chunk::<N>() {
            Some((head, rest)) => {
                self.bytes = rest;
                *head
            }
            None => {
                self.bytes = &[];
                [0; N]
            }
        }
    }
}

impl Iterator for BatchSamples<'_> {
    type Item = WireSample;

    fn next(&mut self) -> Option<WireSample> {
        if self.bytes.len() < self.channels.bytes_per_sample() {
            return None;
        }
        let t = f64::from_le_bytes(self.take());
        let x = f32::from_le_bytes(self.take());
        let v = self
            .channels
            .has_v()
            .then(|| f32::from_le_bytes(self.take()));
        let u = self
            .channels
            .has_u()
            .then(|| f32::from_le_bytes(self.take()));
        Some(WireSample { t, x, v, u })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.bytes.len() / self.channels.bytes_per_sample();
        (n, Some(n))
    }
}

impl ExactSizeIterator for BatchSamples<'_> {}

impl core::iter::FusedIterator for BatchSamples<'_> {}

/// A [`SampleBatch`] as postcard reads it with its samples checked and counted, not stored
/// (for [`crate::decode_host_frame`]): the same visitor, so the same frames decode.
pub(crate) struct BatchHeader {
    pub(crate) seq: u32,
    pub(crate) channels: Channels,
    pub(crate) len: usize,
}

impl<'de> Deserialize<'de> for BatchHeader {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let (seq, channels, Count(len)) = deserialize_batch(deserializer)?;
        Ok(BatchHeader { seq, channels, len })
    }
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

// Serde by hand: which values a sample has depends on the batch's mask, which a derive cannot
// express without a per-sample tag byte. The shape is still plain serde (a struct of seq, mask
// and a sequence of tuples), so postcard writes no more than the values themselves.

impl Serialize for SampleBatch {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut batch = serializer.serialize_struct("SampleBatch", 3)?;
        batch.serialize_field("seq", &self.seq)?;
        batch.serialize_field("channels", &self.channels)?;
        batch.serialize_field(
            "samples",
            &RecordsOut {
                channels: self.channels,
                records: &self.records,
            },
        )?;
        batch.end()
    }
}

struct RecordsOut<'a> {
    channels: Channels,
    records: &'a [Record],
}

impl Serialize for RecordsOut<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut seq = serializer.serialize_seq(Some(self.records.len()))?;
        for record in self.records {
            seq.serialize_element(&RecordOut {
                channels: self.channels,
                record,
            })?;
        }
        seq.end()
    }
}

struct RecordOut<'a> {
    channels: Channels,
    record: &'a Record,
}

impl Serialize for RecordOut<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut tuple = serializer.serialize_tuple(self.channels.values_per_sample())?;
        tuple.serialize_element(&self.record.t)?;
        tuple.serialize_element(&self.record.x)?;
        if self.channels.has_v() {
            tuple.serialize_element(&self.record.v)?;
        }
        if self.channels.has_u() {
            tuple.serialize_element(&self.record.u)?;
        }
        tuple.end()
    }
}

impl<'de> Deserialize<'de> for SampleBatch {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let (seq, channels, records) = deserialize_batch(deserializer)?;
        Ok(SampleBatch {
            seq,
            channels,
            records,
        })
    }
}

/// Where a batch's records go as postcard reads them: kept ([`SampleBatch`]) or only
/// counted ([`BatchHeader`]); both go through the one visitor and its checks.
trait RecordSink: Default {
    /// Takes one record; false when the batch holds [`MAX_BATCH`] already.
    fn take(&mut self, record: Record) -> bool;
}

impl RecordSink for heapless::Vec<Record, MAX_BATCH> {
    fn take(&mut self, record: Record) -> bool {
        self.push(record).is_ok()
    }
}

/// A record count, for [`BatchHeader`].
#[derive(Default)]
struct Count(usize);

impl RecordSink for Count {
    fn take(&mut self, _: Record) -> bool {
        if self.0 == MAX_BATCH {
            return false;
        }
        self.0 += 1;
        true
    }
}

/// Reads a batch's sequence number, channels and records (into `S`).
fn deserialize_batch<'de, D: Deserializer<'de>, S: RecordSink>(
    deserializer: D,
) -> Result<(u32, Channels, S), D::Error> {
    deserializer.deserialize_struct(
        "SampleBatch",
        &["seq", "channels", "samples"],
        BatchVisitor(PhantomData),
    )
}

struct BatchVisitor<S>(PhantomData<S>);

impl<'de, S: RecordSink> Visitor<'de> for BatchVisitor<S> {
    type Value = (u32, Channels, S);

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a sample batch: sequence number, channel mask, samples")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut fields: A) -> Result<Self::Value, A::Error> {
        let seq = fields
            .next_element()?
            .ok_or_else(|| de::Error::invalid_length(0, &self))?;
        let channels: Channels = fields
            .next_element()?
            .ok_or_else(|| de::Error::invalid_length(1, &self))?;
        let records = fields
            .next_element_seed(RecordsIn {
                channels,
                sink: PhantomData,
            })?
            .ok_or_else(|| de::Error::invalid_length(2, &self))?;
        Ok((seq, channels, records))
    }
}

struct RecordsIn<S> {
    channels: Channels,
    sink: PhantomData<S>,
}

impl<'de, S: RecordSink> DeserializeSeed<'de> for RecordsIn<S> {
    type Value = S;

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<S, D::Error> {
        deserializer.deserialize_seq(self)
    }
}

impl<'de, S: RecordSink> Visitor<'de> for RecordsIn<S> {
    type Value = S;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "at most {MAX_BATCH} samples")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut samples: A) -> Result<S, A::Error> {
        // Refuse an oversized count before reading any of it.
        if let Some(count) = samples.size_hint()
            && count > MAX_BATCH
        {
            return Err(de::Error::invalid_length(count, &self));
        }
        let mut sink = S::default();
        while let Some(record) = samples.next_element_seed(RecordIn {
            channels: self.channels,
        })? {
            if !sink.take(record) {
                return Err(de::Error::invalid_length(MAX_BATCH + 1, &self));
            }
        }
        Ok(sink)
    }
}

#[derive(Clone, Copy)]
struct RecordIn {
    channels: Channels,
}

impl<'de> DeserializeSeed<'de> for RecordIn {
    type Value = Record;

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<Record, D::Error> {
        deserializer.deserialize_tuple(self.channels.values_per_sample(), self)
    }
}

impl<'de> Visitor<'de> for RecordIn {
    type Value = Record;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a sample of {} values",
            self.channels.values_per_sample()
        )
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut values: A) -> Result<Record, A::Error> {
        let t: f64 = values
            .next_element()?
            .ok_or_else(|| de::Error::invalid_length(0, &self))?;
        let x: f32 = values
            .next_element()?
            .ok_or_else(|| de::Error::invalid_length(1, &self))?;
        let v = if self.channels.has_v() {
            values
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(2, &self))?
        } else {
            0.0
        };
        let u = if self.channels.has_u() {
            let index = 2 + usize::from(self.channels.has_v());
            values
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(index, &self))?
        } else {
            0.0
        };
        Ok(Record { t, x, v, u })
    }
}
