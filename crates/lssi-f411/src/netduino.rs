//! What differs when this crate is built for QEMU's `netduinoplus2` machine (an STM32F405,
//! `--no-default-features --features netduinoplus2`; scripts/netduinoplus2.sh runs it).
//! QEMU 7.2 models the F405's USARTs, TIM2–5, ADC1–3 and EXTI, but not its RCC, flash
//! interface, DWT cycle counter or system memory; so this build
//!
//! - runs from the HSI (16 MHz, the reset clock) without the PLL, waiting on no ready bit;
//! - reads time from TIM5 (QEMU's virtual nanoseconds) instead of the DWT cycle counter
//!   ([`now`]);
//! - sets TIM2's prescaler, reload and count for QEMU's timer model (clocked at 1 GHz
//!   whatever RCC holds, and periodic only from a zero tick offset) ([`start_sampling`]);
//! - converts on ADC1 by its registers ([`Converter`]): QEMU's ADC never sets the STRT and
//!   EOC flags the HAL's `convert` waits on, and the HAL's `Adc::adc1` reads the VREFINT
//!   calibration from system memory, which QEMU leaves unmapped (a bus fault);
//! - keeps no configuration in flash (QEMU has no flash interface; the HAL reads the flash
//!   size from system memory too).
//!
//! QEMU's ADC returns a synthetic ramp (the previous code plus 7, modulo 4,096) each time
//! its data register is read after a start: the identifier gets a sawtooth, not a
//! harvester. The point of this build is the board's paths (clocks, timer interrupt, ADC,
//! USART interrupts, `wfi`, frames), not the model.

#![allow(unsafe_code)]

use stm32f4xx_hal::pac::{ADC1, TIM2, TIM5};

/// The clock QEMU's STM32F2xx timer model counts, whatever RCC is set to.
pub const TIMER_HZ: u32 = 1_000_000_000;
/// The rate [`now`] ticks at: TIM5 left as reset counts QEMU's virtual nanoseconds,
/// wrapping every 4.3 s.
pub const CLOCK_HZ: u32 = TIMER_HZ;
/// TIM2's prescaler for sampling: 1 MHz counts.
const SAMPLING_PRESCALER: u32 = TIMER_HZ / 1_000_000 - 1;

/// TIM5's count: [`CLOCK_HZ`] ticks. QEMU's model counts from its reset at virtual time 0
/// with the prescaler at 0 and ignores the reload, so TIM5, never written, reads the
/// virtual time in nanoseconds (its low 32 bits) without being started.
pub fn now() -> u32 {
    // SAFETY: a read of TIM5's counter, which nothing writes (the TIM5 peripheral is
    // never taken); no side effect.
    unsafe { (*TIM5::ptr()).cnt().read().bits() }
}

/// Sets TIM2's prescaler and reload so that its update comes `rate_hz` times a second on
/// QEMU's timer clock (the HAL set them for the 16 MHz it configured), and arms it. Call
/// after the HAL started the timer and enabled its update interrupt; `rate_hz` must
/// divide 1 MHz.
///
/// QEMU 7.2's model (hw/timer/stm32f2xx_timer.c) schedules each update at the current
/// virtual time plus the *absolute* time of the next reload computed from its tick offset
/// (the virtual time, in counts, when the count was last set): with any offset but 0 the
/// updates come ever later (twice the time since boot). Setting the count to the virtual
/// time in counts makes that offset 0, and then every update schedules the next one
/// reload counts later, for as long as the interrupt stays enabled.
pub fn start_sampling(rate_hz: u32) {
    let reload = 1_000_000 / rate_hz;
    // SAFETY: TIM2 is owned by the HAL's counter, whose interrupt is still masked; these
    // writes change its period and count, as `start` would.
    unsafe {
        let tim2 = &*TIM2::ptr();
        tim2.psc().write(|w| w.bits(SAMPLING_PRESCALER));
        tim2.arr().write(|w| w.bits(reload));
        let counts = now() / (TIMER_HZ / 1_000_000);
        tim2.cnt().write(|w| w.bits(counts));
    }
}

/// ADC1 converting channel 0 (PA0), and channel 1 (PA1) for a system, one conversion at a
/// time, by its registers.
pub struct Converter {
    adc: ADC1,
}

impl Converter {
    /// One channel in the regular sequence (channel 0 until [`Converter::convert`] names
    /// another), 56 cycles of sampling on channels 0 and 1, 12 bits, right aligned, the ADC on.
    pub fn new(adc: ADC1) -> Self {
        // SAFETY: register writes to the ADC this function owns; the values are the
        // reference manual's (RM0090 §13.13): SMP0 = SMP1 = 0b011 (56 cycles), SQ1 = 0, L = 0.
        unsafe {
            adc.cr1().write(|w| w.bits(0));
            adc.smpr2().write(|w| w.bits(0b011_011)); // SMP0, SMP1: 56 cycles
            adc.sqr1().write(|w| w.bits(0));
            adc.sqr3().write(|w| w.bits(0));
            adc.cr2().write(|w| w.bits(1)); // ADON
        }
        Self { adc }
    }

    /// Starts a conversion of `channel` (0: PA0, 1: PA1) and reads it. QEMU's model
    /// converts on the data register's read after SWSTART and never sets EOC, so nothing
    /// is waited on (silicon would need the HAL's `convert`, which waits for EOC).
    pub fn convert(&mut self, channel: u8) -> u16 {
        // SAFETY: SQ1 (bits 0-4 of SQR3) names the channel the next conversion reads.
        unsafe {
            self.adc.sqr3().write(|w| w.bits(u32::from(channel & 0x1F)));
        }
        self.adc.cr2().modify(|_, w| w.swstart().set_bit());
        self.adc.dr().read().data().bits()
    }
}
