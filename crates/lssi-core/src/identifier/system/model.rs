//! What a system's screening reports: one sparse equation per state over the shared library.

use crate::library::{Electrical, MAX_ELECTRICAL, StateTerm, StateTermName};
use crate::model::{MAX_SOLUTIONS, Solution};
use crate::real::Real;
use core::fmt;

/// The left-hand side of an equation: the mechanical state's second derivative or an
/// electrical state's first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Target {
    /// x'' (the mechanical equation, second order; x1'' of two displacements).
    Acceleration,
    /// x2'' (the second displacement's equation, in a two-degree-of-freedom system).
    Acceleration2,
    /// V' or i' (an electrical channel's equation, first order).
    Rate(Electrical),
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Target::Acceleration => f.write_str("x''"),
            Target::Acceleration2 => f.write_str("x2''"),
            Target::Rate(e) => write!(f, "{}'", e.symbol()),
        }
    }
}

/// One equation of a system: its target and its sparse coefficients over the shared
/// library, selected by its own threshold sweep and MES.
#[derive(Clone, Debug)]
pub struct Equation<T, const P: usize> {
    /// The left-hand side.
    pub target: Target,
    /// Coefficients of the selected solution over the shared library's columns (0 for the
    /// inactive ones), in physical units: the target's unit over the term's.
    pub coefficients: [T; P],
    /// The distinct solutions of this equation's sweep, by increasing threshold; each one's
    /// held-out mean squared error is in the target's unit squared.
    pub solutions: heapless::Vec<Solution<T>, MAX_SOLUTIONS>,
    /// Index of the solution MES selected.
    pub selected: usize,
}

impl<T: Real, const P: usize> Equation<T, P> {
    /// The selected solution.
    pub fn selected_solution(&self) -> Option<&Solution<T>> {
        self.solutions.get(self.selected)
    }

    /// The active columns (bit j: column j).
    pub fn support(&self) -> u32 {
        self.selected_solution().map_or(0, |s| s.support)
    }
}

/// The identified system: the shared library and one equation per state, the mechanical
/// one first, then the electrical channels' in their order.
#[derive(Clone, Debug)]
pub struct SystemModel<T, const P: usize, const E: usize> {
    /// The shared library's terms, in column order.
    pub terms: heapless::Vec<StateTerm, P>,
    /// The electrical channels (naming their states and equations).
    pub electrical: [Option<Electrical>; MAX_ELECTRICAL],
    /// Displacements (1, or 2: the states are then named x1, v1, x2, v2).
    pub displacements: u8,
    /// x'' first (x1'' then x2'' with two displacements), then V' (or i') for each
    /// electrical channel.
    pub equations: heapless::Vec<Equation<T, P>, E>,
    /// Base angular frequency Ω of the harmonics, rad/s.
    pub omega: f64,
    /// Accepted samples so far.
    pub samples: u64,
    /// Rejected samples so far.
    pub rejected: u64,
    /// Regression rows folded in so far (each one serves every equation).
    pub rows: u64,
}

impl<T: Real, const P: usize, const E: usize> SystemModel<T, P, E> {
    /// The equation of a target.
    pub fn equation(&self, target: Target) -> Option<&Equation<T, P>> {
        self.equations.iter().find(|e| e.target == target)
    }

    /// The coefficient of `term` in the equation of `target` (0 when the term is inactive),
    /// if both exist.
    pub fn coefficient(&self, target: Target, term: StateTerm) -> Option<T> {
        let j = self.terms.iter().position(|&t| t == term)?;
        self.equation(target)?.coefficients.get(j).copied()
    }

    /// Column `j`'s name (`x*V`), as the command line and JSON write it.
    pub fn term_name(&self, j: usize) -> Option<StateTermName> {
        let term = self.terms.get(j)?;
        Some(
            term.name(self.omega, &self.electrical)
                .in_system(self.displacements),
        )
    }

    /// The name of equation `k`'s left-hand side: `x''`, `V'`, and with two displacements
    /// `x1''` and `x2''`.
    pub fn target_name(&self, k: usize) -> Option<TargetName> {
        let target = self.equations.get(k)?.target;
        Some(TargetName {
            target,
            displacements: self.displacements,
        })
    }

    /// The active terms of the equation of `target`, with their coefficients, in column
    /// order.
    pub fn active(&self, target: Target) -> impl Iterator<Item = (StateTerm, T)> + '_ {
        let equation = self.equation(target);
        self.terms.iter().enumerate().filter_map(move |(j, &t)| {
            let e = equation?;
            (e.support() & (1 << j) != 0).then(|| (t, e.coefficients[j]))
        })
    }

    /// Writes equation `k` as text, `x'' = -1 x - 0.04 v + 0.1 V + 0.3 cos(0.8t)` (coefficients
    /// with `decimals` places).
    pub fn write_equation<W: fmt::Write>(
        &self,
        k: usize,
        decimals: usize,
        out: &mut W,
    ) -> fmt::Result {
        let Some(e) = self.equations.get(k) else {
            return Ok(());
        };
        write!(
            out,
            "{} =",
            TargetName {
                target: e.target,
                displacements: self.displacements
            }
        )?;
        let mut any = false;
        for (j, term) in self.terms.iter().enumerate() {
            if e.support() & (1 << j) == 0 {
                continue;
            }
            let c = e.coefficients[j].to_f64();
            let sign = if c < 0.0 { '-' } else { '+' };
            if any || c < 0.0 {
                write!(out, " {sign}")?;
            }
            write!(out, " {:.*} ", decimals, c.abs())?;
            term.write_name_in(out, self.omega, &self.electrical, self.displacements)?;
            any = true;
        }
        if !any {
            out.write_str(" 0")?;
        }
        Ok(())
    }
}

/// A target as a system of some displacements names it (`x1''` where there are two).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetName {
    /// The target.
    pub target: Target,
    /// Displacements of its system.
    pub displacements: u8,
}

impl fmt::Display for TargetName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.target {
            Target::Acceleration if self.displacements > 1 => f.write_str("x1''"),
            t => fmt::Display::fmt(&t, f),
        }
    }
}
