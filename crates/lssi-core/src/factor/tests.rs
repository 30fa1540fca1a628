use super::*;

/// A deterministic pseudo-random sequence for tests (xorshift).
fn noise(state: &mut u64) -> f64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    (*state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

fn rows(count: usize) -> std::vec::Vec<([f64; 4], f64)> {
    let mut s = 7u64;
    (0..count)
        .map(|_| {
            let row = [1.0, noise(&mut s), noise(&mut s) * 3.0, noise(&mut s)];
            let y = 0.5 - 2.0 * row[1] + 0.25 * row[2] + 0.01 * noise(&mut s);
            (row, y)
        })
        .collect()
}

extern crate std;

#[test]
fn matches_batch_least_squares() {
    let data = rows(500);
    let mut f: Factor<f64, 4> = Factor::new(4);
    for (row, y) in &data {
        f.update(row, *y, 1.0);
    }
    let a = nalgebra::DMatrix::from_fn(data.len(), 4, |i, j| data[i].0[j]);
    let b = nalgebra::DVector::from_fn(data.len(), |i, _| data[i].1);
    let reference = a.clone().svd(true, true).solve(&b, 1e-14).unwrap();
    let mut xi = [0.0; 4];
    assert_eq!(f.solve(0b1111, &mut xi), 0b1111);
    for j in 0..4 {
        assert!(
            (xi[j] - reference[j]).abs() < 1e-10,
            "{j}: {} vs {}",
            xi[j],
            reference[j]
        );
    }
    let residual = (&a * &reference - &b).norm_squared();
    assert!((f.error(&xi) - residual).abs() < 1e-10 * residual.max(1.0));
    assert!((f.residual_energy() - residual).abs() < 1e-10);
    // A subset: columns 0, 1 and 3.
    let sub = a.select_columns(&[0, 1, 3]);
    let reference = sub.svd(true, true).solve(&b, 1e-14).unwrap();
    f.solve(0b1011, &mut xi);
    assert_eq!(xi[2], 0.0);
    for (p, j) in [0, 1, 3].into_iter().enumerate() {
        assert!((xi[j] - reference[p]).abs() < 1e-10);
    }
}

#[test]
fn forgetting_weights_rows_geometrically() {
    let data = rows(200);
    let lambda: f64 = 0.98;
    let mut f: Factor<f64, 4> = Factor::new(4);
    for (row, y) in &data {
        f.update(row, *y, lambda.sqrt());
    }
    let n = data.len();
    let w = |i: usize| lambda.powi((n - 1 - i) as i32).sqrt();
    let a = nalgebra::DMatrix::from_fn(n, 4, |i, j| data[i].0[j] * w(i));
    let b = nalgebra::DVector::from_fn(n, |i, _| data[i].1 * w(i));
    let reference = a.svd(true, true).solve(&b, 1e-14).unwrap();
    let mut xi = [0.0; 4];
    f.solve(0b1111, &mut xi);
    for j in 0..4 {
        assert!((xi[j] - reference[j]).abs() < 1e-9);
    }
    let total: f64 = (0..n).map(|i| lambda.powi((n - 1 - i) as i32)).sum();
    assert!((f.weight() - total).abs() < 1e-9);
}

#[test]
fn merge_equals_one_factor_over_all_rows() {
    let data = rows(300);
    let mut all: Factor<f64, 4> = Factor::new(4);
    let mut even: Factor<f64, 4> = Factor::new(4);
    let mut odd: Factor<f64, 4> = Factor::new(4);
    for (i, (row, y)) in data.iter().enumerate() {
        all.update(row, *y, 1.0);
        if i % 2 == 0 {
            even.update(row, *y, 1.0)
        } else {
            odd.update(row, *y, 1.0)
        }
    }
    even.merge(&odd);
    let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
    all.solve(0b1111, &mut a);
    even.solve(0b1111, &mut b);
    for j in 0..4 {
        assert!((a[j] - b[j]).abs() < 1e-10);
    }
    assert!((all.residual_energy() - even.residual_energy()).abs() < 1e-9);
    assert_eq!(all.weight(), even.weight());
}

#[test]
fn transform_is_a_change_of_basis() {
    let data = rows(200);
    let mut f: Factor<f64, 4> = Factor::new(4);
    for (row, y) in &data {
        f.update(row, *y, 1.0);
    }
    let mut xi = [0.0; 4];
    f.solve(0b1111, &mut xi);
    // New columns: c0, c1 + 2 c0, c2, c3 − c1.
    let mut b = [[0.0; 4]; 4];
    b[0][0] = 1.0;
    b[0][1] = 2.0;
    b[1][1] = 1.0;
    b[2][2] = 1.0;
    b[3][3] = 1.0;
    b[1][3] = -1.0;
    let e = f.residual_energy();
    f.transform(&b);
    let mut eta = [0.0; 4];
    f.solve(0b1111, &mut eta);
    // Θ ξ = Θ B η  ⇒  ξ = B η.
    for i in 0..4 {
        let mapped: f64 = (0..4).map(|j| b[i][j] * eta[j]).sum();
        assert!((mapped - xi[i]).abs() < 1e-10);
    }
    assert!((f.error(&eta) - e).abs() < 1e-9);
}

#[test]
fn f32_stays_finite_and_close_over_a_million_rows() {
    let mut f: Factor<f32, 4> = Factor::new(4);
    let mut s = 3u64;
    let lambda = 0.9999f32;
    for _ in 0..1_000_000 {
        let row = [
            1.0f32,
            noise(&mut s) as f32,
            noise(&mut s) as f32 * 3.0,
            noise(&mut s) as f32,
        ];
        let y = 0.5 - 2.0 * row[1] + 0.25 * row[2] + 0.01 * noise(&mut s) as f32;
        f.update(&row, y, lambda.sqrt());
    }
    let mut xi = [0.0f32; 4];
    f.solve(0b1111, &mut xi);
    // The same rows in f64 are the reference: f32 rounding must stay far below the
    // statistical error (~1e-4 here).
    let mut g: Factor<f64, 4> = Factor::new(4);
    let mut s = 3u64;
    for _ in 0..1_000_000 {
        let row = [
            1.0f32,
            noise(&mut s) as f32,
            noise(&mut s) as f32 * 3.0,
            noise(&mut s) as f32,
        ];
        let y = 0.5 - 2.0 * row[1] + 0.25 * row[2] + 0.01 * noise(&mut s) as f32;
        g.update(&row.map(f64::from), f64::from(y), (lambda as f64).sqrt());
    }
    let mut reference = [0.0f64; 4];
    g.solve(0b1111, &mut reference);
    for j in 0..4 {
        assert!(
            (f64::from(xi[j]) - reference[j]).abs() < 2e-4,
            "{j}: {xi:?} vs {reference:?}"
        );
    }
}

/// An update split in two (`begin_update` at any column, then `finish_update`) leaves both
/// halves of a pair exactly as one `update` does, in f32, with forgetting.
#[test]
fn a_split_update_is_the_update_bit_for_bit() {
    let data = rows(40);
    for split in 0..=5 {
        for to_a in [true, false] {
            let (mut whole, mut parts) = (FactorPair::<f32, 4>::new(4), FactorPair::new(4));
            for (row, y) in &data {
                let row32 = row.map(|v| v as f32);
                whole.half_mut(to_a).update(&row32, *y as f32, 0.99);
                let mut rest = row32;
                let target = parts
                    .half_mut(to_a)
                    .begin_update(&mut rest, *y as f32, split, 0.99);
                parts.half_mut(to_a).finish_update(&mut rest, target, split);
            }
            let (w, p) = if to_a {
                (whole.a(), parts.a())
            } else {
                (whole.b(), parts.b())
            };
            assert_eq!(w.weight().to_bits(), p.weight().to_bits());
            for i in 0..4 {
                for j in 0..4 {
                    assert_eq!(w.gram(i, j).to_bits(), p.gram(i, j).to_bits(), "{split}");
                }
                assert_eq!(w.moment(i).to_bits(), p.moment(i).to_bits(), "{split}");
            }
            assert_eq!(w.target_norm().to_bits(), p.target_norm().to_bits());
        }
    }
}
