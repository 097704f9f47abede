//! Unit tests of `crate::motion::rk4`.

use super::*;

#[test]
fn first_order_lag_matches_closed_form() {
    // dx/dt = k (r - x) with r stepping to 1 at t = 0 (held): x(t) = 1 - e^{-k t}.
    let k = 5.0;
    let period = 0.01;
    let mut cmd = vec![0.0];
    cmd.extend(std::iter::repeat_n(1.0, 200));
    // the FOH ramp from 0 to 1 over the first period, then hold: compare after the ramp
    let x = rk4_first_order_hold(&cmd, period, 20, |st, r, _| {
        [k * (r - st[0]), 0.0, 0.0, 0.0]
    });
    let x1 = x[1];
    for (i, xi) in x.iter().enumerate().skip(1) {
        let t = (i - 1) as f64 * period;
        let expected = 1.0 - (1.0 - x1) * (-k * t).exp();
        assert!((xi - expected).abs() < 1e-9, "i={i}: {xi} vs {expected}");
    }
    assert_eq!(x.len(), cmd.len());
    assert!(rk4_first_order_hold(&[], period, 4, |s, _, _| s).is_empty());
}
