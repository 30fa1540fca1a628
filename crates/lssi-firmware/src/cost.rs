//! Per-call cost of a piece of code, in instructions under QEMU and in cycles on silicon.
//!
//! Two time sources:
//!
//! - **DWT `CYCCNT`**, the cycle counter of real Cortex-M3/M4/M7 parts. QEMU does not model
//!   it (it reads 0), so [`Meter::new`] enables it, lets a few cycles pass and keeps it only
//!   if it moved.
//! - **SysTick**, otherwise: reload `0xFF_FFFF`, clocked from the core clock, with an
//!   exception counting wraps so that a measurement may span any number of them. Under
//!   `qemu-system-arm -icount shift=0` every guest instruction advances virtual time by
//!   exactly 1 ns and SysTick runs at the board's 25 MHz, so one tick is a fixed number of
//!   instructions (40). [`Meter::new`] does not take that on trust: it times
//!   [`cortex_m::asm::delay`] — a `subs`/`bne` loop of exactly 2 instructions per turn — at
//!   two lengths, and converts ticks to instructions with the ratio it finds. On silicon,
//!   SysTick ticks are core clock cycles and are reported as such.
//!
//! The mean cost of the measuring itself (an empty closure) is subtracted. Under QEMU one
//! reading is exact to a tick (40 instructions): a single call's figure is within ±40 of
//! the truth, a mean over many calls much closer.
//!
//! ```ignore
//! let mut meter = cost::Meter::new(core.SYST, &mut core.DCB, core.DWT);
//! let (sum, instructions) = meter.measure(|| (0..100u32).sum::<u32>());
//! ```

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::{DCB, DWT, SCB, SYST, syst::SystClkSource};
use cortex_m_rt::exception;

/// SysTick's reload value: its full 24 bits.
const SYSTICK_RELOAD: u32 = 0x00FF_FFFF;

/// SysTick wraps since the meter started; bumped by the SysTick exception.
static SYSTICK_WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    SYSTICK_WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// The delay-loop lengths timed to find instructions per tick (iterations of 2 instructions).
/// 20 million instructions apart: 500 000 ticks under QEMU, so the ratio is good to 1e-5.
const CALIBRATION_SHORT: u32 = 10_000;
const CALIBRATION_LONG: u32 = 10_010_000;

/// Which counter a [`Meter`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Source {
    /// The DWT cycle counter (real silicon).
    DwtCycleCounter,
    /// SysTick on the core clock with a wrap counter.
    SysTick,
}

/// What a [`Meter`]'s figures count.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Unit {
    /// Executed instructions (SysTick under QEMU `-icount`).
    Instructions,
    /// Core clock cycles (silicon).
    Cycles,
}

impl Unit {
    /// The unit's name for logs, plural.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Instructions => "instructions",
            Self::Cycles => "cycles",
        }
    }
}

/// Measures the cost of closures; owns SysTick and the DWT.
pub struct Meter {
    source: Source,
    unit: Unit,
    /// Units per tick as the fraction `per_tick_num / per_tick_den`.
    per_tick_num: u64,
    per_tick_den: u64,
    /// Units that measuring an empty closure costs, on average.
    overhead_units: u64,
    _syst: SYST,
    _dwt: DWT,
}

impl Meter {
    /// Starts the counters, picks the source, calibrates and measures its own overhead.
    pub fn new(mut syst: SYST, dcb: &mut DCB, mut dwt: DWT) -> Self {
        dcb.enable_trace();
        DWT::unlock();
        dwt.set_cycle_count(0);
        dwt.enable_cycle_counter();
        cortex_m::asm::delay(100);
        let source = if DWT::cycle_count() != 0 {
            Source::DwtCycleCounter
        } else {
            dwt.disable_cycle_counter();
            syst.disable_counter();
            syst.set_clock_source(SystClkSource::Core);
            syst.set_reload(SYSTICK_RELOAD);
            syst.clear_current();
            SYSTICK_WRAPS.store(0, Ordering::Relaxed);
            syst.enable_interrupt();
            syst.enable_counter();
            // The counter reads 0 until its first tick loads the reload value; a reading
            // taken then would look like the end of a period rather than its start.
            while SYST::get_current() == 0 {
                core::hint::spin_loop();
            }
            Source::SysTick
        };
        let unit = if cfg!(feature = "qemu") && source == Source::SysTick {
            Unit::Instructions
        } else {
            Unit::Cycles
        };
        let mut meter = Self {
            source,
            unit,
            per_tick_num: 1,
            per_tick_den: 1,
            overhead_units: 0,
            _syst: syst,
            _dwt: dwt,
        };
        if unit == Unit::Instructions {
            let (num, den) = meter.calibrate();
            if num > 0 && den > 0 {
                meter.per_tick_num = num;
                meter.per_tick_den = den;
            }
        }
        meter.overhead_units = meter.mean_overhead_units();
        meter
    }

