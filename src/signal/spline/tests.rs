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

#[test]
fn eval_samples_matches_the_hermite_form_and_is_the_same_bits_on_any_path() {
    let x = [-1.5, 0.3, 4.0, 4.5, 9.25, 17.0, 30.0];
    let y = [0.2, -1.0, 0.7, 0.1, 2.0, -0.4, 0.9];
    let s = CubicSpline::not_a_knot(&x, &y).unwrap();
    let n = 33;
    let fast = s.eval_samples(n);
    // The scalar segment loop (what the AVX2 path must reproduce bit for bit).
    let mut scalar = vec![0.0; n];
    let mut k = 0;
    for i in 0..x.len() - 1 {
        let stop = if i + 2 == x.len() {
            n
        } else {
            (x[i + 1].ceil().max(0.0) as usize).min(n)
        };
        if stop <= k {
            continue;
        }
        let h = x[i + 1] - x[i];
        let (d0, d1) = (s.slopes[i] * h, s.slopes[i + 1] * h);
        let c2 = -3.0 * y[i] - 2.0 * d0 + 3.0 * y[i + 1] - d1;
        let c3 = 2.0 * y[i] + d0 - 2.0 * y[i + 1] + d1;
        horner(&mut scalar[k..stop], k, [x[i], 1.0 / h, y[i], d0, c2, c3]);
        k = stop;
    }
    for t in 0..n {
        assert_eq!(fast[t].to_bits(), scalar[t].to_bits(), "t = {t}");
        assert!((fast[t] - s.eval(t as f64)).abs() < 1e-9, "t = {t}");
    }
}
