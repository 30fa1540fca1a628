//! One candidate term of the library and its name.

use core::fmt;

/// One candidate term.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Term {
    /// The constant 1.
    Constant,
    /// x^px · v^pv, with px + pv ≥ 1.
    Monomial {
        /// Power of the displacement x.
        px: u8,
        /// Power of the velocity v = x'.
        pv: u8,
    },
    /// sin(k Ω t).
    Sin(u8),
    /// cos(k Ω t).
    Cos(u8),
    /// The measured excitation u.
    Input,
}

impl Term {
    /// Writes the term's name, with `omega` the base angular frequency in rad/s.
    pub fn write_name<W: fmt::Write>(&self, out: &mut W, omega: f64) -> fmt::Result {
        match *self {
            Term::Constant => out.write_str("1"),
            Term::Monomial { px, pv } => {
                let mut first = true;
                for (symbol, power) in [("x", px), ("v", pv)] {
                    if power == 0 {
                        continue;
                    }
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
            Term::Sin(k) | Term::Cos(k) => {
                let name = if matches!(self, Term::Sin(_)) {
                    "sin"
                } else {
                    "cos"
                };
                out.write_str(name)?;
                out.write_str("(")?;
                write_frequency(out, f64::from(k) * omega)?;
                out.write_str("t)")
            }
            Term::Input => out.write_str("u"),
        }
    }

    /// A value that `Display`s as the term's name.
    pub fn name(&self, omega: f64) -> TermName {
        TermName { term: *self, omega }
    }
}

/// A term together with Ω, displayed as the term's name.
#[derive(Clone, Copy, Debug)]
pub struct TermName {
    term: Term,
    omega: f64,
}

impl fmt::Display for TermName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.term.write_name(f, self.omega)
    }
}

/// Writes an angular frequency with at most 6 significant digits and no trailing zeros;
/// exactly 1 is written as nothing (`cos(t)`).
fn write_frequency<W: fmt::Write>(out: &mut W, w: f64) -> fmt::Result {
    if w == 1.0 {
        return Ok(());
    }
    if !w.is_finite() || w <= 0.0 {
        return write!(out, "{w}*");
    }
    // Number of digits before the point decides how many decimals keep 6 significant ones.
    let mut magnitude = 0i32;
    let mut scaled = w;
    while scaled >= 10.0 {
        scaled /= 10.0;
        magnitude += 1;
    }
    while scaled < 1.0 {
        scaled *= 10.0;
        magnitude -= 1;
    }
    let decimals = (5 - magnitude).clamp(0, 12) as usize;
    let mut buffer = heapless::String::<40>::new();
    if fmt::write(&mut buffer, format_args!("{w:.decimals$}")).is_err() {
        return write!(out, "{w}");
    }
    let text = buffer.as_str();
    let text = if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        text
    };
    out.write_str(text)
}
