//! The lssi standalone instrument on an STM32F411 ("Black Pill", 25 MHz crystal, run at
//! 96 MHz): TIM2 samples the sensor on PA0 through ADC1 at 10 kHz, the identify task runs on
//! a pended EXTI1 interrupt, thread mode screens on the snapshot and sends Model and Health
//! frames on USART1 (PA9 TX, PA10 RX, 921,600 baud) every second. defmt logs go over RTT
//! (`cargo run --release` with probe-rs). Wiring and use: docs/hardware.md.
//!
//! The application is `lssi_device::standalone`, the same code the QEMU image runs
//! (crates/lssi-firmware/src/bin/lssi-standalone.rs) and its tests exercise; this file wires
//! it to this part's peripherals through the vendor HAL.
//!
//! | context | priority | does |
//! |---|---|---|
//! | TIM2 update | 0x00 | one ADC conversion → the decimator; a row (every 50) → the 64-place queue, pends EXTI1 |
//! | USART1 | 0x40 | RX bytes into a ring; TX ring out on TXE |
//! | EXTI1 (pended) | 0x80 | queue → identifier rows; the snapshot at a screening point |
//! | SysTick (the slicer) | 0xF0 | thread mode awake for a slice: `wfi` until the next row |
//! | thread mode | lowest | screening on the snapshot, frames, host commands, `wfi` |
//!
//! The screening is spread over rows (no long wake-up): past [`SLICE_TICKS`] awake, the
//! slicer sleeps until a row period of conversions has passed and lets thread mode go on;
//! the same code on the same snapshot, so the same model (see crates/lssi-firmware's
//! lssi-standalone, where QEMU measures it).
//!
//! At power-up it starts from the configuration a host last sent (kept in flash sector 7,
//! [`store`]), or else from the image's own.
//!
//! Built with `--no-default-features --features netduinoplus2`, the same application runs
//! on QEMU's `netduinoplus2` machine (an STM32F405): see [`netduino`] for what differs.
//!
//! With the `system` feature it is the two-channel instrument: each TIM2 interrupt converts
//! PA0 (x) and then PA1 (the voltage across the harvester's load), both are decimated to
//! rows, and lssi-core's `SystemIdentifier` identifies x'' and V' (`SystemModel` frames; a
//! host's `ConfigureSystem` is applied, not kept in flash).

#![no_std]
#![no_main]
#![deny(unsafe_code)]

#[cfg(all(feature = "stm32f411", feature = "netduinoplus2"))]
compile_error!(
    "choose one part: the default (stm32f411) or `--no-default-features --features netduinoplus2`"
);
#[cfg(not(any(feature = "stm32f411", feature = "netduinoplus2")))]
compile_error!("choose a part: the default feature stm32f411, or netduinoplus2 (QEMU)");

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

#[cfg(not(feature = "netduinoplus2"))]
use cortex_m::peripheral::DWT;
use cortex_m::peripheral::NVIC;
use cortex_m::peripheral::scb::SystemHandler;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use critical_section::Mutex;
use defmt_rtt as _;
use heapless::spsc::{Consumer, Producer, Queue};
use lssi_core::Config;
use lssi_device::Transport;
use lssi_device::decimate::{self, Decimator};
use lssi_device::standalone::{
    Clock, EventQueue, IdentifyTask, Reading, Reporter, Sampler, Shared,
};
use panic_probe as _;
#[cfg(feature = "system")]
use stm32f4xx_hal::gpio::PA1;
#[cfg(not(feature = "netduinoplus2"))]
use stm32f4xx_hal::{
    adc::{
        Adc,
        config::{AdcConfig, SampleTime},
    },
    flash::LockedFlash,
    pac::ADC1,
};
use stm32f4xx_hal::{
    gpio::{Analog, PA0},
    pac::{self, Interrupt, TIM2, USART1, interrupt},
    prelude::*,
    serial::{Rx, Tx},
    timer::{CounterHz, Event as TimerEvent},
};

#[cfg(feature = "netduinoplus2")]
mod netduino;
// A system's configuration (`ConfigureSystem`) is not kept: only `load`'s caller differs.
#[cfg(not(feature = "netduinoplus2"))]
#[cfg_attr(feature = "system", allow(dead_code))]
mod store;

