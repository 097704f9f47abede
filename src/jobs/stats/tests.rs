//! Tests of the job counters and run-time buckets.

use super::*;

#[test]
fn run_times_fill_cumulative_buckets() {
    let stats = JobStats::default();
    stats.finished(
        "decomposition",
        Outcome::Done,
        Some(Duration::from_millis(30)),
    );
    stats.finished(
        "decomposition",
        Outcome::Failed,
        Some(Duration::from_secs(20)),
    );
    stats.finished("decomposition", Outcome::Cancelled, None);
    let s = stats.snapshot();
    assert_eq!(s.outcomes.len(), 3);
    let (kind, h) = &s.run_times[0];
    assert_eq!((kind.as_str(), h.count), ("decomposition", 2));
    // 30 ms: from the 0.05 s bucket on; 20 s: from the 60 s bucket on.
    assert_eq!(h.counts[0], 0);
    assert_eq!(h.counts[1], 1);
    assert_eq!(h.counts[6], 2);
    assert!((h.sum_s - 20.03).abs() < 1e-9);
    stats.taken_back(TakeBack::DeadInstance, 2, 1);
    let s = stats.snapshot();
    assert_eq!(s.requeued, vec![("dead_instance", 2)]);
    assert_eq!(s.failed, vec![("dead_instance", 1)]);
}
