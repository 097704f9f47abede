//! What this instance's jobs came to, for `/metrics`: outcomes and run times by kind, and
//! the jobs given back to the queue or failed by a takeover, by reason. Labels are bounded:
//! kinds are the code's own job kinds, outcomes and reasons the constants below.
//!
//! Also the request id a job carries into its log lines ([`REQUEST_ID`]).

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::Duration;

tokio::task_local! {
    /// The X-Request-Id of the request being served (set by the API's request-id
    /// middleware): a job queued or submitted inside it records it, and the job's span
    /// names it, on whichever instance runs the job.
    pub static REQUEST_ID: String;
}

/// The request id of the request this task serves, if any ([`REQUEST_ID`]).
pub fn current_request_id() -> Option<String> {
    REQUEST_ID.try_with(Clone::clone).ok()
}

/// Upper bounds (seconds) of the job run-time histogram: jobs run from milliseconds (a
/// small decomposition) to an hour (a long training).
pub const RUN_BUCKETS_S: [f64; 11] = [
    0.01, 0.05, 0.25, 1.0, 5.0, 15.0, 60.0, 300.0, 900.0, 1800.0, 3600.0,
];

/// How a job's run on this instance ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Outcome {
    /// Its result is stored.
    Done,
    /// It ended with an error sentence.
    Failed,
    /// Cancelled by a client while queued: it never ran.
    Cancelled,
    /// Stopped at `--job-timeout`.
    TimedOut,
    /// Went back to the queue (a database outage met while storing its outcome).
    Requeued,
    /// Its run ended but its outcome was not stored: cancelled by a client while running,
    /// taken back (its instance judged gone), or this instance fenced.
    NotStored,
}

impl Outcome {
    /// The metric label.
    pub fn label(self) -> &'static str {
        match self {
            Outcome::Done => "done",
            Outcome::Failed => "failed",
            Outcome::Cancelled => "cancelled",
            Outcome::TimedOut => "timed_out",
            Outcome::Requeued => "requeued",
            Outcome::NotStored => "not_stored",
        }
    }
}

/// Why jobs were taken back from an instance (re-queued or failed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum TakeBack {
    /// Their instance's lease expired (a crash, a kill, a lost network).
    DeadInstance,
    /// This instance stopped gracefully before they ended.
    Shutdown,
    /// Claims whose answer a cut connection lost.
    LostClaim,
    /// Recorded as running here with no worker on them.
    Orphan,
}

impl TakeBack {
    /// The metric label.
    pub fn label(self) -> &'static str {
        match self {
            TakeBack::DeadInstance => "dead_instance",
            TakeBack::Shutdown => "shutdown",
            TakeBack::LostClaim => "lost_claim",
            TakeBack::Orphan => "orphan",
        }
    }
}

/// A run-time histogram.
#[derive(Clone, Debug, Default)]
pub struct RunTimes {
    /// Runs at or under each bound of [`RUN_BUCKETS_S`] (cumulative).
    pub counts: [u64; RUN_BUCKETS_S.len()],
    /// Sum of run times, s.
    pub sum_s: f64,
    /// Runs.
    pub count: u64,
}

#[derive(Default)]
struct Inner {
    outcomes: BTreeMap<(String, Outcome), u64>,
    run_times: BTreeMap<String, RunTimes>,
    requeued: BTreeMap<TakeBack, u64>,
    failed: BTreeMap<TakeBack, u64>,
}

/// Counters of this instance's jobs (since it started).
#[derive(Default)]
pub struct JobStats {
    inner: Mutex<Inner>,
}

/// A copy of the counters, for rendering.
#[derive(Clone, Debug, Default)]
pub struct StatsSnapshot {
    /// Runs by (kind, outcome label).
    pub outcomes: Vec<(String, &'static str, u64)>,
    /// Run times by kind (runs that started on a worker).
    pub run_times: Vec<(String, RunTimes)>,
    /// Jobs re-queued by a takeover, by reason label.
    pub requeued: Vec<(&'static str, u64)>,
    /// Jobs failed by a takeover (no stored input or out of attempts), by reason label.
    pub failed: Vec<(&'static str, u64)>,
}

impl JobStats {
    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Records a run of a job of `kind` ending in `outcome` after `ran` on a worker
    /// (`None`: it never reached one).
    pub fn finished(&self, kind: &str, outcome: Outcome, ran: Option<Duration>) {
        let mut inner = self.lock();
        *inner
            .outcomes
            .entry((kind.to_string(), outcome))
            .or_default() += 1;
        if let Some(ran) = ran {
            let s = ran.as_secs_f64();
            let h = inner.run_times.entry(kind.to_string()).or_default();
            for (i, le) in RUN_BUCKETS_S.iter().enumerate() {
                if s <= *le {
                    h.counts[i] += 1;
                }
            }
            h.sum_s += s;
            h.count += 1;
        }
    }

    /// Records jobs taken back for `why`: `requeued` went back to the queue, `failed` ended.
    pub fn taken_back(&self, why: TakeBack, requeued: u64, failed: u64) {
        let mut inner = self.lock();
        *inner.requeued.entry(why).or_default() += requeued;
        *inner.failed.entry(why).or_default() += failed;
    }

    /// A copy of every counter.
    pub fn snapshot(&self) -> StatsSnapshot {
        let inner = self.lock();
        StatsSnapshot {
            outcomes: inner
                .outcomes
                .iter()
                .map(|((k, o), n)| (k.clone(), o.label(), *n))
                .collect(),
            run_times: inner
                .run_times
                .iter()
                .map(|(k, h)| (k.clone(), h.clone()))
                .collect(),
            requeued: inner
                .requeued
                .iter()
                .map(|(w, n)| (w.label(), *n))
                .collect(),
            failed: inner.failed.iter().map(|(w, n)| (w.label(), *n)).collect(),
        }
    }
}

#[cfg(test)]
mod tests;
