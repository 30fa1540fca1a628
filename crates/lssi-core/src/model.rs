//! What a screening reports: the selected sparse model and every solution it chose among.

use crate::library::Term;
use crate::real::Real;
use crate::restoring::RestoringForce;

/// The most distinct solutions one screening keeps.
pub const MAX_SOLUTIONS: usize = 32;

/// One sparse solution S_i of the threshold sweep (the paper's Table 2 rows).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Solution<T> {
    /// The smallest threshold (on scaled coefficients) that gave this support.
    pub threshold: T,
    /// Held-out mean squared error of x'' (eq. 15), in (physical units of x'')².
    pub mean_error: T,
    /// Active terms: bit j is column j of the library.
    pub support: u32,
}

impl<T> Solution<T> {
    /// Number of active terms.
    pub fn len(&self) -> u32 {
        self.support.count_ones()
    }

    /// Whether no term is active.
    pub fn is_empty(&self) -> bool {
        self.support == 0
    }
}

/// A snapshot of the identified model, in physical units and in the sensor's coordinates
/// moved to the equilibrium the offsets estimate found.
#[derive(Clone, Debug)]
pub struct Model<T, const P: usize> {
    /// The library's terms, in column order.
    pub terms: heapless::Vec<Term, P>,
    /// Coefficients of the selected solution (0 for inactive terms), physical units.
    pub coefficients: [T; P],
    /// The distinct solutions of the sweep, by increasing threshold.
    pub solutions: heapless::Vec<Solution<T>, MAX_SOLUTIONS>,
    /// Index of the solution MES selected.
    pub selected: usize,
    /// K of the k-neighbour smoothing, for x and for v (0 when smoothing is off).
    pub k: (u8, u8),
    /// Base angular frequency Ω, rad/s.
    pub omega: f64,
    /// Estimated sensor offset of x (the model is in x − offset_x).
    pub offset_x: T,
    /// Estimated sensor offset of v (the model is in v − offset_v).
    pub offset_v: T,
    /// Accepted samples so far.
    pub samples: u64,
    /// Rejected samples so far.
    pub rejected: u64,
    /// Regression rows folded in so far.
    pub rows: u64,
}

impl<T: Real, const P: usize> Model<T, P> {
    /// The coefficient of a term, if the library has it.
    pub fn coefficient(&self, term: Term) -> Option<T> {
        self.terms
            .iter()
            .position(|&t| t == term)
            .and_then(|i| self.coefficients.get(i).copied())
    }

    /// The selected solution.
    pub fn selected_solution(&self) -> Option<&Solution<T>> {
        self.solutions.get(self.selected)
    }

    /// The restoring force: the x-only terms, about the x offset (its wells, potential and
    /// resonances).
    pub fn restoring_force(&self) -> RestoringForce {
        RestoringForce::from_model(self)
    }

    /// Linear resonance f = √(−ξ_x)/2π in Hz, where ξ_x < 0
    /// ([`RestoringForce::resonance_hz`]).
    pub fn resonance_hz(&self) -> Option<f64> {
        self.restoring_force().resonance_hz()
    }

    /// For a double well (ξ_x > 0, ξ_x³ < 0): the well positions ±√(−ξ_x/ξ_x³), in the
    /// model's coordinates ([`RestoringForce::wells`]).
    pub fn wells(&self) -> Option<f64> {
        self.restoring_force().wells()
    }

    /// For a double well: the small-oscillation frequency inside a well, √(2ξ_x)/2π in Hz
    /// ([`RestoringForce::well_resonance_hz`]).
    pub fn well_resonance_hz(&self) -> Option<f64> {
        self.restoring_force().well_resonance_hz()
    }
}
