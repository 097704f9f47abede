//! Bounded worker pool for CPU-heavy work, off the async runtime.
//!
//! At most `workers` closures run at once (on tokio's blocking threads); at most
//! `workers + queue` are admitted (running or waiting). Beyond that callers get
//! [`Error::Full`] (answered 503 + Retry-After by `api`) instead of piling up.
//!
//! Background jobs are rows in the database. A job with a stored input
//! ([`JobPool::enqueue`]: a kind and its JSON) runs on whichever instance sharing the
//! database has a free worker first: each instance's claim loop takes queued jobs of the
//! kinds it has a [`Runner`] for ([`JobPool::serve`]; `FOR UPDATE SKIP LOCKED` on
//! PostgreSQL), so a job runs exactly once. In-process work ([`JobPool::submit`], a closure)
//! runs on the instance that submitted it. Each instance holds a lease renewed by a
//! heartbeat; the jobs of an instance whose lease expired (crash, kill, lost network) are
//! re-queued if their input is stored and they have attempts left, failed otherwise, by
//! whichever live instance notices first. A graceful stop does the same for its own jobs.
//!
//! Every piece of work runs with a should-stop check (`numeric::stop`) that the cores poll
//! between units of work: a cancelled job, a job or request past `--job-timeout`, and a
//! request whose client went away free their worker within about 100 ms. A job's input is
//! dropped when it ends, and jobs older than `--job-retention` are deleted
//! ([`JobPool::start_pruning`]).

mod error;
mod keyed;
mod lease;
mod limits;
mod pool;
mod progress;
mod stats;
mod worker;

pub use error::{Error, RETRY_AFTER_S};
pub use keyed::with_keyed_id;
pub use limits::prune_interval;
pub use pool::{CLAIM_POLL, DEFAULT_LEASE, INTERRUPTED, JobPage, JobPool, MAX_ATTEMPTS, Runner};
pub use progress::{CANCEL_POLL, Cancel, Cancelled, JobStatus, Progress};
pub use stats::{
    JobStats, Outcome, REQUEST_ID, RUN_BUCKETS_S, RunTimes, StatsSnapshot, TakeBack,
    current_request_id,
};
