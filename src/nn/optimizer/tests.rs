//! Unit tests of `crate::nn::optimizer`.

use super::*;

#[test]
fn sgd_momentum_follows_eq_14() {
    let opt = Optimizer::Sgd {
        lr: 0.1,
        momentum: 0.8,
    };
    let mut st = OptimizerState::new(&[1]);
    let mut w = [1.0];
    st.next_step();
    st.update(&opt, 0.1, 0, &mut w, &[2.0]); // v = -0.2, w = 0.8
    assert!((w[0] - 0.8).abs() < 1e-15);
    st.next_step();
    st.update(&opt, 0.1, 0, &mut w, &[1.0]); // v = 0.8*-0.2 - 0.1 = -0.26
    assert!((w[0] - 0.54).abs() < 1e-15);
}

#[test]
fn adam_first_step_is_lr_sized() {
    let opt = Optimizer::adam(0.01);
    let mut st = OptimizerState::new(&[2]);
    let mut w = [0.0, 0.0];
    st.next_step();
    st.update(&opt, 0.01, 0, &mut w, &[3.0, -0.5]);
    assert!((w[0] + 0.01).abs() < 1e-9 && (w[1] - 0.01).abs() < 1e-9);
}

#[test]
fn cosine_schedule_ends_at_final_factor() {
    let s = LrSchedule::Cosine { final_factor: 0.1 };
    assert!((s.factor(0, 10) - 1.0).abs() < 1e-12);
    assert!((s.factor(9, 10) - 0.1).abs() < 1e-12);
    assert!(
        Optimizer::Sgd {
            lr: 0.1,
            momentum: 1.0
        }
        .validate()
        .is_err()
    );
    assert!(Optimizer::adam(-1.0).validate().is_err());
}
