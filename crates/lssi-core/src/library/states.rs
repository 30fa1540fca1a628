//! The one library a system of equations shares: candidate terms over its states.
//!
//! A harvester's recording gives states: the displacement x and its velocity v = x' (the
//! mechanical equation is second order, x'' = f), and one or two electrical channels, the
//! voltage V across the load or the current i (each a first-order equation, V' = f). Every
//! equation of the system is sparse over the same candidates:
//!
//! - the constant, and the monomials of (x, v) exactly as [`Library`] makes them
//!   (`poly_order`, `family`);
//! - the coupling terms: every monomial holding at least one electrical state, of total
//!   degree up to `coupling_order` (1: V; 2: V, x·V, v·V, V²; with two channels their
//!   products too);
//! - sin/cos(kΩt) and the measured input u, as in [`Library`].
//!
//! ```
//! use lssi_core::library::{Electrical, LibraryConfig, StateLibrary, StateLibraryConfig};
//! let config = StateLibraryConfig {
//!     mechanical: LibraryConfig::default(), // 1, the 9 monomials of (x, v) to order 3, sin, cos
//!     electrical: [Some(Electrical::Voltage), None],
//!     coupling_order: 2,
//!     displacements: 1,
//! };
//! let library: StateLibrary<16> = StateLibrary::new(&config).unwrap();
//! assert_eq!(library.len(), 16); // … and V, x*V, v*V, V^2
//! let names: Vec<String> = (0..library.len()).map(|j| library.name(j, 1.0).to_string()).collect();
//! assert_eq!(&names[..6], ["1", "x", "v", "V", "x^2", "x*v"]);
//! ```
//!
//! Columns are ordered: the constant, the monomials by total degree and then by falling
//! powers of x, v and the electrical channels in turn (so the mechanical ones keep
//! [`Library`]'s order among themselves), the sin/cos pairs by harmonic, u.

use super::{Library, LibraryConfig, LibraryError, MAX_HARMONICS, MAX_POLY_ORDER, Term};
use crate::real::Real;
use core::fmt;

/// The most electrical (first-order) channels a system has.
pub const MAX_ELECTRICAL: usize = 2;
/// The most displacements (second-order equations) a system has: two, a two-degree-of-freedom
/// harvester's x1 and x2.
pub const MAX_DISPLACEMENTS: u8 = 2;
/// States a monomial is a product of, in this order: x (x1), v (v1), the electrical channels
/// e₁, e₂, then the second displacement x2 and its velocity v2 (0 in a one-displacement
/// system, so that its monomials keep their indices).
pub const STATES: usize = 2 + MAX_ELECTRICAL + 2;
/// The highest total degree of a coupling term.
pub const MAX_COUPLING_ORDER: u8 = 3;

/// What an electrical channel measures; its symbol names its state and equation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Electrical {
    /// The voltage across the load, `V` (a piezoelectric harvester's; equation V' = …).
    // Discriminants from 1, so that `None::<Electrical>` is the byte 0: an empty
    // `SystemSlot` is all zero bits and a device's static of it lies in `.bss`.
    Voltage = 1,
    /// The current through the coil or load, `i` (an electromagnetic harvester's; i' = …).
    Current = 2,
}

impl Electrical {
    /// The state's symbol: `V` or `i`.
    pub const fn symbol(self) -> &'static str {
        match self {
            Electrical::Voltage => "V",
            Electrical::Current => "i",
        }
    }
}

/// The shared library's configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StateLibraryConfig {
    /// The mechanical part, as for one equation: the monomials of (x, v), the constant, the
    /// harmonics and u.
    pub mechanical: LibraryConfig,
    /// The electrical channels, in the order a sample carries them: `Some` ones first, each
    /// kind at most once.
    pub electrical: [Option<Electrical>; MAX_ELECTRICAL],
    /// The highest total degree of a term holding an electrical state (1..=3).
    pub coupling_order: u8,
    /// Displacements, each with its velocity and second-order equation: 1 (x, v) or 2 (x1,
    /// v1, x2, v2). With two, the mechanical monomials above degree 1 are each
    /// displacement's own powers (x1^k and x2^k, the family applied to k): the damping and
    /// the coupling stay linear, so that order 3 is 8 monomials instead of 34. (The cross
    /// terms x1^a·x2^b of all the displacements' monomials are near collinear on a
    /// two-mode record, where x1 and x2 move together: with 1 % noise their group came in
    /// spuriously on about one record in eight.)
    pub displacements: u8,
}

