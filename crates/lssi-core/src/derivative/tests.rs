use super::*;

#[test]
fn exact_on_polynomials_up_to_the_degree() {
    let dt = 0.002;
    let taps: Taps<f64, 128> = Taps::design(101, 5, dt).unwrap();
    // x(t) = 1 + 2t − 3t² + 0.5t⁵ about the centre (t = 0 at the centre).
    let x: std::vec::Vec<f64> = (0..101)
        .map(|k| {
            let t = (k as f64 - 50.0) * dt;
            1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t.powi(5)
        })
        .collect();
    assert!((taps.apply(0, &x, &[]) - 1.0).abs() < 1e-10);
    assert!((taps.apply(1, &x, &[]) - 2.0).abs() < 1e-8);
    assert!((taps.apply(2, &x, &[]) + 6.0).abs() < 1e-6);
    // The same through a split ring with older samples in front.
    let mut longer = std::vec![9.0; 20];
    longer.extend_from_slice(&x);
    let (a, b) = longer.split_at(57);
    assert!((taps.apply(1, a, b) - 2.0).abs() < 1e-8);
}

extern crate std;

#[test]
fn sine_derivatives_are_accurate_well_inside_the_band() {
    let dt = 0.001;
    let taps: Taps<f64, 512> = Taps::design(257, 5, dt).unwrap();
    let w = 2.0;
    let x: std::vec::Vec<f64> = (0..257)
        .map(|k| (w * (k as f64 - 128.0) * dt + 0.3).sin())
        .collect();
    assert!((taps.apply(0, &x, &[]) - 0.3f64.sin()).abs() < 1e-7);
    assert!((taps.apply(1, &x, &[]) - w * 0.3f64.cos()).abs() < 1e-6);
    assert!((taps.apply(2, &x, &[]) + w * w * 0.3f64.sin()).abs() < 1e-4);
}

#[test]
fn folded_taps_match_the_full_ones_at_every_split() {
    for len in [33usize, 34, 63, 64] {
        let taps: Taps<f64, 64> = Taps::design(len, 5, 0.01).unwrap();
        let folded = FoldedTaps::fold(&taps);
        let x: std::vec::Vec<f64> = (0..70)
            .map(|k| (0.37 * k as f64).sin() + 0.01 * (k * k % 7) as f64)
            .collect();
        for order in 0..3 {
            for split in 0..=x.len() {
                let (a, b) = x.split_at(split);
                let (p, q) = (taps.apply(order, a, b), folded.apply(order, a, b));
                let scale = taps.taps(order).iter().map(|h| h.abs()).sum::<f64>();
                assert!(
                    (p - q).abs() < 1e-11 * scale,
                    "{len} {order} {split}: {p} {q}"
                );
            }
            // Where the ring wraps does not change a bit (host and device capacities).
            let reference = folded.apply(order, &x, &[]);
            for split in 0..=x.len() {
                let (a, b) = x.split_at(split);
                assert_eq!(
                    folded.apply(order, a, b),
                    reference,
                    "{len} {order} {split}"
                );
            }
            // Fewer samples than the window: zero, as the full taps give.
            assert_eq!(folded.apply(order, &x[..len - 1], &[]), 0.0);
        }
    }
}

#[test]
fn folded_in_place_is_fold_of_the_full_taps_bit_for_bit() {
    fn check<T: Real + PartialEq>() {
        let mut folded = FoldedTaps::<T, 64>::empty();
        // Longest first: the storage is reused by the shorter windows.
        for len in [64usize, 63, 33, 34, 8, 7] {
            let full: Taps<T, 64> = Taps::design(len, 4, 0.003).unwrap();
            let design = Design::<T>::new(len, 4, 0.003, 64).unwrap();
            let mut seen = std::vec::Vec::new();
            folded.design(&design, |h| seen.push(h));
            let reference = FoldedTaps::fold(&full);
            assert_eq!(
                (folded.len(), folded.half),
                (reference.len(), reference.half)
            );
            assert!(folded.taps == reference.taps, "{len}");
            for (k, h) in seen.iter().enumerate() {
                for (order, hk) in h.iter().enumerate() {
                    assert!(*hk == full.taps(order)[k], "{len} {order} {k}");
                }
            }
            assert_eq!(seen.len(), len);
        }
    }
    check::<f32>();
    check::<f64>();
}

#[test]
fn bad_designs_are_errors() {
    assert!(matches!(
        Taps::<f32, 64>::design(65, 4, 0.01),
        Err(TapsError::Window { .. })
    ));
    assert!(matches!(
        Taps::<f32, 64>::design(5, 4, 0.01),
        Err(TapsError::Window { .. })
    ));
    assert!(matches!(
        Taps::<f32, 64>::design(33, 1, 0.01),
        Err(TapsError::Degree(1))
    ));
    assert!(matches!(
        Taps::<f32, 64>::design(33, 4, 0.0),
        Err(TapsError::SamplePeriod)
    ));
}
