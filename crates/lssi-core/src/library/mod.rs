//! The library of candidate terms Θ(x, x', t [, u]) (paper eqs. 12, 13 and 18).
//!
//! ```
//! use lssi_core::{Library, LibraryConfig, PolyFamily};
//! let config = LibraryConfig { poly_order: 3, family: PolyFamily::All, constant: true,
//!                              harmonics: 1, input: false };
//! let library: Library<16> = Library::new(&config).unwrap();
//! assert_eq!(library.len(), 12); // 1, 9 monomials, sin and cos (the firmware default)
//! ```
//!
//! Columns are ordered: constant, monomials by total degree then by falling power of x,
//! sin/cos pairs by harmonic, then the measured input `u`. A term is named the same way
//! everywhere (the command line, JSON, the wire): `1`, `x`, `v`, `x^2`, `x*v`, `x^2*v`,
//! `v^3`, `u`, `cos(2t)`, `sin(21.4t)`.

use crate::real::Real;
use core::fmt;

/// The largest polynomial order the library supports (the paper's harvester goes to 9).
pub const MAX_POLY_ORDER: u8 = 9;
/// The largest number of harmonics of Ω.
pub const MAX_HARMONICS: u8 = 8;

/// Which monomials of (x, v) enter the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PolyFamily {
    /// Every monomial x^a v^b with 1 ≤ a + b ≤ order (the paper's eq. 18 at order 3).
    All,
    /// x^k and x^(k-1)·v for k = 1..=order.
    Families,
    /// x^k and x^(k-1)·v for odd k only (the paper's Table 7).
    OddFamilies,
}

/// What the library holds: runtime selection within the const capacity.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LibraryConfig {
    /// Highest total polynomial order (1..=9).
    pub poly_order: u8,
    /// Which monomials.
    pub family: PolyFamily,
    /// Whether the constant term is a candidate.
    pub constant: bool,
    /// sin/cos(kΩt) for k = 1..=harmonics (0 leaves them out).
    pub harmonics: u8,
    /// Whether the measured excitation u is a candidate.
    pub input: bool,
}

impl Default for LibraryConfig {
    fn default() -> Self {
        Self {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: 1,
            input: false,
        }
    }
}

/// Why a library cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LibraryError {
    /// `poly_order` is 0 or above [`MAX_POLY_ORDER`].
    PolyOrder(u8),
    /// `harmonics` is above [`MAX_HARMONICS`].
    Harmonics(u8),
    /// More terms than the capacity `P` (or than 32, the width of a support mask).
    TooManyTerms {
        /// Terms the configuration asks for.
        wanted: usize,
        /// Room there is.
        capacity: usize,
    },
}

impl fmt::Display for LibraryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LibraryError::PolyOrder(p) => {
                write!(
                    f,
                    "library.poly_order is {p}, but it must be between 1 and {MAX_POLY_ORDER}"
                )
            }
            LibraryError::Harmonics(h) => {
                write!(
                    f,
                    "library.harmonics is {h}, but at most {MAX_HARMONICS} are supported"
                )
            }
            LibraryError::TooManyTerms { wanted, capacity } => write!(
                f,
                "the library has {wanted} terms, but the identifier was built for at most {capacity}"
            ),
        }
    }
}

impl core::error::Error for LibraryError {}

/// The active library: up to `P` terms, in column order.
#[derive(Clone, Debug)]
pub struct Library<const P: usize> {
    terms: heapless::Vec<Term, P>,
    config: LibraryConfig,
    /// Each term as a product `left[a] · right[b]` of [`Library::evaluate_scaled`]'s two
    /// tables: (a, b) per column.
    factors: [[u8; 2]; P],
}

/// [`Library::evaluate_scaled`]'s left table: x^0..x^9 at 0..=9, sin(kΩt) at 9 + k, cos(kΩt)
/// at 17 + k (k = 1..=8), u at 26; its right table holds v^0..v^9. An index is masked with
/// the table's length − 1, which the compiler sees is in bounds.
const LEFT: usize = 32;
const RIGHT: usize = 16;

/// The two tables a row's terms are products of ([`Library::evaluate_scaled_in`]), kept by a
/// caller from row to row: a row then writes the entries its terms read (the powers up to
/// the order, the harmonics up to theirs, u) instead of zeroing 192 bytes first (on the M4F
/// the zeroing cost about 5 % of a row).
#[derive(Clone, Debug)]
pub struct RowTables<T> {
    left: [T; LEFT],
    right: [T; RIGHT],
}

