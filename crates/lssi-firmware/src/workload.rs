//! A benchmark workload (the `bench` image): one update of a
//! 16-term square-root-information least-squares factor by Givens rotations (the RLS form
//! docs/design.md prescribes), f32, fixed memory.
//!
//! Each update scales the triangular factor R and the vector z by √λ, then rotates the new
//! row [θ | y] into them, one Givens rotation per column: about 16·17/2 rotated pairs and
//! 16 square roots.

use core::hint::black_box;

/// Number of library terms.
pub const TERMS: usize = 16;

/// Triangular factor R, right-hand side z and residual energy of a weighted least-squares
/// problem.
pub struct GivensFactor {
    r: [[f32; TERMS]; TERMS],
    z: [f32; TERMS],
    residual: f32,
    sqrt_lambda: f32,
}

impl GivensFactor {
    /// An empty factor with forgetting factor `lambda` (0 < λ ≤ 1).
    pub fn new(lambda: f32) -> Self {
        Self {
            r: [[0.0; TERMS]; TERMS],
            z: [0.0; TERMS],
            residual: 0.0,
            sqrt_lambda: libm::sqrtf(lambda),
        }
    }

    /// Rotates the observation `row · ξ = y` into the factor.
    pub fn update(&mut self, row: &[f32; TERMS], y: f32) {
        let mut a = *row;
        let mut b = y;
        let s = self.sqrt_lambda;
        for i in 0..TERMS {
            let (r_row, a_tail) = (&mut self.r[i][i..], &mut a[i..]);
            for r in r_row.iter_mut() {
                *r *= s;
            }
            self.z[i] *= s;
            let (rii, ai) = (r_row[0], a_tail[0]);
            let h = libm::sqrtf(rii * rii + ai * ai);
            if h == 0.0 {
                continue;
            }
            let (c, sn) = (rii / h, ai / h);
            for (r, a) in r_row.iter_mut().zip(a_tail.iter_mut()) {
                let (rv, av) = (*r, *a);
                *r = c * rv + sn * av;
                *a = c * av - sn * rv;
            }
            let zi = self.z[i];
            self.z[i] = c * zi + sn * b;
            b = c * b - sn * zi;
        }
        self.residual = s * s * self.residual + b * b;
    }

    /// Solves R ξ = z by back substitution; `None` if R is singular.
    pub fn solve(&self) -> Option<[f32; TERMS]> {
        let mut x = [0.0f32; TERMS];
        for i in (0..TERMS).rev() {
            let tail: f32 = self.r[i][i + 1..]
                .iter()
                .zip(&x[i + 1..])
                .map(|(r, x)| r * x)
                .sum();
            if self.r[i][i] == 0.0 {
                return None;
            }
            x[i] = (self.z[i] - tail) / self.r[i][i];
        }
        Some(x)
    }

    /// Weighted residual energy of the fit.
    pub fn residual(&self) -> f32 {
        self.residual
    }
}

/// A small deterministic generator of rows in [-1, 1) (xorshift32).
pub struct Rows {
    state: u32,
}

impl Rows {
    /// A generator from a non-zero seed.
    pub fn new(seed: u32) -> Self {
        Self { state: seed | 1 }
    }

    fn next_unit(&mut self) -> f32 {
        let mut x = self.state;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.state = x;
        // 24 random bits to [-1, 1).
        (x >> 8) as f32 / (1u32 << 23) as f32 - 1.0
    }

    /// The next row, and its target for the coefficients `truth` plus small noise.
    pub fn next_row(&mut self, truth: &[f32; TERMS]) -> ([f32; TERMS], f32) {
        let mut row = [0.0f32; TERMS];
        for v in row.iter_mut() {
            *v = self.next_unit();
        }
        let y = row.iter().zip(truth).map(|(a, b)| a * b).sum::<f32>() + 1e-3 * self.next_unit();
        (black_box(row), black_box(y))
    }
}
