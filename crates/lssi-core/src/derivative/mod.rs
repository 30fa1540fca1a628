//! Fixed-lag local polynomial (Savitzky–Golay) estimates of x, x' and x'' from a window of
//! equally spaced samples (docs/design.md, "Derivatives").
//!
//! A polynomial of degree `p` is fitted by least squares to the last `N` samples and
//! evaluated, with its first two derivatives, at the window's centre, so the estimates lag
//! the newest sample by (N − 1)/2 sample periods. The fit is linear in the samples, so each
//! estimate is a dot product with a fixed set of taps designed once from (N, p, dt).
//!
//! ```
//! use lssi_core::derivative::Taps;
//! let taps: Taps<f64, 64> = Taps::design(33, 4, 0.01).unwrap();
//! // x(t) = t² sampled at t = -0.16 … 0.16: value 0, slope 0, curvature 2 at the centre.
//! let x: Vec<f64> = (0..33).map(|k| { let t = (k as f64 - 16.0) * 0.01; t * t }).collect();
//! assert!((taps.apply(2, &x, &[]) - 2.0).abs() < 1e-9);
//! ```

use crate::real::Real;
use core::marker::PhantomData;

/// The highest supported polynomial degree.
pub const MAX_DEGREE: usize = 10;

/// Why taps cannot be designed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum TapsError {
    /// The window is longer than the capacity or too short for the degree.
    Window {
        /// Requested window.
        window: usize,
        /// Shortest allowed (degree + 3).
        min: usize,
        /// Capacity.
        max: usize,
    },
    /// The degree is below 2 or above [`MAX_DEGREE`].
    Degree(usize),
    /// The sample period is not a positive finite number.
    SamplePeriod,
}

impl core::fmt::Display for TapsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TapsError::Window { window, min, max } => {
                write!(
                    f,
                    "window is {window} samples, but it must be between {min} and {max}"
                )
            }
            TapsError::Degree(d) => write!(
                f,
                "derivative_degree is {d}, but it must be between 2 and {MAX_DEGREE}"
            ),
            TapsError::SamplePeriod => {
                f.write_str("sample_period must be a positive number of seconds")
            }
        }
    }
}

impl core::error::Error for TapsError {}

/// Taps for the value (0), first (1) and second (2) derivative at the window's centre.
#[derive(Clone, Debug)]
pub struct Taps<T, const W: usize> {
    len: usize,
    taps: [[T; W]; 3],
}

/// The least-squares design of a window's taps, before any tap is made: rows 0, 1 and 2 of
/// the inverse Gram matrix of the local polynomial (a few hundred bytes, where the taps take
/// 3·N values). [`Taps::design`] makes every tap from it, and [`FoldedTaps::design`] folds
/// them into place one sample at a time, so that no full set of taps needs to exist.
///
/// Generic over the `T` the taps are rounded to only so that it is compiled where it is used
/// (a firmware builds it for size, where lssi-core's own code is built for speed: it runs
/// once per configuration).
#[derive(Clone, Copy, Debug)]
pub struct Design<T> {
    len: usize,
    /// Coefficients of the polynomial (degree + 1).
    m: usize,
    /// (N − 1)/2: the abscissae are u_k = (k − half)/half.
    half: f64,
    /// half · dt: the unit of u in seconds.
    scale: f64,
    inverse: [[f64; MAX_DEGREE + 1]; 3],
    real: PhantomData<T>,
}

impl<T: Real> Design<T> {
    /// Designs the taps of a window of `len` samples (at most `max`), degree `degree`,
    /// sample period `dt`. Every error is found here, before any tap is made.
    pub fn new(len: usize, degree: usize, dt: f64, max: usize) -> Result<Self, TapsError> {
        check_window(len, degree, dt, max)?;
        // Abscissae u_k in [-1, 1] keep the normal equations well conditioned (in f64).
        let half = (len as f64 - 1.0) / 2.0;
        let m = degree + 1;
        let gram = gram(len, m, half);
        let inverse = inverse_rows(gram, m).ok_or(TapsError::Degree(degree))?;
        Ok(Self {
            len,
            m,
            half,
            scale: half * dt,
            inverse,
            real: PhantomData,
        })
    }

