//! Unit tests of `crate::volumetric::motion_basis`.

use super::*;

#[test]
fn legendre_matches_closed_forms() {
    let mut p = Vec::new();
    legendre(0.3, 4, &mut p);
    let s: f64 = 0.3;
    let closed = [
        1.0,
        s,
        0.5 * (3.0 * s * s - 1.0),
        0.5 * (5.0 * s.powi(3) - 3.0 * s),
        (35.0 * s.powi(4) - 30.0 * s * s + 3.0) / 8.0,
    ];
    for (a, b) in p.iter().zip(closed) {
        assert!((a - b).abs() < 1e-12);
    }
}

#[test]
fn spline_terms_are_orthonormal_curved_and_ordered_by_roughness() {
    for cap in 4..=MAX_CAP {
        let g = 2001;
        let mut vals = vec![Vec::new(); g];
        for (i, v) in vals.iter_mut().enumerate() {
            MotionBasis::Spline.values(-1.0 + 2.0 * i as f64 / (g - 1) as f64, cap, v);
        }
        // trapezoid rule on [−1, 1]
        let ip = |a: usize, b: usize| {
            let h = 2.0 / (g - 1) as f64;
            let ends = 0.5 * (vals[0][a] * vals[0][b] + vals[g - 1][a] * vals[g - 1][b]);
            (vals.iter().map(|v| v[a] * v[b]).sum::<f64>() - ends) * h
        };
        for a in 2..=cap {
            // orthogonal to the constant and the line (no straight-line part)
            assert!(
                ip(a, 0).abs() < 1e-3,
                "cap {cap} term {a}: mean {}",
                ip(a, 0)
            );
            assert!(
                ip(a, 1).abs() < 1e-3,
                "cap {cap} term {a}: slope {}",
                ip(a, 1)
            );
            assert!((ip(a, a) - 1.0).abs() < 1e-3);
            for b in 2..a {
                assert!(ip(a, b).abs() < 1e-3);
            }
        }
        let w: Vec<f64> = (2..=cap)
            .map(|d| MotionBasis::Spline.weight(cap, d))
            .collect();
        assert!((w[0] - 1.0).abs() < 1e-12);
        assert!(w.windows(2).all(|p| p[1] > p[0]), "cap {cap}: {w:?}");
    }
}

#[test]
fn low_caps_and_legendre_keep_the_polynomials() {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    MotionBasis::Spline.values(0.4, 3, &mut a);
    MotionBasis::Legendre.values(0.4, 3, &mut b);
    assert_eq!(a, b);
    assert_eq!(MotionBasis::Legendre.weight(5, 2), 1.0);
    assert_eq!(MotionBasis::Spline.weight(5, 1), 0.0);
}
