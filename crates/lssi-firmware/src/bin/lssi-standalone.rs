//! The standalone instrument on QEMU's `mps2-an386`: samples its "sensor" (a recording in
//! PSRAM, see `lssi_firmware::mps2`) by TIMER0, identifies, and reports Model and Health
//! frames on UART0 by itself (every second; every minute, with a new model every 5 minutes,
//! at a harvester's row rates: [`LOW_POWER_ROW_HZ`]); a host may connect at any time and query or
//! reconfigure (`lssi monitor`). The application logic is lssi-device's `standalone`
//! module, shared with the STM32F411 board (crates/lssi-board-f411).
//!
//! | context | priority | does |
//! |---|---|---|
//! | TIMER0 | 0x00 | one conversion → the decimator; a row → the 64-place queue (overruns counted), pends identify |
//! | UART0 RX/TX | 0x40 | bytes ↔ bounded rings |
//! | identify (IRQ 10, pended) | 0x80 | queue → identifier rows; a screening's snapshot to thread mode |
//! | SysTick (the slicer) | 0xE0 | thread mode awake for a slice: `wfi` until the next row |
//! | thread mode | lowest | the screening on the snapshot; frames; host commands; `wfi` |
//!
//! **No long wake-up.** The screening (≈ 8 M instructions at the configuration `lssi
//! identify` picks for eveh at 200 rows a second) is spread over rows: while thread mode is
//! awake, SysTick counts [`SLICE_TICKS`]; when it fires, its handler (the lowest priority,
//! so it preempts only thread mode) sleeps with `wfi` until a row period of conversions has
//! passed (the rows and conversions are taken meanwhile, at their own priorities), then
//! returns, and the screening goes on where it was. The screening is the same code on the
//! same snapshot, so its model is the same bit for bit; it ends a few hundred rows later
//! instead of in one wake-up of a few hundred milliseconds.
//!
//! When the recording ends, the last model (a screening of every sample, as `lssi identify`
//! makes; sliced like the rest, the timer going on as the slicer's clock) and a Health frame
//! go out, the UART drains and QEMU exits with status 0.
//!
//! Built with the `system` feature, it is the two-channel instrument: each conversion reads
//! x and the voltage V across the harvester's load (the recording's electrical channel),
//! both decimated to rows, and lssi-core's `SystemIdentifier` identifies x'' and V'
//! (`SystemModel` frames; a stored or host's `ConfigureSystem`).

#![no_std]
#![no_main]
#![deny(unsafe_code)]
#![deny(missing_docs)]

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use cortex_m::peripheral::NVIC;
use cortex_m::peripheral::scb::SystemHandler;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use critical_section::Mutex;
use heapless::spsc::{Consumer, Producer, Queue};
use lssi_core::Config;
use lssi_device::decimate::{self, Decimator};
use lssi_device::standalone::{Clock, EventQueue, IdentifyTask, Reporter, Sampler, Shared};
use lssi_device::{DEFAULT_TERMS, Transport};
use lssi_firmware::mps2::{self, BoardClock, Irq, Recording};
use lssi_firmware::once::TakeOnce;
use lssi_firmware::{CHANNELS, WINDOW, platform, uart};
use lssi_proto::{HostMsg, WireDuty, decode_frame};

/// One equation (x'' from x): the default image.
#[cfg(not(feature = "system"))]
mod flavour {
    use lssi_core::{Config, Snapshot};
    use lssi_device::DEFAULT_TERMS;
    use lssi_device::standalone::Engine;
    use lssi_firmware::{CHANNELS, WINDOW};
    use lssi_proto::{HostMsg, WireDuty};

    pub type Id = Engine<WINDOW, DEFAULT_TERMS, CHANNELS>;
    pub type Shot = Snapshot<f32, DEFAULT_TERMS>;
    pub type IdConfig = Config;
    pub const EMPTY: Shot = Snapshot::empty();

    /// The image's configuration for the recording's channels.
    pub fn config(base: Config) -> IdConfig {
        base
    }

    pub fn base(config: &mut IdConfig) -> &mut Config {
        config
    }

    pub fn from_host(message: HostMsg) -> Option<(IdConfig, Option<WireDuty>)> {
        match message {
            HostMsg::Configure(c) => Some((lssi_device::wire::config_from_wire(&c), c.duty)),
            _ => None,
        }
    }
}

