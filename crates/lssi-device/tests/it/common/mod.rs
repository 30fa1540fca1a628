//! A loopback link, host-side helpers and a synthetic recording shared by the tests.
#![allow(dead_code)]

use lssi_core::{Config, LibraryConfig, PolyFamily};
use lssi_device::{CostMeter, CostUnit, Device, Transport};
use lssi_proto::{
    Channels, DeviceFrameDecoder, DeviceMsg, HostMsg, MAX_BATCH, MAX_HOST_FRAME_LEN, SampleBatch,
    WireSample, encode,
};
use std::collections::VecDeque;

/// Bytes from the host in `rx`, bytes to the host in `tx`; reads at most `chunk` at a time.
pub struct Loopback {
    pub rx: VecDeque<u8>,
    pub tx: Vec<u8>,
    pub chunk: usize,
}

impl Default for Loopback {
    fn default() -> Self {
        Self {
            rx: VecDeque::new(),
            tx: Vec::new(),
            chunk: usize::MAX,
        }
    }
}

impl Transport for Loopback {
    type Error = std::convert::Infallible;

    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let n = buf.len().min(self.rx.len()).min(self.chunk);
        for (slot, byte) in buf.iter_mut().zip(self.rx.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        self.tx.extend_from_slice(bytes);
        Ok(())
    }
}

/// A meter that charges a fixed cost per call, in cycles.
pub struct FixedMeter(pub u32);

impl CostMeter for FixedMeter {
    fn unit(&self) -> CostUnit {
        CostUnit::Cycles
    }

    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        (f(), self.0)
    }
}

/// The host end: frames commands into the device's receive queue and decodes its replies.
pub struct Host<const W: usize, const P: usize, const C: usize = 3> {
    pub device: Box<Device<W, P, C>>,
    pub link: Loopback,
    pub meter: FixedMeter,
    decoder: DeviceFrameDecoder,
}

impl<const W: usize, const P: usize, const C: usize> Default for Host<W, P, C> {
    fn default() -> Self {
        Self {
            device: Box::new(Device::new()),
            link: Loopback::default(),
            meter: FixedMeter(7),
            decoder: DeviceFrameDecoder::new(),
        }
    }
}

impl<const W: usize, const P: usize, const C: usize> Host<W, P, C> {
    /// Queues raw bytes for the device.
    pub fn raw(&mut self, bytes: &[u8]) {
        self.link.rx.extend(bytes);
    }

    /// Queues a framed message for the device.
    pub fn send(&mut self, message: &HostMsg) {
        let frame = frame(message);
        self.raw(&frame);
    }

    /// Polls the device until it has read everything, then returns what it sent.
    pub fn replies(&mut self) -> Vec<DeviceMsg> {
        while self
            .device
            .poll(&mut self.link, &mut self.meter)
            .is_ok_and(|n| n > 0)
        {}
        let tx = std::mem::take(&mut self.link.tx);
        self.decoder
            .feed::<DeviceMsg>(&tx)
            .map(|r| r.expect("the device sends valid frames"))
            .collect()
    }

    /// Sends `message` and returns the replies.
    pub fn exchange(&mut self, message: &HostMsg) -> Vec<DeviceMsg> {
        self.send(message);
        self.replies()
    }
}

/// The frame of a host message.
pub fn frame(message: &HostMsg) -> Vec<u8> {
    let mut out = vec![0u8; MAX_HOST_FRAME_LEN];
    let len = encode(message, &mut out).expect("fits");
    out.truncate(len);
    out
}

/// A forced Duffing oscillator x'' = -k x - c x' - a x³ + F cos(Ω t) (k = 400, c = 2,
/// a = 4·10⁴, F = 60, Ω = [`OMEGA`]), RK4 with 10 steps per sample of `dt`: `n` samples of
/// (t, x) in f64 (`lssi_testkit::duffing_at`).
pub fn duffing(n: usize, dt: f64) -> Vec<(f64, f64)> {
    lssi_testkit::duffing_at(n, dt)
        .into_iter()
        .map(|p| (p.t, p.x))
        .collect()
}

/// The Duffing forcing's angular frequency, rad/s.
pub const OMEGA: f64 = 15.0;

/// The configuration the tests identify the Duffing recording with.
pub fn duffing_config() -> Config {
    Config {
        sample_period: 1e-3,
        window: 63,
        library: LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: 1,
            input: false,
        },
        omega: OMEGA,
        screening_period: 5_000,
        ..Config::default()
    }
}

/// The recording cut into x-only batches numbered from `first_seq`.
pub fn batches(samples: &[(f64, f64)], first_seq: u32) -> Vec<SampleBatch> {
    samples
        .chunks(MAX_BATCH)
        .zip(first_seq..)
        .map(|(chunk, seq)| {
            let mut batch = SampleBatch::new(seq, Channels::X);
            for &(t, x) in chunk {
                batch
                    .push(WireSample {
                        t,
                        x: x as f32,
                        v: None,
                        u: None,
                    })
                    .expect("room");
            }
            batch
        })
        .collect()
}