    /// The mean cost of measuring nothing. A single SysTick reading under QEMU is exact only
    /// to a tick (40 instructions), so the empty measurement is repeated from start points
    /// spread over a tick by delay loops of 2 to 40 instructions, and averaged.
    fn mean_overhead_units(&mut self) -> u64 {
        const RUNS: u32 = 400;
        let mut ticks = 0u64;
        for i in 0..RUNS {
            cortex_m::asm::delay(i % 20);
            ticks += self.ticks_of(|| ()).1;
        }
        ticks * self.per_tick_num / (self.per_tick_den * u64::from(RUNS))
    }

    /// Times the 2-instruction delay loop at two lengths: `(instructions, ticks)` between them.
    fn calibrate(&mut self) -> (u64, u64) {
        let (_, short) = self.ticks_of(|| cortex_m::asm::delay(CALIBRATION_SHORT));
        let (_, long) = self.ticks_of(|| cortex_m::asm::delay(CALIBRATION_LONG));
        let instructions = 2 * u64::from(CALIBRATION_LONG - CALIBRATION_SHORT);
        (instructions, long.saturating_sub(short))
    }

    /// The counter in use.
    pub fn source(&self) -> Source {
        self.source
    }

    /// What [`Meter::measure`] returns.
    pub fn unit(&self) -> Unit {
        self.unit
    }

    /// The mean cost of measuring an empty closure, subtracted from every figure.
    pub fn overhead(&self) -> u64 {
        self.overhead_units
    }

    /// Units per tick, times 1000 (40 000 under QEMU `-icount shift=0`).
    pub fn units_per_tick_milli(&self) -> u64 {
        (self.per_tick_num * 1000 + self.per_tick_den / 2) / self.per_tick_den
    }

    /// Runs `f` and returns its result with its cost in [`Meter::unit`]s, less the cost of
    /// measuring; saturates at `u32::MAX`. With SysTick, interrupts must not stay masked
    /// for more than one wrap (2^24 ticks) during `f`.
    pub fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        let (result, ticks) = self.ticks_of(f);
        let units =
            (ticks * self.per_tick_num / self.per_tick_den).saturating_sub(self.overhead_units);
        (result, u32::try_from(units).unwrap_or(u32::MAX))
    }

    /// Runs `f`; its result and the ticks it took, overhead included.
    #[inline(always)]
    fn ticks_of<R>(&mut self, f: impl FnOnce() -> R) -> (R, u64) {
        match self.source {
            Source::DwtCycleCounter => {
                let start = DWT::cycle_count();
                let result = f();
                let end = DWT::cycle_count();
                (result, u64::from(end.wrapping_sub(start)))
            }
            Source::SysTick => {
                let start = systick_now();
                let result = f();
                let end = systick_now();
                (result, end.wrapping_sub(start))
            }
        }
    }
}

/// Ticks since the meter started: wraps × 2^24 + elapsed part of the current wrap.
#[inline(always)]
fn systick_now() -> u64 {
    loop {
        let wraps = SYSTICK_WRAPS.load(Ordering::Acquire);
        let current = SYST::get_current();
        // A wrap whose exception has not run yet: count it if `current` was read after the
        // reload (the counter is then near the top, not near 0).
        let pending = SCB::is_pendst_pending();
        if SYSTICK_WRAPS.load(Ordering::Acquire) != wraps {
            continue;
        }
        let wraps = u64::from(wraps) + u64::from(pending && current > SYSTICK_RELOAD / 2);
        return (wraps << 24) | u64::from(SYSTICK_RELOAD - current);
    }
}

/// The device application's cost meter: the same figures as [`Meter::measure`], in
/// instructions under QEMU and in cycles on silicon.
impl lssi_device::CostMeter for Meter {
    fn unit(&self) -> lssi_device::CostUnit {
        match self.unit {
            Unit::Instructions => lssi_device::CostUnit::Instructions,
            Unit::Cycles => lssi_device::CostUnit::Cycles,
        }
    }

    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        Meter::measure(self, f)
    }
}