/// A system (x'' and V' from x and V): the `system` feature's image.
#[cfg(feature = "system")]
mod flavour {
    use lssi_core::library::Electrical;
    use lssi_core::{Config, SystemConfig};
    use lssi_device::DEFAULT_TERMS;
    use lssi_device::standalone::{SystemEngine, SystemShot};
    use lssi_firmware::{CHANNELS, WINDOW};
    use lssi_proto::{HostMsg, WireDuty};

    pub type Id = SystemEngine<WINDOW, DEFAULT_TERMS, CHANNELS>;
    pub type Shot = SystemShot<DEFAULT_TERMS>;
    pub type IdConfig = SystemConfig;
    pub const EMPTY: Shot = SystemShot::snapshot();

    /// The image's configuration: the voltage as the electrical channel, coupling terms of
    /// degree 1 (`lssi identify`'s default).
    pub fn config(base: Config) -> IdConfig {
        SystemConfig {
            base,
            electrical: [Some(Electrical::Voltage), None],
            coupling_order: 1,
            displacements: 1,
        }
    }

    pub fn base(config: &mut IdConfig) -> &mut Config {
        &mut config.base
    }

    pub fn from_host(message: HostMsg) -> Option<(IdConfig, Option<WireDuty>)> {
        match message {
            HostMsg::ConfigureSystem(c) => Some((
                lssi_device::system::system_config_from_wire(&c),
                c.base.duty,
            )),
            _ => None,
        }
    }
}

use flavour::{EMPTY, Id, IdConfig, Shot};

/// Bytes the receive ring holds (one more slot than that).
const RX_SLOTS: usize = 257;
/// Bytes the transmit ring holds (one more slot than that): two Model frames.
const TX_SLOTS: usize = 1537;

static SHARED: Shared<DEFAULT_TERMS, Shot> = Shared::new();
#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.ENGINE")]
static ENGINE: TakeOnce<Id> = TakeOnce::new(Id::new());
#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.SNAPSHOT")]
static SNAPSHOT: TakeOnce<Shot> = TakeOnce::new(EMPTY);
static QUEUE: TakeOnce<EventQueue> = TakeOnce::new(Queue::new());
static RX: TakeOnce<Queue<u8, RX_SLOTS>> = TakeOnce::new(Queue::new());
static TX: TakeOnce<Queue<u8, TX_SLOTS>> = TakeOnce::new(Queue::new());

/// What the timer interrupt owns.
struct Sensor {
    sampler: Sampler<'static>,
    recording: Recording,
    next: u32,
}

static SENSOR: Mutex<RefCell<Option<Sensor>>> = Mutex::new(RefCell::new(None));
static IDENTIFY: IdentifyTask<WINDOW, DEFAULT_TERMS, CHANNELS, Id> = IdentifyTask::new();
static RX_IN: Mutex<RefCell<Option<Producer<'static, u8>>>> = Mutex::new(RefCell::new(None));
static TX_OUT: Mutex<RefCell<Option<Consumer<'static, u8>>>> = Mutex::new(RefCell::new(None));
/// The TX interrupt found the ring empty: the next write must start it again.
static TX_IDLE: AtomicBool = AtomicBool::new(true);
/// Received bytes lost (ring full or UART overrun).
static RX_LOST: AtomicU32 = AtomicU32::new(0);
/// The longest the core stayed awake between two `wfi`s while sampling, clock ticks (the
/// interrupts taken in between included): the longest wake-up, what a harvester's storage
/// capacitor must carry at run current.
static AWAKE_MAX: AtomicU32 = AtomicU32::new(0);
/// The same once the recording ended (QEMU's recording only: the final screening, sliced
/// like the rest, the timer going on as the slicer's clock).
static AWAKE_MAX_ENDED: AtomicU32 = AtomicU32::new(0);
/// `wfi`s executed (wake-ups).
static SLEEPS: AtomicU32 = AtomicU32::new(0);
/// Clock ticks awake while sampling, all wake-ups together (what the energy figure of
/// scripts/firmware-bench.sh takes: rows, conversions, frames and screenings).
static AWAKE_TOTAL: Mutex<core::cell::Cell<u64>> = Mutex::new(core::cell::Cell::new(0));
/// Clock ticks awake after the recording ended (the final screening, sliced, and its
/// frames): what a screening costs, as the sliced screening's own clock time is not.
static AWAKE_ENDED: Mutex<core::cell::Cell<u64>> = Mutex::new(core::cell::Cell::new(0));
/// The clock when the core last woke.
static WOKE: AtomicU32 = AtomicU32::new(0);
/// TIMER0's interrupts so far (conversions, or their times in an interval): the slicer
/// sleeps until a row period of them has passed.
static TICKS: AtomicU32 = AtomicU32::new(0);
/// The sampling timer stopped (the recording ended): the slicer sleeps no more.
static STOPPED: AtomicBool = AtomicBool::new(false);
/// TIMER0's interrupts when the recording ended (the timer goes on after it).
static TICKS_ENDED: AtomicU32 = AtomicU32::new(0);
/// Times the slicer put thread mode to sleep until the next row.
static SLICES: AtomicU32 = AtomicU32::new(0);