/// Window capacity, library capacity, channels (x only: one ADC channel; x and V with the
/// `system` feature).
const W: usize = 256;
const P: usize = 16;
#[cfg(not(feature = "system"))]
const C: usize = 1;
#[cfg(feature = "system")]
const C: usize = 2;
/// The core clock (the DWT cycle counter counts it).
#[cfg(not(feature = "netduinoplus2"))]
const CORE_HZ: u32 = 96_000_000;
/// The clock's rate: TIM5's ticks under QEMU (no DWT cycle counter there).
#[cfg(feature = "netduinoplus2")]
const CORE_HZ: u32 = netduino::CLOCK_HZ;
/// The ADC's conversion rate (TIM2): what the anti-alias filter in front of PA0 needs.
const RATE_HZ: u32 = 10_000;
/// The row rate of the image's configuration: the conversions are decimated by
/// `RATE_HZ / ROW_HZ` = 50 (a CIC of order [`CIC_ORDER`], lssi_device::decimate), about 60
/// rows a forcing period of a harvester forced at 3.4 Hz.
const ROW_HZ: u32 = 200;
/// The decimator's CIC order.
const CIC_ORDER: u8 = 3;
/// The ADC's reference, volts, and its full scale.
const VREF: f32 = 3.3;
const FULL_SCALE: f32 = 4095.0;

/// One equation (x'' from x).
#[cfg(not(feature = "system"))]
mod flavour {
    use super::{C, P, W};
    use lssi_core::{Config, Snapshot};

    pub type Id = lssi_device::standalone::Engine<W, P, C>;
    pub type Shot = Snapshot<f32, P>;
    pub type IdConfig = Config;
    pub const EMPTY: Shot = Snapshot::empty();

    pub fn config(base: Config) -> IdConfig {
        base
    }

    pub fn base(config: &IdConfig) -> &Config {
        config
    }
}

/// A system (x'' and V' from x on PA0 and V on PA1).
#[cfg(feature = "system")]
mod flavour {
    use super::{C, P, W};
    use lssi_core::library::Electrical;
    use lssi_core::{Config, SystemConfig};
    use lssi_device::standalone::SystemShot;

    pub type Id = lssi_device::standalone::SystemEngine<W, P, C>;
    pub type Shot = SystemShot<P>;
    pub type IdConfig = SystemConfig;
    pub const EMPTY: Shot = SystemShot::snapshot();

    /// The voltage as the electrical channel, coupling terms of degree 1 (`lssi identify`'s
    /// default).
    pub fn config(base: Config) -> IdConfig {
        SystemConfig {
            base,
            electrical: [Some(Electrical::Voltage), None],
            coupling_order: 1,
            displacements: 1,
        }
    }

    pub fn base(config: &IdConfig) -> &Config {
        &config.base
    }
}

use flavour::{EMPTY, Id, IdConfig, Shot};

mod once;
use once::TakeOnce;

#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.ENGINE")]
static ENGINE: TakeOnce<Id> = TakeOnce::new(Id::new());
#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.SNAPSHOT")]
static SNAPSHOT: TakeOnce<Shot> = TakeOnce::new(EMPTY);
static QUEUE: TakeOnce<EventQueue> = TakeOnce::new(Queue::new());
static RX_RING: TakeOnce<Queue<u8, 257>> = TakeOnce::new(Queue::new());
static TX_RING: TakeOnce<Queue<u8, 1537>> = TakeOnce::new(Queue::new());

static SHARED: Shared<P, Shot> = Shared::new();
static SENSOR: Mutex<RefCell<Option<Sensor>>> = Mutex::new(RefCell::new(None));
static IDENTIFY: IdentifyTask<W, P, C, Id> = IdentifyTask::new();
static UART: Mutex<RefCell<Option<Uart>>> = Mutex::new(RefCell::new(None));
/// Received bytes lost (ring full).
static RX_LOST: AtomicU32 = AtomicU32::new(0);
/// The clock when the core last woke.
static WOKE: AtomicU32 = AtomicU32::new(0);
/// TIM2's interrupts so far: the slicer sleeps until a row period of them has passed.
static TICKS: AtomicU32 = AtomicU32::new(0);
/// Thread mode's longest stretch awake before the slicer makes it sleep until the next row,
/// in [`BoardClock`] ticks: 1 ms, a fifth of a row at 200 rows a second.
const SLICE_TICKS: u32 = CORE_HZ / 1000;

