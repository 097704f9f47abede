//! The worker pool: admission (back-pressure), synchronous work, in-process and stored
//! jobs, the instance's lease, cancellation, the time limit of work and shutdown.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::sync::{Notify, OwnedSemaphorePermit, Semaphore};
use tokio::task::JoinHandle;

use super::error::Error;
use super::keyed::take_keyed_id;
use super::lease::{heartbeat_loop, log_reaped, reaper_loop};
use super::limits::{SetOnDrop, sleep_or_forever};
use super::progress::{Cancel, JobStatus, Progress};
use super::stats::{JobStats, StatsSnapshot, TakeBack, current_request_id};
use super::worker::{
    Ran, claim_loop, finish, job_span, new_progress, persist, stoppable, watch_job,
};
use crate::numeric;
use crate::store::{CancelOutcome, Store};
use serde_json::Value;
use tracing::Instrument;

/// Runs one kind of stored job: reads the job's input (JSON text), reports progress and
/// returns the result JSON or an error sentence, like a [`JobPool::submit`] closure.
pub type Runner = Arc<dyn Fn(&str, &Progress) -> Result<Value, String> + Send + Sync>;

/// How many counted claims a stored job may have before an interruption fails it instead
/// of re-queueing it (a job that crashes its instance must not crash them all). Counted are
/// the claims whose instance crashed (went without giving the job back) and the running
/// one; claims given back through no fault of the job (outage, lost claim answer, graceful
/// stop, orphan sweep) are not, and [`crate::store::MAX_CLAIMS`] bounds all claims.
pub const MAX_ATTEMPTS: i64 = 3;

/// Default lease of an instance: gone when its heartbeat (every third of this) is older.
pub const DEFAULT_LEASE: Duration = Duration::from_secs(10);

/// How often an idle instance looks for jobs queued through another instance (jobs queued
/// through this one are taken at once).
pub const CLAIM_POLL: Duration = Duration::from_millis(250);

pub(super) struct Inner {
    pub(super) store: Store,
    pub(super) workers: Arc<Semaphore>,
    pub(super) admission: Arc<Semaphore>,
    pub(super) worker_count: usize,
    pub(super) queued: AtomicUsize,
    pub(super) running: AtomicUsize,
    pub(super) rejected: AtomicU64,
    pub(super) live: Mutex<HashMap<String, Arc<Progress>>>,
    pub(super) idle: Notify,
    /// Wakes the claim loop when a job is queued through this instance.
    pub(super) work: Notify,
    /// The runners of the stored job kinds ([`JobPool::serve`]). They capture the service's
    /// state, which holds this pool: [`JobPool::release_runners`] breaks that cycle when the
    /// server is stopped or dropped, so the database pool closes its connections.
    pub(super) runners: Mutex<Option<Arc<HashMap<String, Runner>>>>,
    pub(super) queue: usize,
    pub(super) lease: Duration,
    pub(super) claim_loop: Mutex<Option<JoinHandle<()>>>,
    pub(super) heartbeat: Mutex<Option<JoinHandle<()>>>,
    /// Looks for gone instances every third of the lease, apart from the heartbeat: a
    /// reaper waiting on a lock never delays a renewal.
    pub(super) reaper: Mutex<Option<JoinHandle<()>>>,
    /// The periodic pruning of old jobs ([`JobPool::start_pruning`]).
    pub(super) pruner: Mutex<Option<JoinHandle<()>>>,
    /// Longest run of a piece of work in ms (`--job-timeout`); 0: no limit.
    pub(super) timeout_ms: AtomicU64,
    /// What this instance's jobs came to (`/metrics`).
    pub(super) stats: JobStats,
}

impl Inner {
    /// The time limit of a piece of work (`--job-timeout`), if any.
    pub(super) fn timeout(&self) -> Option<Duration> {
        match self.timeout_ms.load(Ordering::Relaxed) {
            0 => None,
            ms => Some(Duration::from_millis(ms)),
        }
    }

    /// The runners, while the pool serves stored jobs.
    pub(super) fn runners(&self) -> Option<Arc<HashMap<String, Runner>>> {
        self.runners
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }
}

/// A page of [`JobPool::list`].
#[derive(Clone, Debug)]
pub struct JobPage {
    /// The jobs, newest first.
    pub jobs: Vec<JobStatus>,
    /// Where the next page starts (the `seq` of this page's last job), when there are more
    /// jobs.
    pub next: Option<i64>,
}

