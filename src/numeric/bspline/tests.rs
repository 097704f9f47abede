//! Unit tests of `crate::numeric::bspline`.

use super::*;

#[test]
fn partition_of_unity_and_clamping() {
    for q in [-1.0, 0.0, 0.3, 2.5, 7.0, 10.0, 11.0] {
        let (j, w) = uniform_cubic(q, [0.0, 10.0], 5);
        assert!(j < 5);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(w.iter().all(|&v| v >= 0.0));
    }
    assert_eq!(uniform_cubic(11.0, [0.0, 10.0], 5).0, 4);
    assert_eq!(
        uniform_cubic(-1.0, [0.0, 10.0], 5),
        uniform_cubic(0.0, [0.0, 10.0], 5)
    );
}