/// Thread mode's longest stretch awake before the slicer makes it sleep until the next row,
/// in SysTick counts (the 25 MHz system clock): 1 ms, a fifth of a row at 200 rows a second
/// (62,500 instructions under `-icount shift=4`; 16,000 cycles of an L432 at 16 MHz).
pub const SLICE_TICKS: u32 = 25_000;

/// The row rate of the image's own configuration, Hz: about 60 rows a forcing period of
/// a harvester forced at 3.4 Hz (eveh, Ω = 21.4 rad/s), 10 a period at 20 Hz. The ADC
/// (the recording's rate) is decimated to it by a whole factor.
pub const DEFAULT_ROW_HZ: f64 = 200.0;

/// Rows a second up to which the image takes itself to be on a harvester's power (the
/// rates `lssi identify` proposes for harvesters: 50 samples a period of a 3–20 Hz line):
/// it then runs a scheduled screening, and reports a new model, only about every
/// [`MODEL_INTERVAL_S`]. Above it (a bench instrument at kHz rates) every scheduled
/// screening runs.
pub const LOW_POWER_ROW_HZ: f64 = 1000.0;

/// Seconds between the models a device on a harvester's power screens and reports (the
/// scheduled screenings in between are left out whole; the rows, the K re-choice and so the
/// models made are the same bit for bit). A screening at eveh's configuration is ≈ 7.5 M
/// instructions; one every 48 s (`lssi identify`'s 10 000 rows at 210 Hz) was 37 % of the
/// instructions on top of the rows (scripts/firmware-power.sh). A harvester changes over
/// weeks: a model every 5 minutes tracks it.
pub const MODEL_INTERVAL_S: f64 = 300.0;

/// Seconds between the unsolicited Model and Health frames of a device on a harvester's
/// power (every second above [`LOW_POWER_ROW_HZ`]). A frame costs the core tens of
/// thousands of instructions (encoding, CRC, a UART interrupt a byte): at 210 rows a second
/// a Model and a Health every second were ≈ 0.2 of the instructions of the rows
/// (scripts/firmware-power.sh). A host's Query is answered at once either way.
pub const LOW_POWER_REPORT_S: u32 = 60;

/// Clock ticks between the unsolicited reports for `config`.
fn report_ticks(config: &Config) -> u32 {
    if config.sample_period * LOW_POWER_ROW_HZ >= 1.0 {
        BoardClock::HZ.saturating_mul(LOW_POWER_REPORT_S)
    } else {
        BoardClock::HZ
    }
}

/// The stride of scheduled screenings for `config` (see [`LOW_POWER_ROW_HZ`]).
fn model_stride(config: &Config) -> u32 {
    if config.sample_period * LOW_POWER_ROW_HZ >= 1.0 {
        lssi_device::standalone::model_stride_for(MODEL_INTERVAL_S, config)
    } else {
        1
    }
}

/// The CIC order of the decimation (see lssi_device::decimate): −57 dB on what folds onto
/// a tenth of the row rate.
pub const CIC_ORDER: u8 = 3;

/// The decimation factor of the image's own configuration for an ADC converting at
/// `adc_hz`: the whole number of conversions nearest to a row at [`DEFAULT_ROW_HZ`].
fn default_factor(adc_hz: f64) -> u32 {
    let d = libm::round(adc_hz / DEFAULT_ROW_HZ);
    (d as u32).clamp(1, lssi_device::decimate::MAX_FACTOR)
}

