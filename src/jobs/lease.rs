//! The lease's two loops, apart from each other and from the request pool (issue 41 item
//! 1): the heartbeat renews this instance's lease on its own connection, and the reaper
//! (on a third connection, each pass bounded by the lease) takes back the jobs of gone
//! instances and this instance's orphans. A reaper waiting on a lock never delays a renewal.

use std::sync::Weak;
use std::time::Duration;

use super::pool::{INTERRUPTED, Inner, MAX_ATTEMPTS};
use super::stats::{JobStats, TakeBack};
use crate::store::{Reaped, Store};

/// Renews the lease every third of it ([`Store::heartbeat`]); failures are logged and
/// reported by `/healthz`.
pub(super) async fn heartbeat_loop(store: Store, lease: Duration) {
    let lease_ms = i64::try_from(lease.as_millis()).unwrap_or(i64::MAX);
    let mut tick = tokio::time::interval(lease / 3);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    tick.tick().await;
    loop {
        tick.tick().await;
        if let Err(e) = store.heartbeat(lease_ms).await {
            tracing::error!("heartbeat failed: {e:#}");
        }
    }
}

/// Every third of the lease, apart from the heartbeat and on the reaper's own connection
/// (each pass bounded by the lease): re-queues or fails the jobs of gone instances, then the
/// orphans of this one (jobs recorded as ours that no worker of ours runs, untouched for a
/// lease). Ends when the pool is gone.
pub(super) async fn reaper_loop(pool: Weak<Inner>, lease: Duration) {
    let lease_ms = i64::try_from(lease.as_millis()).unwrap_or(i64::MAX);
    let mut tick = tokio::time::interval(lease / 3);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    tick.tick().await;
    loop {
        tick.tick().await;
        let Some(inner) = pool.upgrade() else {
            return;
        };
        let store = inner.store.clone();
        let pass = async {
            // A fenced instance's own jobs are among those put back here.
            let gone = store.reap_dead_instances(MAX_ATTEMPTS, INTERRUPTED).await?;
            log_reaped(
                &inner.stats,
                TakeBack::DeadInstance,
                "jobs of instances that are gone: re-queued or failed",
                gone,
            );
            let live: Vec<String> = inner
                .live
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .keys()
                .cloned()
                .collect();
            let orphans = store.release_orphans(&live, lease_ms, ORPHANED).await?;
            log_reaped(
                &inner.stats,
                TakeBack::Orphan,
                "jobs recorded as this instance's that none of its workers runs: re-queued or failed",
                orphans,
            );
            anyhow::Ok(())
        };
        match tokio::time::timeout(lease, pass).await {
            Ok(Ok(())) => {}
            Ok(Err(e)) => tracing::error!("cannot look for gone instances or orphaned jobs: {e:#}"),
            Err(_) => tracing::warn!(
                "looking for gone instances took longer than the lease ({} ms); trying again \
                 at the next tick",
                lease.as_millis()
            ),
        }
    }
}

/// Error of a job whose worker ended without its outcome recorded ([`reaper_loop`]).
pub const ORPHANED: &str = "interrupted: its worker ended but its outcome could not be \
     recorded; send it again";

/// Logs and counts (`/metrics`) jobs taken back for `why`.
pub(super) fn log_reaped(stats: &JobStats, why: TakeBack, what: &str, r: Reaped) {
    stats.taken_back(why, r.requeued, r.failed);
    if r.requeued > 0 || r.failed > 0 {
        tracing::warn!(
            requeued = r.requeued,
            failed = r.failed,
            instances = r.instances,
            "{what}"
        );
    }
}