/// What TIM2's interrupt owns.
struct Sensor {
    timer: CounterHz<TIM2>,
    #[cfg(not(feature = "netduinoplus2"))]
    adc: Adc<ADC1>,
    #[cfg(feature = "netduinoplus2")]
    adc: netduino::Converter,
    #[cfg_attr(feature = "netduinoplus2", allow(dead_code))]
    pin: PA0<Analog>,
    /// The voltage across the harvester's load (the `system` feature).
    #[cfg(feature = "system")]
    #[cfg_attr(feature = "netduinoplus2", allow(dead_code))]
    pin_v: PA1<Analog>,
    sampler: Sampler<'static>,
}

/// What USART1's interrupt owns.
struct Uart {
    tx: Tx<USART1>,
    rx: Rx<USART1>,
    rx_in: Producer<'static, u8>,
    tx_out: Consumer<'static, u8>,
}

/// The cycle counter: 96 MHz ticks, wrapping every 44 s (under QEMU, TIM5: virtual
/// nanoseconds, wrapping every 4.3 s).
struct BoardClock;

impl Clock for BoardClock {
    const HZ: u32 = CORE_HZ;
    fn now(&self) -> u32 {
        #[cfg(not(feature = "netduinoplus2"))]
        return DWT::cycle_count();
        #[cfg(feature = "netduinoplus2")]
        return netduino::now();
    }
}

/// The image's configuration: rows at [`ROW_HZ`], x only, a derivative window of a tenth
/// of a second, a row every sample, a screening a second; lssi-core's defaults otherwise.
fn default_config() -> Config {
    Config {
        sample_period: 1.0 / ROW_HZ as f64,
        window: (ROW_HZ / 10) as usize | 1,
        row_stride: 1,
        screening_period: ROW_HZ,
        ..Config::default()
    }
}

/// The decimator from [`RATE_HZ`] conversions to `config`'s rows, if its row period is a
/// whole number (1 to 255) of conversions.
fn decimator_for(config: &IdConfig) -> Option<Decimator> {
    let d = decimate::factor_for(f64::from(RATE_HZ), flavour::base(config).sample_period)?;
    Decimator::new(d, CIC_ORDER).ok()
}

