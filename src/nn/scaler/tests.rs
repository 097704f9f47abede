//! Unit tests of `crate::nn::scaler`.

use super::*;

#[test]
fn fit_transform_inverse() {
    let x = [1.0, 5.0, 2.0, 5.0, 3.0, 5.0, 6.0, 5.0];
    let z = ZScore::fit(&x, 2).unwrap();
    assert!((z.mean[0] - 3.0).abs() < 1e-12);
    // sample std of 1,2,3,6 = sqrt(14/3)
    assert!((z.std[0] - (14.0f64 / 3.0).sqrt()).abs() < 1e-12);
    assert_eq!(z.std[1], 1.0, "constant column keeps std 1");
    let mut y = z.transform(&x);
    assert!(y.iter().skip(1).step_by(2).all(|v| *v == 0.0));
    z.inverse_in_place(&mut y);
    for (a, b) in x.iter().zip(&y) {
        assert!((a - b).abs() < 1e-12);
    }
}

#[test]
fn rejects_bad_input() {
    assert!(ZScore::fit(&[1.0, 2.0, 3.0], 2).is_err());
    assert!(ZScore::fit(&[1.0, 2.0], 2).is_err());
    assert!(matches!(
        ZScore::fit(&[1.0, f64::NAN], 1),
        Err(Error::NonFinite { index: 1, .. })
    ));
}
