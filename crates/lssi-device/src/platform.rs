//! What a platform implements to run the device: the byte link to the host and a cost meter.

use crate::CostUnit;
#[cfg(doc)]
use crate::Device;
#[cfg(doc)]
use lssi_proto::MAX_DEVICE_FRAME_LEN;

/// The byte link to the host, as the platform provides it.
///
/// `read` must not block: it returns the bytes that have arrived (0 when none). `write`
/// sends a whole frame (at most [`MAX_DEVICE_FRAME_LEN`] bytes) and may block until the
/// bytes are on their way. An error from either ends [`Device::poll`] with that error; the
/// device's state stays consistent (a reply that could not be written is simply lost, as
/// on a noisy line, and the host's timeout recovers it).
pub trait Transport {
    /// What can go wrong: `core::convert::Infallible` for a UART, `std::io::Error` on a host.
    type Error;

    /// Copies received bytes into `buf` without blocking; returns how many (0: none yet).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error>;

    /// Sends all of `bytes`.
    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error>;
}

impl<T: Transport + ?Sized> Transport for &mut T {
    type Error = T::Error;

    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        (**self).read(buf)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        (**self).write(bytes)
    }
}

/// Measures what a piece of code costs, in the platform's unit.
///
/// The firmware's meter reads SysTick (instructions under QEMU `-icount shift=0`) or the DWT
/// cycle counter and subtracts its own overhead; a host uses wall-clock nanoseconds.
pub trait CostMeter {
    /// The unit of every figure [`CostMeter::measure`] returns.
    fn unit(&self) -> CostUnit;

    /// Runs `f` once and returns its result and its cost (saturating at `u32::MAX`).
    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32);
}

impl<M: CostMeter + ?Sized> CostMeter for &mut M {
    fn unit(&self) -> CostUnit {
        (**self).unit()
    }

    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        (**self).measure(f)
    }
}

/// A meter that measures nothing: every cost is 0 [`CostUnit::Ticks`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoCost;

impl CostMeter for NoCost {
    fn unit(&self) -> CostUnit {
        CostUnit::Ticks
    }

    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        (f(), 0)
    }
}
