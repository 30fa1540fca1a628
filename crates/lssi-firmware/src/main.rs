//! The lssi Cortex-M4F image (QEMU's `mps2-an386` board stands in for the board).
//!
//! Start-up: cortex-m-rt paints the stack, then `main` brings up the cost meter and UART0,
//! logs `lssi firmware up` over defmt and hands the UART to the application: for now the
//! echo demo in `app.rs`; with `--features bench`, the benchmarks in `bench.rs`, after which
//! the run exits.
//!
//! Plugging in `lssi-device` later: add it as a dependency, implement its transport trait
//! for `Uart0` (replacing `transport.rs`), and replace the `app::run(&mut uart)` line below
//! with the device's command loop, e.g. `lssi_device::Device::new(config).run(&mut uart)`.

#![no_std]
#![no_main]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

#[cfg(not(feature = "bench"))]
mod app;
#[cfg(feature = "bench")]
mod bench;

use cortex_m_rt::entry;
use lssi_firmware::{cost, platform, stack, uart};

/// UART0's baud rate (QEMU ignores it; a real part needs it to match the host).
const BAUD: u32 = 115_200;

#[entry]
fn main() -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else {
        defmt::error!("core peripherals already taken");
        platform::exit(platform::EXIT_PANIC)
    };
    let meter = cost::Meter::new(core.SYST, &mut core.DCB, core.DWT);

    let uart = match uart::Uart0::take(uart::MPS2_PERIPHERAL_CLOCK_HZ, BAUD) {
        Ok(uart) => uart,
        Err(e) => {
            defmt::error!("UART0: {}", e);
            platform::exit(platform::EXIT_PANIC)
        }
    };

    defmt::info!("lssi firmware up");
    defmt::info!(
        "cost meter: {} in {=str}, {=u64} milli-{=str} per tick, overhead {=u64}; stack region {=usize} bytes",
        meter.source(),
        meter.unit().as_str(),
        meter.units_per_tick_milli(),
        meter.unit().as_str(),
        meter.overhead(),
        stack::size()
    );

    #[cfg(feature = "bench")]
    {
        // The benchmarks do not use the link; UART0 stays set up, as in a real image.
        let _uart = uart;
        let mut meter = meter;
        bench::run(&mut meter);
        defmt::info!("stack: peak {=usize} bytes since reset", stack::peak_used());
        platform::exit(platform::EXIT_SUCCESS)
    }

    #[cfg(not(feature = "bench"))]
    {
        let mut uart = uart;
        app::run(&mut uart)
    }
}