/// The worker pool. Cheap to clone.
#[derive(Clone)]
pub struct JobPool {
    pub(super) inner: Arc<Inner>,
}

impl std::fmt::Debug for JobPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JobPool")
            .field("workers", &self.inner.worker_count)
            .field("queued", &self.queued())
            .field("running", &self.running())
            .finish()
    }
}

/// Decrements a counter when dropped (keeps gauges right when a request is cancelled).
pub(super) struct Count<'a>(&'a AtomicUsize);

impl<'a> Count<'a> {
    pub(super) fn up(c: &'a AtomicUsize) -> Self {
        c.fetch_add(1, Ordering::Relaxed);
        Count(c)
    }
}

impl Drop for Count<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

/// The message stored for jobs an interruption failed (no stored input, or out of attempts).
pub const INTERRUPTED: &str = "interrupted: the instance running it stopped (shutdown or crash) \
     before this job finished; submit it again";

impl JobPool {
    /// Creates the pool (`workers` ≥ 1 running at once, `queue` more waiting) with the
    /// [`DEFAULT_LEASE`]; see [`JobPool::start_with_lease`].
    pub async fn start(store: Store, workers: usize, queue: usize) -> anyhow::Result<JobPool> {
        Self::start_with_lease(store, workers, queue, DEFAULT_LEASE).await
    }

    /// Creates the pool, registers this instance with a lease of `lease` (renewed every
    /// third of it), and re-queues or fails the jobs of instances whose lease expired (now
    /// and every third of the lease, apart from the heartbeat). Stored jobs run once [`JobPool::serve`] gives the runners.
    pub async fn start_with_lease(
        store: Store,
        workers: usize,
        queue: usize,
        lease: Duration,
    ) -> anyhow::Result<JobPool> {
        let workers = workers.max(1);
        let lease = lease.max(Duration::from_millis(300));
        let lease_ms = i64::try_from(lease.as_millis()).unwrap_or(i64::MAX);
        store.register_instance(lease_ms).await?;
        let stats = JobStats::default();
        log_reaped(
            &stats,
            TakeBack::DeadInstance,
            "jobs of instances that are gone: re-queued or failed",
            store.reap_dead_instances(MAX_ATTEMPTS, INTERRUPTED).await?,
        );
        let heartbeat = tokio::spawn(heartbeat_loop(store.clone(), lease));
        let inner = Arc::new(Inner {
            store,
            workers: Arc::new(Semaphore::new(workers)),
            admission: Arc::new(Semaphore::new(workers + queue)),
            worker_count: workers,
            queued: AtomicUsize::new(0),
            running: AtomicUsize::new(0),
            rejected: AtomicU64::new(0),
            live: Mutex::new(HashMap::new()),
            idle: Notify::new(),
            work: Notify::new(),
            runners: Mutex::new(None),
            queue,
            lease,
            claim_loop: Mutex::new(None),
            heartbeat: Mutex::new(Some(heartbeat)),
            reaper: Mutex::new(None),
            pruner: Mutex::new(None),
            timeout_ms: AtomicU64::new(0),
            stats,
        });
        let reaper = tokio::spawn(reaper_loop(Arc::downgrade(&inner), lease));
        *inner.reaper.lock().unwrap_or_else(|p| p.into_inner()) = Some(reaper);
        Ok(JobPool { inner })
    }

    /// Starts taking stored jobs of the kinds in `runners` from the queue (shared by every
    /// instance on the database) whenever a worker is free. Call once.
    pub fn serve(&self, runners: HashMap<String, Runner>) {
        {
            let mut slot = self.inner.runners.lock().unwrap_or_else(|p| p.into_inner());
            if slot.is_some() {
                tracing::error!("JobPool::serve called twice; the first runners stay");
                return;
            }
            *slot = Some(Arc::new(runners));
        }
        let task = tokio::spawn(claim_loop(self.inner.clone()));
        *self
            .inner
            .claim_loop
            .lock()
            .unwrap_or_else(|p| p.into_inner()) = Some(task);
    }

    /// The lease this instance holds (see [`JobPool::start_with_lease`]).
    pub fn lease(&self) -> Duration {
        self.inner.lease
    }

    /// Forgets the runners [`JobPool::serve`] was given (no stored job is claimed after
    /// this). They hold the service's state, which holds this pool: a server calls this when
    /// it stops or is dropped, so nothing keeps the database pool (and its connections) alive.
    pub fn release_runners(&self) {
        self.inner
            .runners
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take();
        self.inner.work.notify_waiters();
    }

