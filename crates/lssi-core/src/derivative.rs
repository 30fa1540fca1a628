//! Fixed-lag local polynomial (Savitzky–Golay) estimates of x, x' and x'' from a window of
//! equally spaced samples (DESIGN.md, "Derivatives").
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

impl<T: Real, const W: usize> Taps<T, W> {
    /// Designs the taps for a window of `len` samples, degree `degree`, sample period `dt`.
    pub fn design(len: usize, degree: usize, dt: f64) -> Result<Self, TapsError> {
        if !(2..=MAX_DEGREE).contains(&degree) {
            return Err(TapsError::Degree(degree));
        }
        if len < degree + 3 || len > W {
            return Err(TapsError::Window {
                window: len,
                min: degree + 3,
                max: W,
            });
        }
        if !(dt.is_finite() && dt > 0.0) {
            return Err(TapsError::SamplePeriod);
        }
        // Abscissae u_k in [-1, 1] keep the normal equations well conditioned (in f64).
        let half = (len as f64 - 1.0) / 2.0;
        let m = degree + 1;
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
        // Rows 0, 1, 2 of G⁻¹ by Gauss–Jordan on [G | I] (G is small and positive definite).
        let mut inverse = [[0.0f64; MAX_DEGREE + 1]; MAX_DEGREE + 1];
        for (i, row) in inverse.iter_mut().enumerate().take(m) {
            row[i] = 1.0;
        }
        for col in 0..m {
            let pivot = gram[col][col];
            if pivot.abs() < 1e-300 {
                return Err(TapsError::Degree(degree));
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
        let scale = half * dt;
        let mut taps = [[T::ZERO; W]; 3];
        for k in 0..len {
            let u = (k as f64 - half) / half;
            let mut power = 1.0;
            let mut basis = [0.0f64; MAX_DEGREE + 1];
            for b in basis.iter_mut().take(m) {
                *b = power;
                power *= u;
            }
            for (d, factor) in [(0usize, 1.0), (1, 1.0 / scale), (2, 2.0 / (scale * scale))] {
                let coefficient: f64 = (0..m).map(|j| inverse[d][j] * basis[j]).sum();
                taps[d][k] = T::from_f64(coefficient * factor);
            }
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

    /// Σ_k taps_i[k] · taps_j[k + lag]: the covariance, per unit white-noise variance, of the
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_on_polynomials_up_to_the_degree() {
        let dt = 0.002;
        let taps: Taps<f64, 128> = Taps::design(101, 5, dt).unwrap();
        // x(t) = 1 + 2t − 3t² + 0.5t⁵ about the centre (t = 0 at the centre).
        let x: std::vec::Vec<f64> = (0..101)
            .map(|k| {
                let t = (k as f64 - 50.0) * dt;
                1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t.powi(5)
            })
            .collect();
        assert!((taps.apply(0, &x, &[]) - 1.0).abs() < 1e-10);
        assert!((taps.apply(1, &x, &[]) - 2.0).abs() < 1e-8);
        assert!((taps.apply(2, &x, &[]) + 6.0).abs() < 1e-6);
        // The same through a split ring with older samples in front.
        let mut longer = std::vec![9.0; 20];
        longer.extend_from_slice(&x);
        let (a, b) = longer.split_at(57);
        assert!((taps.apply(1, a, b) - 2.0).abs() < 1e-8);
    }

    extern crate std;

    #[test]
    fn sine_derivatives_are_accurate_well_inside_the_band() {
        let dt = 0.001;
        let taps: Taps<f64, 512> = Taps::design(257, 5, dt).unwrap();
        let w = 2.0;
        let x: std::vec::Vec<f64> = (0..257)
            .map(|k| (w * (k as f64 - 128.0) * dt + 0.3).sin())
            .collect();
        assert!((taps.apply(0, &x, &[]) - 0.3f64.sin()).abs() < 1e-7);
        assert!((taps.apply(1, &x, &[]) - w * 0.3f64.cos()).abs() < 1e-6);
        assert!((taps.apply(2, &x, &[]) + w * w * 0.3f64.sin()).abs() < 1e-4);
    }

    #[test]
    fn bad_designs_are_errors() {
        assert!(matches!(
            Taps::<f32, 64>::design(65, 4, 0.01),
            Err(TapsError::Window { .. })
        ));
        assert!(matches!(
            Taps::<f32, 64>::design(5, 4, 0.01),
            Err(TapsError::Window { .. })
        ));
        assert!(matches!(
            Taps::<f32, 64>::design(33, 1, 0.01),
            Err(TapsError::Degree(1))
        ));
        assert!(matches!(
            Taps::<f32, 64>::design(33, 4, 0.0),
            Err(TapsError::SamplePeriod)
        ));
    }
}
