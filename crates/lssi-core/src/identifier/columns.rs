//! The library row of a regression row, in scaled units: the columns θ(x, x', t [, u]) and
//! the target x'' divided by their warm-up RMS, so that every column is O(1).

use super::Row;
use crate::library::{Library, RowTables, Term, powi};
use crate::real::Real;

/// Where a row is made: the library's tables and θ, kept from row to row so that neither is
/// zeroed for every row (on the M4F, 256 bytes: about 5 % of a row). Only the first
/// `library.len()` entries of θ mean anything; the rest stay zero.
#[derive(Clone, Debug)]
pub(super) struct Scratch<T, const P: usize> {
    tables: RowTables<T>,
    pub(super) theta: [T; P],
}

impl<T: Real, const P: usize> Scratch<T, P> {
    /// Zeroed.
    pub(super) const fn zeroed() -> Self {
        Self {
            tables: RowTables::zeroed(),
            theta: [T::ZERO; P],
        }
    }
}

/// The column scales, set once from the warm-up rows.
///
/// ```text
/// let mut columns = Columns::new();
/// columns.set(&library, &warmup_rows);
/// let y = columns.row(&library, &row, sin, cos, &mut theta); // θ/d, y/d_y
/// ```
#[derive(Clone, Copy, Debug)]
pub(super) struct Columns<T, const P: usize> {
    /// d_j: the scale of column j (its typical size).
    scales: [T; P],
    inverse_scales: [T; P],
    /// The scale of the target x''.
    y_scale: T,
    /// RMS of x̂ and v̂ over the warm-up: the units of the scaled columns.
    #[cfg_attr(not(feature = "noise-correction"), allow(dead_code))]
    state_scales: (T, T),
}

impl<T: Real, const P: usize> Columns<T, P> {
    /// Storage, not usable scales (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            scales: [T::ZERO; P],
            inverse_scales: [T::ZERO; P],
            y_scale: T::ZERO,
            state_scales: (T::ZERO, T::ZERO),
        }
    }

    /// Unit scales (until the warm-up ends).
    pub(super) fn new() -> Self {
        Self {
            scales: [T::ONE; P],
            inverse_scales: [T::ONE; P],
            y_scale: T::ONE,
            state_scales: (T::ONE, T::ONE),
        }
    }

    /// Column scales from the warm-up rows: each column and x'' become O(1).
    pub(super) fn set(&mut self, library: &Library<P>, warmup: &[Row<T>]) {
        let mut sums = [T::ZERO; 4];
        for r in warmup.iter() {
            for (s, v) in sums.iter_mut().zip([r.x, r.v, r.u, r.y]) {
                *s += v * v;
            }
        }
        let count = T::from_usize(warmup.len().max(1));
        let rms = sums.map(|s| {
            let r = (s / count).sqrt();
            if r > T::ZERO && r.is_finite() {
                r
            } else {
                T::ONE
            }
        });
        let (sx, sv, su, sy) = (rms[0], rms[1], rms[2], rms[3]);
        self.state_scales = (sx, sv);
        for (j, term) in library.terms().iter().enumerate() {
            let d = match *term {
                Term::Monomial { px, pv } => powi(sx, px) * powi(sv, pv),
                Term::Input => su,
                _ => T::ONE,
            };
            self.scales[j] = d;
            self.inverse_scales[j] = T::ONE / d;
        }
        self.y_scale = sy;
    }

    /// Evaluates the library on a row (with the phasor (sin Ωt, cos Ωt) = (`s1`, `c1`)) into
    /// the scratch's θ, scaled; returns the scaled target.
    #[inline]
    pub(super) fn row(
        &self,
        library: &Library<P>,
        r: &Row<T>,
        (s1, c1): (T, T),
        scratch: &mut Scratch<T, P>,
    ) -> T {
        let Scratch { tables, theta } = scratch;
        library.evaluate_scaled_in((r.x, r.v, s1, c1, r.u), &self.inverse_scales, theta, tables);
        r.y / self.y_scale
    }

    /// Coefficient `j` of a scaled solution in physical units.
    #[inline]
    pub(super) fn physical(&self, j: usize, xi: T) -> T {
        xi * self.y_scale / self.scales[j]
    }

    /// Entry (k, j) of a column map in scaled columns: `m`·d_k/d_j (columns θ/d).
    #[inline]
    pub(super) fn scale_entry(&self, m: T, k: usize, j: usize) -> T {
        m * self.scales[k] * self.inverse_scales[j]
    }

    /// The scale of the target x''.
    pub(super) fn y_scale(&self) -> T {
        self.y_scale
    }

    /// RMS of x̂ and v̂ over the warm-up.
    #[cfg(feature = "noise-correction")]
    pub(super) fn state_scales(&self) -> (T, T) {
        self.state_scales
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::library::{LibraryConfig, PolyFamily};

    #[test]
    fn scaled_columns_are_of_unit_size() {
        let config = LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: 0,
            input: false,
        };
        let library = Library::<16>::new(&config).expect("fits");
        let rows: Vec<Row<f64>> = (0..64)
            .map(|i| {
                let t = f64::from(i) * 0.1;
                Row {
                    x: 0.01 * t.sin(),
                    v: 0.3 * t.cos(),
                    y: -40.0 * t.sin(),
                    u: 0.0,
                    t,
                }
            })
            .collect();
        let mut columns = Columns::<f64, 16>::new();
        columns.set(&library, &rows);
        let n = library.len();
        let mut power = [0.0; 16];
        let mut scratch = Scratch::zeroed();
        for r in &rows {
            let y = columns.row(&library, r, (0.0, 1.0), &mut scratch);
            let theta = scratch.theta;
            assert!(y.abs() <= 2.0, "{y}");
            for j in 0..n {
                power[j] += theta[j] * theta[j] / rows.len() as f64;
            }
        }
        for (j, term) in library.terms().iter().enumerate() {
            // x^a v^b / (rms x)^a (rms v)^b is of order one.
            assert!(power[j] > 0.01 && power[j] < 10.0, "{term:?}: {}", power[j]);
            let c = columns.physical(j, 1.0);
            assert!(c.is_finite());
        }
    }
}