    /// Queues a stored job: `kind` names its [`Runner`], `input` is the JSON it reads. Any
    /// instance serving that kind may run it (answer `202 {"job": id}`). [`Error::Full`]
    /// (503 + Retry-After) when more jobs wait than the queue holds beyond this instance's
    /// free workers; [`Error::ShuttingDown`] once the pool stopped.
    pub async fn enqueue(&self, kind: &str, input: String) -> Result<String, Error> {
        if self.inner.admission.is_closed() {
            return Err(Error::ShuttingDown);
        }
        if !self.inner.runners().is_some_and(|r| r.contains_key(kind)) {
            return Err(Error::Worker(format!("no runner for job kind '{kind}'")));
        }
        let waiting = self.inner.store.count_queued_jobs().await?;
        let room = self.inner.queue + self.inner.workers.available_permits();
        if waiting >= room as u64 {
            self.inner.rejected.fetch_add(1, Ordering::Relaxed);
            return Err(Error::Full {
                workers: self.inner.worker_count,
            });
        }
        let id = take_keyed_id().unwrap_or_else(|| uuid::Uuid::now_v7().to_string());
        let request_id = current_request_id();
        // False: a job with this keyed id exists (an earlier try of the same request
        // recorded it): its id is the answer, and it runs once.
        if self
            .inner
            .store
            .insert_job_for(&id, kind, Some(&input), request_id.as_deref())
            .await?
        {
            self.inner.work.notify_one();
        }
        Ok(id)
    }

    fn admit(&self) -> Result<OwnedSemaphorePermit, Error> {
        self.inner
            .admission
            .clone()
            .try_acquire_owned()
            .map_err(|e| {
                self.inner.rejected.fetch_add(1, Ordering::Relaxed);
                match e {
                    tokio::sync::TryAcquireError::Closed => Error::ShuttingDown,
                    tokio::sync::TryAcquireError::NoPermits => Error::Full {
                        workers: self.inner.worker_count,
                    },
                }
            })
    }

    /// Whether a slot is free now (nothing counted, nothing taken).
    pub fn has_room(&self) -> bool {
        !self.inner.admission.is_closed() && self.inner.admission.available_permits() > 0
    }

    /// Whether new work would be admitted now, without taking a slot: [`Error::Full`] (counted
    /// as a rejection) or [`Error::ShuttingDown`] when not. Lets a caller turn a request away
    /// before reading its body; the later [`JobPool::run`] or [`JobPool::submit`] still decides.
    pub fn check_room(&self) -> Result<(), Error> {
        if self.inner.admission.is_closed() {
            return Err(Error::ShuttingDown);
        }
        if self.inner.admission.available_permits() == 0 {
            self.inner.rejected.fetch_add(1, Ordering::Relaxed);
            return Err(Error::Full {
                workers: self.inner.worker_count,
            });
        }
        Ok(())
    }

    /// Runs CPU-heavy work synchronously for a request; [`Error::Full`] (503 + Retry-After)
    /// when the pool is full. A panic in `f` becomes [`Error::Worker`] (a 500).
    ///
    /// The work is stopped (at its next `numeric::stop::check`, within ~100 ms for the cores)
    /// when it runs longer than [`JobPool::set_timeout`] ([`Error::Stopped`]), or when the
    /// request is dropped (its client went away): the worker is then free for others.
    pub async fn run<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, Error> {
        let admitted = self.admit()?;
        let inner = self.inner.clone();
        let worker = {
            let _queued = Count::up(&inner.queued);
            inner
                .workers
                .clone()
                .acquire_owned()
                .await
                .map_err(|e| Error::Worker(e.to_string()))?
        };
        let inner2 = inner.clone();
        let stop = Arc::new(AtomicBool::new(false));
        // The request's future dropped (client gone): stop the work it no longer waits for.
        let _stop_on_drop = SetOnDrop(stop.clone());
        let flag = stop.clone();
        let work = tokio::task::spawn_blocking(move || {
            // Permits live with the work, not with the (cancellable) request future.
            let _permits = (admitted, worker);
            let _running = Count::up(&inner2.running);
            numeric::stop::run(Arc::new(move || flag.load(Ordering::Relaxed)), f)
        });
        tokio::pin!(work);
        let limit = inner.timeout();
        let joined = tokio::select! {
            done = &mut work => done,
            () = sleep_or_forever(limit) => {
                stop.store(true, Ordering::Relaxed);
                work.await
            }
        };
        match joined {
            Ok(Ok(v)) => Ok(v),
            Ok(Err(numeric::stop::Stopped)) => Err(Error::Stopped {
                after: limit.unwrap_or_default(),
            }),
            Err(e) => Err(Error::Worker(format!("worker failed: {e}"))),
        }
    }

