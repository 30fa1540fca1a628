//! What differs between QEMU and a real board: the defmt transport, how the firmware stops,
//! and what a panic or a hard fault does.
//!
//! - feature `qemu` (default): defmt frames over semihosting to QEMU's stdout, decoded on
//!   the host by `defmt-print -e ELF`; [`exit`] ends QEMU with a status code.
//! - feature `rtt`: defmt frames over RTT for probe-rs; [`exit`] stops at a breakpoint.
//!
//! In both cases the defmt global logger is [`crate::logger`], which also keeps the frames
//! for the UART (`DeviceMsg::Log`).
//!
//! A panic or a hard fault is logged through defmt and ends the run with
//! [`EXIT_PANIC`] / [`EXIT_HARD_FAULT`], so a test under QEMU fails at once instead of
//! hanging until its timeout.

use core::sync::atomic::{AtomicBool, Ordering};

#[cfg(all(feature = "qemu", feature = "rtt"))]
compile_error!(
    "features `qemu` and `rtt` both pick a defmt transport: build for hardware with \
     `--no-default-features --features rtt`"
);

#[cfg(not(any(feature = "qemu", feature = "rtt")))]
compile_error!("pick a defmt transport: feature `qemu` (the default) or `rtt`");

/// Exit status of a clean run.
pub const EXIT_SUCCESS: i32 = 0;
/// Exit status after a panic.
pub const EXIT_PANIC: i32 = 101;
/// Exit status after a hard fault.
pub const EXIT_HARD_FAULT: i32 = 102;

/// Ends the run: under QEMU the process exits with `code`; on hardware the core stops at a
/// breakpoint (probe-rs reports it and stops).
pub fn exit(code: i32) -> ! {
    #[cfg(feature = "qemu")]
    {
        semihosting::process::exit(code)
    }
    #[cfg(not(feature = "qemu"))]
    {
        let _ = code;
        loop {
            cortex_m::asm::bkpt();
        }
    }
}

/// Set by the first panic: a panic while reporting one must not recurse.
static PANICKING: AtomicBool = AtomicBool::new(false);

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::interrupt::disable();
    if !PANICKING.swap(true, Ordering::Relaxed) {
        // Where it panicked, not what it said: printing the message pulls core::fmt's
        // formatting machinery and the messages' text into flash (2.9 KB of the device
        // image). Build with `--features panic-message` to have the whole message.
        #[cfg(feature = "panic-message")]
        defmt::error!("panic: {}", defmt::Display2Format(info));
        #[cfg(not(feature = "panic-message"))]
        match info.location() {
            Some(at) => defmt::error!("panic at {=str}:{=u32}", at.file(), at.line()),
            None => defmt::error!("panic"),
        }
    }
    exit(EXIT_PANIC)
}

/// `defmt::panic!` and friends: the message is already logged.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    exit(EXIT_PANIC)
}

#[allow(unsafe_code)]
#[cortex_m_rt::exception]
// cortex-m-rt requires the HardFault handler to be an `unsafe fn`; its body does nothing
// unsafe.
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    defmt::error!(
        "hard fault: pc={=u32:#010x} lr={=u32:#010x} xpsr={=u32:#010x}",
        frame.pc(),
        frame.lr(),
        frame.xpsr()
    );
    exit(EXIT_HARD_FAULT)
}
