//! The standalone instrument's board under QEMU (`mps2-an386`): the sampling timer, a
//! free-running clock, UART0's interrupts, and the "sensor": a recording that QEMU preloads
//! into PSRAM (`-device loader,file=REC,addr=0x21000000`), read one sample per timer tick.
//!
//! Interrupt numbers and addresses are QEMU's `hw/arm/mps2.c` (AN385/AN386): UART0 RX 0,
//! TX 1; CMSDK APB TIMER0 at 0x4000_0000 (IRQ 8), TIMER1 at 0x4000_1000 (IRQ 9); the
//! dual timer's IRQ 10 is unused here and serves as the identify task's software
//! interrupt. Every timer runs at the 25 MHz system clock; under `-icount shift=4` that is
//! guest time, 2.5 instructions a tick (62.5 M instructions a guest second).
//!
//! The recording (`lssi monitor --qemu` writes it), little-endian:
//!
//! | offset | bytes | what |
//! |---|---|---|
//! | 0 | 8 | magic `LSSIREC1` |
//! | 8 | 4 | channels: bit 0 v, bit 1 u, bit 2 an electrical channel V or i (x always) |
//! | 12 | 4 | samples N |
//! | 16 | 8 | rate, Hz (f64) |
//! | 24 | 4 | length L of the stored configuration (0: none) |
//! | 28 | L ≤ 228 | a `HostMsg::Configure` frame (COBS + CRC), as a host would send it |
//! | 256 | 4·N·channels | the samples, f32, channel-interleaved (x[, v][, u][, V]) |

use lssi_device::standalone::{Clock, Reading};

/// Where QEMU's mps2 boards map their 16 MiB PSRAM.
pub const PSRAM: usize = 0x2100_0000;
/// The recording's header size; the samples follow.
pub const HEADER: usize = 256;
/// Largest stored configuration frame.
pub const MAX_CONFIG: usize = HEADER - 28;
/// The system clock that drives the timers and UARTs.
pub const SYSCLK_HZ: u32 = 25_000_000;

const TIMER0: usize = 0x4000_0000;
const TIMER1: usize = 0x4000_1000;
const UART0: usize = 0x4000_4000;

/// IRQ numbers (QEMU's hw/arm/mps2.c).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u16)]
pub enum Irq {
    /// UART0 receive.
    Uart0Rx = 0,
    /// UART0 transmit.
    Uart0Tx = 1,
    /// TIMER0: the sampling timer.
    Timer0 = 8,
    /// The dual timer's line, unused by it here: the identify task's software interrupt.
    Identify = 10,
}

#[allow(unsafe_code)]
// SAFETY: each variant is an interrupt line that the AN386's NVIC (32 lines) has.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

fn read(addr: usize) -> u32 {
    #[allow(unsafe_code)]
    // SAFETY: only called with the 4-aligned register addresses above and PSRAM words
    // within the recording, all mapped on this board; reading them has no side effect
    // but the UART's DATA pop, which the caller asks for.
    unsafe {
        core::ptr::read_volatile(addr as *const u32)
    }
}

fn write(addr: usize, value: u32) {
    #[allow(unsafe_code)]
    // SAFETY: the register addresses above; not Rust memory.
    unsafe {
        core::ptr::write_volatile(addr as *mut u32, value);
    }
}

/// CMSDK APB timer registers.
const CTRL: usize = 0x0;
const VALUE: usize = 0x4;
const RELOAD: usize = 0x8;
const INTCLEAR: usize = 0xC;
const CTRL_ENABLE: u32 = 1 << 0;
const CTRL_IRQ: u32 = 1 << 3;

/// TIMER0 as the sampling clock: an interrupt every `SYSCLK_HZ / rate` ticks (rounded;
/// see [`sampling_reload`]).
pub fn start_sampling(reload: u32) {
    write(TIMER0 + CTRL, 0);
    write(TIMER0 + RELOAD, reload);
    write(TIMER0 + VALUE, reload);
    write(TIMER0 + INTCLEAR, 1);
    write(TIMER0 + CTRL, CTRL_ENABLE | CTRL_IRQ);
}

/// The reload value for `rate_hz` (the period is reload + 1 ticks).
pub fn sampling_reload(rate_hz: f64) -> u32 {
    let ticks = libm::round(f64::from(SYSCLK_HZ) / rate_hz);
    (ticks as u32).max(2) - 1
}

/// Stops the sampling timer.
pub fn stop_sampling() {
    write(TIMER0 + CTRL, 0);
}

/// Acknowledges TIMER0's interrupt.
pub fn clear_sampling_irq() {
    write(TIMER0 + INTCLEAR, 1);
}

/// TIMER1, free-running from 2³² − 1 down: [`BoardClock`] reads it.
pub fn start_clock() {
    write(TIMER1 + CTRL, 0);
    write(TIMER1 + RELOAD, u32::MAX);
    write(TIMER1 + VALUE, u32::MAX);
    write(TIMER1 + CTRL, CTRL_ENABLE);
}