    /// The window length N.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the window is empty (never, once designed).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The taps of the value, first and second derivative for sample `k` of the window
    /// (0: the oldest), rounded to `T`.
    pub fn taps(&self, k: usize) -> [T; 3] {
        let (half, m, scale) = (self.half, self.m, self.scale);
        let u = (k as f64 - half) / half;
        let mut power = 1.0;
        let mut basis = [0.0f64; MAX_DEGREE + 1];
        for b in basis.iter_mut().take(m) {
            *b = power;
            power *= u;
        }
        let mut out = [T::ZERO; 3];
        for (d, factor) in [(0usize, 1.0), (1, 1.0 / scale), (2, 2.0 / (scale * scale))] {
            let coefficient: f64 = (0..m).map(|j| self.inverse[d][j] * basis[j]).sum();
            out[d] = T::from_f64(coefficient * factor);
        }
        out
    }
}

/// The checks of [`Design::new`]: a degree in 2..=[`MAX_DEGREE`], a window of at least
/// degree + 3 samples and at most `max`, a positive finite sample period.
///
/// [`Design::new`]'s steps are inlined into it: out of line, `inverse_rows` alone took
/// 2.3 KB of the device image's flash (measured with llvm-nm), as one function 0.4 KB.
#[inline(always)]
fn check_window(len: usize, degree: usize, dt: f64, max: usize) -> Result<(), TapsError> {
    if !(2..=MAX_DEGREE).contains(&degree) {
        return Err(TapsError::Degree(degree));
    }
    if len < degree + 3 || len > max {
        return Err(TapsError::Window {
            window: len,
            min: degree + 3,
            max,
        });
    }
    if !(dt.is_finite() && dt > 0.0) {
        return Err(TapsError::SamplePeriod);
    }
    Ok(())
}

/// The Gram matrix G[i][j] = Σ_k u_k^(i+j) of the local polynomial's `m` coefficients over
/// the abscissae u_k = (k − half)/half of a window of `len` samples.
#[inline(always)]
fn gram(len: usize, m: usize, half: f64) -> [[f64; MAX_DEGREE + 1]; MAX_DEGREE + 1] {
    let mut gram = [[0.0f64; MAX_DEGREE + 1]; MAX_DEGREE + 1];
    for k in 0..len {
        let u = (k as f64 - half) / half;
        let mut powers = [1.0f64; 2 * MAX_DEGREE + 2];
        for j in 1..2 * m {
            powers[j] = powers[j - 1] * u;
        }
        for i in 0..m {
            for j in 0..m {
                gram[i][j] += powers[i + j];
            }
        }
    }
    gram
}

/// Rows 0, 1, 2 of G⁻¹ by Gauss–Jordan on [G | I] (G is small and positive definite);
/// `None` if a pivot vanishes.
#[inline(always)]
fn inverse_rows(
    mut gram: [[f64; MAX_DEGREE + 1]; MAX_DEGREE + 1],
    m: usize,
) -> Option<[[f64; MAX_DEGREE + 1]; 3]> {
    let mut inverse = [[0.0f64; MAX_DEGREE + 1]; MAX_DEGREE + 1];
    for (i, row) in inverse.iter_mut().enumerate().take(m) {
        row[i] = 1.0;
    }
    for col in 0..m {
        let pivot = gram[col][col];
        if pivot.abs() < 1e-300 {
            return None;
        }
        for j in 0..m {
            gram[col][j] /= pivot;
            inverse[col][j] /= pivot;
        }
        for row in 0..m {
            if row != col {
                let f = gram[row][col];
                for j in 0..m {
                    gram[row][j] -= f * gram[col][j];
                    inverse[row][j] -= f * inverse[col][j];
                }
            }
        }
    }
    Some([inverse[0], inverse[1], inverse[2]])
}