    /// In-process long work: records a job and returns its id at once (answer
    /// `202 {"job": id}`); `f` reports progress 0..1 and returns the result JSON or an error
    /// sentence. Only this instance can run `f`, so an interruption fails the job; work that
    /// any instance should be able to run (or resume) goes through [`JobPool::enqueue`].
    /// Poll with `GET /v1/jobs/{id}`. [`Error::Full`] (503 + Retry-After) when the pool is full.
    ///
    /// Cancellation (`DELETE /v1/jobs/{id}`, [`JobPool::cancel`]): a job cancelled while
    /// queued never runs; a running one sees [`Progress::is_cancelled`] (set here, or within
    /// [`CANCEL_POLL`](super::CANCEL_POLL) when the cancel came through another instance), and whatever it returns
    /// is dropped. A job that stores something (a model) must pass [`Progress::commit`] first.
    pub async fn submit(
        &self,
        kind: &str,
        f: impl FnOnce(&Progress) -> Result<serde_json::Value, String> + Send + 'static,
    ) -> Result<String, Error> {
        let admitted = self.admit()?;
        let id = take_keyed_id().unwrap_or_else(|| uuid::Uuid::now_v7().to_string());
        let request_id = current_request_id();
        if !self
            .inner
            .store
            .insert_job_for(&id, kind, None, request_id.as_deref())
            .await?
        {
            // An earlier try of the same request recorded this job (keyed id): the answer
            // is that job, whatever became of it (a try whose instance died ended it
            // failed, "interrupted"); it is not run twice.
            return Ok(id);
        }
        let progress = new_progress(&self.inner, &id);
        self.lock_live().insert(id.clone(), progress.clone());
        self.inner.queued.fetch_add(1, Ordering::Relaxed);
        let inner = self.inner.clone();
        let job_id = id.clone();
        let kind = kind.to_string();
        let span = job_span(&id, &kind, request_id.as_deref());
        tokio::spawn(
            async move {
                let mut ran = Ran::default();
                let worker = inner.workers.clone().acquire_owned().await;
                inner.queued.fetch_sub(1, Ordering::Relaxed);
                let outcome = match worker {
                    Err(e) => Some(Err(format!("worker pool closed: {e}"))),
                    Ok(worker) => {
                        let (store, job) = (&inner.store, job_id.as_str());
                        // A start whose answer a cut connection lost shows as running here.
                        let started =
                            persist(store, "cannot mark the job running", move || async move {
                                match store.start_job(job).await? {
                                    Some(epoch) => Ok(Some(epoch)),
                                    None => store.running_here(job).await,
                                }
                            })
                            .await;
                        match started {
                            Ok(None) => None, // cancelled while queued: never runs
                            Err(e) => {
                                tracing::error!(job = %job_id, "cannot mark job running: {e:#}");
                                Some(Err(format!("the job could not be started: {e:#}")))
                            }
                            Ok(Some(epoch)) => {
                                progress.set_epoch(epoch);
                                let p = progress.clone();
                                let inner2 = inner.clone();
                                let limit = inner.timeout();
                                let span = tracing::Span::current();
                                ran.start();
                                let work = tokio::task::spawn_blocking(move || {
                                    let _span = span.enter();
                                    let _permits = (admitted, worker);
                                    let _running = Count::up(&inner2.running);
                                    stoppable(&p, limit, |p| f(p))
                                });
                                Some(watch_job(&inner.store, &job_id, &progress, work, limit).await)
                            }
                        }
                    }
                };
                finish(&inner, &job_id, &kind, ran, &progress, outcome).await;
            }
            .instrument(span),
        );
        Ok(id)
    }

    /// Cancels a job of any instance: queued or running jobs end `cancelled` at once (the
    /// worker, if any, is told to stop and its result is dropped); ended jobs are left alone.
    pub async fn cancel(&self, id: &str) -> anyhow::Result<Cancel> {
        let outcome = self.inner.store.cancel_job(id).await?;
        if outcome == CancelOutcome::Cancelled {
            if let Some(p) = self.lock_live().get(id) {
                p.cancel();
            }
            // After the worker was told: dropping a large input is the slower write.
            if let Err(e) = self.inner.store.drop_job_input(id).await {
                tracing::warn!(job = %id, "cannot drop the cancelled job's input (pruning will): {e:#}");
            }
        }
        let Some(status) = self.status(id).await? else {
            return Ok(Cancel::Unknown);
        };
        Ok(match outcome {
            CancelOutcome::Cancelled => Cancel::Cancelled(status),
            CancelOutcome::Ended(_) => Cancel::Ended(status),
            CancelOutcome::Unknown => Cancel::Unknown,
        })
    }

