//! The claim loop that takes stored jobs from the shared queue, and what every job does
//! around its work: progress stored in its row, cancellation, takeover and the time limit
//! noticed and passed to the work as its should-stop check (`numeric::stop`), outcome
//! recorded.
//!
//! Database outages (a cut connection, a failover: `store::database_outage`) do not end a
//! job: the writes of its bookkeeping are retried ([`persist`]) while this instance's lease
//! holds, work whose own database access failed that way goes back to the queue, and a
//! claim whose answer was lost is given back ([`Store::release_lost_claims`]).

use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::AtomicI64;
use std::time::{Duration, Instant};

use serde_json::Value;
use tokio::sync::OwnedSemaphorePermit;
use tokio::task::JoinHandle;

use super::limits::sleep_or_forever;
use super::pool::{CLAIM_POLL, Count, Inner};
use super::progress::{CANCEL_POLL, Gate, Progress};
use super::stats::{Outcome, TakeBack};
use crate::store::{ClaimedJob, Store};
use tracing::Instrument;

/// The span of a job's run: every line logged inside it names the job, its kind and the
/// request that queued it (`-` when none), on whichever instance runs it.
pub(super) fn job_span(id: &str, kind: &str, request_id: Option<&str>) -> tracing::Span {
    tracing::info_span!("job", job = %id, kind = %kind, request_id = %request_id.unwrap_or("-"))
}

/// When a job's work started on a worker (none: it never reached one), for its run time.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Ran(Option<Instant>);

impl Ran {
    /// The work starts now.
    pub(super) fn start(&mut self) {
        self.0 = Some(Instant::now());
    }

    fn elapsed(self) -> Option<Duration> {
        self.0.map(|t| t.elapsed())
    }
}

/// A job's progress with its commit gate on this instance's store.
pub(super) fn new_progress(inner: &Inner, id: &str) -> Arc<Progress> {
    Arc::new(Progress::with_gate(Gate {
        store: inner.store.clone(),
        id: id.to_string(),
        runtime: tokio::runtime::Handle::current(),
        epoch: AtomicI64::new(0),
    }))
}

/// Longest a job's bookkeeping write is retried through a database outage (while this
/// instance's lease holds; a lapsed instance stops at once and its jobs are taken back).
const OUTAGE_RETRY: Duration = Duration::from_secs(600);

/// Runs `op` (a write of a job's bookkeeping), retrying it while it fails with a database
/// outage, this instance's lease holds and the pool is open: waits 50 ms, doubling to 1 s,
/// for at most [`OUTAGE_RETRY`]. The writes retried this way are idempotent (conditional on
/// the job's state and claim), so a retry after an answer lost in transit changes nothing.
pub(super) async fn persist<T, F, Fut>(store: &Store, what: &str, mut op: F) -> anyhow::Result<T>
where
    F: FnMut() -> Fut,
    Fut: Future<Output = anyhow::Result<T>>,
{
    let t0 = Instant::now();
    let mut wait = Duration::from_millis(50);
    loop {
        match op().await {
            Ok(v) => return Ok(v),
            Err(e)
                if crate::store::database_outage(&e).is_some()
                    && !store.fenced()
                    && !store.pool().is_closed()
                    && t0.elapsed() < OUTAGE_RETRY =>
            {
                tracing::warn!("{what}: {e:#}; retrying in {} ms", wait.as_millis());
                tokio::time::sleep(wait).await;
                wait = (wait * 2).min(Duration::from_secs(1));
            }
            Err(e) => return Err(e),
        }
    }
}

/// Runs a job's work `f` with the job's cancellation as its should-stop check: the cores it
/// calls end at their next check once the job is cancelled or timed out, and the job's
/// outcome is then the sentence saying which (`limit`: the `--job-timeout` it had).
pub(super) fn stoppable(
    progress: &Arc<Progress>,
    limit: Option<Duration>,
    f: impl FnOnce(&Progress) -> Result<Value, String>,
) -> Result<Value, String> {
    let p = progress.clone();
    let check: crate::numeric::stop::Check = Arc::new(move || p.is_cancelled());
    match crate::numeric::stop::run(check, || f(progress.as_ref())) {
        Ok(outcome) if progress.timed_out() => {
            // Work that looks at `is_cancelled` itself (training) ends with its own error.
            outcome.and(Err(progress.stop_sentence(limit)))
        }
        Ok(outcome) => outcome,
        Err(crate::numeric::stop::Stopped) => Err(progress.stop_sentence(limit)),
    }
}