impl<T: Real, const W: usize> Taps<T, W> {
    /// Designs the taps for a window of `len` samples, degree `degree`, sample period `dt`.
    pub fn design(len: usize, degree: usize, dt: f64) -> Result<Self, TapsError> {
        let design = Design::<T>::new(len, degree, dt, W)?;
        let mut taps = [[T::ZERO; W]; 3];
        for k in 0..len {
            let [h0, h1, h2] = design.taps(k);
            taps[0][k] = h0;
            taps[1][k] = h1;
            taps[2][k] = h2;
        }
        Ok(Self { len, taps })
    }

    /// The window length N.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the window is empty (never, once designed).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The taps of derivative `order` (0, 1 or 2).
    pub fn taps(&self, order: usize) -> &[T] {
        match self.taps.get(order) {
            Some(t) => &t[..self.len],
            None => &[],
        }
    }

    /// Applies derivative `order`'s taps to the newest `len` samples of the sequence `a ++ b`
    /// (oldest first, as `heapless::HistoryBuf::as_slices` gives them).
    pub fn apply(&self, order: usize, a: &[T], b: &[T]) -> T {
        let taps = self.taps(order);
        let total = a.len() + b.len();
        if total < self.len {
            return T::ZERO;
        }
        let skip = total - self.len;
        let mut acc = T::ZERO;
        if skip >= a.len() {
            for (h, s) in taps.iter().zip(&b[skip - a.len()..]) {
                acc += *h * *s;
            }
        } else {
            let first = &a[skip..];
            for (h, s) in taps.iter().zip(first) {
                acc += *h * *s;
            }
            for (h, s) in taps[first.len()..].iter().zip(b) {
                acc += *h * *s;
            }
        }
        acc
    }

    /// `Σ_k taps_i[k] · taps_j[k + lag]`: the covariance, per unit white-noise variance, of the
    /// two estimates taken `lag` samples apart.
    pub fn cross(&self, i: usize, j: usize, lag: isize) -> f64 {
        let (a, b) = (self.taps(i), self.taps(j));
        let mut s = 0.0;
        for k in 0..self.len as isize {
            let l = k + lag;
            if l >= 0 && (l as usize) < self.len {
                s += a[k as usize].to_f64() * b[l as usize].to_f64();
            }
        }
        s
    }
}

/// [`Taps`] folded by their symmetry, in two thirds of the memory and half the multiplies.
///
/// A Savitzky–Golay window is symmetric about its centre: the taps of the value and of the
/// second derivative are even (`h[k] = h[N−1−k]`), those of the first derivative odd
/// (`h[k] = −h[N−1−k]`, and 0 at the centre). So `Σ h[k]·s[k] = Σ_{k<N/2} h[k]·(s[k] ± s[N−1−k])`
/// (+ the centre tap once when N is odd): one multiply per pair of samples. Only the first
/// ⌈N/2⌉ taps of each order are stored, averaged with their mirror images so that the
/// rounding of the f64 design does not break the symmetry; the three halves fit in two rows
/// of `W` (3·⌈N/2⌉ ≤ 2W). The sums run in a different order than [`Taps::apply`]'s, so
/// results agree with it to rounding (a few ulps of the largest partial sum), not bit for bit.
#[derive(Clone, Debug)]
pub struct FoldedTaps<T, const W: usize> {
    len: usize,
    half: usize,
    taps: [[T; W]; 2],
}

impl<T: Real, const W: usize> FoldedTaps<T, W> {
    /// Folds designed taps.
    pub fn fold(full: &Taps<T, W>) -> Self {
        let len = full.len();
        let half = len.div_ceil(2);
        let mut taps = [[T::ZERO; W]; 2];
        {
            let flat = taps.as_flattened_mut();
            for order in 0..3 {
                let h = full.taps(order);
                let odd = order == 1;
                for k in 0..half {
                    let (a, b) = (h[k].to_f64(), h[len - 1 - k].to_f64());
                    let v = if odd {
                        if k == len - 1 - k { 0.0 } else { 0.5 * (a - b) }
                    } else {
                        0.5 * (a + b)
                    };
                    if let Some(slot) = flat.get_mut(order * half + k) {
                        *slot = T::from_f64(v);
                    }
                }
            }
        }
        Self { len, half, taps }
    }