/// The free-running clock: 25 MHz ticks, wrapping every 172 s.
#[derive(Clone, Copy, Debug, Default)]
pub struct BoardClock;

impl Clock for BoardClock {
    const HZ: u32 = SYSCLK_HZ;
    fn now(&self) -> u32 {
        u32::MAX - read(TIMER1 + VALUE)
    }
}

/// UART0 registers (see `uart.rs`) and the interrupt bits.
const DATA: usize = 0x0;
const STATE: usize = 0x4;
const UCTRL: usize = 0x8;
const INTSTATUS: usize = 0xC;
const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const STATE_RX_OVERRUN: u32 = 1 << 3;
const UCTRL_TX_IRQ: u32 = 1 << 2;
const UCTRL_RX_IRQ: u32 = 1 << 3;
const INT_TX: u32 = 1 << 0;
const INT_RX: u32 = 1 << 1;

/// Turns on UART0's RX and TX interrupts (the UART itself is set up by `uart::Uart0::take`).
pub fn uart_interrupts_on() {
    let ctrl = read(UART0 + UCTRL);
    write(UART0 + UCTRL, ctrl | UCTRL_TX_IRQ | UCTRL_RX_IRQ);
}

/// In the RX interrupt: the received byte, if any (the interrupt acknowledged), and
/// whether the UART lost one (overrun, flag cleared).
pub fn uart_rx() -> (Option<u8>, bool) {
    write(UART0 + INTSTATUS, INT_RX);
    let state = read(UART0 + STATE);
    let overrun = state & STATE_RX_OVERRUN != 0;
    if overrun {
        write(UART0 + STATE, STATE_RX_OVERRUN);
    }
    let byte = (state & STATE_RX_FULL != 0).then(|| (read(UART0 + DATA) & 0xFF) as u8);
    (byte, overrun)
}

/// In the TX interrupt: acknowledges it.
pub fn uart_tx_ack() {
    write(UART0 + INTSTATUS, INT_TX);
}

/// Whether UART0 can take a byte now.
pub fn uart_tx_ready() -> bool {
    read(UART0 + STATE) & STATE_TX_FULL == 0
}

/// Hands UART0 one byte (check [`uart_tx_ready`] first).
pub fn uart_tx(byte: u8) {
    write(UART0 + DATA, u32::from(byte));
}

/// The recording QEMU preloaded into PSRAM.
#[derive(Clone, Copy, Debug)]
pub struct Recording {
    /// Samples in it.
    pub len: u32,
    /// Its sampling rate, Hz.
    pub rate_hz: f64,
    /// Whether it has v, u.
    pub velocity: bool,
    /// Whether it has u.
    pub input: bool,
    /// Whether it has an electrical channel (the second ADC channel of a system's
    /// instrument: a harvester's voltage across its load).
    pub electrical: bool,
    config_len: usize,
}

impl Recording {
    /// The recording at [`PSRAM`], if its header is there.
    pub fn find() -> Option<Self> {
        if read(PSRAM) != u32::from_le_bytes(*b"LSSI")
            || read(PSRAM + 4) != u32::from_le_bytes(*b"REC1")
        {
            return None;
        }
        let channels = read(PSRAM + 8);
        let len = read(PSRAM + 12);
        let rate_hz =
            f64::from_bits(u64::from(read(PSRAM + 16)) | (u64::from(read(PSRAM + 20)) << 32));
        let config_len = read(PSRAM + 24) as usize;
        let max_len = (16 << 20) as u32 / 16;
        if !(rate_hz.is_finite() && rate_hz > 0.0) || config_len > MAX_CONFIG || len > max_len {
            return None;
        }
        Some(Self {
            len,
            rate_hz,
            velocity: channels & 1 != 0,
            input: channels & 2 != 0,
            electrical: channels & 4 != 0,
            config_len,
        })
    }

    /// The stored configuration frame (a host's `Configure`), copied into `out`.
    pub fn config_frame<'a>(&self, out: &'a mut [u8; MAX_CONFIG]) -> &'a mut [u8] {
        for (i, slot) in out.iter_mut().enumerate().take(self.config_len) {
            let word = read(PSRAM + 28 + (i & !3));
            *slot = word.to_le_bytes()[i & 3];
        }
        &mut out[..self.config_len]
    }

    /// Sample `i` (below `len`).
    pub fn reading(&self, i: u32) -> Reading {
        let (v, u, e) = (
            usize::from(self.velocity),
            usize::from(self.input),
            usize::from(self.electrical),
        );
        let per = 1 + v + u + e;
        let base = PSRAM + HEADER + 4 * per * i as usize;
        let value = |k: usize| f32::from_bits(read(base + 4 * k));
        Reading {
            x: value(0),
            v: self.velocity.then(|| value(1)),
            u: self.input.then(|| value(1 + v)),
            e: self.electrical.then(|| value(1 + v + u)),
        }
    }
}
