//! Every integration test of this crate in one binary (one link instead of one per file).

mod common;
mod decoder;
mod figures;
mod golden;
mod in_place;
mod max_size;
mod roundtrip;