impl StateLibraryConfig {
    /// The number of electrical channels.
    pub fn electrical_count(&self) -> usize {
        self.electrical.iter().take_while(|e| e.is_some()).count()
    }
}

/// Why a shared library cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StateLibraryError {
    /// The mechanical part is out of range (as for one equation).
    Library(LibraryError),
    /// No electrical channel, a `None` before a `Some`, or one kind twice.
    Electrical,
    /// `coupling_order` is 0 or above [`MAX_COUPLING_ORDER`].
    CouplingOrder(u8),
    /// `displacements` is 0 or above [`MAX_DISPLACEMENTS`].
    Displacements(u8),
}

impl fmt::Display for StateLibraryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StateLibraryError::Library(e) => fmt::Display::fmt(e, f),
            StateLibraryError::Electrical => f.write_str(
                "a system needs one or two electrical channels, listed first, each kind (V or i) once",
            ),
            StateLibraryError::CouplingOrder(c) => write!(
                f,
                "coupling_order is {c}, but it must be between 1 and {MAX_COUPLING_ORDER}"
            ),
            StateLibraryError::Displacements(d) => write!(
                f,
                "displacements is {d}, but it must be between 1 and {MAX_DISPLACEMENTS}"
            ),
        }
    }
}

impl core::error::Error for StateLibraryError {}

impl From<LibraryError> for StateLibraryError {
    fn from(e: LibraryError) -> Self {
        StateLibraryError::Library(e)
    }
}

/// One candidate term of the shared library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StateTerm {
    /// The constant 1.
    Constant,
    /// x^p₀ · v^p₁ · e₁^p₂ · e₂^p₃ · x2^p₄ · v2^p₅ (e: the electrical channels), total
    /// degree ≥ 1.
    Monomial([u8; STATES]),
    /// sin(k Ω t).
    Sin(u8),
    /// cos(k Ω t).
    Cos(u8),
    /// The measured excitation u.
    Input,
}

impl StateTerm {
    /// The one-equation [`Term`] this is, when it holds no electrical state.
    pub fn mechanical(&self) -> Option<Term> {
        match *self {
            StateTerm::Constant => Some(Term::Constant),
            StateTerm::Monomial([px, pv, 0, 0, 0, 0]) => Some(Term::Monomial { px, pv }),
            StateTerm::Monomial(_) => None,
            StateTerm::Sin(k) => Some(Term::Sin(k)),
            StateTerm::Cos(k) => Some(Term::Cos(k)),
            StateTerm::Input => Some(Term::Input),
        }
    }

    /// Whether the term holds an electrical state.
    pub fn is_coupling(&self) -> bool {
        matches!(self, StateTerm::Monomial(p) if p[2..2 + MAX_ELECTRICAL].iter().any(|&q| q > 0))
    }

    /// Writes the term's name (`x*V`, `v^2`, `cos(2t)`), with `omega` the base angular
    /// frequency and `electrical` the channels' kinds naming the electrical states; the
    /// names of a one-displacement system (see [`StateTerm::write_name_in`]).
    pub fn write_name<W: fmt::Write>(
        &self,
        out: &mut W,
        omega: f64,
        electrical: &[Option<Electrical>; MAX_ELECTRICAL],
    ) -> fmt::Result {
        self.write_name_in(out, omega, electrical, 1)
    }

    /// Writes the term's name in a system of `displacements` displacements: with one the
    /// mechanical states are `x` and `v`, with two `x1`, `v1`, `x2` and `v2` (`x1*x2^2`).
    pub fn write_name_in<W: fmt::Write>(
        &self,
        out: &mut W,
        omega: f64,
        electrical: &[Option<Electrical>; MAX_ELECTRICAL],
        displacements: u8,
    ) -> fmt::Result {
        let StateTerm::Monomial(powers) = *self else {
            return match self.mechanical() {
                Some(t) => t.write_name(out, omega),
                None => Ok(()),
            };
        };
        let mut first = true;
        // The mechanical states first (x, v, x2, v2), then the electrical ones.
        for s in [0, 1, 4, 5, 2, 3] {
            let power = powers[s];
            if power == 0 {
                continue;
            }
            let two = displacements > 1;
            let symbol = match s {
                0 if two => "x1",
                1 if two => "v1",
                0 => "x",
                1 => "v",
                4 => "x2",
                5 => "v2",
                _ => electrical[s - 2].map_or("e", Electrical::symbol),
            };
            if !first {
                out.write_str("*")?;
            }
            first = false;
            out.write_str(symbol)?;
            if power > 1 {
                write!(out, "^{power}")?;
            }
        }
        Ok(())
    }
}

