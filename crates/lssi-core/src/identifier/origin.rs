//! The x origin: equilibria, Newton refinement, golden-section search and the shift map.

use super::*;

/// Steps of the grid on which the equilibria of the dense model are bracketed.
const EQUILIBRIUM_STEPS: usize = 256;

/// The range of x̂ over the rows: where the origin search looks.
#[derive(Clone, Copy, Debug)]
pub(super) struct Extent<T> {
    min: T,
    max: T,
}

impl<T: Real> Extent<T> {
    /// Storage (all zero bits).
    pub(super) const fn zeroed() -> Self {
        Self {
            min: T::ZERO,
            max: T::ZERO,
        }
    }

    /// No rows yet: empty.
    pub(super) fn new() -> Self {
        Self {
            min: T::MAX,
            max: -T::MAX,
        }
    }

    /// Widens the range to `x`.
    #[inline]
    pub(super) fn include(&mut self, x: T) {
        self.min = self.min.min(x);
        self.max = self.max.max(x);
    }

    /// max − min.
    pub(super) fn span(&self) -> T {
        self.max - self.min
    }

    /// Whether no row was included.
    pub(super) fn is_empty(&self) -> bool {
        self.max < self.min
    }

    /// (min, max) in f64.
    pub(super) fn bounds(&self) -> (f64, f64) {
        (self.min.to_f64(), self.max.to_f64())
    }
}

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// With the origin at `c`: the equilibrium, nearest 0, of the model on `support` and the
    /// columns an x-shift of it needs. Returns the step to it, if Newton's method converges.
    pub(super) fn refine_origin(
        &self,
        offset_v: T,
        c: T,
        support: u32,
        w: &mut Work<T, P>,
    ) -> Option<T> {
        self.prepare(offset_v, c, false, w);
        let closure = self.library.x_shift_closure(support);
        let mut xi = [T::ZERO; P];
        w.all.solve_in(closure, &mut xi, &mut w.m);
        let mut poly = [0.0f64; crate::library::MAX_POLY_ORDER as usize + 1];
        for (j, term) in self.library.terms().iter().enumerate() {
            let value = self.columns.physical(j, xi[j]).to_f64();
            match *term {
                Term::Constant => poly[0] = value,
                Term::Monomial { px, pv: 0 } => poly[usize::from(px)] = value,
                _ => {}
            }
        }
        let span = self.extent.span().to_f64().abs();
        let mut x = 0.0f64;
        for _ in 0..30 {
            let (mut p, mut dp) = (0.0, 0.0);
            for &coefficient in poly.iter().rev() {
                dp = dp * x + p;
                p = p * x + coefficient;
            }
            if dp == 0.0 || !dp.is_finite() {
                return None;
            }
            let step = p / dp;
            x -= step;
            if libm::fabs(x) > span {
                return None;
            }
            if libm::fabs(step) <= 1e-12 * span.max(1e-300) {
                break;
            }
        }
        Some(T::from_f64(x))
    }

    /// Drops from `support` (at x origin `c`), one at a time, the term whose removal costs
    /// least once the origin is moved to suit the smaller model ([`Self::best_origin`]), as
    /// long as the residual energy (A and B together) grows by at most `tolerance` of the
    /// full support's; returns the origin reached, or `None` if no term went.
    pub(super) fn shed_by_shift(
        &self,
        offset_v: T,
        c: T,
        support: u32,
        tolerance: T,
        w: &mut Work<T, P>,
    ) -> Option<T> {
        self.prepare(offset_v, T::ZERO, false, w);
        let limit = self.origin_rss(c, support, w) * (T::ONE + tolerance);
        let (mut kept, mut at, mut moved) = (support, c, false);
        while kept.count_ones() > 1 {
            let mut best: Option<(T, u32, T)> = None;
            let mut rest = kept;
            while rest != 0 {
                let j = rest.trailing_zeros();
                rest &= rest - 1;
                let smaller = kept & !(1u32 << j);
                // Only a term that moving the origin of the others creates can go.
                if self.library.x_shift_closure(smaller) & (1u32 << j) == 0 {
                    continue;
                }
                let Some(origin) = self.best_origin(offset_v, at, smaller, w) else {
                    continue;
                };
                // `best_origin` left `w.all` at x's own origin.
                let rss = self.origin_rss(origin, smaller, w);
                if rss <= limit && best.is_none_or(|(r, _, _)| rss < r) {
                    best = Some((rss, smaller, origin));
                }
            }
            let Some((_, smaller, origin)) = best else {
                break;
            };
            kept = smaller;
            at = origin;
            moved = true;
        }
        moved.then_some(at)
    }

    /// Residual energy of A and B together, at x origin `at`, of the least-squares model on
    /// `support`; `w.all` holds the union at x's own origin, A of `w.ab` is the scratch.
    pub(super) fn origin_rss(&self, at: T, support: u32, w: &mut Work<T, P>) -> T {
        self.shift_into(at, T::ZERO, &mut w.m);
        let mut scratch = w.ab.a_mut();
        scratch.copy_from(w.all.view());
        scratch.transform(&w.m);
        let mut xi = [T::ZERO; P];
        let scratch = w.ab.a();
        scratch.solve_in(support, &mut xi, &mut w.m);
        scratch.error(&xi)
    }

    /// The origin near `c` at which the model on `support` fits best (least residual energy
    /// of A and B together), by golden-section search over ±5 % of the data's span. `None`
    /// when the support is closed under x-shifts (the residual does not depend on the origin).
    pub(super) fn best_origin(
        &self,
        offset_v: T,
        c: T,
        support: u32,
        w: &mut Work<T, P>,
    ) -> Option<T> {
        if self.library.x_shift_closure(support) == support {
            return None;
        }
        let span = self.extent.span().abs();
        if !(span > T::ZERO) {
            return None;
        }
        self.prepare(offset_v, T::ZERO, false, w);
        let g = T::from_f64(0.618_033_988_749_894_8);
        let half = span * T::from_f64(0.05);
        let (mut lo, mut hi) = (c - half, c + half);
        let (mut p, mut q) = (hi - g * (hi - lo), lo + g * (hi - lo));
        let (mut fp, mut fq) = (
            self.origin_rss(p, support, w),
            self.origin_rss(q, support, w),
        );
        for _ in 0..golden_steps::<T>() {
            if fp < fq {
                hi = q;
                q = p;
                fq = fp;
                p = hi - g * (hi - lo);
                fp = self.origin_rss(p, support, w);
            } else {
                lo = p;
                p = q;
                fp = fq;
                q = lo + g * (hi - lo);
                fq = self.origin_rss(q, support, w);
            }
        }
        let best = (lo + hi) * T::from_f64(0.5);
        // At the edge of the bracket the minimum is elsewhere: no answer.
        if (best - (c - half)).abs() < span * T::from_f64(1e-3)
            || (c + half - best).abs() < span * T::from_f64(1e-3)
        {
            return None;
        }
        Some(best)
    }

    /// Writes the column map (scaled) that moves the origin of x and v by (cx, cv) into `b`:
    /// the new columns are θ(x − cx, v − cv) = M(−c) θ(x, v), B = diag(d) Mᵀ diag(d)⁻¹.
    /// Built in place (M, then transposed and scaled) so that no second matrix is needed.
    pub(super) fn shift_into(&self, cx: T, cv: T, b: &mut [[T; P]; P]) {
        let n = self.library.len();
        self.library.shift_matrix(-cx, -cv, b);
        for k in 0..n {
            for j in 0..k {
                let t = b[k][j];
                b[k][j] = b[j][k];
                b[j][k] = t;
            }
        }
        for k in 0..n {
            for j in 0..n {
                // Scaled: B[k][j] = M[j][k] d_k / d_j (columns θ/d).
                b[k][j] = self.columns.scale_entry(b[k][j], k, j);
            }
        }
    }

    /// Real roots of the dense model's unforced restoring force p(x) = Σ ξ_(a,0) x^a (v = 0,
    /// no excitation) within the data's range widened by half of it, nearest the middle first.
    pub(super) fn equilibria(
        &self,
        all: &Factor<T, P>,
        work: &mut [[T; P]; P],
        out: &mut heapless::Vec<T, 7>,
    ) {
        let n = self.library.len();
        let full: u32 = if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
        let mut xi = [T::ZERO; P];
        all.solve_in(full, &mut xi, work);
        let mut poly = [0.0f64; crate::library::MAX_POLY_ORDER as usize + 1];
        let mut any = false;
        for (j, term) in self.library.terms().iter().enumerate() {
            let c = self.columns.physical(j, xi[j]).to_f64();
            match *term {
                Term::Constant => poly[0] = c,
                Term::Monomial { px, pv: 0 } => {
                    poly[usize::from(px)] = c;
                    any = true;
                }
                _ => {}
            }
        }
        if !any || self.extent.is_empty() {
            return;
        }
        let (lo, hi) = self.extent.bounds();
        let middle = 0.5 * (lo + hi);
        let (lo, hi) = (lo - 0.5 * (hi - lo), hi + 0.5 * (hi - lo));
        let p = |x: f64| poly.iter().rev().fold(0.0, |acc, &c| acc * x + c);
        let mut roots: heapless::Vec<f64, 16> = heapless::Vec::new();
        crate::restoring::bracket_roots(p, lo, hi, EQUILIBRIUM_STEPS, |root| {
            let _ = roots.push(root);
        });
        // Nearest the middle of the data first.
        let r = roots.as_mut_slice();
        for i in 1..r.len() {
            let mut k = i;
            while k > 0 && libm::fabs(r[k - 1] - middle) > libm::fabs(r[k] - middle) {
                r.swap(k - 1, k);
                k -= 1;
            }
        }
        // One place is left for the selected model's equilibrium (see `screen`).
        for &root in roots.iter() {
            if out.len() + 1 >= out.capacity() || out.push(T::from_f64(root)).is_err() {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Channels, LibraryConfig, PolyFamily, Sample};

    /// The forced Duffing oscillator with measured v, its x read by a sensor whose zero is
    /// `offset` off: x'' = −400(x − c) − 2v − 4·10⁴(x − c)³ + 60 cos(15t).
    fn identifier(offset: f64) -> Box<Identifier<f64, 128, 16, 3>> {
        let config = Config {
            sample_period: 1e-3,
            window: 63,
            library: LibraryConfig {
                poly_order: 3,
                family: PolyFamily::All,
                constant: true,
                harmonics: 1,
                input: false,
            },
            omega: 15.0,
            channels: Channels {
                velocity: true,
                input: false,
            },
            screening_period: 100_000,
            offsets: true,
            ..Config::default()
        };
        let mut id = Box::new(Identifier::new(config).expect("valid"));
        for p in lssi_testkit::duffing(30_000) {
            let sample = Sample {
                t: p.t,
                x: p.x + offset,
                v: Some(p.v),
                u: None,
            };
            id.push(sample).expect("clean");
        }
        id
    }

    fn support(id: &Identifier<f64, 128, 16, 3>, terms: &[Term]) -> u32 {
        terms.iter().fold(0, |s, &t| {
            s | 1u32 << id.library.index_of(t).expect("in the library")
        })
    }

    #[test]
    fn the_origin_search_finds_a_sensor_offset() {
        let offset = 0.004;
        let mut id = identifier(offset);
        let mut w = Work::new(id.library.len());
        id.prepare(0.0, 0.0, false, &mut w);
        // The dense model's equilibria: the one nearest the data's middle is the offset.
        let mut candidates: heapless::Vec<f64, 7> = heapless::Vec::new();
        id.equilibria(&w.all, &mut w.m, &mut candidates);
        assert!((candidates[0] - offset).abs() < 2e-4, "{candidates:?}");
        // The true support, about the right origin, fits best there (golden section from a
        // guess 1 mm off).
        let truth = support(
            &id,
            &[
                Term::Monomial { px: 1, pv: 0 },
                Term::Monomial { px: 0, pv: 1 },
                Term::Monomial { px: 3, pv: 0 },
                Term::Cos(1),
            ],
        );
        let found = id
            .best_origin(0.0, 0.003, truth, &mut w)
            .expect("inside the bracket");
        assert!((found - offset).abs() < 2e-5, "{found}");
        // Newton on the model with the terms a shift creates, from the recording's zero.
        let shifted = truth | support(&id, &[Term::Constant, Term::Monomial { px: 2, pv: 0 }]);
        let step = id
            .refine_origin(0.0, 0.0, shifted, &mut w)
            .expect("converges");
        assert!((step - offset).abs() < 2e-5, "{step}");
        // A support closed under shifts has no best origin.
        assert!(id.best_origin(0.0, 0.0, shifted, &mut w).is_none());
        // The screening puts the model about it, with the true terms only.
        assert!(id.screen());
        let model = id.model().expect("a model");
        assert!((model.offset_x - offset).abs() < 2e-5, "{}", model.offset_x);
        let selected = model.selected_solution().expect("selected").support;
        assert_eq!(selected, truth);
    }

    #[test]
    fn extent_spans_the_rows() {
        let mut e = Extent::<f32>::new();
        assert!(e.is_empty());
        for x in [0.5, -1.5, 2.0] {
            e.include(x);
        }
        assert!(!e.is_empty());
        assert_eq!(e.span(), 3.5);
        assert_eq!(e.bounds(), (-1.5, 2.0));
    }
}
