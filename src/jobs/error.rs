//! Why the pool did not run or record a piece of work (mapped to HTTP once, in `api`).

use std::time::Duration;

/// Seconds a rejected caller is told to wait (`Retry-After`).
pub const RETRY_AFTER_S: u64 = 2;

/// Why the pool did not run or record a piece of work. The pool knows nothing of HTTP:
/// `api/error.rs` decides the statuses (503 + Retry-After for the rejections, 500 otherwise).
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Every worker is busy and the queue is full: retry after [`RETRY_AFTER_S`].
    #[error("all {workers} workers are busy and the queue is full; retry in {RETRY_AFTER_S} s")]
    Full {
        /// Number of worker slots.
        workers: usize,
    },
    /// The pool stopped admitting work ([`super::JobPool::shutdown`]).
    #[error("the server is shutting down; retry on another instance or after restart")]
    ShuttingDown,
    /// The worker running the closure failed (a panic) or the pool closed under it.
    #[error("{0}")]
    Worker(String),
    /// The job could not be recorded.
    #[error("{0:#}")]
    Store(#[from] anyhow::Error),
    /// Synchronous work ran longer than the pool's time limit (`--job-timeout`) and was
    /// stopped.
    #[error(
        "the computation ran longer than the server's --job-timeout ({} s) and was stopped; \
         send a smaller input, or ask the operator for a longer timeout",
        .after.as_secs_f64()
    )]
    Stopped {
        /// The time limit.
        after: Duration,
    },
}