impl StateTerm {
    /// A value that `Display`s as the term's name (see [`StateTerm::write_name`]).
    pub fn name(
        &self,
        omega: f64,
        electrical: &[Option<Electrical>; MAX_ELECTRICAL],
    ) -> StateTermName {
        StateTermName {
            term: *self,
            omega,
            electrical: *electrical,
            displacements: 1,
        }
    }
}

/// A term with what names it, displayed as its name.
#[derive(Clone, Copy, Debug)]
pub struct StateTermName {
    term: StateTerm,
    omega: f64,
    electrical: [Option<Electrical>; MAX_ELECTRICAL],
    displacements: u8,
}

impl StateTermName {
    /// The name in a system of `displacements` displacements (`x1`, `v2`: see
    /// [`StateTerm::write_name_in`]).
    pub fn in_system(self, displacements: u8) -> Self {
        Self {
            displacements,
            ..self
        }
    }
}

impl fmt::Display for StateTermName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.term
            .write_name_in(f, self.omega, &self.electrical, self.displacements)
    }
}

/// The shared library: up to `P` terms (at most 32), in column order.
#[derive(Clone, Debug)]
pub struct StateLibrary<const P: usize> {
    terms: heapless::Vec<StateTerm, P>,
    config: StateLibraryConfig,
    /// The highest power of any state a term reads.
    max_power: u8,
}

/// Per state, the powers 0..=9 (the tables a row's monomials are products of).
type Powers<T> = [[T; MAX_POLY_ORDER as usize + 1]; STATES];

impl<const P: usize> StateLibrary<P> {
    /// No terms: storage for an identifier not configured yet.
    pub(crate) const fn zeroed() -> Self {
        Self {
            terms: heapless::Vec::new(),
            config: StateLibraryConfig {
                mechanical: LibraryConfig {
                    poly_order: 0,
                    family: super::PolyFamily::All,
                    constant: false,
                    harmonics: 0,
                    input: false,
                },
                electrical: [None; MAX_ELECTRICAL],
                coupling_order: 0,
                displacements: 0,
            },
            max_power: 0,
        }
    }

    /// Builds the library a configuration asks for.
    pub fn new(config: &StateLibraryConfig) -> Result<Self, StateLibraryError> {
        let m = &config.mechanical;
        if m.poly_order == 0 || m.poly_order > MAX_POLY_ORDER {
            return Err(LibraryError::PolyOrder(m.poly_order).into());
        }
        if m.harmonics > MAX_HARMONICS {
            return Err(LibraryError::Harmonics(m.harmonics).into());
        }
        if config.coupling_order == 0 || config.coupling_order > MAX_COUPLING_ORDER {
            return Err(StateLibraryError::CouplingOrder(config.coupling_order));
        }
        if config.displacements == 0 || config.displacements > MAX_DISPLACEMENTS {
            return Err(StateLibraryError::Displacements(config.displacements));
        }
        let e = config.electrical_count();
        let listed_first = config.electrical[e..].iter().all(Option::is_none);
        let distinct = e < 2 || config.electrical[0] != config.electrical[1];
        if e == 0 || !listed_first || !distinct {
            return Err(StateLibraryError::Electrical);
        }
        let wanted = Self::count(config);
        let capacity = P.min(32);
        if wanted > capacity {
            return Err(LibraryError::TooManyTerms { wanted, capacity }.into());
        }
        let mut terms = heapless::Vec::new();
        Self::each(config, |t| {
            // Cannot fail: `count` was checked against the capacity above.
            let _ = terms.push(t);
        });
        let max_power = m.poly_order.max(config.coupling_order);
        Ok(Self {
            terms,
            config: *config,
            max_power,
        })
    }

    /// The number of terms a configuration asks for.
    pub fn count(config: &StateLibraryConfig) -> usize {
        let mut n = 0;
        Self::each(config, |_| n += 1);
        n
    }