#[entry]
fn main() -> ! {
    #[cfg_attr(feature = "netduinoplus2", allow(unused_mut))]
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        defmt::panic!("peripherals taken twice")
    };
    #[cfg(not(feature = "netduinoplus2"))]
    let clocks = {
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
        let rcc = dp.RCC.constrain();
        rcc.cfgr.use_hse(25.MHz()).sysclk(CORE_HZ.Hz()).freeze()
    };
    // The HSI (16 MHz) without the PLL: nothing waits on an RCC ready bit QEMU never sets.
    #[cfg(feature = "netduinoplus2")]
    let clocks = {
        let rcc = dp.RCC.constrain();
        rcc.cfgr.freeze()
    };

    // Statics with constant initialisers (`cortex_m::singleton!` built each value in this
    // frame and copied it: the identifier's 9.8 KB stayed in main's frame for good).
    let engine = ENGINE.take();
    let snapshot = SNAPSHOT.take();
    let queue = QUEUE.take();
    let rx_ring = RX_RING.take();
    let tx_ring = TX_RING.take();
    let (Some(engine), Some(snapshot), Some(queue), Some(rx_ring), Some(tx_ring)) =
        (engine, snapshot, queue, rx_ring, tx_ring)
    else {
        defmt::panic!("start-up ran twice")
    };
    #[cfg(not(feature = "netduinoplus2"))]
    let mut flash = LockedFlash::new(dp.FLASH);
    #[cfg(not(any(feature = "netduinoplus2", feature = "system")))]
    let (mut config, duty) = match store::load(&flash) {
        Ok(stored) => stored,
        Err(why) => {
            defmt::info!("no stored configuration ({}): the image's", why);
            (default_config(), None)
        }
    };
    #[cfg(any(feature = "netduinoplus2", feature = "system"))]
    let (mut config, duty) = (flavour::config(default_config()), None);
    let configured = match decimator_for(&config) {
        Some(d) => engine
            .configure_at(config, d.time_offset(f64::from(RATE_HZ)))
            .map(|()| d)
            .map_err(|e| {
                defmt::warn!(
                    "the stored configuration is refused ({})",
                    defmt::Debug2Format(&e)
                )
            }),
        None => {
            defmt::warn!("the stored row period is no whole number of conversions");
            Err(())
        }
    };
    let configured_from_store = configured.is_ok();
    let decimator = match configured {
        Ok(d) => d,
        Err(()) => {
            defmt::warn!("using the image's configuration");
            config = flavour::config(default_config());
            let Some(d) = decimator_for(&config) else {
                defmt::panic!("the image's row rate is no whole number of conversions")
            };
            if let Err(e) = engine.configure_at(config, d.time_offset(f64::from(RATE_HZ))) {
                defmt::panic!(
                    "the image's configuration is refused: {}",
                    defmt::Debug2Format(&e)
                );
            }
            d
        }
    };
    SHARED.give_snapshot(snapshot);
    let (producer, consumer) = queue.split();
    IDENTIFY.give(engine, consumer);
    let (rx_in, mut rx_out) = rx_ring.split();
    let (tx_in, tx_out) = tx_ring.split();

    let gpioa = dp.GPIOA.split();
    let pin = gpioa.pa0.into_analog();
    #[cfg(feature = "system")]
    let pin_v = gpioa.pa1.into_analog();
    #[cfg(not(feature = "netduinoplus2"))]
    let adc = Adc::adc1(dp.ADC1, true, AdcConfig::default());
    #[cfg(feature = "netduinoplus2")]
    let adc = netduino::Converter::new(dp.ADC1);
    let Ok(serial) = dp
        .USART1
        .serial((gpioa.pa9, gpioa.pa10), 921_600.bps(), &clocks)
    else {
        defmt::panic!("USART1 cannot run at 921600 baud with these clocks")
    };
    let (tx, mut rx) = serial.split();
    rx.listen();
    let mut timer = dp.TIM2.counter_hz(&clocks);
    if timer.start(RATE_HZ.Hz()).is_err() {
        defmt::panic!("TIM2 cannot run at {=u32} Hz", RATE_HZ);
    }
    timer.listen(TimerEvent::Update);
    #[cfg(feature = "netduinoplus2")]
    netduino::start_sampling(RATE_HZ);

    let mut sampler = Sampler::new(producer);
    sampler.set_decimator(decimator);
    critical_section::with(|cs| {
        SENSOR.borrow_ref_mut(cs).replace(Sensor {
            timer,
            adc,
            pin,
            #[cfg(feature = "system")]
            pin_v,
            sampler,
        });
        UART.borrow_ref_mut(cs).replace(Uart {
            tx,
            rx,
            rx_in,
            tx_out,
        });
    });
    #[cfg(not(feature = "netduinoplus2"))]
    defmt::info!(
        "lssi on STM32F411: {=u32} Hz on PA0 decimated by {=u32} to rows, frames on USART1",
        RATE_HZ,
        decimator.factor()
    );
    #[cfg(feature = "netduinoplus2")]
    defmt::info!(
        "lssi on STM32F405 (QEMU netduinoplus2): {=u32} Hz on PA0 decimated by {=u32} to rows, frames on USART1",
        RATE_HZ,
        decimator.factor()
    );
    let row_hz = (1.0 / flavour::base(&config).sample_period) as f32;
    let mut reporter: Reporter<W, P, C, Shot> = Reporter::new(config, row_hz, CORE_HZ);
    reporter.set_adc(
        f64::from(RATE_HZ),
        CIC_ORDER,
        decimator.time_offset(f64::from(RATE_HZ)),
    );
    // The stored duty cycle, if any (a stored configuration refused above leaves the
    // image's, which has none).
    reporter.set_duty(if configured_from_store { duty } else { None }, &SHARED);
    let mut link = Link { tx: tx_in };

    #[allow(unsafe_code)]
    // SAFETY: priorities are set before the interrupts are unmasked; critical sections here
    // disable interrupts (cortex-m's single-core implementation), none relies on masking by
    // priority.
    unsafe {
        cp.NVIC.set_priority(Interrupt::TIM2, 0x00);
        cp.NVIC.set_priority(Interrupt::USART1, 0x40);
        cp.NVIC.set_priority(Interrupt::EXTI1, 0x80);
        NVIC::unmask(Interrupt::TIM2);
        NVIC::unmask(Interrupt::USART1);
        NVIC::unmask(Interrupt::EXTI1);
    }

    // The slicer: SysTick at the lowest priority, every quarter of a slice of the core clock
    // (the handler measures the time awake by BoardClock itself), counting while awake.
    #[allow(unsafe_code)]
    // SAFETY: the slicer's priority is set before SysTick's interrupt is enabled.
    unsafe {
        cp.SCB.set_priority(SystemHandler::SysTick, 0xF0);
    }
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST
        .set_reload((clocks.hclk().raw() / 4000).clamp(2, 0x00FF_FFFF) - 1);
    cp.SYST.clear_current();
    cp.SYST.enable_interrupt();
    WOKE.store(BoardClock.now(), Ordering::Relaxed);
    slicer(true);

    loop {
        let Ok(idle) = reporter.pass(&mut rx_out, &SHARED, &mut link, &BoardClock, || {
            NVIC::pend(Interrupt::EXTI1)
        });
        if let Some(accepted) = reporter.take_accepted() {
            #[cfg(not(feature = "netduinoplus2"))]
            keep(&mut flash, &accepted);
            #[cfg(feature = "netduinoplus2")]
            defmt::info!(
                "configuration not kept: QEMU has no flash interface ({=usize} bytes)",
                core::mem::size_of_val(&accepted)
            );
        }
        if idle {
            cortex_m::interrupt::free(|_| {
                if !SHARED.screening_waiting() && !rx_out.ready() {
                    slicer(false);
                    sleep();
                    slicer(true);
                }
            });
        }
    }
}

