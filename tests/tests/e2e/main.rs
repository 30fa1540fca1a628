//! Every integration test of this crate in one binary (one link instead of one per file).

mod identify;
mod qemu;
mod replay;
mod replay_sweep;
mod standalone_qemu;
mod standalone_system_qemu;
mod system_qemu;