/// The image's own configuration, used when no configuration is stored: rows at about
/// [`DEFAULT_ROW_HZ`] (a whole number of the ADC's conversions at `adc_hz`), a derivative
/// window of a tenth of a second at that rate, a row every sample, a screening a second;
/// lssi-core's defaults otherwise.
fn default_config(adc_hz: f64) -> Config {
    let d = default_factor(adc_hz);
    let row_hz = adc_hz / f64::from(d);
    let window = ((row_hz / 10.0) as usize | 1).clamp(7, WINDOW - 1);
    Config {
        sample_period: f64::from(d) / adc_hz,
        window,
        row_stride: 1,
        screening_period: (row_hz as u32).max(100),
        ..Config::default()
    }
}

/// Configures `engine` with `config`, its rows decimated from the ADC's `adc_hz` (a whole
/// number of conversions a row); the decimator, or `None` if either is refused.
fn configure(engine: &mut Id, adc_hz: f64, mut config: IdConfig) -> Option<Decimator> {
    let period = flavour::base(&mut config).sample_period;
    let Some(d) = decimate::factor_for(adc_hz, period) else {
        defmt::warn!(
            "a row period of {=f64} s is no whole number of conversions at {=f64} Hz",
            period,
            adc_hz
        );
        return None;
    };
    let decimator = Decimator::new(d, CIC_ORDER).ok()?;
    match engine.configure_at(config, decimator.time_offset(adc_hz)) {
        Ok(()) => Some(decimator),
        Err(e) => {
            defmt::warn!("configuration refused ({})", defmt::Display2Format(&e));
            None
        }
    }
}

/// The stored configuration (a host's `Configure` frame) and its duty cycle, if there is a
/// valid one.
fn stored_config(recording: &Recording) -> Option<(IdConfig, Option<WireDuty>)> {
    let mut buffer = [0u8; mps2::MAX_CONFIG];
    let frame = recording.config_frame(&mut buffer);
    if frame.is_empty() {
        return None;
    }
    match decode_frame::<HostMsg>(frame)
        .ok()
        .and_then(flavour::from_host)
    {
        Some(stored) => Some(stored),
        None => {
            defmt::warn!("the stored configuration does not decode: using the image's");
            None
        }
    }
}