/// Sleeps until an interrupt (called with interrupts off: it is taken right after).
fn sleep() {
    cortex_m::asm::wfi();
    WOKE.store(BoardClock.now(), Ordering::Relaxed);
}

/// Lets SysTick count (`on`, while the core is awake) or stops it (asleep: it would wake
/// the core).
fn slicer(on: bool) {
    const CSR: usize = 0xE000_E010;
    // ENABLE, TICKINT, CLKSOURCE (the processor clock): as set up in `main`.
    let csr = if on { 0b111 } else { 0b110 };
    #[allow(unsafe_code)]
    // SAFETY: SysTick's control register, owned by the slicer (set up in `main`).
    unsafe {
        core::ptr::write_volatile(CSR as *mut u32, csr);
    }
}

/// The slicer: if thread mode has been awake [`SLICE_TICKS`] since the core last woke (a
/// screening), sleeps until a row period of conversions has passed, then lets it go on.
#[exception]
fn SysTick() {
    if BoardClock.now().wrapping_sub(WOKE.load(Ordering::Relaxed)) < SLICE_TICKS {
        return;
    }
    let factor = critical_section::with(|cs| {
        SENSOR
            .borrow_ref(cs)
            .as_ref()
            .map_or(1, |s| s.sampler.decimator().factor())
    });
    let start = TICKS.load(Ordering::Relaxed);
    loop {
        let slept = cortex_m::interrupt::free(|_| {
            let waiting = TICKS.load(Ordering::Relaxed).wrapping_sub(start) < factor;
            if waiting {
                sleep();
            }
            waiting
        });
        if !slept {
            break;
        }
    }
}

#[cfg(not(feature = "netduinoplus2"))]
/// Keeps a host's configuration in flash. The erase stalls every interrupt for about a
/// second: the samples TIM2 could not take meanwhile are counted as overruns (the
/// identifier restarts with this configuration anyway).
fn keep(flash: &mut LockedFlash, config: &lssi_proto::WireConfig) {
    let start = BoardClock.now();
    let result = store::save(flash, config);
    let stalled = u64::from(BoardClock.now().wrapping_sub(start));
    let missed = stalled * u64::from(RATE_HZ) / u64::from(CORE_HZ);
    SHARED
        .counters
        .overruns
        .fetch_add(u32::try_from(missed).unwrap_or(u32::MAX), Ordering::Relaxed);
    match result {
        Ok(()) => defmt::info!(
            "configuration kept in flash ({=u64} samples missed)",
            missed
        ),
        Err(e) => defmt::warn!(
            "the configuration could not be kept: {}",
            defmt::Debug2Format(&e)
        ),
    }
}

