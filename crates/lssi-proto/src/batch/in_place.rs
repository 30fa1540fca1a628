//! A sample batch read in place from a received frame's bytes.

use super::codec::{Count, deserialize_batch};
use super::{Channels, SampleBatch, WireSample};
use serde::{Deserialize, Deserializer};

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