#[entry]
fn main() -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else {
        platform::exit(platform::EXIT_PANIC)
    };
    if let Err(e) = uart::Uart0::take(mps2::SYSCLK_HZ, 115_200) {
        defmt::error!("UART0: {}", e);
        platform::exit(platform::EXIT_PANIC)
    }
    mps2::start_clock();
    let Some(recording) = Recording::find() else {
        defmt::error!(
            "no recording at PSRAM 0x21000000: load one with -device loader (lssi monitor --qemu does)"
        );
        platform::exit(platform::EXIT_PANIC)
    };
    let (Some(engine), Some(snapshot), Some(queue), Some(rx), Some(tx)) = (
        ENGINE.take(),
        SNAPSHOT.take(),
        QUEUE.take(),
        RX.take(),
        TX.take(),
    ) else {
        platform::exit(platform::EXIT_PANIC)
    };
    let (mut config, duty) = stored_config(&recording).map_or_else(
        || (flavour::config(default_config(recording.rate_hz)), None),
        |(c, d)| (c, d),
    );
    flavour::base(&mut config).channels.velocity = recording.velocity;
    flavour::base(&mut config).channels.input = recording.input;
    let rate = recording.rate_hz;
    let decimator = match configure(engine, rate, config) {
        Some(d) => d,
        None => {
            defmt::warn!("using the image's configuration");
            config = flavour::config(default_config(rate));
            flavour::base(&mut config).channels.velocity = recording.velocity;
            flavour::base(&mut config).channels.input = recording.input;
            let Some(d) = configure(engine, rate, config) else {
                platform::exit(platform::EXIT_PANIC)
            };
            d
        }
    };
    SHARED.give_snapshot(snapshot);
    let (producer, consumer) = queue.split();
    IDENTIFY.give(engine, consumer);
    let (rx_in, mut rx_out) = rx.split();
    let (tx_in, tx_out) = tx.split();
    let mut sampler = Sampler::new(producer);
    sampler.set_decimator(decimator);
    critical_section::with(|cs| {
        SENSOR.borrow_ref_mut(cs).replace(Sensor {
            sampler,
            recording,
            next: 0,
        });
        RX_IN.borrow_ref_mut(cs).replace(rx_in);
        TX_OUT.borrow_ref_mut(cs).replace(tx_out);
    });
    let base = *flavour::base(&mut config);
    let row_hz = 1.0 / base.sample_period;
    SHARED.set_model_stride(model_stride(&base));
    defmt::info!(
        "lssi standalone: {=u32} conversions at {=f64} Hz, decimated by {=u32} (CIC order {=u8}) to rows at {=f64} Hz, window {=usize}, screening every {=u32}",
        recording.len,
        rate,
        decimator.factor(),
        decimator.order(),
        row_hz,
        base.window,
        base.screening_period
    );
    defmt::info!(
        "a model every {=u32} scheduled screening(s)",
        SHARED.model_stride()
    );
    let mut reporter: Reporter<WINDOW, DEFAULT_TERMS, CHANNELS, Shot> =
        Reporter::new(config, row_hz as f32, report_ticks(&base));
    reporter.set_adc(rate, CIC_ORDER, decimator.time_offset(rate));
    // A duty cycle: windows of identification, Model and Health at the end of each, the
    // sensor left alone in between (the sampling interrupt drops the recording's samples
    // of the interval: time goes on).
    reporter.set_duty(duty, &SHARED);
    if let Some(d) = duty {
        defmt::info!(
            "duty cycle: {=f32} s windows every {=f32} s, a model every {=u16} window(s)",
            d.window,
            d.window + d.interval,
            d.model_every.max(1)
        );
    }
    let mut link = Link { tx: tx_in };

    #[allow(unsafe_code)]
    // SAFETY: priorities are set before the interrupts are unmasked; no critical section
    // based on priority masking exists here (critical sections disable interrupts).
    unsafe {
        core.NVIC.set_priority(Irq::Timer0, 0x00);
        core.NVIC.set_priority(Irq::Uart0Rx, 0x40);
        core.NVIC.set_priority(Irq::Uart0Tx, 0x40);
        core.NVIC.set_priority(Irq::Identify, 0x80);
        NVIC::unmask(Irq::Timer0);
        NVIC::unmask(Irq::Uart0Rx);
        NVIC::unmask(Irq::Uart0Tx);
        NVIC::unmask(Irq::Identify);
    }
    #[allow(unsafe_code)]
    // SAFETY: the slicer's priority is set before SysTick's interrupt is enabled.
    unsafe {
        core.SCB.set_priority(SystemHandler::SysTick, 0xE0);
    }
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(SLICE_TICKS / 4 - 1);
    core.SYST.clear_current();
    core.SYST.enable_interrupt();
    mps2::uart_interrupts_on();
    mps2::start_sampling(mps2::sampling_reload(rate));
    let mut windows_logged = 0;
    WOKE.store(BoardClock.now(), Ordering::Relaxed);
    slicer(true);

    loop {
        let Ok(idle) = reporter.pass(&mut rx_out, &SHARED, &mut link, &BoardClock, || {
            NVIC::pend(Irq::Identify)
        });
        if reporter.finished() {
            finish(&reporter)
        }
        if let Some(drift) = reporter.drift()
            && drift.windows != windows_logged
        {
            windows_logged = drift.windows;
            defmt::info!(
                "window {=u32}: coefficients moved {=f32} (RMS relative), at most {=f32} (term {=u8}), {=u8} terms in or out",
                drift.windows,
                drift.relative,
                drift.largest,
                drift.largest_term,
                drift.support_changes
            );
        }
        // Sleeps until thread mode has work: a snapshot to screen (the recording's final one
        // too), a byte from the host, a report due. The rows' interrupts in between come and go
        // without a pass of thread mode (its reporter's pass costs instructions every row
        // otherwise). Checked with interrupts off so that an interrupt in between still
        // wakes the `wfi` (it is taken right after).
        if idle {
            loop {
                let work = cortex_m::interrupt::free(|_| {
                    let work = SHARED.screening_waiting()
                        || rx_out.ready()
                        || reporter.due(BoardClock.now());
                    if !work {
                        // Asleep, thread mode needs no slicing: SysTick stops (it would wake
                        // the core).
                        slicer(false);
                        sleep();
                        slicer(true);
                    }
                    work
                });
                if work {
                    break;
                }
            }
        }
    }
}

