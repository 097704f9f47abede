//! Unit tests of the should-stop check: runs, nesting, propagation to scoped threads.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use super::{Stopped, check, current, requested, run};
use crate::numeric::parallel;

#[test]
fn check_outside_a_run_never_stops() {
    assert!(current().is_none());
    assert!(!requested());
    check();
}

#[test]
fn a_run_that_is_not_stopped_returns_its_value() {
    let r = run(Arc::new(|| false), || {
        check();
        41 + 1
    });
    assert_eq!(r, Ok(42));
    assert!(current().is_none(), "the check is removed after the run");
}

#[test]
fn a_stopped_run_ends_at_the_next_check_with_stopped() {
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    let steps = AtomicUsize::new(0);
    let r = run(Arc::new(move || f.load(Ordering::Relaxed)), || {
        for i in 0..1000 {
            check();
            steps.fetch_add(1, Ordering::Relaxed);
            if i == 9 {
                flag.store(true, Ordering::Relaxed);
            }
        }
        "finished"
    });
    assert_eq!(r, Err(Stopped));
    assert_eq!(
        steps.load(Ordering::Relaxed),
        10,
        "stopped at the first check after"
    );
}

#[test]
fn the_check_reaches_the_threads_a_core_splits_work_over() {
    let flag = Arc::new(AtomicBool::new(true));
    let f = flag.clone();
    let items: Vec<usize> = (0..8).collect();
    let ran = AtomicUsize::new(0);
    let r = run(Arc::new(move || f.load(Ordering::Relaxed)), || {
        parallel::map_dynamic(&items, 4, |_| {
            check();
            ran.fetch_add(1, Ordering::Relaxed);
        })
    });
    assert_eq!(r, Err(Stopped));
    assert_eq!(ran.load(Ordering::Relaxed), 0, "every thread saw the stop");
}

#[test]
fn other_panics_still_unwind() {
    let caught = std::panic::catch_unwind(|| {
        let _ = run(Arc::new(|| false), || -> usize { panic!("a real bug") });
    });
    assert!(caught.is_err());
}

#[test]
fn runs_nest_and_restore_the_outer_check() {
    let outer = run(Arc::new(|| false), || {
        let inner = run(Arc::new(|| true), check);
        assert_eq!(inner, Err(Stopped));
        check();
        requested()
    });
    assert_eq!(outer, Ok(false));
}
