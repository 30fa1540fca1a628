//! `--features bench-system`: the cost of a system of equations on the target (issue 26
//! item 2, issue 27 item 5): one channel against two on the same harvester.
//!
//! A piezoelectric harvester, x'' = −x − 0.5x³ − 0.04x' + 0.1V + 0.4 cos 0.8t,
//! V' = −V − 0.5x', is integrated on the device by RK4 in f32 (10 steps a sample of 10 ms)
//! and its x and V streamed, [`SAMPLES`] of them, each push timed, through
//!
//! 1. `Identifier<f32, 256, 16, 2>` on x alone (one channel: x'' over the 12 mechanical
//!    terms: 1, the 9 monomials of (x, x') to order 3, cos/sin 0.8t), and
//! 2. `SystemIdentifier<f32, 256, 16, 2, 2>` on x and V (two channels: x'' and V' over
//!    the 16 terms of the shared library, the 12 and V, x·V, x'·V, V²),
//!
//! with the same base configuration: window 63, degree 5, a row every 4 samples, a
//! screening every 10 000 samples (the device replay test's, `tests/e2e/system_qemu.rs`).
//! Each identifier lives in its own static in `.bss` and is configured in place, as the
//! device does. Every figure is one `bench-sys <key> ...` line for
//! `scripts/firmware-bench-system.sh`.

use core::hint::black_box;

use lssi_core::identifier::system::Target;
use lssi_core::library::{Electrical, StateTerm};
use lssi_core::{
    Config, IdentifierSlot, LibraryConfig, PolyFamily, Sample, SystemConfig, SystemSample,
    SystemSlot,
};
use lssi_firmware::cost::Meter;
use lssi_firmware::once::TakeOnce;
use lssi_firmware::{platform, stack};

const W: usize = lssi_firmware::WINDOW;
const P: usize = 16;
/// Samples streamed: three screenings' worth.
const SAMPLES: u32 = 30_000;
/// Sample period, s.
const DT: f64 = 0.01;
/// Forcing frequency, rad/s.
const OMEGA: f64 = 0.8;

type Single = IdentifierSlot<f32, W, P, 2>;
type System = SystemSlot<f32, W, P, 2, 2>;

#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.SINGLE")]
static SINGLE: TakeOnce<Single> = TakeOnce::new(Single::new());
#[allow(unsafe_code)]
#[unsafe(link_section = ".bss.lssi.SYSTEM")]
static SYSTEM: TakeOnce<System> = TakeOnce::new(System::new());

fn base() -> Config {
    Config {
        sample_period: DT,
        window: 63,
        derivative_degree: 5,
        library: LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: 1,
            input: false,
        },
        omega: OMEGA,
        screening_period: 10_000,
        ..Config::default()
    }
}

fn system_config() -> SystemConfig {
    SystemConfig {
        base: base(),
        electrical: [Some(Electrical::Voltage), None],
        coupling_order: 2,
        displacements: 1,
    }
}

/// The harvester, RK4 in f32.
struct Piezo {
    s: [f32; 3],
    step: u32,
}

impl Piezo {
    const SUBSTEPS: u32 = 10;

    fn derivative(t: f64, s: [f32; 3]) -> [f32; 3] {
        let [x, v, e] = s;
        let tau = 2.0 * core::f64::consts::PI;
        let p = OMEGA * t;
        let forcing = 0.4 * libm::cosf((p - tau * libm::floor(p / tau)) as f32);
        [
            v,
            -x - 0.5 * x * x * x - 0.04 * v + 0.1 * e + forcing,
            -e - 0.5 * v,
        ]
    }