/// The recording is done: waits for the UART to send everything, logs the figures, exits.
fn finish(reporter: &Reporter<WINDOW, DEFAULT_TERMS, CHANNELS, Shot>) -> ! {
    // Taken first: the logging below is not the device's work.
    let awake_ended = critical_section::with(|cs| AWAKE_ENDED.borrow(cs).get())
        + u64::from(BoardClock.now().wrapping_sub(WOKE.load(Ordering::Relaxed)));
    while !TX_IDLE.load(Ordering::Acquire) || !mps2::uart_tx_ready() {
        sleep();
    }
    let c = &SHARED.counters;
    let status = SHARED.status();
    defmt::info!(
        "recording done: {=u64} samples, {=u32} overruns, queue high-water {=u32}, worst latency {=u32} ticks, {=u32} screenings skipped, {=u32} frames, {=u32} RX bytes lost",
        status.samples,
        c.overruns.load(Ordering::Relaxed),
        c.queue_high_water.load(Ordering::Relaxed),
        c.latency_max.load(Ordering::Relaxed),
        c.screenings_skipped.load(Ordering::Relaxed),
        reporter.frames_sent,
        RX_LOST.load(Ordering::Relaxed)
    );
    defmt::info!(
        "wake-ups: {=u32}, the longest while sampling {=u32} ticks awake (2.5 instructions a tick under -icount shift=4), after the recording ended {=u32}; the worst row {=u32} ticks, the worst screening {=u32} ticks from start to end ({=u32} slices: sleeps until the next row)",
        SLEEPS.load(Ordering::Relaxed),
        AWAKE_MAX.load(Ordering::Relaxed),
        AWAKE_MAX_ENDED.load(Ordering::Relaxed),
        status.cost_max,
        reporter.screen_cost_max(),
        SLICES.load(Ordering::Relaxed)
    );
    // The whole image's deepest stack (cortex-m-rt painted it at reset): main's frame with
    // the reporter, a screening, and the interrupts nested on it.
    defmt::info!(
        "stack: {=usize} bytes at the deepest; static RAM and this are what a part must hold",
        lssi_firmware::stack::peak_used()
    );
    defmt::info!(
        "awake while sampling: {=u64} ticks over {=u32} sampling interrupts",
        critical_section::with(|cs| AWAKE_TOTAL.borrow(cs).get()),
        TICKS_ENDED.load(Ordering::Relaxed)
    );
    defmt::info!(
        "awake after the recording ended: {=u64} ticks (the final screening, sliced, and its frames)",
        awake_ended
    );
    defmt::info!(
        "screenings run while sampling: {=u32} (a model every {=u32} scheduled screening(s))",
        reporter.screenings_run,
        SHARED.model_stride()
    );
    platform::exit(platform::EXIT_SUCCESS)
}

/// Sleeps until an interrupt (with interrupts off: it is taken right after the caller's
/// critical section, and counts in the next wake-up), keeping the longest wake-up.
fn sleep() {
    let awake = BoardClock.now().wrapping_sub(WOKE.load(Ordering::Relaxed));
    if STOPPED.load(Ordering::Relaxed) {
        AWAKE_MAX_ENDED.fetch_max(awake, Ordering::Relaxed);
        critical_section::with(|cs| {
            let total = AWAKE_ENDED.borrow(cs);
            total.set(total.get() + u64::from(awake));
        });
    } else {
        AWAKE_MAX.fetch_max(awake, Ordering::Relaxed);
        critical_section::with(|cs| {
            let total = AWAKE_TOTAL.borrow(cs);
            total.set(total.get() + u64::from(awake));
        });
    }
    SLEEPS.fetch_add(1, Ordering::Relaxed);
    cortex_m::asm::wfi();
    WOKE.store(BoardClock.now(), Ordering::Relaxed);
}