    /// One page of jobs, newest first (`state` `queued`, `running`, `done`, `failed` or
    /// `cancelled`; `kind` as submitted), at most `limit`, after `after` (the
    /// [`JobPage::next`] of the previous page), with live progress for this instance's
    /// running ones; results only `with_result`.
    pub async fn list(
        &self,
        state: Option<&str>,
        kind: Option<&str>,
        limit: usize,
        after: Option<i64>,
        with_result: bool,
    ) -> anyhow::Result<JobPage> {
        let mut recs = self
            .inner
            .store
            .list_jobs(state, kind, limit + 1, after, with_result)
            .await?;
        let more = recs.len() > limit;
        recs.truncate(limit);
        let next = recs.last().filter(|_| more).map(|r| r.seq);
        let live = self.lock_live();
        let jobs = recs
            .into_iter()
            .map(|r| {
                let p = live.get(&r.id).map(|p| p.get());
                JobStatus::of(r, p)
            })
            .collect();
        Ok(JobPage { jobs, next })
    }

    fn lock_live(&self) -> std::sync::MutexGuard<'_, HashMap<String, Arc<Progress>>> {
        self.inner.live.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The job's state, with live progress for jobs running in this instance.
    pub async fn status(&self, id: &str) -> anyhow::Result<Option<JobStatus>> {
        let Some(rec) = self.inner.store.get_job(id).await? else {
            return Ok(None);
        };
        let live = self.lock_live().get(id).map(|p| p.get());
        Ok(Some(JobStatus::of(rec, live)))
    }

    /// Work items waiting for a worker.
    pub fn queued(&self) -> usize {
        self.inner.queued.load(Ordering::Relaxed)
    }

    /// Work items running now.
    pub fn running(&self) -> usize {
        self.inner.running.load(Ordering::Relaxed)
    }

    /// Requests and jobs turned away with 503 since start.
    pub fn rejected(&self) -> u64 {
        self.inner.rejected.load(Ordering::Relaxed)
    }

    /// What this instance's jobs came to since start: outcomes and run times by kind, jobs
    /// taken back by reason.
    pub fn stats(&self) -> StatsSnapshot {
        self.inner.stats.snapshot()
    }

    /// The state of this instance's lease ([`Store::lease`]).
    pub fn lease_report(&self) -> crate::store::LeaseReport {
        self.inner.store.lease()
    }

    /// Number of worker slots.
    pub fn worker_count(&self) -> usize {
        self.inner.worker_count
    }

    /// Stops admitting and claiming work, waits up to `grace` for background jobs to end,
    /// then re-queues the stored jobs still running (another instance, or the next start,
    /// runs them) and fails the in-process ones, and gives up this instance's lease.
    /// Returns how many jobs were cut off.
    pub async fn shutdown(&self, grace: Duration) -> anyhow::Result<u64> {
        self.inner.admission.close();
        if let Some(t) = self
            .inner
            .claim_loop
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
        {
            t.abort();
        }
        if let Some(t) = self
            .inner
            .pruner
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
        {
            t.abort();
        }
        let deadline = Instant::now() + grace;
        loop {
            let notified = self.inner.idle.notified();
            if self.lock_live().is_empty() {
                break;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            let _ = tokio::time::timeout(left.min(Duration::from_millis(200)), notified).await;
        }
        let cut = self.inner.store.release_own_jobs(INTERRUPTED).await?;
        self.inner
            .stats
            .taken_back(TakeBack::Shutdown, cut.requeued, cut.failed);
        // The work of the jobs that outlived the grace stops at its next should-stop check
        // (their records were settled just above; a late write of theirs is fenced).
        for p in self.lock_live().values() {
            p.cancel();
        }
        for task in [&self.inner.heartbeat, &self.inner.reaper] {
            if let Some(t) = task.lock().unwrap_or_else(|p| p.into_inner()).take() {
                t.abort();
            }
        }
        self.inner.store.deregister_instance().await?;
        Ok(cut.requeued + cut.failed)
    }
}
