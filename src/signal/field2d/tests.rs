//! Unit tests of `crate::signal::field2d`.

use super::*;

#[test]
fn serpentine_round_trip() {
    let x: Vec<f64> = (0..12).map(|k| k as f64).collect();
    let s = flatten(&x, 4, 3, Order::Serpentine);
    assert_eq!(s, vec![0., 1., 2., 3., 7., 6., 5., 4., 8., 9., 10., 11.]);
    assert_eq!(unflatten(&s, 4, 3, Order::Serpentine), x);
}

#[test]
fn planes_pass_and_bad_grids_fail() {
    let (nu, nv) = (9, 7);
    let x: Vec<f64> = (0..nu * nv)
        .map(|k| 0.3 + 0.01 * (k % nu) as f64 - 0.02 * (k / nu) as f64)
        .collect();
    let s = whittaker_2d(&x, nu, nv, 2, Some(100.0)).unwrap();
    let err = x
        .iter()
        .zip(&s.signal)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-10, "{err}");
    assert!(whittaker_2d(&x, 8, 7, 2, None).is_err());
}
