//! Two factors over the same columns in the memory of about one (the held-out halves A and
//! B): P² + P entries instead of 2P² (1,240 bytes instead of 2,208 with f32 and P = 16).

use super::*;

/// Two square-root factors over the same `n` columns, A and B. A's rows are kept in place
/// (R[i][i..n]); B's diagonal in an array of its own and the entries right of it at the
/// start of row P − 1 − i, which A leaves free (see the `view` module). Their algorithms are
/// [`Factor`]'s, bit for bit, through [`FactorPair::a`], [`FactorPair::b`] and the `_mut`
/// forms.
#[derive(Clone, Debug)]
pub struct FactorPair<T, const P: usize> {
    n: usize,
    r: [[T; P]; P],
    diag_b: [T; P],
    z: [[T; P]; 2],
    rho2: [T; 2],
    weight: [T; 2],
}

impl<T: Real, const P: usize> FactorPair<T, P> {
    /// Two empty factors over `n` columns (`n` is clamped to `P`).
    pub const fn new(n: usize) -> Self {
        Self {
            n: if n < P { n } else { P },
            r: [[T::ZERO; P]; P],
            diag_b: [T::ZERO; P],
            z: [[T::ZERO; P]; 2],
            rho2: [T::ZERO; 2],
            weight: [T::ZERO; 2],
        }
    }

    /// Sets the number of columns of an empty pair (clamped to `P`).
    pub fn set_columns(&mut self, n: usize) {
        self.n = n.min(P);
    }