    /// Calls `f` with every term of a configuration, in column order.
    fn each(config: &StateLibraryConfig, mut f: impl FnMut(StateTerm)) {
        let m = &config.mechanical;
        let e = config.electrical_count();
        if m.constant {
            f(StateTerm::Constant);
        }
        let top = m
            .poly_order
            .min(MAX_POLY_ORDER)
            .max(config.coupling_order.min(MAX_COUPLING_ORDER));
        let two = config.displacements > 1;
        for degree in 1..=top {
            // Powers with the given sum: x's falling, then v's, x2's, v2's and e₁'s (a
            // one-displacement system's order is unchanged: x2 and v2 are 0 there).
            for px in (0..=degree).rev() {
                for pv in (0..=degree - px).rev() {
                    let left = degree - px - pv;
                    for qx in (0..=if two { left } else { 0 }).rev() {
                        for qv in (0..=if two { left - qx } else { 0 }).rev() {
                            let rest = left - qx - qv;
                            for p2 in (0..=rest).rev() {
                                let p3 = rest - p2;
                                let electrical = [p2, p3];
                                let coupled = p2 + p3 > 0;
                                // Only the channels there are.
                                if electrical[e..].iter().any(|&p| p > 0) {
                                    continue;
                                }
                                let admitted = if coupled {
                                    degree <= config.coupling_order
                                } else if two {
                                    // Linear in every state; above, each displacement's own
                                    // powers (x1^k, x2^k: its spring's nonlinearity).
                                    degree == 1
                                        || (degree <= m.poly_order
                                            && pv + qv == 0
                                            && (px == 0 || qx == 0)
                                            && Library::<P>::admits(m.family, px + qx, 0))
                                } else {
                                    degree <= m.poly_order && Library::<P>::admits(m.family, px, pv)
                                };
                                if admitted {
                                    f(StateTerm::Monomial([px, pv, p2, p3, qx, qv]));
                                }
                            }
                        }
                    }
                }
            }
        }
        for k in 1..=m.harmonics.min(MAX_HARMONICS) {
            f(StateTerm::Sin(k));
            f(StateTerm::Cos(k));
        }
        if m.input {
            f(StateTerm::Input);
        }
    }

