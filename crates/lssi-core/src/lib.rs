//! # lssi-core — streaming local sparse screening identification
//!
//! Recovers a vibration energy harvester's equation of motion x'' = f(x, x', t) from its
//! displacement signal, sample by sample, in fixed memory, with no allocator: the LSSI
//! algorithm (Li, Wang & Wang 2020) made streaming. See [`Identifier`] for the pipeline and
//! a runnable example, and docs/design.md for the decisions the paper leaves open.
//!
//! `#![no_std]`, no `alloc`, no panics on data: a bad sample is a counted [`Rejection`].
//! Generic over [`Real`] (`f32` on a device, `f64` as the host's reference); every
//! transcendental function goes through `libm`.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(missing_docs)]

pub mod config;
pub mod derivative;
#[cfg(feature = "noise-correction")]
mod eiv;
pub mod factor;
pub mod identifier;
pub mod library;
pub mod model;
pub mod real;
pub mod restoring;
mod screen;
pub mod smoothing;
pub mod tuning;
mod weak;

pub use config::{Channels, Config, ConfigError};
pub use identifier::system::{
    SystemConfig, SystemConfigError, SystemIdentifier, SystemModel, SystemSample, SystemSlot,
    SystemSnapshot,
};
pub use identifier::{Counters, Identifier, IdentifierSlot, Rejection, Sample, Snapshot};
pub use library::{Library, LibraryConfig, LibraryError, PolyFamily, RowTables, Term};
pub use model::{MAX_SOLUTIONS, Model, Solution};
pub use real::Real;
pub use restoring::{Equilibrium, RestoringForce};
