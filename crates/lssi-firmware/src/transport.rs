//! The byte link between the device application and the host.
//!
//! A stand-in until `lssi-device` defines its own transport trait: then this module goes
//! and the UART implements the device crate's trait instead (one `impl` block in
//! `uart.rs`).

/// A byte stream to and from the host: non-blocking in, blocking out.
pub trait Transport {
    /// The next received byte, if one is waiting; never blocks.
    fn read(&mut self) -> Option<u8>;
    /// Sends all of `bytes`, waiting for room as needed.
    fn write(&mut self, bytes: &[u8]);
}
