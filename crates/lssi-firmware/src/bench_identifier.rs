//! `--features bench-identifier`: the cost of lssi-core's identifier on the target.
//!
//! The default configuration of the device: `Identifier<f32, 256, 16, CHANNELS>`, two state channels
//! (x and a measured x'), window 255 of capacity 256, derivative degree 5, the library of
//! the paper's eq. 18 (constant, the 9 monomials of (x, x') to order 3, sin/cos(kΩt) for
//! k = 1..3: 16 terms), Ω = 2 rad/s, a row every 4 samples, a screening every 10 000
//! samples; every other field is `Config::default()`.
//!
//! The signal is the paper's eq. 17, x'' = −x + x' + 2x² − 4x³ − 2x²x' + 5 cos 2t, sampled
//! every 2 ms, integrated on the device by RK4 in f32 (4 steps per sample) with uniform
//! noise of the paper's kind (eq. 16, e in (0, 1)) of about 0.1 % added to x and x'. Making
//! it costs flash (a few hundred bytes) but no table; only the identifier's calls are timed.
//!
//! Every figure is printed as one `bench-id <key> <value>` line, which
//! `scripts/firmware-bench.sh` turns into its table:
//!
//! 1. **Stream**: [`SAMPLES`] samples through `Identifier::push`, each timed, sorted by what
//!    the push did (nothing but buffer the sample; a regression row; a row that closed a
//!    block, whose factor is then merged; the one-off warm-up flush; a screening), then one
//!    explicit `screen()` as the host runs at the end of a file. Stack is measured by
//!    painting: once over the samples before the first screening, once over the rest.
//!    The identifier lives in a static [`IdentifierSlot`] in `.bss`, configured in place as
//!    the device configures its own: its stack and cost are measured the first time (an
//!    empty slot), and once more at the end (configuring the used identifier anew, as a
//!    second `Configure` or a `Reset` does).
//! 2. **Profile**: the stages of a row, run by the same public lssi-core parts the
//!    identifier uses, each timed on its own: the four 255-tap FIR filters (x, x' and x'' or
//!    their velocity counterparts), the two k-neighbour smoothers, the library row, the
//!    Givens update of the block factor and the merge of a block.
//!
//! With `bench-baseline` as well, no identifier call is made (the signal is still made and
//! consumed): the difference in size between the two images is the identifier's flash.

// The baseline image leaves the identifier's helpers unused, on purpose.
#![cfg_attr(feature = "bench-baseline", allow(dead_code, unused_imports))]

use core::hint::black_box;

use lssi_core::{Channels, Config, Identifier, IdentifierSlot, LibraryConfig, PolyFamily, Sample};
use lssi_firmware::CHANNELS;
use lssi_firmware::cost::Meter;
use lssi_firmware::once::TakeOnce;
use lssi_firmware::{platform, stack};

/// Window capacity (samples).
pub const WINDOW_CAPACITY: usize = lssi_firmware::WINDOW;
/// Library capacity (terms).
pub const TERMS: usize = 16;
/// The identifier benchmarked: ring buffers for the firmware's [`CHANNELS`] (x and v).
pub type Id = Identifier<f32, WINDOW_CAPACITY, TERMS, CHANNELS>;
/// Its storage.
type Slot = IdentifierSlot<f32, WINDOW_CAPACITY, TERMS, CHANNELS>;

/// Samples streamed: three screenings' worth.
const SAMPLES: u32 = 30_000;
/// Sample period, seconds.
const DT: f64 = 0.002;
/// Excitation frequency Ω, rad/s.
const OMEGA: f64 = 2.0;

/// The configuration benchmarked (see the module docs).
#[cfg(not(feature = "bench-weak"))]
pub fn config() -> Config {
    base_config()
}

/// With `bench-weak`: what `lssi identify` chooses for this signal (the mean period of v,
/// 1571 samples at 2 ms, gives `tuning::choose_test_rows` 520 rows and a 33-sample window).
#[cfg(feature = "bench-weak")]
pub fn config() -> Config {
    Config {
        window: 33,
        derivative_degree: 5,
        row_stride: 1,
        test_rows: 520,
        ..base_config()
    }
}

fn base_config() -> Config {
    Config {
        sample_period: DT,
        window: WINDOW_CAPACITY - 1,
        library: LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: 3,
            input: false,
        },
        omega: OMEGA,
        channels: Channels {
            velocity: true,
            input: false,
        },
        ..Config::default()
    }
}

