//! Unit tests of `crate::signal::spline`.

use super::*;

#[test]
fn reproduces_cubics_exactly() {
    // Not-a-knot splines reproduce any cubic polynomial.
    let f = |t: f64| 0.5 * t * t * t - 2.0 * t * t + t - 3.0;
    let x = [0.0, 0.7, 1.9, 2.5, 4.0, 5.5];
    let y: Vec<f64> = x.iter().map(|&t| f(t)).collect();
    let s = CubicSpline::not_a_knot(&x, &y).unwrap();
    for k in 0..50 {
        let t = -0.5 + 0.13 * k as f64;
        assert!((s.eval(t) - f(t)).abs() < 1e-9, "t={t}");
    }
    let v = s.eval_samples(6);
    for (k, val) in v.iter().enumerate() {
        assert!((val - f(k as f64)).abs() < 1e-9);
    }
}

#[test]
fn three_points_is_a_parabola_two_a_line() {
    let s = CubicSpline::not_a_knot(&[0.0, 1.0, 3.0], &[1.0, 2.0, 10.0]).unwrap();
    let f = |t: f64| t * t + 1.0;
    assert!((s.eval(2.0) - f(2.0)).abs() < 1e-12);
    let l = CubicSpline::not_a_knot(&[0.0, 2.0], &[1.0, 5.0]).unwrap();
    assert!((l.eval(1.0) - 3.0).abs() < 1e-12);
}

#[test]
fn rejects_unsorted_knots() {
    assert!(CubicSpline::not_a_knot(&[0.0, 0.0, 1.0], &[1.0, 2.0, 3.0]).is_err());
    assert!(CubicSpline::not_a_knot(&[0.0], &[1.0]).is_err());
}
