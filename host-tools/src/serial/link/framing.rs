//! Framing: the reader thread that splits the incoming bytes into frames, the batches
//! of samples ([`BatchSource`], [`F32Samples`]) and the frame of one batch ([`batch_frame`]).

use std::io::{self, Read};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::thread::JoinHandle;
use std::time::Instant;

use lssi_proto::{
    Channels, HostMsg, MAX_DEVICE_FRAME_LEN, MAX_SYSTEM_BATCH, SampleBatch, SystemBatch,
    SystemWireSample, WireSample, encode,
};

use crate::telemetry::now_us;

/// What the reader thread hands over.
#[derive(Debug)]
pub(super) enum Incoming {
    /// One frame's bytes (COBS, no delimiter) and when it ended.
    Frame(Vec<u8>, u64),
    /// A frame longer than any device frame (its start), dropped.
    Overlong(Vec<u8>, u64),
    /// The port closed (end of file or an error).
    Closed(String),
    /// Raw defmt bytes from outside the link (QEMU's semihosting output).
    Defmt(Vec<u8>, u64),
}

/// Reads the port on its own thread and splits the bytes into frames.
#[derive(Debug)]
pub(super) struct Reader {
    pub(super) rx: Receiver<Incoming>,
    pub(super) tx: mpsc::Sender<Incoming>,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) thread: Option<JoinHandle<()>>,
}

impl Reader {
    pub(super) fn spawn(mut port: Box<dyn Read + Send>) -> Self {
        let (tx, rx) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = Arc::clone(&stop);
        let sender = tx.clone();
        let thread = std::thread::spawn(move || {
            let tx = sender;
            let mut buffer = [0u8; 4096];
            let mut frame = Vec::with_capacity(MAX_DEVICE_FRAME_LEN);
            let mut overlong = false;
            while !stopped.load(Ordering::Relaxed) {
                let n = match port.read(&mut buffer) {
                    Ok(0) => {
                        let _ = tx.send(Incoming::Closed("end of file".into()));
                        return;
                    }
                    Ok(n) => n,
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::TimedOut
                                | io::ErrorKind::WouldBlock
                                | io::ErrorKind::Interrupted
                        ) =>
                    {
                        continue;
                    }
                    Err(e) => {
                        let _ = tx.send(Incoming::Closed(e.to_string()));
                        return;
                    }
                };
                for &byte in &buffer[..n] {
                    if byte == 0 {
                        let bytes = std::mem::take(&mut frame);
                        let message = if std::mem::take(&mut overlong) {
                            Incoming::Overlong(bytes, now_us())
                        } else if bytes.is_empty() {
                            continue;
                        } else {
                            Incoming::Frame(bytes, now_us())
                        };
                        if tx.send(message).is_err() {
                            return;
                        }
                    } else if frame.len() < MAX_DEVICE_FRAME_LEN {
                        frame.push(byte);
                    } else {
                        overlong = true;
                    }
                }
            }
        });
        Self {
            rx,
            tx,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for Reader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // The thread wakes at the port's read timeout; a port without one (a test's pipe)
        // ends with its writer, so do not wait for it here.
        if let Some(thread) = self.thread.take()
            && thread.is_finished()
        {
            let _ = thread.join();
        }
    }
}

/// One batch on the wire, kept until acknowledged.
#[derive(Debug)]
pub(super) struct InFlight {
    pub(super) seq: u32,
    pub(super) frame: Vec<u8>,
    pub(super) samples: usize,
    /// Index of its first sample in the stream.
    pub(super) start: usize,
    /// When it was sent, and whether only once (Karn: only those time the round trip).
    pub(super) sent: Instant,
    pub(super) once: bool,
}

/// Where the samples of a stream come from: batches framed on demand.
pub trait BatchSource {
    /// Samples in the stream.
    fn len(&self) -> usize;
    /// Whether there are none.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Most samples in one batch.
    fn max_batch(&self) -> usize;
    /// Wire bytes a sample costs in a batch.
    fn bytes_per_sample(&self) -> usize;
    /// The frame of batch `seq` holding at most `max` samples from sample `from`, and how
    /// many it holds (at least one while `from` is a sample).
    fn frame(&self, seq: u32, from: usize, max: usize) -> (Vec<u8>, usize);
}