/// Thread mode's end of USART1: frames into the TX ring, sent by the USART1 interrupt.
struct Link {
    tx: Producer<'static, u8>,
}

impl Transport for Link {
    type Error = core::convert::Infallible;

    fn read(&mut self, _: &mut [u8]) -> Result<usize, Self::Error> {
        Ok(0)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        for &b in bytes {
            while self.tx.enqueue(b).is_err() {
                NVIC::pend(Interrupt::USART1);
                cortex_m::asm::wfi();
            }
        }
        NVIC::pend(Interrupt::USART1);
        Ok(())
    }
}

#[interrupt]
fn TIM2() {
    let stamp = BoardClock.now();
    TICKS.fetch_add(1, Ordering::Relaxed);
    let row = critical_section::with(|cs| {
        if let Some(sensor) = SENSOR.borrow_ref_mut(cs).as_mut() {
            let _ = sensor.timer.wait();
            // Between the windows of a duty cycle no conversion is made: the sampler only
            // counts the time. (A board for the field would stop TIM2 and the ADC and wake
            // by the RTC instead: the F4 keeps its timer and ADC only out of Stop.)
            if !sensor.sampler.sampling() {
                let idle = Reading {
                    x: f32::NAN,
                    v: None,
                    u: None,
                    e: cfg!(feature = "system").then_some(f32::NAN),
                };
                return sensor.sampler.convert(stamp, idle, &SHARED);
            }
            #[cfg(not(feature = "netduinoplus2"))]
            let code = sensor.adc.convert(&sensor.pin, SampleTime::Cycles_56);
            #[cfg(feature = "netduinoplus2")]
            let code = sensor.adc.convert(0);
            // The second channel right after the first (56 + 12 ADC cycles: 2.8 µs at
            // 24 MHz, the pair's skew; a 1 kHz harvester phase error of 0.001 rad).
            #[cfg(all(feature = "system", not(feature = "netduinoplus2")))]
            let code_v = Some(sensor.adc.convert(&sensor.pin_v, SampleTime::Cycles_56));
            #[cfg(all(feature = "system", feature = "netduinoplus2"))]
            let code_v = Some(sensor.adc.convert(1));
            #[cfg(not(feature = "system"))]
            let code_v: Option<u16> = None;
            let reading = Reading {
                x: volts(code),
                v: None,
                u: None,
                e: code_v.map(volts),
            };
            sensor.sampler.convert(stamp, reading, &SHARED)
        } else {
            false
        }
    });
    // The identify task wakes once a row, not once a conversion.
    if row {
        NVIC::pend(Interrupt::EXTI1);
    }
}

/// An ADC code in volts; a reading at either rail is saturated: passed on as NaN, which the
/// identifier counts as rejected and skips like a gap (sampling goes on).
fn volts(code: u16) -> f32 {
    if code == 0 || f32::from(code) >= FULL_SCALE {
        f32::NAN
    } else {
        f32::from(code) * (VREF / FULL_SCALE)
    }
}

#[interrupt]
fn EXTI1() {
    IDENTIFY.run(&SHARED, &BoardClock);
}

#[interrupt]
fn USART1() {
    critical_section::with(|cs| {
        let mut uart = UART.borrow_ref_mut(cs);
        let Some(uart) = uart.as_mut() else {
            return;
        };
        while let Ok(b) = uart.rx.read() {
            if uart.rx_in.enqueue(b).is_err() {
                RX_LOST.fetch_add(1, Ordering::Relaxed);
            }
        }
        if uart.tx_out.ready() {
            if uart.tx.is_tx_empty()
                && let Some(b) = uart.tx_out.dequeue()
            {
                let _ = uart.tx.write(b);
            }
            uart.tx.listen();
        } else {
            uart.tx.unlisten();
        }
    });
}