/// Rows per block factor: the identifier's rule, `max(2 · window / row_stride, 16)`.
fn block_rows(config: &Config) -> u64 {
    (2 * config.window / usize::from(config.row_stride)).max(16) as u64
}

/// The eq. 17 oscillator, integrated by RK4 in f32, with eq. 16 noise on what it reports.
struct Eq17 {
    x: f32,
    v: f32,
    step: u32,
    rng: u32,
}

impl Eq17 {
    /// RK4 steps per sample.
    const SUBSTEPS: u32 = 4;
    /// Noise amplitudes of x and x' (the recording's: δ = 1e-3 of the signals' 2-norm).
    const NOISE: (f32, f32) = (0.002, 0.004);

    fn new() -> Self {
        Self {
            x: 2.0,
            v: 0.0,
            step: 0,
            rng: 0x2026_0017,
        }
    }

    fn acceleration(x: f32, v: f32, forcing: f32) -> f32 {
        let x2 = x * x;
        -x + v + 2.0 * x2 - 4.0 * x2 * x - 2.0 * x2 * v + forcing
    }

    /// 5 cos(2t), the phase reduced in f64 so that f32 keeps its precision over hours.
    fn forcing(t: f64) -> f32 {
        let tau = 2.0 * core::f64::consts::PI;
        let p = OMEGA * t;
        5.0 * libm::cosf((p - tau * libm::floor(p / tau)) as f32)
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f32 {
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 17;
        self.rng ^= self.rng << 5;
        (self.rng >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// The next sample, then one sample period of motion.
    fn next(&mut self) -> Sample<f32> {
        let t = f64::from(self.step) * DT;
        let sample = Sample {
            t,
            x: self.x + Self::NOISE.0 * self.uniform(),
            v: Some(self.v + Self::NOISE.1 * self.uniform()),
            u: None,
        };
        let h = DT / f64::from(Self::SUBSTEPS);
        let hf = h as f32;
        for k in 0..Self::SUBSTEPS {
            let t0 = t + f64::from(k) * h;
            let (f0, f1, f2) = (
                Self::forcing(t0),
                Self::forcing(t0 + 0.5 * h),
                Self::forcing(t0 + h),
            );
            let (x, v) = (self.x, self.v);
            let (k1x, k1v) = (v, Self::acceleration(x, v, f0));
            let (x2, v2) = (x + 0.5 * hf * k1x, v + 0.5 * hf * k1v);
            let (k2x, k2v) = (v2, Self::acceleration(x2, v2, f1));
            let (x3, v3) = (x + 0.5 * hf * k2x, v + 0.5 * hf * k2v);
            let (k3x, k3v) = (v3, Self::acceleration(x3, v3, f1));
            let (x4, v4) = (x + hf * k3x, v + hf * k3v);
            let (k4x, k4v) = (v4, Self::acceleration(x4, v4, f2));
            self.x += hf / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            self.v += hf / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        self.step += 1;
        sample
    }
}

/// Count, total and largest of a set of costs.
#[derive(Clone, Copy, Default)]
struct Stat {
    count: u32,
    total: u64,
    max: u32,
}

impl Stat {
    fn add(&mut self, cost: u32) {
        self.count += 1;
        self.total += u64::from(cost);
        self.max = self.max.max(cost);
    }

    fn mean(&self) -> u32 {
        if self.count == 0 {
            0
        } else {
            u32::try_from(self.total / u64::from(self.count)).unwrap_or(u32::MAX)
        }
    }

    fn print(&self, key: &str) {
        defmt::info!(
            "bench-id {=str} count={=u32} mean={=u32} max={=u32}",
            key,
            self.count,
            self.mean(),
            self.max
        );
    }
}

/// What the pushes cost, by kind.
#[derive(Default)]
struct Costs {
    /// Every sample, screenings included.
    all: Stat,
    /// Every sample but the one-off warm-up flush and the screenings.
    steady: Stat,
    /// Buffered only (3 samples in 4).
    idle: Stat,
    /// A regression row into the block factor.
    row: Stat,
    /// A row that closed a block: the block is merged into one of the two factors.
    row_merge: Stat,
    /// The warm-up flush: the first 64 rows folded in at once (one-off).
    warmup: Stat,
    /// A push that ran a screening.
    screen: Stat,
}

/// Prints the selected model's terms and coefficients.
fn print_model(id: &Id) {
    let Some(model) = id.model() else {
        defmt::warn!("bench-id: no model");
        return;
    };
    let Some(selected) = model.selected_solution() else {
        defmt::warn!("bench-id: no solution selected");
        return;
    };
    defmt::info!(
        "model: {=u32} terms, K = {=u8}/{=u8}, offsets x {=f32} v {=f32}",
        selected.len(),
        model.k.0,
        model.k.1,
        model.offset_x,
        model.offset_v
    );
    for (j, (term, c)) in model.terms.iter().zip(&model.coefficients).enumerate() {
        if selected.support & (1 << j) == 0 {
            continue;
        }
        // `Term::write_name` would pull in core::fmt's float formatting (about 20 KiB of
        // flash): the defmt form is decoded on the host instead.
        defmt::info!("model:   {} = {=f32}", term, *c);
    }
}

/// Where the identifier lives: an empty slot in `.bss` (see [`TakeOnce`]), as in the device.
#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.SLOT")]
static SLOT: TakeOnce<Slot> = TakeOnce::new(Slot::new());

/// The identifier, configured in place in its static slot as the device configures its own
/// (lssi-device's `Configure`).
fn place(meter: &mut Meter) -> &'static mut Id {
    let Some(slot) = SLOT.take().map(black_box) else {
        defmt::error!("bench-id: the identifier's slot was already taken");
        platform::exit(platform::EXIT_PANIC)
    };
    let depth = stack::used_now();
    stack::repaint();
    let (configured, cost) = meter.measure(|| slot.configure(black_box(config())).is_ok());
    let configure_stack = stack::peak_used().saturating_sub(depth);
    let (true, Some(id)) = (configured, slot.get_mut()) else {
        defmt::error!("bench-id: the configuration was refused");
        platform::exit(platform::EXIT_PANIC)
    };
    defmt::info!(
        "bench-id size_of_identifier {=usize}",
        core::mem::size_of::<Id>()
    );
    defmt::info!("bench-id configure_cost {=u32}", cost);
    defmt::info!("bench-id configure_stack {=usize}", configure_stack);
    id
}

/// Configures the used identifier anew in place (what a second `Configure` or a `Reset`
/// does on the device) and prints the stack and cost of that.
fn replace_config(meter: &mut Meter, id: &mut Id) {
    let depth = stack::used_now();
    stack::repaint();
    let (configured, cost) = meter.measure(|| id.reconfigure(black_box(config())).is_ok());
    let reconfigure_stack = stack::peak_used().saturating_sub(depth);
    if !configured {
        defmt::error!("bench-id: the configuration was refused");
        platform::exit(platform::EXIT_PANIC)
    }
    defmt::info!("bench-id reconfigure_cost {=u32}", cost);
    defmt::info!("bench-id reconfigure_stack {=usize}", reconfigure_stack);
}

/// Called once before every sample's push, outside the measurement: the execution trace of
/// `scripts/firmware-profile.sh` counts samples by its entries.
#[inline(never)]
fn sample_mark(i: u32) {
    black_box(i);
}

/// Streams the signal through the identifier, timing every push.
#[cfg(not(feature = "bench-baseline"))]
fn stream(meter: &mut Meter) {
    let id = place(meter);
    let config = *id.config();
    let block = block_rows(&config);
    let period = config.screening_period;
    let mut signal = Eq17::new();
    let mut costs = Costs::default();
    let mut rejected = 0u32;

    // Stack of the samples before the first screening, then of the rest.
    let depth = stack::used_now();
    let mut push_stack = 0;
    stack::repaint();
    for i in 0..SAMPLES {
        if i == period - 1 {
            push_stack = stack::peak_used().saturating_sub(depth);
            stack::repaint();
        }
        let sample = signal.next();
        sample_mark(i);
        let before = *id.counters();
        let (result, cost) = meter.measure(|| id.push(black_box(sample)));
        let after = *id.counters();
        if result.is_err() {
            rejected += 1;
        }
        costs.all.add(cost);
        let rows = after.rows - before.rows;
        if after.screenings > before.screenings {
            costs.screen.add(cost);
            continue;
        }
        if rows > 1 {
            costs.warmup.add(cost);
            continue;
        }
        costs.steady.add(cost);
        if rows == 0 {
            costs.idle.add(cost);
        } else if after.rows.is_multiple_of(block) {
            costs.row_merge.add(cost);
        } else {
            costs.row.add(cost);
        }
    }
    let screen_stack = stack::peak_used().saturating_sub(depth);
    let (_, final_screen) = meter.measure(|| id.screen());

    costs.all.print("push_all");
    costs.steady.print("push_steady");
    costs.idle.print("push_idle");
    costs.row.print("push_row");
    costs.row_merge.print("push_row_merge");
    costs.warmup.print("push_warmup");
    costs.screen.print("push_screen");
    defmt::info!("bench-id final_screen {=u32}", final_screen);
    defmt::info!("bench-id push_stack {=usize}", push_stack);
    defmt::info!("bench-id screen_stack {=usize}", screen_stack);
    let c = id.counters();
    defmt::info!(
        "bench-id counters samples={=u64} rejected={=u32} rows={=u64} gated={=u64} screenings={=u64}",
        c.accepted,
        rejected,
        c.rows,
        c.gated,
        c.screenings
    );
    print_model(id);
    replace_config(meter, id);
}

/// The same stream, the identifier left out (the size baseline).
#[cfg(feature = "bench-baseline")]
fn stream(_meter: &mut Meter) {
    let mut signal = Eq17::new();
    for _ in 0..SAMPLES {
        black_box(signal.next());
    }
    defmt::info!("bench-id baseline: {=u32} samples made", SAMPLES);
}

/// Times the stages of a regression row with the identifier's own parts.
#[cfg(all(feature = "bench-profile", not(feature = "bench-baseline")))]
fn profile(meter: &mut Meter) {
    use lssi_core::Library;
    use lssi_core::derivative::{FoldedTaps, Taps};
    use lssi_core::factor::Factor;
    use lssi_core::smoothing::KnnSmoother;

    /// Rows timed.
    const PROFILE_ROWS: u32 = 2_000;

    let config = config();
    let window = config.window;
    let Ok(taps) = Taps::<f32, WINDOW_CAPACITY>::design(
        window,
        usize::from(config.derivative_degree),
        config.sample_period,
    ) else {
        defmt::error!("bench-id: taps refused");
        return;
    };
    // The identifier keeps its taps folded by symmetry.
    let taps = FoldedTaps::fold(&taps);
    let Ok(library) = Library::<TERMS>::new(&config.library) else {
        defmt::error!("bench-id: library refused");
        return;
    };
    let n = library.len();
    let block_len = block_rows(&config);
    let mut signal = Eq17::new();
    let (mut xs, mut vs) = ([0.0f32; WINDOW_CAPACITY], [0.0f32; WINDOW_CAPACITY]);
    for k in 0..window {
        let s = signal.next();
        xs[k] = s.x;
        vs[k] = s.v.unwrap_or(0.0);
    }
    let mut smooth_x = KnnSmoother::<f32>::new();
    let mut smooth_v = KnnSmoother::<f32>::new();
    let mut block = Factor::<f32, TERMS>::new(n);
    let mut big = Factor::<f32, TERMS>::new(n);
    let (mut fir, mut knn_plain, mut knn_eval, mut lib, mut givens, mut merge) = (
        Stat::default(),
        Stat::default(),
        Stat::default(),
        Stat::default(),
        Stat::default(),
        Stat::default(),
    );
    let mut smoothed = 0u32;
    let stride = usize::from(config.row_stride);
    let step = OMEGA * DT * stride as f64;
    let rotation = (libm::sin(step) as f32, libm::cos(step) as f32);
    let mut phasor = (0.0f32, 1.0f32);
    for r in 0..PROFILE_ROWS {
        // Slide the window by a row's stride (not timed).
        xs.copy_within(stride..window, 0);
        vs.copy_within(stride..window, 0);
        for k in window - stride..window {
            let s = signal.next();
            xs[k] = s.x;
            vs[k] = s.v.unwrap_or(0.0);
        }
        let (x, v) = (black_box(&xs[..window]), black_box(&vs[..window]));
        // The three folded FIR filters of a row with a measured velocity: x, x', x'' (the
        // velocity offset's dx/dt is a difference of successive x̂ now).
        let ((x_hat, v_hat, y_hat), cost) = meter.measure(|| {
            let x_hat = taps.apply(0, x, &[]);
            let v_hat = taps.apply(0, v, &[]);
            (x_hat, v_hat, taps.apply(1, v, &[]))
        });
        fir.add(cost);
        // As in the identifier with the smoothing off (its state on this signal): ε(K) on
        // one row in 16, the others only buffered.
        let ((sx, sv), cost) = meter.measure(|| {
            (
                smooth_x.push_with(x_hat, false, false),
                smooth_v.push_with(v_hat, false, false),
            )
        });
        if sx.is_some() {
            smoothed += 1;
            // The smoothers try every K on every 16th row.
            if smoothed.is_multiple_of(16) {
                knn_eval.add(cost);
            } else {
                knn_plain.add(cost);
            }
        }
        if r == PROFILE_ROWS / 4 {
            smooth_x.choose_k(0.5);
            smooth_v.choose_k(0.5);
        }
        let (xr, vr) = (sx.unwrap_or(x_hat), sv.unwrap_or(v_hat));
        // The identifier's phasor: one rotation per row (its exact re-sync every 64 rows is
        // left out here).
        let mut theta = [0.0f32; TERMS];
        let ((), cost) = meter.measure(|| {
            let (s, c) = phasor;
            phasor = (
                s * rotation.1 + c * rotation.0,
                c * rotation.1 - s * rotation.0,
            );
            library.evaluate_sin_cos(xr, vr, phasor.0, phasor.1, 0.0, &mut theta)
        });
        lib.add(cost);
        let ((), cost) = meter.measure(|| block.update(&theta, y_hat, 1.0));
        givens.add(cost);
        if u64::from(r + 1).is_multiple_of(block_len) {
            let ((), cost) = meter.measure(|| big.merge(&block));
            merge.add(cost);
            block.clear();
        }
    }
    black_box(&big);
    fir.print("stage_fir4");
    knn_plain.print("stage_knn2_plain");
    knn_eval.print("stage_knn2_eval");
    lib.print("stage_library");
    givens.print("stage_givens");
    merge.print("stage_merge");
    defmt::info!(
        "bench-id stage_k {=usize} {=usize}",
        smooth_x.k(),
        smooth_v.k()
    );
}

/// Not in this image (feature `bench-profile`).
#[cfg(not(all(feature = "bench-profile", not(feature = "bench-baseline"))))]
fn profile(_meter: &mut Meter) {}

/// Times one ADC conversion through the standalone device's decimator (a CIC of order 3,
/// 50 conversions a row, x only: the F4's software path from 10 kHz to 200 Hz rows), and
/// through the standalone sampler as the timer interrupt calls it (decimator, stuck-sensor
/// check and, once a row, the queue).
#[cfg(all(feature = "bench-profile", not(feature = "bench-baseline")))]
fn decimation(meter: &mut Meter) {
    use lssi_device::decimate::Decimator;
    use lssi_device::standalone::{Counters, Event, EventQueue, Reading, Sampler, Shared};

    const CONVERSIONS: u32 = 5_000;
    let Ok(mut decimator) = Decimator::new(50, 3) else {
        defmt::error!("bench-id: decimator refused");
        return;
    };
    let mut signal = Eq17::new();
    let mut push = Stat::default();
    for _ in 0..CONVERSIONS {
        let x = signal.next().x;
        let (row, cost) = meter.measure(|| decimator.push_channels(black_box([x, 0.0, 0.0]), 1));
        black_box(row);
        push.add(cost);
    }
    push.print("decimate_conversion");

    let shared: Shared<1> = Shared::new();
    let counters: &Counters = &shared.counters;
    let mut queue: EventQueue = EventQueue::new();
    let (producer, mut consumer) = queue.split();
    let mut sampler = Sampler::new(producer);
    sampler.set_decimator(decimator);
    let mut tick = Stat::default();
    for i in 0..CONVERSIONS {
        let x = signal.next().x;
        let reading = Reading {
            x,
            v: None,
            u: None,
            e: None,
        };
        let (_, cost) = meter.measure(|| sampler.tick(black_box(i), black_box(reading), counters));
        tick.add(cost);
        while let Some(Event::Sample { .. }) = consumer.dequeue() {}
    }
    tick.print("sampler_conversion");
}

/// Not in this image (feature `bench-profile`).
#[cfg(not(all(feature = "bench-profile", not(feature = "bench-baseline"))))]
fn decimation(_meter: &mut Meter) {}

/// Runs the stream and the profile and prints their figures.
pub fn run(meter: &mut Meter) {
    defmt::info!(
        "bench-id unit {=str} samples {=u32} window {=usize} terms {=usize}",
        meter.unit().as_str(),
        SAMPLES,
        WINDOW_CAPACITY - 1,
        TERMS
    );
    stream(meter);
    profile(meter);
    decimation(meter);
    defmt::info!("bench-id end");
}
