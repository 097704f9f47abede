//! Unit tests of `crate::gap::judge`.

use super::*;

#[test]
fn named_when_the_steps_remove_most_of_the_gap_above_the_noise() {
    // 1,000 samples of σ̂ = 1: floor 1,000; stored 11,000 (excess 10,000)
    let j = |left: f64, step: bool| judge(11_000.0, left, 1.0, 1000, step, 0.5, 1.0);
    assert_eq!(j(3_000.0, true), (Outcome::Named, 0.2));
    assert_eq!(j(6_000.0, true), (Outcome::Named, 0.5));
    assert_eq!(j(6_001.0, true).0, Outcome::Unexplained);
    assert_eq!(j(11_000.0, false), (Outcome::Unexplained, 1.0));
    // below the floor: nothing left
    assert_eq!(j(900.0, true), (Outcome::Named, 0.0));
}

#[test]
fn a_gap_at_the_noise_is_none_or_the_step_never_unexplained() {
    let j = |stored: f64, step: bool| judge(stored, stored, 1.0, 1000, step, 0.5, 1.0);
    assert_eq!(j(1_500.0, false).0, Outcome::None);
    assert_eq!(j(1_500.0, true).0, Outcome::Named);
    assert_eq!(j(900.0, false), (Outcome::None, 1.0));
    assert_eq!(j(2_000.0, false).0, Outcome::Unexplained);
}