/// Records a job's outcome (`None`: it never ran) and forgets its live progress. A result
/// object carries `truecut_version` ([`crate::version`]), the version of the instance that
/// computed it, unless the runner set it.
pub(super) async fn finish(
    inner: &Inner,
    id: &str,
    kind: &str,
    ran: Ran,
    progress: &Progress,
    mut outcome: Option<Result<Value, String>>,
) {
    if let Some(Ok(Value::Object(result))) = &mut outcome {
        result
            .entry("truecut_version")
            .or_insert_with(|| Value::from(crate::version()));
    }
    let store = &inner.store;
    let epoch = progress.epoch();
    let mut requeued = false;
    if matches!(outcome, Some(Err(_))) && progress.wants_retry() {
        match persist(store, "cannot put the job back in the queue", || {
            store.requeue_job(id, epoch)
        })
        .await
        {
            Ok(r) => requeued = r,
            Err(e) => tracing::error!(job = %id, "cannot put the job back in the queue: {e:#}"),
        }
        if requeued {
            tracing::warn!(job = %id, "the job met a database outage: back in the queue");
        }
    }
    let saved = match &outcome {
        _ if requeued => Ok(true),
        None => Ok(false),
        Some(Ok(v)) => {
            persist(store, "cannot store the job's result", || {
                store.finish_job(id, epoch, "done", 1.0, Some(v), None)
            })
            .await
        }
        Some(Err(msg)) => {
            persist(store, "cannot store the job's failure", || {
                store.finish_job(id, epoch, "failed", progress.get(), None, Some(msg))
            })
            .await
        }
    };
    let counted = match (&outcome, &saved) {
        _ if requeued => Outcome::Requeued,
        (None, _) => Outcome::Cancelled,
        (_, Ok(false) | Err(_)) => Outcome::NotStored,
        (Some(Ok(_)), Ok(true)) => Outcome::Done,
        (Some(Err(_)), Ok(true)) if progress.timed_out() => Outcome::TimedOut,
        (Some(Err(_)), Ok(true)) => Outcome::Failed,
    };
    let run_s = ran.elapsed().map_or(0.0, |d| d.as_secs_f64());
    tracing::info!(outcome = counted.label(), run_s, "job ended");
    inner.stats.finished(kind, counted, ran.elapsed());
    if let Err(e) = saved {
        tracing::error!(job = %id, "cannot store job outcome: {e:#}");
    }
    forget(inner, id);
    // A worker is free: take the next queued job now rather than at the next poll (a deep
    // queue of short jobs would otherwise run two per CLAIM_POLL on two workers).
    inner.work.notify_one();
}

/// Forgets a job's live progress (its worker is done with it) and wakes a waiting shutdown.
fn forget(inner: &Inner, id: &str) {
    inner
        .live
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .remove(id);
    inner.idle.notify_waiters();
}

