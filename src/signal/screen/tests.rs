//! Unit tests of `crate::signal::screen`.

use super::*;

#[test]
fn pearson_known_values() {
    let a = [1.0, 2.0, 3.0, 4.0];
    assert!((pearson(&a, &[2.0, 4.0, 6.0, 8.0]) - 1.0).abs() < 1e-15);
    assert!((pearson(&a, &[8.0, 6.0, 4.0, 2.0]) + 1.0).abs() < 1e-15);
    assert_eq!(pearson(&a, &[1.0; 4]), 0.0);
    assert!(pearson(&[1.0, 0.0, -1.0, 0.0], &[0.0, 1.0, 0.0, -1.0]).abs() < 1e-15);
}

#[test]
fn screening_uses_absolute_value() {
    let reference = vec![1.0, 2.0, 3.0, 4.0];
    let comps = vec![vec![-1.0, -2.0, -3.0, -4.0], vec![1.0, -1.0, -1.0, 1.0]];
    let (r, strong) = screen(&comps, &reference, 0.3);
    assert_eq!(strong, vec![true, false]);
    assert!(r[0] < 0.0);
    assert_eq!(
        sum_selected(&comps, &strong, 4),
        vec![-1.0, -2.0, -3.0, -4.0]
    );
}
