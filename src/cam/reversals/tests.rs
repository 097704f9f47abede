//! Unit tests of `crate::cam::reversals`.

use super::*;

/// The bias follows each axis' last direction; only a change (a reversal, a first
/// move) asks for a take-up; an axis without play never does.
#[test]
fn the_bias_follows_the_last_direction() {
    let mut r = Reversals::new([0.02, 0.01, 0.0]);
    assert!(r.any());
    assert_eq!(r.bias(), [0.0; 3]);
    assert!(r.turn([5.0, 0.0, -1.0]));
    assert_eq!(r.bias(), [0.01, 0.0, 0.0]);
    assert!(!r.turn([3.0, 0.0, 1.0]), "X goes on, Z has no play");
    assert!(r.turn([1.0, -2.0, 0.0]), "Y's first move");
    assert_eq!(r.bias(), [0.01, -0.005, 0.0]);
    assert!(!r.turn([0.0, -1.0, 0.0]));
    assert!(r.turn([-1.0, 0.0, 0.0]), "X reverses");
    assert_eq!(r.bias(), [-0.01, -0.005, 0.0]);
    assert!(!Reversals::new([0.0; 3]).any());
}