impl<T: Real> RowTables<T> {
    /// Zeroed tables.
    pub const fn zeroed() -> Self {
        Self {
            left: [T::ZERO; LEFT],
            right: [T::ZERO; RIGHT],
        }
    }
}

impl<T: Real> Default for RowTables<T> {
    fn default() -> Self {
        Self::zeroed()
    }
}
const SIN_AT: u8 = MAX_POLY_ORDER;
const COS_AT: u8 = MAX_POLY_ORDER + MAX_HARMONICS;
const INPUT_AT: u8 = MAX_POLY_ORDER + 2 * MAX_HARMONICS + 1;
const _: () = assert!((INPUT_AT as usize) < LEFT && (MAX_POLY_ORDER as usize) < RIGHT);

impl Term {
    /// (a, b) with the term = left[a] · right[b] ([`Library::evaluate_scaled`]); the factor
    /// that is not a power is x⁰ or v⁰ = 1, and a product by 1 is exact.
    const fn factors(self) -> [u8; 2] {
        match self {
            Term::Constant => [0, 0],
            Term::Monomial { px, pv } => [px, pv],
            Term::Sin(k) => [SIN_AT + k, 0],
            Term::Cos(k) => [COS_AT + k, 0],
            Term::Input => [INPUT_AT, 0],
        }
    }
}

impl<const P: usize> Library<P> {
    /// No terms and every field of its configuration zero: storage for an identifier not
    /// configured yet.
    pub(crate) const fn zeroed() -> Self {
        Self {
            terms: heapless::Vec::new(),
            config: LibraryConfig {
                poly_order: 0,
                family: PolyFamily::All,
                constant: false,
                harmonics: 0,
                input: false,
            },
            factors: [[0; 2]; P],
        }
    }

    /// Builds the library a configuration asks for.
    pub fn new(config: &LibraryConfig) -> Result<Self, LibraryError> {
        if config.poly_order == 0 || config.poly_order > MAX_POLY_ORDER {
            return Err(LibraryError::PolyOrder(config.poly_order));
        }
        if config.harmonics > MAX_HARMONICS {
            return Err(LibraryError::Harmonics(config.harmonics));
        }
        let wanted = Self::count(config);
        let capacity = P.min(32);
        if wanted > capacity {
            return Err(LibraryError::TooManyTerms { wanted, capacity });
        }
        let mut terms = heapless::Vec::new();
        let mut push = |t: Term| {
            // Cannot fail: `count` was checked against the capacity above.
            let _ = terms.push(t);
        };
        if config.constant {
            push(Term::Constant);
        }
        for degree in 1..=config.poly_order {
            for pv in 0..=degree {
                let px = degree - pv;
                if Self::admits(config.family, px, pv) {
                    push(Term::Monomial { px, pv });
                }
            }
        }
        for k in 1..=config.harmonics {
            push(Term::Sin(k));
            push(Term::Cos(k));
        }
        if config.input {
            push(Term::Input);
        }
        let mut factors = [[0; 2]; P];
        for (f, t) in factors.iter_mut().zip(terms.iter()) {
            *f = t.factors();
        }
        Ok(Self {
            terms,
            config: *config,
            factors,
        })
    }

    /// The number of terms a configuration asks for.
    pub fn count(config: &LibraryConfig) -> usize {
        let mut n = usize::from(config.constant)
            + 2 * usize::from(config.harmonics)
            + usize::from(config.input);
        for degree in 1..=config.poly_order.min(MAX_POLY_ORDER) {
            for pv in 0..=degree {
                if Self::admits(config.family, degree - pv, pv) {
                    n += 1;
                }
            }
        }
        n
    }

    fn admits(family: PolyFamily, px: u8, pv: u8) -> bool {
        match family {
            PolyFamily::All => true,
            PolyFamily::Families => pv == 0 || pv == 1,
            PolyFamily::OddFamilies => {
                (pv == 0 && px % 2 == 1) || (pv == 1 && px.is_multiple_of(2))
            }
        }
    }