    /// The terms, in column order.
    pub fn terms(&self) -> &[StateTerm] {
        &self.terms
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &StateLibraryConfig {
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
    pub fn index_of(&self, term: StateTerm) -> Option<usize> {
        self.terms.iter().position(|&t| t == term)
    }

    /// Column `j`'s name (empty past the last column).
    pub fn name(&self, j: usize, omega: f64) -> StateTermName {
        StateTermName {
            term: self
                .terms
                .get(j)
                .copied()
                .unwrap_or(StateTerm::Monomial([0; STATES])),
            omega,
            electrical: self.config.electrical,
            displacements: self.config.displacements,
        }
    }

    /// Column `j` of a row whose states' power tables are `powers` (see
    /// [`StateLibrary::evaluate`]).
    #[inline(always)]
    fn column<T: Real>(term: StateTerm, powers: &Powers<T>, (s1, c1): (T, T), u: T) -> T {
        match term {
            StateTerm::Constant => T::ONE,
            StateTerm::Monomial(p) => {
                let mut v = powers[0][usize::from(p[0]).min(9)];
                for s in 1..STATES {
                    if p[s] > 0 {
                        v *= powers[s][usize::from(p[s]).min(9)];
                    }
                }
                v
            }
            StateTerm::Sin(k) => harmonic(k, s1, c1).0,
            StateTerm::Cos(k) => harmonic(k, s1, c1).1,
            StateTerm::Input => u,
        }
    }

    /// Evaluates one row θ into `row` (length ≥ `len()`), each column divided by its scale
    /// (`inverse_scales[j]`, 1 for the unscaled row): `states` are (x, v, e₁, e₂, x2, v2) (0
    /// for a channel there is not), (sin Ωt, cos Ωt) the phasor, `u` the input. A monomial is a
    /// product of powers built by repeated multiplication; harmonics by the Chebyshev
    /// recurrence.
    pub fn evaluate<T: Real>(
        &self,
        states: &[T; STATES],
        phasor: (T, T),
        u: T,
        inverse_scales: &[T],
        row: &mut [T],
    ) {
        let mut powers: Powers<T> = [[T::ZERO; MAX_POLY_ORDER as usize + 1]; STATES];
        let top = usize::from(self.max_power).min(MAX_POLY_ORDER as usize);
        for (table, &s) in powers.iter_mut().zip(states) {
            table[0] = T::ONE;
            for i in 1..=top {
                table[i] = table[i - 1] * s;
            }
        }
        for ((slot, &term), &d) in row.iter_mut().zip(self.terms.iter()).zip(inverse_scales) {
            *slot = Self::column(term, &powers, phasor, u) * d;
        }
    }

    /// The scale of every column from the states' and the input's typical sizes (a monomial's
    /// is the product of its states' powers; the constant's and the harmonics' 1), into
    /// `scales`.
    pub fn scales<T: Real>(&self, state_scales: &[T; STATES], u_scale: T, scales: &mut [T]) {
        let mut powers: Powers<T> = [[T::ZERO; MAX_POLY_ORDER as usize + 1]; STATES];
        for (table, &s) in powers.iter_mut().zip(state_scales) {
            table[0] = T::ONE;
            for i in 1..=MAX_POLY_ORDER as usize {
                table[i] = table[i - 1] * s;
            }
        }
        for (slot, &term) in scales.iter_mut().zip(self.terms.iter()) {
            *slot = match term {
                StateTerm::Input => u_scale,
                StateTerm::Monomial(_) => Self::column(term, &powers, (T::ZERO, T::ONE), T::ONE),
                _ => T::ONE,
            };
        }
    }
}

/// (sin kφ, cos kφ) from (sin φ, cos φ) by the Chebyshev recurrence (k ≤ 8).
#[inline(always)]
fn harmonic<T: Real>(k: u8, s1: T, c1: T) -> (T, T) {
    let (mut s0, mut c0) = (T::ZERO, T::ONE);
    let (mut s, mut c) = (s1, c1);
    let two_c = c1 + c1;
    for _ in 1..k.min(MAX_HARMONICS) {
        (s0, s) = (s, two_c * s - s0);
        (c0, c) = (c, two_c * c - c0);
    }
    (s, c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::library::PolyFamily;
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn config(electrical: [Option<Electrical>; 2], coupling_order: u8) -> StateLibraryConfig {
        StateLibraryConfig {
            mechanical: LibraryConfig::default(),
            electrical,
            coupling_order,
            displacements: 1,
        }
    }

    fn names<const P: usize>(library: &StateLibrary<P>) -> Vec<String> {
        (0..library.len())
            .map(|j| library.name(j, 1.0).to_string())
            .collect()
    }

    /// The mechanical terms come in the one-equation library's order, the coupling terms
    /// among them by degree; names as everywhere (`x*V`, `v*i`).
    #[test]
    fn terms_and_names() {
        let library =
            StateLibrary::<16>::new(&config([Some(Electrical::Voltage), None], 2)).expect("fits");
        assert_eq!(
            names(&library),
            [
                "1", "x", "v", "V", "x^2", "x*v", "x*V", "v^2", "v*V", "V^2", "x^3", "x^2*v",
                "x*v^2", "v^3", "sin(t)", "cos(t)"
            ]
        );
        let one = Library::<16>::new(&LibraryConfig::default()).expect("fits");
        let mechanical: Vec<Term> = library
            .terms()
            .iter()
            .filter_map(|t| t.mechanical())
            .collect();
        assert_eq!(mechanical, one.terms());
        let two = StateLibrary::<32>::new(&StateLibraryConfig {
            mechanical: LibraryConfig {
                poly_order: 3,
                family: PolyFamily::OddFamilies,
                constant: false,
                harmonics: 0,
                input: true,
            },
            electrical: [Some(Electrical::Current), Some(Electrical::Voltage)],
            coupling_order: 2,
            displacements: 1,
        })
        .expect("fits");
        assert_eq!(
            names(&two),
            [
                "x", "v", "i", "V", "x*i", "x*V", "v*i", "v*V", "i^2", "i*V", "V^2", "x^3",
                "x^2*v", "u"
            ]
        );
        assert!(two.terms()[2].is_coupling() && !two.terms()[1].is_coupling());
    }

    /// Two displacements: every state linear, then each displacement's own powers (the
    /// family applied to them), named x1, v1, x2, v2.
    #[test]
    fn two_displacements_share_one_bounded_library() {
        let mut c = config([Some(Electrical::Voltage), None], 1);
        c.displacements = 2;
        c.mechanical.harmonics = 1;
        c.mechanical.input = true;
        let library = StateLibrary::<32>::new(&c).expect("fits");
        assert_eq!(
            names(&library),
            [
                "1", "x1", "v1", "x2", "v2", "V", "x1^2", "x2^2", "x1^3", "x2^3", "sin(t)",
                "cos(t)", "u"
            ]
        );
        assert_eq!(
            library.index_of(StateTerm::Monomial([0, 0, 0, 0, 1, 0])),
            Some(3)
        );
        c.mechanical.family = PolyFamily::OddFamilies;
        c.coupling_order = 2;
        let odd = StateLibrary::<32>::new(&c).expect("fits");
        assert_eq!(
            names(&odd),
            [
                "1", "x1", "v1", "x2", "v2", "V", "x1*V", "v1*V", "x2*V", "v2*V", "V^2", "x1^3",
                "x2^3", "sin(t)", "cos(t)", "u"
            ]
        );
        // The largest: order 3 with every family, coupling 3, two channels, 8 harmonics.
        c.mechanical.family = PolyFamily::All;
        c.coupling_order = 3;
        c.electrical = [Some(Electrical::Voltage), Some(Electrical::Current)];
        assert!(matches!(
            StateLibrary::<32>::new(&c),
            Err(StateLibraryError::Library(
                LibraryError::TooManyTerms { .. }
            ))
        ));
        c.displacements = 3;
        assert_eq!(
            StateLibrary::<32>::new(&c).err(),
            Some(StateLibraryError::Displacements(3))
        );
        // Evaluated: x2 and v2 are the fifth and sixth states.
        let mut row = [0.0; 32];
        let ones = [1.0; 32];
        let s = [2.0, 3.0, 5.0, 0.0, 7.0, 11.0];
        library.evaluate(&s, (0.0, 1.0), 13.0, &ones, &mut row);
        assert_eq!(
            &row[..10],
            [1.0, 2.0, 3.0, 7.0, 11.0, 5.0, 4.0, 49.0, 8.0, 343.0]
        );
        assert_eq!(row[12], 13.0);
    }

    #[test]
    fn bad_configurations_are_refused_with_a_reason() {
        let cases = [
            (config([None, None], 1), StateLibraryError::Electrical),
            (
                config([None, Some(Electrical::Voltage)], 1),
                StateLibraryError::Electrical,
            ),
            (
                config([Some(Electrical::Voltage), Some(Electrical::Voltage)], 1),
                StateLibraryError::Electrical,
            ),
            (
                config([Some(Electrical::Voltage), None], 0),
                StateLibraryError::CouplingOrder(0),
            ),
            (
                config([Some(Electrical::Voltage), None], 3),
                StateLibraryError::Library(LibraryError::TooManyTerms {
                    wanted: 22,
                    capacity: 16,
                }),
            ),
        ];
        for (c, expected) in cases {
            assert_eq!(StateLibrary::<16>::new(&c).err(), Some(expected), "{c:?}");
            assert!(!expected.to_string().is_empty());
        }
    }

    /// A row is the product of its states' powers, scaled; the harmonics those of Ωt.
    #[test]
    fn rows_evaluate_each_term() {
        let library =
            StateLibrary::<16>::new(&config([Some(Electrical::Voltage), None], 2)).expect("fits");
        let (x, v, e) = (0.3f64, -1.5, 2.0);
        let phase = 0.7f64;
        let mut row = [0.0; 16];
        let ones = [1.0; 16];
        library.evaluate(
            &[x, v, e, 0.0, 0.0, 0.0],
            (phase.sin(), phase.cos()),
            0.0,
            &ones,
            &mut row,
        );
        let expected = [
            1.0,
            x,
            v,
            e,
            x * x,
            x * v,
            x * e,
            v * v,
            v * e,
            e * e,
            x * x * x,
            x * x * v,
            x * v * v,
            v * v * v,
            phase.sin(),
            phase.cos(),
        ];
        for (j, (r, w)) in row.iter().zip(expected).enumerate() {
            assert!((r - w).abs() < 1e-12, "{j}: {r} {w}");
        }
        let mut scales = [0.0; 16];
        library.scales(&[2.0, 3.0, 5.0, 1.0, 1.0, 1.0], 1.0, &mut scales);
        assert_eq!(scales[6], 10.0);
        assert_eq!(scales[11], 12.0);
        assert_eq!(scales[15], 1.0);
        // Harmonic k of the recurrence is sin/cos kφ.
        for k in 1..=8u8 {
            let (s, c) = harmonic(k, phase.sin(), phase.cos());
            assert!((s - (f64::from(k) * phase).sin()).abs() < 1e-12, "{k}");
            assert!((c - (f64::from(k) * phase).cos()).abs() < 1e-12, "{k}");
        }
    }
}