    /// No taps (a window of 0 samples): storage for [`FoldedTaps::design`].
    pub(crate) const fn empty() -> Self {
        Self {
            len: 0,
            half: 0,
            taps: [[T::ZERO; W]; 2],
        }
    }

    /// Designs the taps in place, bit for bit as `FoldedTaps::fold(&Taps::design(..))`
    /// makes them, without the full taps (3·W values) ever existing: `each` is handed the
    /// full taps `[h₀[k], h₁[k], h₂[k]]` of every sample k = 0..N in order, e.g. to sum their
    /// squares. `design` must be for a window of at most `W` samples (it is from
    /// `Design::new(.., W)`); a longer one's taps past the storage are left out.
    pub fn design(&mut self, design: &Design<T>, mut each: impl FnMut([T; 3])) {
        let len = design.len();
        let half = len.div_ceil(2);
        self.len = len;
        self.half = half;
        let flat = self.taps.as_flattened_mut();
        flat.fill(T::ZERO);
        for k in 0..len {
            let h = design.taps(k);
            each(h);
            let mirror = len - 1 - k;
            for (order, &hk) in h.iter().enumerate() {
                let odd = order == 1;
                // The first tap of a pair waits in its slot (exactly: T → f64 is exact)
                // until its mirror image comes; then the two are averaged as `fold` does.
                let lower = k.min(mirror);
                let Some(slot) = flat.get_mut(order * half + lower) else {
                    continue;
                };
                if k < mirror {
                    *slot = hk;
                    continue;
                }
                let (a, b) = if k == mirror {
                    (hk.to_f64(), hk.to_f64())
                } else {
                    (slot.to_f64(), hk.to_f64())
                };
                let v = if odd {
                    if k == mirror { 0.0 } else { 0.5 * (a - b) }
                } else {
                    0.5 * (a + b)
                };
                *slot = T::from_f64(v);
            }
        }
    }

    /// The window length N.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the window is empty (never, once designed).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The stored half (⌈N/2⌉ taps, oldest sample first) of derivative `order`'s taps.
    pub fn half_taps(&self, order: usize) -> &[T] {
        let flat = self.taps.as_flattened();
        if order > 2 {
            return &[];
        }
        flat.get(order * self.half..(order + 1) * self.half)
            .unwrap_or(&[])
    }