/// Lets SysTick count (`on`, while the core is awake) or stops it (asleep: it would wake
/// the core). Its count goes on from where it was: a slice may end early, and the handler
/// then returns at once (it measures the time awake itself).
fn slicer(on: bool) {
    const CSR: usize = 0xE000_E010;
    // ENABLE, TICKINT, CLKSOURCE (the processor clock): as set up in `main`.
    let csr = if on { 0b111 } else { 0b110 };
    #[allow(unsafe_code)]
    // SAFETY: SysTick's control register, owned by this image's slicer (set up in `main`).
    unsafe {
        core::ptr::write_volatile(CSR as *mut u32, csr);
    }
}

/// The slicer: if thread mode has been awake [`SLICE_TICKS`] since the core last woke (a
/// screening, most likely), sleeps until a row period of conversions has passed, then lets
/// it go on.
#[exception]
fn SysTick() {
    let awake = BoardClock.now().wrapping_sub(WOKE.load(Ordering::Relaxed));
    if awake < SLICE_TICKS {
        return;
    }
    let factor = critical_section::with(|cs| {
        SENSOR
            .borrow_ref(cs)
            .as_ref()
            .map_or(1, |s| s.sampler.decimator().factor())
    });
    let start = TICKS.load(Ordering::Relaxed);
    SLICES.fetch_add(1, Ordering::Relaxed);
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

/// Thread mode's end of the UART: frames into the TX ring (the TX interrupt sends them).
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
                kick_tx();
                // Asleep while the UART drains the ring (counted as asleep: the core waits
                // in WFI, which the awake total took for work before).
                sleep();
            }
        }
        kick_tx();
        Ok(())
    }
}

/// Starts the TX interrupt if it went idle.
fn kick_tx() {
    if TX_IDLE.swap(false, Ordering::AcqRel) {
        NVIC::pend(Irq::Uart0Tx);
    }
}

fn on_timer() {
    mps2::clear_sampling_irq();
    TICKS.fetch_add(1, Ordering::Relaxed);
    // After the recording the timer goes on as the slicer's clock (the final screening is
    // sliced like the rest): it counts, and samples nothing.
    if STOPPED.load(Ordering::Relaxed) {
        return;
    }
    let stamp = BoardClock.now();
    // The identify task is woken only when a row is made (once every decimation factor
    // conversions), and at the end.
    let row = critical_section::with(|cs| {
        let mut sensor = SENSOR.borrow_ref_mut(cs);
        let Some(sensor) = sensor.as_mut() else {
            return false;
        };
        if sensor.next < sensor.recording.len {
            let reading = sensor.recording.reading(sensor.next);
            sensor.next += 1;
            sensor.sampler.convert(stamp, reading, &SHARED)
        } else {
            if sensor.sampler.end() {
                TICKS_ENDED.store(TICKS.load(Ordering::Relaxed), Ordering::Relaxed);
                STOPPED.store(true, Ordering::Relaxed);
            }
            true
        }
    });
    if row {
        NVIC::pend(Irq::Identify);
    }
}

fn on_identify() {
    IDENTIFY.run(&SHARED, &BoardClock);
}

fn on_uart_rx() {
    let (byte, overrun) = mps2::uart_rx();
    if overrun {
        RX_LOST.fetch_add(1, Ordering::Relaxed);
    }
    if let Some(b) = byte {
        critical_section::with(|cs| {
            if let Some(rx) = RX_IN.borrow_ref_mut(cs).as_mut()
                && rx.enqueue(b).is_err()
            {
                RX_LOST.fetch_add(1, Ordering::Relaxed);
            }
        });
    }
}

fn on_uart_tx() {
    mps2::uart_tx_ack();
    critical_section::with(|cs| {
        let mut out = TX_OUT.borrow_ref_mut(cs);
        let Some(out) = out.as_mut() else {
            return;
        };
        while mps2::uart_tx_ready() {
            match out.dequeue() {
                Some(b) => mps2::uart_tx(b),
                None => {
                    TX_IDLE.store(true, Ordering::Release);
                    return;
                }
            }
        }
    });
}

/// Every device interrupt comes here (no peripheral crate for this board): dispatched by
/// its number.
#[allow(unsafe_code)]
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn {
        8 => on_timer(),
        10 => on_identify(),
        0 => on_uart_rx(),
        1 => on_uart_tx(),
        _ => {
            defmt::error!("unexpected interrupt {=i16}", irqn);
            platform::exit(platform::EXIT_HARD_FAULT)
        }
    }
}