    /// The terms, in column order.
    pub fn terms(&self) -> &[Term] {
        &self.terms
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &LibraryConfig {
        &self.config
    }

    /// Number of terms.
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Whether the library is empty (it never is once built).
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// Column index of a term.
    pub fn index_of(&self, term: Term) -> Option<usize> {
        self.terms.iter().position(|&t| t == term)
    }

    /// Evaluates one row θ(x, v, φ, u) into `row` (length ≥ `len()`); `phase` is Ω t reduced
    /// to [0, 2π). Powers are built by repeated multiplication, harmonics by the Chebyshev
    /// recurrence, so a row costs one sin and one cos whatever H is.
    pub fn evaluate<T: Real>(&self, x: T, v: T, phase: T, u: T, row: &mut [T]) {
        let (s1, c1) = if self.config.harmonics > 0 {
            (phase.sin(), phase.cos())
        } else {
            (T::ZERO, T::ONE)
        };
        self.evaluate_sin_cos(x, v, s1, c1, u, row);
    }

    /// [`Library::evaluate`] with the phase given as (sin φ, cos φ): for a caller that
    /// advances the phase by rotation instead of calling sin and cos for every row.
    pub fn evaluate_sin_cos<T: Real>(&self, x: T, v: T, s1: T, c1: T, u: T, row: &mut [T]) {
        let mut left = [T::ZERO; LEFT];
        let mut right = [T::ZERO; RIGHT];
        self.fill_tables((x, v, s1, c1, u), &mut left, &mut right);
        let n = self.terms.len();
        for (slot, [a, b]) in row.iter_mut().zip(&self.factors[..n]) {
            *slot = left[usize::from(*a) & (LEFT - 1)] * right[usize::from(*b) & (RIGHT - 1)];
        }
    }

    /// [`Library::evaluate_sin_cos`] with column j multiplied by `scales[j]`, bit for bit:
    /// each term is one product of two table entries (a term that is not a monomial times
    /// x⁰ or v⁰ = 1, exact), so the row is one loop without a branch per term.
    #[inline]
    pub fn evaluate_scaled<T: Real>(
        &self,
        values: (T, T, T, T, T),
        scales: &[T; P],
        row: &mut [T; P],
    ) {
        self.evaluate_scaled_in(values, scales, row, &mut RowTables::zeroed());
    }

    /// [`Library::evaluate_scaled`] with the tables kept by the caller (`tables`, any
    /// previous content): the same row, bit for bit, without zeroing them for every row.
    #[inline]
    pub fn evaluate_scaled_in<T: Real>(
        &self,
        values: (T, T, T, T, T),
        scales: &[T; P],
        row: &mut [T; P],
        tables: &mut RowTables<T>,
    ) {
        // Filled in place (returned by value they were copied on every row: 3 % of a row on
        // the M4F). Every entry a term reads is written here.
        let RowTables { left, right } = tables;
        self.fill_tables(values, left, right);
        let n = self.terms.len();
        for ((slot, [a, b]), d) in row[..n].iter_mut().zip(&self.factors).zip(scales) {
            *slot = left[usize::from(*a) & (LEFT - 1)] * right[usize::from(*b) & (RIGHT - 1)] * *d;
        }
    }

    /// Fills the two tables a row's terms are products of (whatever they held before): `left`
    /// holds 1, x, x², …, then sin kφ and cos kφ (Chebyshev recurrence from sin φ = `s1`,
    /// cos φ = `c1`) and u; `right` holds 1, v, v², …. Term j is `left[a] · right[b]` for its
    /// pair of factors. Only the powers up to the order, the harmonics up to theirs and u are
    /// written: every entry a term of this library reads.
    #[inline(always)]
    fn fill_tables<T: Real>(
        &self,
        (x, v, s1, c1, u): (T, T, T, T, T),
        left: &mut [T; LEFT],
        right: &mut [T; RIGHT],
    ) {
        let order = usize::from(self.config.poly_order).min(MAX_POLY_ORDER as usize);
        (left[0], right[0]) = (T::ONE, T::ONE);
        for i in 1..=order {
            left[i] = left[i - 1] * x;
            right[i] = right[i - 1] * v;
        }
        let harmonics = usize::from(self.config.harmonics).min(MAX_HARMONICS as usize);
        if harmonics > 0 {
            let (sin, cos) = (usize::from(SIN_AT), usize::from(COS_AT));
            // sin 0 = 0 and cos 0 = 1 start the recurrence.
            let (mut s0, mut c0) = (T::ZERO, T::ONE);
            let (mut s, mut c) = (s1, c1);
            let two_c = c1 + c1;
            for k in 1..=harmonics {
                left[sin + k] = s;
                left[cos + k] = c;
                (s0, s) = (s, two_c * s - s0);
                (c0, c) = (c, two_c * c - c0);
            }
        }
        left[usize::from(INPUT_AT)] = u;
    }

    /// Whether every lower monomial a shift of x (and of v) produces is in the library, so
    /// that moving the coordinate origin is a linear map of the columns (docs/design.md, "Sensor
    /// offsets"). Returns (x-shift closed, v-shift closed).
    pub fn shift_closed(&self) -> (bool, bool) {
        let has = |px: u8, pv: u8| {
            if px == 0 && pv == 0 {
                self.config.constant
            } else {
                self.index_of(Term::Monomial { px, pv }).is_some()
            }
        };
        let mut x_closed = true;
        let mut v_closed = true;
        for term in self.terms.iter() {
            if let Term::Monomial { px, pv } = *term {
                for i in 0..px {
                    x_closed &= has(i, pv);
                }
                for k in 0..pv {
                    v_closed &= has(px, k);
                }
            }
        }
        (x_closed, v_closed)
    }

    /// The columns a shift of x can produce from the columns in `support`: every lower power
    /// of x beside each monomial, the constant included.
    pub fn x_shift_closure(&self, support: u32) -> u32 {
        let mut closure = support;
        for (j, term) in self.terms.iter().enumerate() {
            if support & (1 << j) == 0 {
                continue;
            }
            if let Term::Monomial { px, pv } = *term {
                for i in 0..px {
                    let column = if i == 0 && pv == 0 {
                        self.index_of(Term::Constant)
                    } else {
                        self.index_of(Term::Monomial { px: i, pv })
                    };
                    if let Some(c) = column {
                        closure |= 1 << c;
                    }
                }
            }
        }
        closure
    }

    /// Writes M(cx, cv), the matrix with θ(x + cx, v + cv) = M θ(x, v), into `m` (row-major,
    /// stride `P`). Only meaningful when [`Library::shift_closed`] holds for the shifted
    /// channels; entries that would fall outside the library are dropped.
    pub fn shift_matrix<T: Real>(&self, cx: T, cv: T, m: &mut [[T; P]; P]) {
        let n = self.len();
        for row in m.iter_mut().take(n) {
            for v in row.iter_mut().take(n) {
                *v = T::ZERO;
            }
        }
        for (j, term) in self.terms.iter().enumerate() {
            match *term {
                Term::Monomial { px, pv } => {
                    for i in 0..=px {
                        for k in 0..=pv {
                            let coefficient =
                                T::from_usize((binomial(px, i) * binomial(pv, k)) as usize)
                                    * powi(cx, px - i)
                                    * powi(cv, pv - k);
                            let column = if i == 0 && k == 0 {
                                self.index_of(Term::Constant)
                            } else {
                                self.index_of(Term::Monomial { px: i, pv: k })
                            };
                            if let Some(c) = column {
                                m[j][c] += coefficient;
                            }
                        }
                    }
                }
                _ => m[j][j] = T::ONE,
            }
        }
    }
}

/// The binomial coefficient C(n, k), exact, in integers (no float arithmetic: on the M4F an
/// f64 one was soft-float calls, 5 % of a screening's origin search; no table either, 400 B
/// of flash). Each partial product r·(n − i)/(i + 1) is C(n, i + 1), an integer; 0 for k > n.
fn binomial(n: u8, k: u8) -> u32 {
    if k > n {
        return 0;
    }
    let mut r = 1u32;
    for i in 0..u32::from(k) {
        r = r * (u32::from(n) - i) / (i + 1);
    }
    r
}

/// x^n by repeated multiplication (n ≤ 9).
pub(crate) fn powi<T: Real>(x: T, n: u8) -> T {
    let mut r = T::ONE;
    for _ in 0..n {
        r *= x;
    }
    r
}

mod states;
mod term;
pub use states::{
    Electrical, MAX_COUPLING_ORDER, MAX_DISPLACEMENTS, MAX_ELECTRICAL, STATES, StateLibrary,
    StateLibraryConfig, StateLibraryError, StateTerm, StateTermName,
};
pub use term::{Term, TermName};

#[cfg(test)]
mod tests;