    /// Applies derivative `order`'s taps to the newest N samples of `a ++ b` (oldest first),
    /// as [`Taps::apply`] does.
    pub fn apply(&self, order: usize, a: &[T], b: &[T]) -> T {
        let h = self.half_taps(order);
        let n = self.len;
        let total = a.len() + b.len();
        if total < n || h.is_empty() {
            return T::ZERO;
        }
        let odd = order == 1;
        let pairs = n / 2;
        let sign = if odd { -T::ONE } else { T::ONE };
        // The window within `b` (most rows, in a ring longer than the window): the general
        // path below with s0 empty, without its break points.
        if let Some(s) = b.len().checked_sub(n).map(|k| &b[k..]) {
            let mut lanes = [T::ZERO; 4];
            fold_sum(
                &h[..pairs],
                &s[..pairs],
                &s[n - pairs..],
                sign,
                0,
                &mut lanes,
            );
            let mut acc = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
            if n % 2 == 1 && !odd {
                acc += h[pairs] * s[pairs];
            }
            return acc;
        }
        // The window as two slices s0 ++ s1 of N samples in all.
        let skip = total - n;
        let (s0, s1) = if skip >= a.len() {
            (&b[skip - a.len()..skip - a.len()], &b[skip - a.len()..])
        } else {
            (&a[skip..], b)
        };
        let m = s0.len();
        // Pair k takes s[k] and s[N−1−k]: s[k] lies in s0 for k < m, s[N−1−k] in s1 for
        // k < N−m. Between the two break points both lie in the same slice.
        let e1 = m.min(n - m).min(pairs);
        let e2 = m.max(n - m).min(pairs);
        let mut lanes = [T::ZERO; 4];
        // Where the window does not wrap (s0 empty: most rows, in a ring longer than the
        // window) there are no pairs across the break: skip the call.
        if e1 > 0 {
            fold_sum(
                &h[..e1],
                &s0[..e1],
                &s1[n - m - e1..n - m],
                sign,
                0,
                &mut lanes,
            );
        }
        if m <= n - m {
            fold_sum(
                &h[e1..e2],
                &s1[e1 - m..e2 - m],
                &s1[n - m - e2..n - m - e1],
                sign,
                e1,
                &mut lanes,
            );
        } else {
            fold_sum(
                &h[e1..e2],
                &s0[e1..e2],
                &s0[n - e2..n - e1],
                sign,
                e1,
                &mut lanes,
            );
        }
        let mut acc = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
        if n % 2 == 1 && !odd {
            let c = n / 2;
            let centre = if c < m { s0[c] } else { s1[c - m] };
            acc += h[c] * centre;
        }
        acc
    }
}

/// Adds h[i]·(l[i] ± r[len−1−i]) (`r` walked backwards: the mirror half of the window) to
/// lane (k0 + i) mod 4 of `acc`, i = 0..len.
///
/// Unrolled by four with one accumulator per lane: the M4F then loads with immediate
/// offsets and pays the loop's counter and branch once per four pairs. The lane of a pair
/// depends only on its place k in the window, never on where the ring buffer happens to
/// wrap, so the result is the same for every capacity W (host and device agree bit for bit
/// whatever their W). The mirror sample is multiplied by `sign` = ±1 (exact), which keeps
/// one loop for both parities. Not inlined: its two calls per filter would otherwise be
/// six copies of the unrolled loop in the identifier's row (2 KB of flash).
#[inline(never)]
fn fold_sum<T: Real>(h: &[T], l: &[T], r: &[T], sign: T, k0: usize, acc: &mut [T; 4]) {
    let len = h.len().min(l.len()).min(r.len());
    let (h, l, r) = (&h[..len], &l[..len], &r[r.len() - len..]);
    // Up to three pairs one by one, until the lane is 0 again.
    let head = ((4 - k0 % 4) % 4).min(len);
    for i in 0..head {
        acc[(k0 + i) % 4] += h[i] * (l[i] + sign * r[len - 1 - i]);
    }
    let (h, l, r) = (&h[head..], &l[head..], &r[..len - head]);
    let hc = h.chunks_exact(4);
    let lc = l.chunks_exact(4);
    let rc = r.rchunks_exact(4);
    let (ht, lt, rt) = (hc.remainder(), lc.remainder(), rc.remainder());
    for ((h, l), r) in hc.zip(lc).zip(rc) {
        // Slice patterns: no bounds checks even where the generic code is built for size.
        let (&[h0, h1, h2, h3], &[l0, l1, l2, l3], &[r0, r1, r2, r3]) = (h, l, r) else {
            continue;
        };
        acc[0] += h0 * (l0 + sign * r3);
        acc[1] += h1 * (l1 + sign * r2);
        acc[2] += h2 * (l2 + sign * r1);
        acc[3] += h3 * (l3 + sign * r0);
    }
    // The last pairs: l's tail meets r's head (lanes 0, 1, 2).
    for (i, (&h, &l)) in ht.iter().zip(lt).enumerate() {
        if let Some(&r) = rt.get(rt.len() - 1 - i) {
            acc[i] += h * (l + sign * r);
        }
    }
}

#[cfg(test)]
mod tests;