    /// (t, x, V) of the next sample, then one sample period of motion.
    fn next(&mut self) -> (f64, f32, f32) {
        let t = f64::from(self.step) * DT;
        let out = (t, self.s[0], self.s[2]);
        let h = DT / f64::from(Self::SUBSTEPS);
        let hf = h as f32;
        for k in 0..Self::SUBSTEPS {
            let t0 = t + f64::from(k) * h;
            let s = self.s;
            let add = |a: [f32; 3], b: [f32; 3], f: f32| {
                [a[0] + f * b[0], a[1] + f * b[1], a[2] + f * b[2]]
            };
            let k1 = Self::derivative(t0, s);
            let k2 = Self::derivative(t0 + 0.5 * h, add(s, k1, 0.5 * hf));
            let k3 = Self::derivative(t0 + 0.5 * h, add(s, k2, 0.5 * hf));
            let k4 = Self::derivative(t0 + h, add(s, k3, hf));
            for j in 0..3 {
                self.s[j] += hf / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
        self.step += 1;
        out
    }

    /// After 100 s of transient, as the host tests' harvester.
    fn settled() -> Self {
        let mut p = Self {
            s: [0.1, 0.0, 0.0],
            step: 0,
        };
        for _ in 0..(100.0 / DT) as u32 {
            p.next();
        }
        p
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

    fn print(&self, key: &str) {
        let mean = if self.count == 0 {
            0
        } else {
            u32::try_from(self.total / u64::from(self.count)).unwrap_or(u32::MAX)
        };
        defmt::info!(
            "bench-sys {=str} count={=u32} mean={=u32} max={=u32}",
            key,
            self.count,
            mean,
            self.max
        );
    }
}

/// Every push, the pushes that ran no screening, and those that did.
#[derive(Default)]
struct Costs {
    all: Stat,
    steady: Stat,
    screen: Stat,
}

fn single(meter: &mut Meter) {
    let Some(slot) = SINGLE.take().map(black_box) else {
        platform::exit(platform::EXIT_PANIC)
    };
    let Ok(id) = slot.configure(black_box(base())) else {
        defmt::error!("bench-sys: the single-equation configuration was refused");
        platform::exit(platform::EXIT_PANIC)
    };
    let mut signal = Piezo::settled();
    let mut costs = Costs::default();
    let depth = stack::used_now();
    stack::repaint();
    for _ in 0..SAMPLES {
        let (t, x, _) = signal.next();
        let sample = Sample {
            t,
            x,
            v: None,
            u: None,
        };
        let before = id.counters().screenings;
        let (_, cost) = meter.measure(|| id.push(black_box(sample)));
        costs.all.add(cost);
        if id.counters().screenings > before {
            costs.screen.add(cost);
        } else {
            costs.steady.add(cost);
        }
    }
    let (_, final_screen) = meter.measure(|| id.screen());
    let stack = stack::peak_used().saturating_sub(depth);
    costs.all.print("one_all");
    costs.steady.print("one_steady");
    costs.screen.print("one_screen");
    defmt::info!("bench-sys one_final_screen {=u32}", final_screen);
    defmt::info!("bench-sys one_stack {=usize}", stack);
    defmt::info!(
        "bench-sys one_size {=usize}",
        core::mem::size_of::<Single>()
    );
    defmt::info!("bench-sys one_terms {=usize}", id.library().len());
}

fn system(meter: &mut Meter) {
    let Some(slot) = SYSTEM.take().map(black_box) else {
        platform::exit(platform::EXIT_PANIC)
    };
    let Ok(id) = slot.configure(black_box(system_config())) else {
        defmt::error!("bench-sys: the system configuration was refused");
        platform::exit(platform::EXIT_PANIC)
    };
    let mut signal = Piezo::settled();
    let mut costs = Costs::default();
    let depth = stack::used_now();
    stack::repaint();
    for _ in 0..SAMPLES {
        let (t, x, e) = signal.next();
        let electrical = [e];
        let sample = SystemSample {
            t,
            x2: None,
            v2: None,
            x,
            v: None,
            u: None,
            electrical: &electrical,
        };
        let before = id.counters().screenings;
        let (_, cost) = meter.measure(|| id.push(black_box(&sample)));
        costs.all.add(cost);
        if id.counters().screenings > before {
            costs.screen.add(cost);
        } else {
            costs.steady.add(cost);
        }
    }
    let (_, final_screen) = meter.measure(|| id.screen());
    let stack = stack::peak_used().saturating_sub(depth);
    costs.all.print("two_all");
    costs.steady.print("two_steady");
    costs.screen.print("two_screen");
    defmt::info!("bench-sys two_final_screen {=u32}", final_screen);
    defmt::info!("bench-sys two_stack {=usize}", stack);
    defmt::info!(
        "bench-sys two_size {=usize}",
        core::mem::size_of::<System>()
    );
    defmt::info!("bench-sys two_terms {=usize}", id.library().len());
    if let Some(model) = id.model() {
        let voltage = Target::Rate(Electrical::Voltage);
        let kappa = model.coefficient(voltage, StateTerm::Monomial([0, 1, 0, 0, 0, 0]));
        let chi = model.coefficient(
            Target::Acceleration,
            StateTerm::Monomial([0, 0, 1, 0, 0, 0]),
        );
        defmt::info!(
            "bench-sys model: chi {=f32} (0.1), kappa {=f32} (-0.5)",
            chi.unwrap_or(f32::NAN),
            kappa.unwrap_or(f32::NAN)
        );
    }
}

pub fn run(meter: &mut Meter) {
    defmt::info!(
        "bench-sys unit {=str} samples {=u32}",
        meter.unit().as_str(),
        SAMPLES
    );
    single(meter);
    system(meter);
    defmt::info!("bench-sys end");
}
