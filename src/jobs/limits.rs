//! The limits of the pool's work: the time limit of a job or a request's computation
//! (`--job-timeout`) and the retention of ended jobs (`--job-retention`, pruned by a periodic
//! task, which prunes the idempotency keys too).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use super::pool::JobPool;

impl JobPool {
    /// Sets the time limit of every piece of work (`--job-timeout`): a synchronous request's
    /// work ends `Error::Stopped`, a job ends `failed` saying so. `None`: no limit.
    pub fn set_timeout(&self, limit: Option<Duration>) {
        let ms = limit.map_or(0, |d| {
            u64::try_from(d.as_millis()).unwrap_or(u64::MAX).max(1)
        });
        self.inner.timeout_ms.store(ms, Ordering::Relaxed);
    }

    /// Deletes the jobs that ended more than `retention` ago (`--job-retention`; `None`: keep
    /// them) and the idempotency keys older than [`crate::store::IDEMPOTENCY_KEEP`], now and
    /// then every [`prune_interval`]`(retention)` (10 min without a retention), until
    /// shutdown. Any number of instances may prune one database: the deletion is idempotent.
    pub fn start_pruning(&self, retention: Option<Duration>) {
        let store = self.inner.store.clone();
        let every = retention.map_or(Duration::from_secs(600), prune_interval);
        let task = tokio::spawn(async move {
            let mut tick = tokio::time::interval(every);
            tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            loop {
                tick.tick().await;
                if let Some(retention) = retention {
                    match store.prune_jobs(retention).await {
                        Ok(0) => {}
                        Ok(n) => {
                            tracing::info!(deleted = n, "pruned jobs older than --job-retention")
                        }
                        Err(e) => tracing::error!("cannot prune old jobs: {e:#}"),
                    }
                }
                match store
                    .prune_idempotency_keys(crate::store::IDEMPOTENCY_KEEP)
                    .await
                {
                    Ok(0) => {}
                    Ok(n) => tracing::info!(deleted = n, "pruned idempotency keys older than 24 h"),
                    Err(e) => tracing::error!("cannot prune idempotency keys: {e:#}"),
                }
            }
        });
        if let Some(old) = self
            .inner
            .pruner
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .replace(task)
        {
            old.abort();
        }
    }
}

/// Sets a flag when dropped (a synchronous request's work is told to stop when the request
/// goes away).
pub(super) struct SetOnDrop(pub(super) Arc<AtomicBool>);

impl Drop for SetOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// Sleeps for `limit`, or for ever without one.
pub(super) async fn sleep_or_forever(limit: Option<Duration>) {
    match limit {
        Some(d) => tokio::time::sleep(d).await,
        None => std::future::pending().await,
    }
}

/// How often the jobs are pruned for a retention of `retention`: a quarter of it, between
/// 1 s and 10 min (a job outlives its retention by at most that).
pub fn prune_interval(retention: Duration) -> Duration {
    (retention / 4).clamp(Duration::from_secs(1), Duration::from_secs(600))
}
