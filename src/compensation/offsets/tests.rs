//! Unit tests of `crate::compensation::offsets`.

use super::*;

#[test]
fn moves_against_the_normal() {
    let p = compensate_points(&[[1.0, 2.0, 3.0]], &[[0.0, 0.0, 1.0]], &[0.05]).unwrap();
    assert_eq!(p, vec![[1.0, 2.0, 2.95]]);
}

#[test]
fn rejects_bad_input() {
    let pts = [[0.0; 3]; 2];
    let nrm = [[0.0, 0.0, 1.0]; 2];
    assert!(matches!(
        compensate_points(&pts, &nrm, &[0.1]),
        Err(Error::LengthMismatch {
            field: "offsets",
            ..
        })
    ));
    assert!(matches!(
        compensate_points(&pts, &nrm, &[0.1, f64::NAN]),
        Err(Error::NonFinite {
            field: "offsets",
            index: 1
        })
    ));
    assert!(matches!(
        compensate_points(&pts, &[[0.0; 3]; 2], &[0.1, 0.1]),
        Err(Error::ZeroNormal { index: 0 })
    ));
}
