//! Board support for the lssi Cortex-M4F image: CMSDK UART0 driver (lssi-device's
//! transport), per-call cost meter (its cost meter), stack painting, a take-once static,
//! defmt global logger (debug transport plus a ring buffer for the UART), panic and fault handling.
//!
//! Built for `thumbv7em-none-eabihf` only; the reference board is QEMU's `mps2-an386`.
//! The image itself is `src/main.rs`.

#![no_std]
// Volatile register and stack access is the only `unsafe`; each site opts in and says why.
#![deny(unsafe_code)]
#![deny(missing_docs)]

/// Sample channels the identifier keeps ring buffers for (its `C`): x and one of v, u;
/// x, v and u with the `three-channels` feature.
pub const CHANNELS: usize = if cfg!(feature = "three-channels") {
    3
} else {
    2
};

/// Ring-buffer capacity in samples (the `W` of the identifier): the longest derivative window
/// the device accepts is one less. 256 by default; 64 with the `window-64` feature, for parts
/// with 8–16 KiB of RAM (−4.6 KB of `.bss`: the rings and the folded taps). `lssi identify`
/// chooses windows of 13–33 samples for the bundled recordings; a `Configure` with a longer
/// window is refused (`BadConfig`, and `lssi replay` says the device's capacity).
pub const WINDOW: usize = if cfg!(feature = "window-64") {
    64
} else {
    lssi_device::DEFAULT_WINDOW
};

pub mod cost;
pub mod logger;
pub mod mps2;
pub mod once;
pub mod platform;
pub mod stack;
pub mod uart;
pub mod workload;
