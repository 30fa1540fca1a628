//! The scalar type the identifier computes in: `f32` on a device, `f64` on the host as the
//! reference. Every transcendental function goes through `libm` or this crate's own code, in
//! every build, so that a host test of the `f32` path computes exactly what the Cortex-M4F
//! computes.

use core::fmt::{Debug, Display};
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real number type: implemented for `f32` and `f64`.
pub trait Real:
    Copy
    + Default
    + PartialOrd
    + Debug
    + Display
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Send
    + Sync
    + 'static
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// Machine epsilon.
    const EPSILON: Self;
    /// Largest finite value.
    const MAX: Self;
    /// Converts from `f64` (rounding to nearest).
    fn from_f64(v: f64) -> Self;
    /// Converts to `f64` (exact).
    fn to_f64(self) -> f64;
    /// Square root (`libm`).
    fn sqrt(self) -> Self;
    /// Sine (`libm` in f64; in f32 a short polynomial, see `sin_cos_f32`).
    fn sin(self) -> Self;
    /// Cosine (as [`Real::sin`]).
    fn cos(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Whether the value is neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// Converts a small count.
    #[inline]
    fn from_usize(n: usize) -> Self {
        Self::from_f64(n as f64)
    }
    /// The larger of two values (NaN-free inputs).
    #[inline]
    fn max(self, other: Self) -> Self {
        if self > other { self } else { other }
    }
    /// The smaller of two values (NaN-free inputs).
    #[inline]
    fn min(self, other: Self) -> Self {
        if self < other { self } else { other }
    }
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const EPSILON: Self = f32::EPSILON;
    const MAX: Self = f32::MAX;
    #[inline]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline]
    fn sqrt(self) -> Self {
        sqrtf(self)
    }
    #[inline]
    fn sin(self) -> Self {
        sin_cos_f32(self).0
    }
    #[inline]
    fn cos(self) -> Self {
        sin_cos_f32(self).1
    }
    #[inline]
    fn abs(self) -> Self {
        libm::fabsf(self)
    }
    #[inline]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

/// sin and cos of an f32, within 2·10⁻⁷ of the exact values (absolute, for |x| up to about
/// 10⁶; `libm::sinf` is within 1 ulp), in 0.5 KB of flash instead of sinf's and cosf's 5.9 KB
/// (their range reduction handles any argument exactly, with a table of 2/π's digits). The
/// identifier takes sin and cos of a phase already reduced to [0, 2π) or of one row's
/// small step.
///
/// x is reduced to r ∈ [−π/4, π/4] by the nearest multiple k of π/2, in f64 (x is exact in
/// f64; the product k·π/2 is rounded once, 10⁻¹⁶·k), then the minimax polynomials of
/// Cephes' sinf/cosf (degree 7 and 8, for |r| ≤ π/4) in f32, and the quadrant k mod 4 picks
/// and signs them.
#[inline(never)]
fn sin_cos_f32(x: f32) -> (f32, f32) {
    if !x.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    let xd = f64::from(x);
    let k = libm::floor(xd * core::f64::consts::FRAC_2_PI + 0.5);
    let r = (xd - k * core::f64::consts::FRAC_PI_2) as f32;
    let z = r * r;
    let s = r + r * z * (-1.666_665_5e-1 + z * (8.332_161e-3 + z * -1.951_529_6e-4));
    let c = 1.0 - 0.5 * z + z * z * (4.166_664_6e-2 + z * (-1.388_731_6e-3 + z * 2.443_315_7e-5));
    // k mod 4 (k is whole and |k| < 2^53; two's complement keeps the low bits of a negative).
    match (k as i64) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const EPSILON: Self = f64::EPSILON;
    const MAX: Self = f64::MAX;
    #[inline]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        libm::sqrt(self)
    }
    #[inline]
    fn sin(self) -> Self {
        libm::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        libm::cos(self)
    }
    #[inline]
    fn abs(self) -> Self {
        libm::fabs(self)
    }
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

/// √x in f32, correctly rounded (IEEE 754) wherever it runs, so the host's f32 and the
/// device's agree bit for bit.
///
/// On an Arm core with a hardware FPU (the Cortex-M4F's `thumbv7em-none-eabihf`) this is
/// the FPU's VSQRT.F32, one instruction; `libm::sqrtf` would be its software square root
/// (about 60 instructions a call), and the Givens rotations take one per column.
#[inline(always)]
fn sqrtf(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let bits: u32;
        // SAFETY: the FPU's VSQRT.F32 on a copy of x moved into s15, whose own value is
        // saved on the stack and put back: no register the compiler uses changes (Rust's
        // asm! names single-precision registers only on cores with double precision, which
        // the M4F's FPU lacks). No memory but those 4 bytes of stack, no condition flags.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "vpush {{s15}}",
                "vmov s15, {x}",
                "vsqrt.f32 s15, s15",
                "vmov {root}, s15",
                "vpop {{s15}}",
                x = in(reg) x.to_bits(),
                root = lateout(reg) bits,
                options(pure, nomem, preserves_flags)
            );
        }
        f32::from_bits(bits)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_sin_and_cos_are_within_2e_7_of_the_exact_values() {
        let mut worst: f64 = 0.0;
        // Dense over the phases the identifier uses, [−2π, 2π] and a little beyond, and sparse
        // far out.
        let dense = (-80_000..=80_000).map(|i| i as f32 * 1e-4);
        let far = (-2_000..=2_000).map(|i| i as f32 * 517.3);
        for x in dense.chain(far) {
            let xd = f64::from(x);
            let (s, c) = (Real::sin(x), Real::cos(x));
            worst = worst.max((f64::from(s) - xd.sin()).abs());
            worst = worst.max((f64::from(c) - xd.cos()).abs());
            assert!(s.abs() <= 1.0 && c.abs() <= 1.0, "{x}");
        }
        assert!(worst < 2e-7, "{worst}");
        assert_eq!(Real::sin(0.0f32), 0.0);
        assert_eq!(Real::cos(0.0f32), 1.0);
        assert!(Real::sin(f32::NAN).is_nan() && Real::cos(f32::INFINITY).is_nan());
    }
}
