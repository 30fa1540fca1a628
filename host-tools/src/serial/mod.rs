//! `lssi replay` and `lssi monitor` over a serial link: to `firmware-sim`, to the firmware
//! under QEMU, or to a board.
//!
//! - [`device`]: where `lssi replay`'s device comes from: `firmware-sim` or QEMU started on a
//!   pty, or a real port.
//! - [`qemu`]: the QEMU transport: the board's command line, its UART's socket.
//! - [`link`]: the framed, windowed, retransmitting link to a device.
//! - [`replay`]: a recording through the link, reported as `lssi identify` reports its own.
//! - [`session`]: one `lssi replay`: device started, telemetry log opened, recording replayed.
//! - [`monitor`]: `lssi monitor`: a standalone device's frames, live and logged.

pub mod adapt;
pub mod device;
pub mod link;
pub mod monitor;
pub mod qemu;
pub mod quantise;
pub mod replay;
pub mod session;
