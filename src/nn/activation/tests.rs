//! Unit tests of `crate::nn::activation`.

use super::*;

#[test]
fn derivatives_match_finite_differences() {
    for act in [Activation::Relu, Activation::Sigmoid, Activation::Identity] {
        for z in [-2.0, -0.3, 0.4, 1.7] {
            let h = 1e-6;
            let fd = (act.apply(z + h) - act.apply(z - h)) / (2.0 * h);
            let an = act.derivative_from_output(act.apply(z));
            assert!((fd - an).abs() < 1e-6, "{act:?} at {z}: {fd} vs {an}");
        }
    }
}

#[test]
fn codes_round_trip() {
    for act in [Activation::Relu, Activation::Sigmoid, Activation::Identity] {
        assert_eq!(Activation::from_code(act.code()), Some(act));
    }
    assert_eq!(Activation::from_code(9), None);
}
