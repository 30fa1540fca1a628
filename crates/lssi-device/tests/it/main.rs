//! Every integration test of this crate in one binary (one link instead of one per file).

mod common;
mod equivalence;
mod fuzz;
mod loopback;
mod sizes;
mod standalone;
#[cfg(feature = "system")]
mod system;
