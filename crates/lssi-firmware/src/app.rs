//! The device application: lssi-device's command loop on UART0.
//!
//! The [`Device`] (identifier, frame decoder, transmit buffer, counters: about 10 KiB) lives
//! in a static in `.bss`, never built at run time (its initial bytes are all zero); a
//! `Configure` configures its identifier in place there. The loop polls UART0 (which holds one received byte; QEMU holds the rest back
//! until it is read, so nothing is lost there) and lets the device handle every frame the
//! bytes complete, timing each sample's push with the cost meter. `Device::poll` bumps the
//! watchdog counter that `Health` reports: a host that sees it stop knows the loop hangs.
//!
//! On silicon, a screening (6 to 22 million instructions, see the README) keeps the loop
//! away from the UART for 0.1–0.35 s at 64 MHz: a one-byte UART then overruns unless the host
//! waits for the `Ack` of each batch (as `lssi replay` does) or RX is moved to an interrupt
//! and a ring buffer. An overrun is logged.
//!
//! Between polls the loop drains the defmt logger's ring buffer ([`logger::take`]) into
//! `DeviceMsg::Log` frames (`Device::send_log`), once the host has configured the device.

use lssi_device::{DEFAULT_TERMS, Device};
use lssi_firmware::{CHANNELS, WINDOW};
use lssi_firmware::cost::Meter;
use lssi_firmware::once::TakeOnce;
use lssi_firmware::uart::Uart0;
use lssi_firmware::{logger, platform};

/// Bytes of defmt log per `DeviceMsg::Log` frame (lssi-proto's `MAX_LOG`; `send_log`
/// splits anything longer, so this only sets the stack buffer).
const LOG_CHUNK: usize = 96;

/// The device application's storage, in `.bss` (its initial bytes are all zero: see
/// [`TakeOnce`]): ring buffers for [`CHANNELS`] channels.
#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.DEVICE")]
static DEVICE: TakeOnce<Device<WINDOW, DEFAULT_TERMS, CHANNELS>> =
    TakeOnce::new(Device::new());

/// Runs the command loop forever.
pub fn run(uart: &mut Uart0, meter: &mut Meter) -> ! {
    let Some(device) = DEVICE.take() else {
        defmt::error!("the device application was already taken");
        platform::exit(platform::EXIT_PANIC)
    };
    defmt::info!(
        "lssi device ready: window capacity {=usize}, {=usize} terms, {=usize} channels, costs in {=str}",
        WINDOW,
        DEFAULT_TERMS,
        CHANNELS,
        lssi_firmware::cost::Meter::unit(meter).as_str()
    );
    let mut screenings = 0;
    let mut dropped = 0;
    loop {
        let Ok(_) = device.poll(uart, meter);
        // The log goes out once the host has configured the device: a UART with nobody
        // listening (QEMU's pty before the host opens it) loses what it is sent, so the
        // ring keeps the start-up lines until then, and the handshake (Hello, Configure)
        // stays strictly one reply per command.
        if device.config().is_some() {
            drain_log(device, uart);
            // Said with the ring just emptied, so that the warning itself fits.
            if logger::dropped() != dropped {
                dropped = logger::dropped();
                defmt::warn!("log ring was full: {=u32} defmt frames dropped", dropped);
            }
        }
        if uart.take_overrun() {
            defmt::warn!("UART0 RX overrun: a received byte was lost");
        }
        let s = device.stats();
        if s.screen_cost_max > 0 && s.screen_cost != screenings {
            screenings = s.screen_cost;
            // The stack's peak (a scan of the painted region: only in a debug build of the
            // log, DEFMT_LOG=debug, which evaluates this line) is the device's whole: the
            // main loop's frames under the screening and every configuring so far.
            defmt::debug!(
                "screening: {=u32} (worst {=u32}); per sample mean {=u32}, worst {=u32}; stack peak {=usize} bytes since reset",
                s.screen_cost,
                s.screen_cost_max,
                s.cost_mean(),
                s.cost_max,
                lssi_firmware::stack::peak_used()
            );
        }
    }
}

/// Sends what the defmt logger's ring holds as `Log` frames. Its own frame, so that the
/// chunk is not in the main loop's, under the screening.
#[inline(never)]
fn drain_log(device: &mut Device<WINDOW, DEFAULT_TERMS, CHANNELS>, uart: &mut Uart0) {
    let mut chunk = [0u8; LOG_CHUNK];
    loop {
        let n = logger::take(&mut chunk);
        if n == 0 {
            break;
        }
        let Ok(()) = device.send_log(uart, &chunk[..n]);
    }
}