    /// A, to read.
    #[inline]
    pub fn a(&self) -> FactorRef<'_, T, P> {
        FactorRef {
            n: self.n,
            r: &self.r,
            flipped: None,
            z: &self.z[0],
            rho2: self.rho2[0],
            weight: self.weight[0],
        }
    }

    /// B, to read.
    #[inline]
    pub fn b(&self) -> FactorRef<'_, T, P> {
        FactorRef {
            n: self.n,
            r: &self.r,
            flipped: Some(&self.diag_b),
            z: &self.z[1],
            rho2: self.rho2[1],
            weight: self.weight[1],
        }
    }

    /// A, to write.
    #[inline]
    pub fn a_mut(&mut self) -> FactorMut<'_, T, P> {
        let [z, _] = &mut self.z;
        let [rho2, _] = &mut self.rho2;
        let [weight, _] = &mut self.weight;
        FactorMut {
            n: self.n,
            r: &mut self.r,
            layout: Layout::Upper,
            z,
            rho2,
            weight,
        }
    }

    /// B, to write.
    #[inline]
    pub fn b_mut(&mut self) -> FactorMut<'_, T, P> {
        let [_, z] = &mut self.z;
        let [_, rho2] = &mut self.rho2;
        let [_, weight] = &mut self.weight;
        FactorMut {
            n: self.n,
            r: &mut self.r,
            layout: Layout::Flipped(&mut self.diag_b),
            z,
            rho2,
            weight,
        }
    }

    /// A (`true`) or B, to write.
    #[inline]
    pub fn half_mut(&mut self, a: bool) -> FactorMut<'_, T, P> {
        if a { self.a_mut() } else { self.b_mut() }
    }

    /// Makes this pair a copy of `other` without a temporary.
    pub fn copy_from(&mut self, other: &Self) {
        self.n = other.n;
        self.r = other.r;
        self.diag_b = other.diag_b;
        self.z = other.z;
        self.rho2 = other.rho2;
        self.weight = other.weight;
    }

    /// Empties both (same columns), in place (a new pair would be built on the stack first).
    pub fn clear(&mut self) {
        for row in self.r.iter_mut() {
            row.fill(T::ZERO);
        }
        self.diag_b.fill(T::ZERO);
        for z in self.z.iter_mut() {
            z.fill(T::ZERO);
        }
        self.rho2 = [T::ZERO; 2];
        self.weight = [T::ZERO; 2];
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    fn filled<const P: usize>(n: usize, rows: usize, seed: u64) -> Factor<f64, P> {
        let mut f = Factor::new(n);
        let mut s = seed;
        for _ in 0..rows {
            let mut row = [0.0; P];
            for v in row.iter_mut().take(n) {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                *v = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            }
            let y = row.iter().sum::<f64>() * 0.5 + row[0] * row[0];
            f.update(&row[..n], y, 0.999);
        }
        f
    }

    /// One operation on a factor, for the random sequences below.
    #[derive(Clone, Debug)]
    enum Op {
        Update(std::vec::Vec<f32>, f32, f32),
        Forget(f32),
        Scale(std::vec::Vec<f32>, f32),
        Shift(f32),
        MergeOther,
    }

    fn op(n: usize) -> impl Strategy<Value = Op> {
        let row = proptest::collection::vec(-3.0f32..3.0, n);
        prop_oneof![
            4 => (row.clone(), -3.0f32..3.0, 0.9f32..=1.0).prop_map(|(r, y, l)| Op::Update(r, y, l)),
            1 => (0.5f32..=1.0).prop_map(Op::Forget),
            1 => (proptest::collection::vec(0.25f32..4.0, n), 0.25f32..4.0)
                .prop_map(|(f, t)| Op::Scale(f, t)),
            1 => (-1.0f32..1.0).prop_map(Op::Shift),
            1 => Just(Op::MergeOther),
        ]
    }

    /// x → x + c on the columns (1, x, x², …): the binomial map, upper triangular.
    fn shift_map<const P: usize>(n: usize, c: f32) -> [[f32; P]; P] {
        let mut b = [[0.0f32; P]; P];
        for j in 0..n {
            // Column j (x^j) = Σ_i C(j, i) c^(j−i) x^i.
            let mut binomial = 1.0f32;
            for i in (0..=j).rev() {
                b[i][j] = binomial * c.powi((j - i) as i32);
                binomial = binomial * i as f32 / (j - i + 1) as f32;
            }
        }
        b
    }

    use proptest::prelude::*;

    proptest! {
        /// Any sequence of operations on A and B of a pair gives what the same sequence gives
        /// on two whole factors, bit for bit (f32, P = 8, every width).
        #[test]
        fn a_pair_is_two_factors_under_any_operations(
            (n, ops) in (1usize..=8).prop_flat_map(|n| {
                (Just(n), proptest::collection::vec((proptest::bool::ANY, op(n)), 1..60))
            }),
            seed in 0u64..1000,
        ) {
            let other = filled_f32::<8>(n, 12, seed + 1);
            let (mut fa, mut fb) = (Factor::<f32, 8>::new(n), Factor::<f32, 8>::new(n));
            let mut pair = FactorPair::<f32, 8>::new(n);
            for (to_a, o) in ops {
                let (whole, mut half) = if to_a {
                    (&mut fa, pair.a_mut())
                } else {
                    (&mut fb, pair.b_mut())
                };
                match o {
                    Op::Update(r, y, l) => {
                        whole.update(&r, y, l);
                        half.update(&r, y, l);
                    }
                    Op::Forget(l) => {
                        whole.forget(l);
                        half.forget(l);
                    }
                    Op::Scale(f, t) => {
                        whole.scale(&f, t);
                        half.scale(&f, t);
                    }
                    Op::Shift(c) => {
                        let b = shift_map::<8>(n, c);
                        whole.transform(&b);
                        half.transform(&b);
                    }
                    Op::MergeOther => {
                        whole.merge(&other);
                        half.merge(other.view());
                    }
                }
            }
            let full = (1u32 << n) - 1;
            let mut work = [[0.0f32; 8]; 8];
            for (f, v) in [(&fa, pair.a()), (&fb, pair.b())] {
                let (mut p, mut q) = ([0.0f32; 8], [0.0f32; 8]);
                let w = f.view();
                prop_assert_eq!(w.solve_in(full, &mut p, &mut work), v.solve_in(full, &mut q, &mut work));
                prop_assert_eq!(p.map(f32::to_bits), q.map(f32::to_bits));
                prop_assert_eq!(w.error(&p).to_bits(), v.error(&p).to_bits());
                prop_assert_eq!(w.weight().to_bits(), v.weight().to_bits());
                for i in 0..n {
                    for j in 0..n {
                        prop_assert_eq!(w.gram(i, j).to_bits(), v.gram(i, j).to_bits());
                    }
                }
            }
        }
    }

    fn filled_f32<const P: usize>(n: usize, rows: usize, seed: u64) -> Factor<f32, P> {
        let f64s = filled::<P>(n, rows, seed);
        let mut f = Factor::new(n);
        for i in 0..n {
            let mut row = [0.0f32; P];
            for (j, v) in f64s.r_row(i).iter().enumerate() {
                row[j] = *v as f32;
            }
            f.update(&row[..n], f64s.z()[i] as f32, 1.0);
        }
        f
    }

    #[test]
    #[should_panic(expected = "upper-triangular")]
    fn a_map_with_entries_below_its_diagonal_is_refused() {
        let mut f = filled::<4>(4, 10, 1);
        let mut b = [[0.0; 4]; 4];
        for (k, row) in b.iter_mut().enumerate() {
            row[k] = 1.0;
        }
        b[2][1] = 0.5;
        f.transform(&b);
    }

    #[test]
    fn a_pair_keeps_two_factors_bit_for_bit() {
        // Full width (n = P: the halves meet at the diagonal) and narrower.
        for n in [6, 5, 1] {
            let (mut fa, mut fb) = (filled::<6>(n, 40, 3), filled::<6>(n, 30, 11));
            let mut pair = FactorPair::<f64, 6>::new(n);
            pair.a_mut().copy_from(fa.view());
            pair.b_mut().copy_from(fb.view());
            // The same operations on each.
            let extra = filled::<6>(n, 9, 5);
            fa.merge(&extra);
            pair.a_mut().merge(extra.view());
            fb.forget(0.9);
            pair.b_mut().forget(0.9);
            let row = [0.3, -0.2, 0.7, 0.1, -0.4, 0.25];
            fa.update(&row[..n], 0.5, 0.99);
            pair.a_mut().update(&row[..n], 0.5, 0.99);
            fb.update(&row[..n], -0.5, 0.98);
            pair.b_mut().update(&row[..n], -0.5, 0.98);
            let scales = [2.0, 0.5, 1.5, 3.0, 0.25, 1.0];
            fb.scale(&scales[..n], 1.5);
            pair.b_mut().scale(&scales[..n], 1.5);
            // An upper-triangular map (as the origin shifts).
            let mut upper = [[0.0; 6]; 6];
            for k in 0..6 {
                for j in k..6 {
                    upper[k][j] = if k == j {
                        1.0
                    } else {
                        0.1 * (k + 2 * j) as f64 - 0.4
                    };
                }
            }
            fa.transform(&upper);
            pair.a_mut().transform(&upper);
            fb.transform(&upper);
            pair.b_mut().transform(&upper);
            for (f, v) in [(&fa, pair.a()), (&fb, pair.b())] {
                let w = f.view();
                let (mut p, mut q) = ([0.0; 6], [0.0; 6]);
                let mut work = [[0.0; 6]; 6];
                let full = (1u32 << n) - 1;
                assert_eq!(
                    w.solve_in(full, &mut p, &mut work),
                    v.solve_in(full, &mut q, &mut work)
                );
                assert_eq!(p.map(f64::to_bits), q.map(f64::to_bits));
                assert_eq!(w.error(&p).to_bits(), v.error(&p).to_bits());
                assert_eq!(w.weight().to_bits(), v.weight().to_bits());
                for i in 0..n {
                    assert_eq!(w.moment(i).to_bits(), v.moment(i).to_bits());
                    for j in 0..n {
                        assert_eq!(w.gram(i, j).to_bits(), v.gram(i, j).to_bits());
                    }
                }
            }
        }
    }
}
