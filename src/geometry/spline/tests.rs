//! Unit tests of `crate::geometry::spline`.

use super::*;

#[test]
fn reproduces_a_cubic_exactly() {
    let f = |s: f64| [s, 2.0 * s * s - s, s * s * s - 0.5 * s];
    for m in [4usize, 5, 9, 20] {
        let pts: Vec<[f64; 3]> = (0..m).map(|k| f(k as f64 / (m - 1) as f64)).collect();
        let sp = CubicSpline3::through(&pts, Parameterization::Uniform).unwrap();
        for i in 0..=100 {
            let t = i as f64 / 100.0;
            let (q, e) = (sp.eval(t), f(t));
            for d in 0..3 {
                assert!(
                    (q[d] - e[d]).abs() < 1e-12,
                    "m={m} t={t} d={d}: {} vs {}",
                    q[d],
                    e[d]
                );
            }
            let d2 = sp.eval_d2(t);
            assert!((d2[2] - 6.0 * t).abs() < 1e-9 && (d2[1] - 4.0).abs() < 1e-9);
        }
    }
}

#[test]
fn three_points_give_the_parabola_and_derivatives_match_fd() {
    let pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [2.0, 0.0, 4.0]];
    let sp = CubicSpline3::through(&pts, Parameterization::Uniform).unwrap();
    let q = sp.eval(0.25); // x = 0.5, z = 0.25
    assert!((q[0] - 0.5).abs() < 1e-12 && (q[2] - 0.25).abs() < 1e-12);
    let pts: Vec<[f64; 3]> = (0..12)
        .map(|k| {
            let s = k as f64 * 0.3;
            [s.cos(), s.sin(), 0.2 * s]
        })
        .collect();
    let sp = CubicSpline3::through(&pts, Parameterization::ChordLength).unwrap();
    let h = 1e-6;
    for t in [0.1, 0.37, 0.8] {
        let (a, b) = (sp.eval(t + h), sp.eval(t - h));
        let d1 = sp.eval_d1(t);
        for d in 0..3 {
            assert!(((a[d] - b[d]) / (2.0 * h) - d1[d]).abs() < 1e-6);
        }
    }
    for (k, &t) in sp.knots().iter().enumerate() {
        let q = sp.eval(t);
        assert!((0..3).all(|d| (q[d] - pts[k][d]).abs() < 1e-12));
    }
}

#[test]
fn uniform_fast_path_matches_the_general_solve() {
    // One spline refitted through sizes in a mixed order (cached knots and factors), each
    // compared with the general Thomas solve on the same knots.
    let mut sp = CubicSpline3::new();
    for m in [20usize, 5, 33, 4, 6, 7, 20, 8] {
        let pts: Vec<[f64; 3]> = (0..m)
            .map(|k| {
                let s = k as f64 * 0.37;
                [3.0 * s.sin(), (1.3 * s).cos(), 0.1 * s * s - s]
            })
            .collect();
        sp.fit(&pts, Parameterization::Uniform).unwrap();
        let mut general = sp.clone();
        general.solve_general();
        let scale = general
            .knot_d2()
            .iter()
            .flatten()
            .fold(0.0f64, |a, b| a.max(b.abs()));
        for (k, (a, b)) in sp.knot_d2().iter().zip(general.knot_d2()).enumerate() {
            for d in 0..3 {
                assert!(
                    (a[d] - b[d]).abs() <= 1e-12 * scale,
                    "m={m} k={k} d={d}: {} vs {}",
                    a[d],
                    b[d]
                );
            }
        }
        assert_eq!(sp.knots(), general.knots());
        assert!((sp.knots()[m - 1] - 1.0).abs() < 1e-15 && sp.knots().len() == m);
    }
}

#[test]
fn rejects_degenerate_input() {
    assert!(CubicSpline3::through(&[[0.0; 3], [1.0; 3]], Parameterization::Uniform).is_err());
    let dup = [[0.0; 3], [0.0; 3], [1.0; 3]];
    assert_eq!(
        CubicSpline3::through(&dup, Parameterization::ChordLength).unwrap_err(),
        Error::DuplicatePoints { index: 0 }
    );
}
