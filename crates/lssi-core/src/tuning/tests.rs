/// A third of the period, a multiple of 4, a sixteenth of the samples at most; the
/// window a sixteenth of that, odd; off without a period or when too coarse.
#[test]
fn test_rows_from_the_period() {
    let c = choose_test_rows::<1023>(Some(3150.0), 100_000).unwrap();
    assert_eq!((c.test_rows, c.window, c.degree), (1048, 65, 5));
    let c = choose_test_rows::<1023>(Some(3150.0), 8_000).unwrap();
    assert_eq!((c.test_rows, c.window), (500, 31));
    let c = choose_test_rows::<1023>(Some(200.0), 100_000).unwrap();
    assert_eq!((c.test_rows, c.window), (64, 9));
    assert_eq!(choose_test_rows::<1023>(None, 100_000), None);
    // A field device's rates: half the period, at most 64 rows, under 11 samples of degree 7.
    let c = choose_test_rows::<1023>(Some(150.0), 100_000).unwrap();
    assert_eq!((c.test_rows, c.window, c.degree), (64, 11, 7));
    let c = choose_test_rows::<1023>(Some(60.0), 100_000).unwrap();
    assert_eq!((c.test_rows, c.window, c.degree), (28, 11, 7));
    let c = choose_test_rows::<1023>(Some(30.0), 100_000).unwrap();
    assert_eq!(c.test_rows, 12);
    assert_eq!(choose_test_rows::<1023>(Some(23.0), 100_000), None);
    assert_eq!(choose_test_rows::<9>(Some(60.0), 100_000), None);
    assert_eq!(choose_test_rows::<1023>(Some(f64::NAN), 100_000), None);
    let c = choose_test_rows::<1023>(Some(1e9), 1 << 30).unwrap();
    assert_eq!((c.test_rows, c.window), (65532, 1023));
    let c = choose_test_rows::<63>(Some(1e9), 1 << 30).unwrap();
    assert_eq!(c.window, 63);
    let c = choose_test_rows::<64>(Some(1e9), 1 << 30).unwrap();
    assert_eq!(c.window, 63);
    for t in (192..20_000).step_by(7) {
        let c = choose_test_rows::<1023>(Some(t as f64), 1_000_000).unwrap();
        assert!(c.test_rows.is_multiple_of(4) && c.test_rows >= 64 && c.window % 2 == 1);
        assert!(c.window >= 8 && c.window <= 1023);
    }
}

use super::*;

const W: usize = 1023;

/// `a·sin(2πk/period)` plus uniform white noise of standard deviation `noise`.
fn noisy_sine(n: usize, period: f64, noise: f64) -> Vec<f64> {
    let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
    (0..n)
        .map(|k| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let uniform = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            libm::sin(2.0 * core::f64::consts::PI * k as f64 / period)
                + noise * 12f64.sqrt() * uniform
        })
        .collect()
}

#[test]
fn mean_period_of_a_noisy_sinusoid() {
    let s = noisy_sine(20_000, 40.0, 0.01);
    let t = mean_period(&s, 0.01).unwrap();
    assert!((t - 40.0).abs() < 0.5, "period {t}");
    // Too slow to show two periods: no cap.
    assert_eq!(mean_period(&noisy_sine(2_000, 5_000.0, 0.01), 0.01), None);
}

#[test]
fn the_window_is_no_longer_than_a_period() {
    let s = noisy_sine(20_000, 40.0, 0.01);
    let dt = 1e-3;
    let sigma2 = noise_variance(&s);
    // Without the cap the longest windows win: both fits stop the signal and agree.
    let uncapped = choose_capped::<f64, W>(&s, 2, dt, s.len(), sigma2, W).unwrap();
    assert!(uncapped.window > 40, "uncapped {uncapped:?}");
    let choice = choose_window::<f64, W>(&s, 2, dt, s.len()).unwrap();
    assert!(choice.window <= 40, "{choice:?}");
    assert!((choice.period.unwrap() - 40.0).abs() < 0.5);
    // The estimate still follows the signal: x'' of sin has RMS ω²/√2.
    let expected = (2.0 * core::f64::consts::PI / (40.0 * dt)).powi(2) / 2f64.sqrt();
    assert!(
        (choice.target_rms / expected - 1.0).abs() < 0.05,
        "{choice:?}"
    );
}

