//! Tests of the Brent line search.

use super::*;

#[test]
fn finds_smooth_minima_quickly() {
    let mut calls = 0;
    let (x, fx) = minimize(
        |x| {
            calls += 1;
            (x - 0.3).powi(2) * 2.0 + 1.0 + 0.1 * (x - 0.3).powi(3)
        },
        0.0,
        1.0,
        1e-9,
        100,
    );
    assert!(
        (x - 0.3).abs() < 1e-7 && (fx - 1.0).abs() < 1e-13,
        "{x} {fx}"
    );
    assert!(calls < 40, "{calls} evaluations");
    let (x, _) = minimize(|x| x, 0.2, 0.9, 1e-9, 200);
    assert!((x - 0.2).abs() < 1e-7, "minimum at the end: {x}");
}
