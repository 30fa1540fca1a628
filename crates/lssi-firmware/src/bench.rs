//! `--features bench`: per-call cost and stack of the stand-in workload, printed over defmt.
//!
//! Output (under QEMU, costs in instructions):
//!
//! ```text
//! bench sqrtf: 1000 calls, mean 57 max 72 min 32 instructions/call
//! bench givens16: fit max |error| 0.00006246567 (noise 1e-3), residual 0.00020435758
//! bench givens16: 1000 calls, mean 4220 max 4272 min 1872 instructions/call, stack 184 bytes
//! ```

use core::hint::black_box;

use lssi_firmware::cost::Meter;
use lssi_firmware::stack;
use lssi_firmware::workload::{GivensFactor, Rows, TERMS};

/// Updates timed.
const CALLS: u32 = 1000;

/// Figures of one benchmark.
#[derive(Debug, Clone, Copy, defmt::Format)]
pub struct Figures {
    /// Calls timed.
    pub calls: u32,
    /// Mean cost per call.
    pub mean: u32,
    /// Largest cost of one call.
    pub max: u32,
    /// Smallest cost of one call.
    pub min: u32,
    /// Stack the workload used beyond its caller's frame, bytes.
    pub stack_bytes: usize,
}

/// Times [`CALLS`] Givens updates of a 16-term factor and checks the fit.
pub fn givens16(meter: &mut Meter) -> Figures {
    let truth: [f32; TERMS] = core::array::from_fn(|i| (i as f32 - 7.5) * 0.25);
    let mut factor = GivensFactor::new(0.999);
    let mut rows = Rows::new(0x5eed_1234);

    let depth_at_call = stack::used_now();
    stack::repaint();

    let (mut total, mut max, mut min) = (0u64, 0u32, u32::MAX);
    for _ in 0..CALLS {
        let (row, y) = rows.next_row(&truth);
        let ((), cost) = meter.measure(|| factor.update(&row, y));
        total += u64::from(cost);
        max = max.max(cost);
        min = min.min(cost);
    }
    let stack_bytes = stack::peak_used().saturating_sub(depth_at_call);

    // The solve proves the updates did the work (and keeps them from being optimised out).
    match black_box(&factor).solve() {
        Some(coefficients) => {
            let worst = coefficients
                .iter()
                .zip(&truth)
                .map(|(c, t)| libm::fabsf(c - t))
                .fold(0.0f32, f32::max);
            defmt::info!(
                "bench givens16: fit max |error| {=f32} (noise 1e-3), residual {=f32}",
                worst,
                factor.residual()
            );
        }
        None => defmt::warn!(
            "bench givens16: factor singular after {=u32} updates",
            CALLS
        ),
    }

    Figures {
        calls: CALLS,
        mean: u32::try_from(total / u64::from(CALLS)).unwrap_or(u32::MAX),
        max,
        min,
        stack_bytes,
    }
}

/// Times [`CALLS`] calls of `libm::sqrtf`, which on stable Rust is a software square root
/// even where the FPU has `vsqrt.f32`; the Givens update makes 16 of them.
pub fn sqrtf(meter: &mut Meter) -> Figures {
    let mut rows = Rows::new(0x0bad_cafe);
    let (mut total, mut max, mut min) = (0u64, 0u32, u32::MAX);
    for _ in 0..CALLS {
        let (row, _) = rows.next_row(&[0.0; TERMS]);
        let x = black_box(libm::fabsf(row[0]) * 100.0);
        let (root, cost) = meter.measure(|| libm::sqrtf(x));
        black_box(root);
        total += u64::from(cost);
        max = max.max(cost);
        min = min.min(cost);
    }
    Figures {
        calls: CALLS,
        mean: u32::try_from(total / u64::from(CALLS)).unwrap_or(u32::MAX),
        max,
        min,
        stack_bytes: 0,
    }
}

/// Runs every benchmark and prints its figures.
pub fn run(meter: &mut Meter) {
    let unit = meter.unit().as_str();
    let figures = sqrtf(meter);
    defmt::info!(
        "bench sqrtf: {=u32} calls, mean {=u32} max {=u32} min {=u32} {=str}/call",
        figures.calls,
        figures.mean,
        figures.max,
        figures.min,
        unit
    );
    let figures = givens16(meter);
    defmt::info!(
        "bench givens16: {=u32} calls, mean {=u32} max {=u32} min {=u32} {=str}/call, stack {=usize} bytes",
        figures.calls,
        figures.mean,
        figures.max,
        figures.min,
        unit,
        figures.stack_bytes
    );
}