/// Takes stored jobs from the shared queue while this instance has a free worker (and room
/// under its admission cap), waking when a job is queued here or every [`CLAIM_POLL`].
pub(super) async fn claim_loop(inner: Arc<Inner>) {
    let kinds: Vec<String> = inner
        .runners()
        .map(|r| r.keys().cloned().collect())
        .unwrap_or_default();
    // A claim failed: it may have taken a job whose answer was lost.
    let mut lost_claim = false;
    loop {
        // Runners released (the server stopped or was dropped): claim nothing more.
        if inner.runners().is_none() {
            return;
        }
        // Claim only when a worker looks free, without holding a permit while asking the
        // database (a held permit would turn synchronous requests away).
        if inner.admission.is_closed() {
            return;
        }
        if lost_claim {
            let running: Vec<String> = inner
                .live
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .keys()
                .cloned()
                .collect();
            match inner.store.release_lost_claims(&running).await {
                Ok(n) => {
                    lost_claim = false;
                    inner.stats.taken_back(TakeBack::LostClaim, n, 0);
                    if n > 0 {
                        tracing::warn!(jobs = n, "claims lost in transit: back in the queue");
                    }
                }
                Err(e) => tracing::warn!("cannot look for lost claims yet: {e:#}"),
            }
        }
        if !lost_claim
            && inner.workers.available_permits() > 0
            && inner.admission.available_permits() > 0
        {
            match inner.store.claim_job(&kinds).await {
                Ok(Some(job)) => {
                    // Live from now on, so that a lost-claim sweep leaves it alone.
                    let progress = new_progress(&inner, &job.id);
                    progress.set_epoch(job.attempts);
                    inner
                        .live
                        .lock()
                        .unwrap_or_else(|p| p.into_inner())
                        .insert(job.id.clone(), progress.clone());
                    // A synchronous request may have taken the slot meanwhile: wait for it.
                    // (Closed: shutting down, which gives the job back.)
                    let permits = match (
                        inner.admission.clone().acquire_owned().await,
                        inner.workers.clone().acquire_owned().await,
                    ) {
                        (Ok(a), Ok(w)) => (a, w),
                        _ => {
                            forget(&inner, &job.id);
                            return;
                        }
                    };
                    let span = job_span(&job.id, &job.kind, job.request_id.as_deref());
                    tokio::spawn(
                        run_claimed(inner.clone(), job, progress, permits).instrument(span),
                    );
                    continue;
                }
                Ok(None) => {}
                Err(e) => {
                    lost_claim = true;
                    tracing::warn!("cannot claim a job: {e:#}");
                }
            }
        }
        tokio::select! {
            () = inner.work.notified() => {}
            () = tokio::time::sleep(CLAIM_POLL) => {}
        }
    }
}

/// Runs a claimed stored job on a worker and records its outcome.
async fn run_claimed(
    inner: Arc<Inner>,
    job: ClaimedJob,
    progress: Arc<Progress>,
    permits: (OwnedSemaphorePermit, OwnedSemaphorePermit),
) {
    let runner = inner.runners().and_then(|r| r.get(&job.kind).cloned());
    let p = progress.clone();
    let inner2 = inner.clone();
    let kind = job.kind.clone();
    let input = job.input;
    let limit = inner.timeout();
    let span = tracing::Span::current();
    let mut ran = Ran::default();
    ran.start();
    let work = tokio::task::spawn_blocking(move || {
        let _span = span.enter();
        let _permits = permits;
        let _running = Count::up(&inner2.running);
        match runner {
            Some(run) => stoppable(&p, limit, |p| run(&input, p)),
            None => Err(format!("this instance has no runner for job kind '{kind}'")),
        }
    });
    let outcome = watch_job(&inner.store, &job.id, &progress, work, limit).await;
    finish(&inner, &job.id, &job.kind, ran, &progress, Some(outcome)).await;
}

/// Waits for a job's worker, storing its progress every [`CANCEL_POLL`] (so every instance
/// can answer it) and telling the worker to stop when the row says the job is no longer
/// running here (cancelled through any instance, or taken over after this instance was
/// judged gone), or when it has run for `limit` (`--job-timeout`). A panic in the worker
/// becomes an error sentence.
pub(super) async fn watch_job(
    store: &Store,
    id: &str,
    progress: &Progress,
    work: JoinHandle<Result<Value, String>>,
    limit: Option<Duration>,
) -> Result<Value, String> {
    tokio::pin!(work);
    let mut tick = tokio::time::interval(CANCEL_POLL);
    tick.tick().await;
    let out_of_time = sleep_or_forever(limit);
    tokio::pin!(out_of_time);
    loop {
        tokio::select! {
            done = &mut work => {
                return done.unwrap_or_else(|e| Err(format!("the job crashed: {e}")));
            }
            () = &mut out_of_time, if !progress.is_cancelled() => {
                tracing::warn!(job = %id, "job ran longer than --job-timeout: stopping it");
                progress.time_out();
            }
            _ = tick.tick(), if !progress.is_cancelled() => {
                let epoch = progress.epoch();
                if let Ok(false) = store.report_job_progress(id, epoch, progress.get()).await {
                    progress.cancel();
                }
            }
        }
    }
}
