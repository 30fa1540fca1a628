//! Polled driver for UART0 of the Arm CMSDK APB UART, as on QEMU's `mps2-an386` board.
//!
//! The register block (Arm CMSDK technical reference, "APB UART"):
//!
//! | offset | register  | used bits |
//! |--------|-----------|-----------|
//! | 0x00   | DATA      | 7:0 received byte (read), byte to send (write) |
//! | 0x04   | STATE     | 0 TX buffer full, 1 RX buffer full, 2 TX overrun, 3 RX overrun (write 1 to clear) |
//! | 0x08   | CTRL      | 0 TX enable, 1 RX enable |
//! | 0x10   | BAUDDIV   | peripheral clock / baud rate, at least 16 |
//!
//! Both directions hold one byte, so the driver is byte-in, byte-out: [`Uart0::write`] waits
//! while the TX buffer is full and [`Uart0::try_read`] returns at once. QEMU holds back further
//! input until the guest has read `DATA`, so nothing is lost there; on silicon a slow reader
//! shows up as an RX overrun ([`Uart0::take_overrun`]).
//!
//! Reading and writing these registers is the only `unsafe` in the firmware's data path.
//!
//! ```ignore
//! let mut uart = Uart0::take(uart::MPS2_PERIPHERAL_CLOCK_HZ, 115_200)?;
//! uart.write(b'>');
//! if let Some(b) = uart.try_read() { uart.write(b); }
//! ```

use core::sync::atomic::{AtomicBool, Ordering};

/// Base address of UART0 on the MPS2 AN385/AN386 boards.
pub const UART0_BASE: usize = 0x4000_4000;
/// The clock that drives the APB peripherals on the MPS2 boards (and the core): 25 MHz.
pub const MPS2_PERIPHERAL_CLOCK_HZ: u32 = 25_000_000;
/// The smallest divider the CMSDK UART accepts.
pub const MIN_BAUDDIV: u32 = 16;

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const STATE_TX_OVERRUN: u32 = 1 << 2;
const STATE_RX_OVERRUN: u32 = 1 << 3;
const CTRL_TX_ENABLE: u32 = 1 << 0;
const CTRL_RX_ENABLE: u32 = 1 << 1;

/// Set once UART0 has been handed out, so that only one [`Uart0`] ever exists.
static TAKEN: AtomicBool = AtomicBool::new(false);

/// Why [`Uart0::take`] refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
#[non_exhaustive]
pub enum UartError {
    /// UART0 was already taken.
    AlreadyTaken,
    /// The requested baud rate needs a divider below [`MIN_BAUDDIV`].
    BaudRateTooHigh {
        /// The divider the request works out to.
        bauddiv: u32,
    },
}

impl core::fmt::Display for UartError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::AlreadyTaken => f.write_str("UART0 is already in use"),
            Self::BaudRateTooHigh { bauddiv } => write!(
                f,
                "baud rate too high: divider {bauddiv} is below the minimum {MIN_BAUDDIV}"
            ),
        }
    }
}

impl core::error::Error for UartError {}

/// Exclusive handle on UART0, enabled for transmit and receive.
pub struct Uart0 {
    _private: (),
}

impl Uart0 {
    /// Enables UART0 at `baud` for a peripheral clock of `clock_hz`; fails if UART0 is
    /// already taken or the divider would be below [`MIN_BAUDDIV`].
    pub fn take(clock_hz: u32, baud: u32) -> Result<Self, UartError> {
        let bauddiv = clock_hz.checked_div(baud).unwrap_or(0);
        if bauddiv < MIN_BAUDDIV {
            return Err(UartError::BaudRateTooHigh { bauddiv });
        }
        if TAKEN.swap(true, Ordering::AcqRel) {
            return Err(UartError::AlreadyTaken);
        }
        let mut uart = Self { _private: () };
        uart.write_reg(CTRL, 0);
        uart.write_reg(BAUDDIV, bauddiv);
        uart.write_reg(STATE, STATE_TX_OVERRUN | STATE_RX_OVERRUN);
        uart.write_reg(CTRL, CTRL_TX_ENABLE | CTRL_RX_ENABLE);
        Ok(uart)
    }

    /// Sends one byte, waiting while the transmit buffer is full.
    pub fn write(&mut self, b: u8) {
        while self.read_reg(STATE) & STATE_TX_FULL != 0 {
            core::hint::spin_loop();
        }
        self.write_reg(DATA, u32::from(b));
    }

    /// The received byte, if one is waiting.
    pub fn try_read(&mut self) -> Option<u8> {
        if self.read_reg(STATE) & STATE_RX_FULL != 0 {
            // Only the low 8 bits of DATA hold the byte.
            Some((self.read_reg(DATA) & 0xFF) as u8)
        } else {
            None
        }
    }

    /// Whether a received byte was lost since the last call (and clears the flag).
    pub fn take_overrun(&mut self) -> bool {
        let overrun = self.read_reg(STATE) & STATE_RX_OVERRUN != 0;
        if overrun {
            self.write_reg(STATE, STATE_RX_OVERRUN);
        }
        overrun
    }

    fn read_reg(&self, offset: usize) -> u32 {
        #[allow(unsafe_code)]
        // SAFETY: UART0_BASE + offset is one of the 32-bit, 4-aligned registers of UART0,
        // which is always mapped on this board; a volatile read has no effect on Rust-visible
        // memory (reading DATA pops the RX byte, which is what the caller asks for).
        unsafe {
            core::ptr::read_volatile((UART0_BASE + offset) as *const u32)
        }
    }

    fn write_reg(&mut self, offset: usize, value: u32) {
        #[allow(unsafe_code)]
        // SAFETY: as in `read_reg`; the register block is not Rust memory, and `&mut self`
        // on the only `Uart0` (see `TAKEN`) makes this the only writer.
        unsafe {
            core::ptr::write_volatile((UART0_BASE + offset) as *mut u32, value);
        }
    }
}

/// The device application's link: `read` drains what UART0 holds without blocking (one
/// byte on this UART, which has no FIFO), `write` sends a frame byte by byte.
impl lssi_device::Transport for Uart0 {
    type Error = core::convert::Infallible;

    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let mut n = 0;
        for slot in buf.iter_mut() {
            match self.try_read() {
                Some(b) => *slot = b,
                None => break,
            }
            n += 1;
        }
        Ok(n)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        for &b in bytes {
            Uart0::write(self, b);
        }
        Ok(())
    }
}
