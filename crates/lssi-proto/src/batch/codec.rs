//! The serde of a [`SampleBatch`], by hand.
//!
//! Which values a sample has depends on the batch's mask, which a derive cannot
//! express without a per-sample tag byte. The shape is still plain serde (a struct of seq, mask
//! and a sequence of tuples), so postcard writes no more than the values themselves.

use super::{Channels, Record, SampleBatch};
use crate::MAX_BATCH;
use core::fmt;
use core::marker::PhantomData;
use serde::de::{self, DeserializeSeed, SeqAccess, Visitor};
use serde::ser::{SerializeSeq, SerializeStruct, SerializeTuple};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

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
pub(super) trait RecordSink: Default {
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
pub(super) struct Count(pub(super) usize);

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
pub(super) fn deserialize_batch<'de, D: Deserializer<'de>, S: RecordSink>(
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
