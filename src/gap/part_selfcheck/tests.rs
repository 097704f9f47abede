//! Unit tests of `crate::gap::part_selfcheck`.

use super::*;

#[test]
fn part_self_check_meets_the_goals() {
    let r = run_part(24, 77).unwrap();
    eprintln!("{}", r.render());
    assert!(r.accuracy >= 0.9, "{}", r.render());
    assert!(r.median_shrink >= 0.7, "{}", r.render());
    assert_eq!(r.false_alarm_rate, 0.0, "{}", r.render());
}
