extern crate std;
use super::*;
use std::string::ToString;

/// `evaluate_scaled` is `evaluate_sin_cos` followed by the scaling, bit for bit, for
/// every family, order, harmonic count and the input.
#[test]
fn evaluate_scaled_matches_evaluate_sin_cos_bit_for_bit() {
    let families = [
        PolyFamily::All,
        PolyFamily::Families,
        PolyFamily::OddFamilies,
    ];
    for family in families {
        for poly_order in 1..=MAX_POLY_ORDER {
            for harmonics in 0..=MAX_HARMONICS {
                for (constant, input) in [(true, false), (false, true)] {
                    let config = LibraryConfig {
                        poly_order,
                        family,
                        constant,
                        harmonics,
                        input,
                    };
                    let Ok(library) = Library::<32>::new(&config) else {
                        continue;
                    };
                    let scales: [f32; 32] = core::array::from_fn(|j| 0.3 + j as f32 * 0.7);
                    let (x, v, u) = (-1.37f32, 0.81f32, 2.5f32);
                    let phase = 0.9f32;
                    let (s1, c1) = (phase.sin(), phase.cos());
                    let mut expected = [0.0f32; 32];
                    library.evaluate_sin_cos(x, v, s1, c1, u, &mut expected);
                    for (e, d) in expected.iter_mut().zip(scales) {
                        *e *= d;
                    }
                    let mut row = [0.0f32; 32];
                    library.evaluate_scaled((x, v, s1, c1, u), &scales, &mut row);
                    let bits =
                        |r: &[f32]| r.iter().map(|t| t.to_bits()).collect::<std::vec::Vec<_>>();
                    assert_eq!(bits(&row), bits(&expected), "{config:?}");
                    // Tables kept from row to row: whatever they held (NaN here), the row
                    // is the same, bit for bit.
                    let mut tables = RowTables {
                        left: [f32::NAN; LEFT],
                        right: [f32::NAN; RIGHT],
                    };
                    let mut kept = [0.0f32; 32];
                    library.evaluate_scaled_in((x, v, s1, c1, u), &scales, &mut kept, &mut tables);
                    assert_eq!(bits(&kept), bits(&expected), "{config:?}");
                }
            }
        }
    }
}

/// The table's binomial coefficients are n! / (k! (n − k)!) for every n up to the largest
/// order, and 0 outside.
#[test]
fn binomials_are_pascals_triangle() {
    let factorial = |n: u8| (1..=u64::from(n)).product::<u64>();
    for n in 0..=MAX_POLY_ORDER {
        for k in 0..=n {
            let expected = factorial(n) / (factorial(k) * factorial(n - k));
            assert_eq!(u64::from(binomial(n, k)), expected, "C({n}, {k})");
        }
        assert_eq!(binomial(n, n + 1), 0);
    }
}

#[test]
fn names_follow_the_convention() {
    let cases = [
        (Term::Constant, 2.0, "1"),
        (Term::Monomial { px: 1, pv: 0 }, 2.0, "x"),
        (Term::Monomial { px: 0, pv: 1 }, 2.0, "v"),
        (Term::Monomial { px: 2, pv: 1 }, 2.0, "x^2*v"),
        (Term::Monomial { px: 1, pv: 1 }, 2.0, "x*v"),
        (Term::Monomial { px: 0, pv: 3 }, 2.0, "v^3"),
        (Term::Cos(1), 2.0, "cos(2t)"),
        (Term::Sin(1), 21.4, "sin(21.4t)"),
        (Term::Cos(1), 1.0, "cos(t)"),
        (Term::Sin(3), 1.0, "sin(3t)"),
        (Term::Cos(1), 21.412345678, "cos(21.4123t)"),
        (Term::Cos(1), 0.0123456789, "cos(0.0123457t)"),
        (Term::Input, 2.0, "u"),
    ];
    for (term, omega, name) in cases {
        assert_eq!(term.name(omega).to_string(), name);
    }
}

#[test]
fn paper_eq18_library_has_sixteen_terms() {
    let config = LibraryConfig {
        poly_order: 3,
        family: PolyFamily::All,
        constant: true,
        harmonics: 3,
        input: false,
    };
    let library: Library<24> = Library::new(&config).unwrap();
    assert_eq!(library.len(), 16);
    assert_eq!(library.shift_closed(), (true, true));
    let odd = LibraryConfig {
        family: PolyFamily::OddFamilies,
        ..config
    };
    let library: Library<24> = Library::new(&odd).unwrap();
    assert!(!library.shift_closed().0);
}

#[test]
fn capacity_is_checked() {
    let config = LibraryConfig {
        poly_order: 9,
        family: PolyFamily::All,
        constant: true,
        harmonics: 3,
        input: true,
    };
    let err = Library::<16>::new(&config).unwrap_err();
    assert!(matches!(err, LibraryError::TooManyTerms { .. }));
    assert!(err.to_string().contains("terms"));
}

#[test]
fn shift_matrix_moves_the_origin() {
    let config = LibraryConfig {
        poly_order: 3,
        family: PolyFamily::All,
        constant: true,
        harmonics: 1,
        input: false,
    };
    let library: Library<16> = Library::new(&config).unwrap();
    let (x, v, cx, cv) = (0.7f64, -0.3f64, 0.25f64, -0.1f64);
    let mut m = [[0.0; 16]; 16];
    library.shift_matrix(cx, cv, &mut m);
    let mut row = [0.0; 16];
    let mut shifted = [0.0; 16];
    library.evaluate(x, v, 0.4, 0.0, &mut row);
    library.evaluate(x + cx, v + cv, 0.4, 0.0, &mut shifted);
    for j in 0..library.len() {
        let mapped: f64 = (0..library.len()).map(|c| m[j][c] * row[c]).sum();
        assert!((mapped - shifted[j]).abs() < 1e-12, "column {j}");
    }
}

#[test]
fn harmonics_by_recurrence_match_libm() {
    let config = LibraryConfig {
        poly_order: 1,
        family: PolyFamily::All,
        constant: false,
        harmonics: 5,
        input: false,
    };
    let library: Library<16> = Library::new(&config).unwrap();
    let mut row = [0.0f64; 16];
    library.evaluate(0.0, 0.0, 1.3, 0.0, &mut row);
    for k in 1..=5u8 {
        let s = library.index_of(Term::Sin(k)).unwrap();
        let c = library.index_of(Term::Cos(k)).unwrap();
        assert!((row[s] - (f64::from(k) * 1.3).sin()).abs() < 1e-12);
        assert!((row[c] - (f64::from(k) * 1.3).cos()).abs() < 1e-12);
    }
}