/// Samples sent as they are: t as f64, the channels as f32 ([`HostMsg::Samples`]).
#[derive(Clone, Copy, Debug)]
pub struct F32Samples<'a>(pub &'a [WireSample]);

impl BatchSource for F32Samples<'_> {
    fn len(&self) -> usize {
        self.0.len()
    }

    fn max_batch(&self) -> usize {
        lssi_proto::MAX_BATCH
    }

    fn bytes_per_sample(&self) -> usize {
        self.0
            .first()
            .map_or(Channels::X, Channels::of)
            .bytes_per_sample()
    }

    fn frame(&self, seq: u32, from: usize, max: usize) -> (Vec<u8>, usize) {
        let max = max.clamp(1, lssi_proto::MAX_BATCH);
        let chunk = self
            .0
            .get(from..(from + max).min(self.0.len()))
            .unwrap_or(&[]);
        (batch_frame(seq, chunk), chunk.len())
    }
}

/// A system's samples (t, x, v, u and the electrical channels): [`HostMsg::SystemSamples`].
#[derive(Clone, Copy, Debug)]
pub struct SystemSamples<'a>(pub &'a [SystemWireSample]);

impl BatchSource for SystemSamples<'_> {
    fn len(&self) -> usize {
        self.0.len()
    }

    fn max_batch(&self) -> usize {
        MAX_SYSTEM_BATCH
    }

    fn bytes_per_sample(&self) -> usize {
        // t (8), x (4), v and u (1 or 5 each), the electrical values' count and 4 each.
        self.0.first().map_or(13, |s| {
            let option = |o: Option<f32>| if o.is_some() { 5 } else { 1 };
            12 + option(s.v) + option(s.u) + 1 + 4 * s.electrical.len()
        })
    }

    fn frame(&self, seq: u32, from: usize, max: usize) -> (Vec<u8>, usize) {
        let max = max.clamp(1, MAX_SYSTEM_BATCH);
        let chunk = self
            .0
            .get(from..(from + max).min(self.0.len()))
            .unwrap_or(&[]);
        let mut batch = SystemBatch::new(seq);
        for sample in chunk {
            // At most MAX_SYSTEM_BATCH samples: they fit.
            let _ = batch.samples.push(sample.clone());
        }
        let mut frame = vec![0u8; lssi_proto::MAX_HOST_FRAME_LEN];
        let len = encode(&HostMsg::SystemSamples(batch), &mut frame).unwrap_or(0);
        frame.truncate(len);
        (frame, chunk.len())
    }
}

/// The frame of one batch of samples, numbered `seq`.
///
/// The samples must share their channels (a recording's do); at most
/// [`lssi_proto::MAX_BATCH`] of them.
pub fn batch_frame(seq: u32, samples: &[WireSample]) -> Vec<u8> {
    let channels = samples.first().map_or(Channels::X, Channels::of);
    let mut batch = SampleBatch::new(seq, channels);
    for sample in samples {
        // A recording's samples all have the same channels and a chunk fits a batch.
        let _ = batch.push(*sample);
    }
    let mut frame = vec![0u8; lssi_proto::MAX_HOST_FRAME_LEN];
    let len = encode(&HostMsg::Samples(batch), &mut frame).unwrap_or(0);
    frame.truncate(len);
    frame
}

#[cfg(test)]
mod tests {
    use super::*;
    use lssi_proto::decode_frame;

    #[test]
    fn a_batch_frame_decodes_to_its_samples() {
        let samples: Vec<WireSample> = (0..5)
            .map(|i| WireSample {
                t: f64::from(i) * 0.002,
                x: i as f32,
                v: Some(0.5),
                u: None,
            })
            .collect();
        let mut frame = batch_frame(9, &samples);
        assert_eq!(frame.last(), Some(&0));
        let len = frame.len() - 1;
        match decode_frame::<HostMsg>(&mut frame[..len]).unwrap() {
            HostMsg::Samples(batch) => {
                assert_eq!(batch.seq, 9);
                assert_eq!(batch.iter().collect::<Vec<_>>(), samples);
            }
            other => panic!("not a batch: {other:?}"),
        }
    }
}
