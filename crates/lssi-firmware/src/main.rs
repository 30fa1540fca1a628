//! The lssi Cortex-M4F image (QEMU's `mps2-an386` board stands in for the board).
//!
//! Start-up: cortex-m-rt paints the stack, then `main` brings up the cost meter and UART0,
//! logs `lssi firmware up` over defmt and hands both to the application, lssi-device's
//! command loop (`app.rs`). With `--features bench` or `bench-identifier` the benchmarks run
//! instead (`bench.rs`, `bench_identifier.rs`), after which the run exits.

#![no_std]
#![no_main]
// `deny`, not `forbid`: `cortex_m::singleton!` (a sound, safe macro) opts in inside.
#![deny(unsafe_code)]
#![deny(missing_docs)]

#[cfg(not(any(
    feature = "bench",
    feature = "bench-identifier",
    feature = "bench-system"
)))]
mod app;
#[cfg(feature = "bench")]
mod bench;
#[cfg(feature = "bench-identifier")]
mod bench_identifier;
#[cfg(feature = "bench-system")]
mod bench_system;

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

    #[cfg(any(
        feature = "bench",
        feature = "bench-identifier",
        feature = "bench-system"
    ))]
    {
        // The benchmarks do not use the link; UART0 stays set up, as in a real image.
        let _uart = uart;
        let mut meter = meter;
        #[cfg(feature = "bench")]
        bench::run(&mut meter);
        #[cfg(feature = "bench-identifier")]
        bench_identifier::run(&mut meter);
        #[cfg(feature = "bench-system")]
        bench_system::run(&mut meter);
        defmt::info!("stack: peak {=usize} bytes since reset", stack::peak_used());
        platform::exit(platform::EXIT_SUCCESS)
    }

    #[cfg(not(any(
        feature = "bench",
        feature = "bench-identifier",
        feature = "bench-system"
    )))]
    {
        let (mut uart, mut meter) = (uart, meter);
        app::run(&mut uart, &mut meter)
    }
}