#[test]
fn three_samples_per_period_get_the_shortest_window() {
    let s = noisy_sine(20_000, 3.0, 0.01);
    let choice = choose_window::<f64, W>(&s, 2, 1e-3, s.len()).unwrap();
    assert_eq!(choice.window, WINDOWS[0], "{choice:?}");
}

#[test]
fn a_slow_signal_is_not_capped() {
    // 2 500 samples per period: the cap (2 500) is above every candidate, so the choice is
    // the one without it.
    let s = noisy_sine(50_000, 2_500.0, 1e-3);
    let choice = choose_window::<f64, W>(&s, 2, 1e-3, s.len()).unwrap();
    let sigma2 = noise_variance(&s);
    let mut uncapped = choose_capped::<f64, W>(&s, 2, 1e-3, s.len(), sigma2, W).unwrap();
    uncapped.period = choice.period;
    assert_eq!(choice, uncapped);
    assert!(choice.period.unwrap() > 2_400.0);
}

/// Against the truth: on a two-tone velocity record at low noise, where the measured
/// bias of the shorter windows is mostly noise, the chosen window's true cost (its real
/// bias² from the clean signal plus the averaged noise) is within a factor 2 of the best
/// candidate's, for several noise draws.
#[test]
fn the_choice_is_near_the_true_best() {
    let (n, dt) = (40_000usize, 1e-3);
    let (w1, w2) = (
        2.0 * core::f64::consts::PI / 1.6,
        2.0 * core::f64::consts::PI / 0.5,
    );
    let clean: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            libm::sin(w1 * t) + 0.3 * libm::sin(w2 * t + 1.0)
        })
        .collect();
    let slope = |k: usize| {
        let t = k as f64 * dt;
        w1 * libm::cos(w1 * t) + 0.3 * w2 * libm::cos(w2 * t + 1.0)
    };
    for seed in 1..=3u64 {
        let sigma = 1e-4;
        let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        let noisy: Vec<f64> = clean
            .iter()
            .map(|c| {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let u = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                c + sigma * 12f64.sqrt() * u
            })
            .collect();
        let choice = choose_window::<f64, W>(&noisy, 1, dt, n).unwrap();
        let cap = choice.period.map_or(W, |t| t as usize);
        let true_cost = |len: usize, p: usize| {
            let taps = Taps::<f64, W>::design(len, p, dt).unwrap();
            let h = taps.taps(1);
            let half = len / 2;
            let (mut e2, mut count) = (0.0, 0usize);
            for start in (0..n - len).step_by(97) {
                let est: f64 = h
                    .iter()
                    .zip(&clean[start..start + len])
                    .map(|(a, b)| a * b)
                    .sum();
                let e = est - slope(start + half);
                e2 += e * e;
                count += 1;
            }
            let gain: f64 = h.iter().map(|v| v * v).sum();
            e2 / count as f64 + sigma * sigma * gain * len as f64 / n as f64
        };
        let mut best = f64::MAX;
        for &len in WINDOWS.iter().filter(|&&l| l <= cap.max(WINDOWS[0])) {
            for &p in DEGREES.iter().filter(|&&p| len >= p + 5) {
                best = best.min(true_cost(len, p));
            }
        }
        let chosen = true_cost(choice.window, usize::from(choice.degree));
        assert!(
            chosen <= 2.0 * best,
            "seed {seed}: chose {choice:?} at true cost {chosen:.3e}, best {best:.3e}"
        );
    }
}

#[test]
fn too_short_a_stretch_has_no_choice() {
    assert_eq!(choose_window::<f64, W>(&[0.0; 18], 2, 1e-3, 18), None);
}
