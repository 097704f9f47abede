//! Bounded worker pool for CPU-heavy work, off the async runtime.
//!
//! At most `workers` closures run at once (on tokio's blocking threads); at most
//! `workers + queue` are admitted (running or waiting). Beyond that callers get
//! [`Error::Full`] (answered 503 + Retry-After by `api`) instead of piling up. Background
//! jobs ([`JobPool::submit`]) are
//! recorded in the database; the ones a shutdown or crash interrupted are marked failed
//! when the instance starts again ([`JobPool::start`]).

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio::sync::{Notify, OwnedSemaphorePermit, Semaphore};

use crate::store::{CancelOutcome, JobRecord, Store};

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
    /// The pool stopped admitting work ([`JobPool::shutdown`]).
    #[error("the server is shutting down; retry on another instance or after restart")]
    ShuttingDown,
    /// The worker running the closure failed (a panic) or the pool closed under it.
    #[error("{0}")]
    Worker(String),
    /// The job could not be recorded.
    #[error("{0:#}")]
    Store(#[from] anyhow::Error),
}

/// Progress of a background job, a fraction in 0..1, shared with the running closure, and
/// its cancellation: [`Progress::is_cancelled`] tells long work to stop, and
/// [`Progress::commit`] is the gate a job passes just before it stores what it made.
#[derive(Debug, Default)]
pub struct Progress {
    bits: AtomicU64,
    cancelled: AtomicBool,
    gate: Option<Gate>,
}

/// Where [`Progress::commit`] claims the right to store: the job's row.
#[derive(Debug)]
struct Gate {
    store: Store,
    id: String,
    runtime: tokio::runtime::Handle,
}

/// The job was cancelled: it must stop and store nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the job was cancelled")]
pub struct Cancelled;

impl Progress {
    /// Sets the fraction done (clamped to 0..1; NaN is ignored).
    pub fn set(&self, fraction: f64) {
        if fraction.is_nan() {
            return;
        }
        self.bits
            .store(fraction.clamp(0.0, 1.0).to_bits(), Ordering::Relaxed);
    }

    /// The fraction done, 0..1.
    pub fn get(&self) -> f64 {
        f64::from_bits(self.bits.load(Ordering::Relaxed))
    }

    /// True once a client cancelled the job (`DELETE /v1/jobs/{id}` on any instance).
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }

    fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
    }

    /// Claims the right to store the job's product (a model): `Err(Cancelled)` when the job
    /// was cancelled, and then nothing may be stored. The claim is one conditional update of
    /// the job's row, so it and a cancellation from any instance exclude each other. Call it
    /// from the job's worker thread (it blocks on the database).
    pub fn commit(&self) -> Result<(), Cancelled> {
        if self.is_cancelled() {
            return Err(Cancelled);
        }
        let Some(g) = &self.gate else {
            return Ok(());
        };
        match g.runtime.block_on(g.store.claim_job_commit(&g.id)) {
            Ok(true) => Ok(()),
            Ok(false) => {
                self.cancel();
                Err(Cancelled)
            }
            Err(e) => {
                // Cannot tell: refuse to store rather than store behind a cancellation.
                tracing::error!(job = %g.id, "cannot claim the job's commit: {e:#}");
                Err(Cancelled)
            }
        }
    }
}

/// What [`JobPool::cancel`] did.
#[derive(Clone, Debug)]
pub enum Cancel {
    /// The job is now `cancelled` (its state as answered).
    Cancelled(JobStatus),
    /// The job had already ended, or is storing its result: its status.
    Ended(JobStatus),
    /// No such job.
    Unknown,
}

/// How often a running job's own instance looks for a cancellation made on another one.
pub const CANCEL_POLL: Duration = Duration::from_millis(250);

/// Unix ms as RFC 3339 (UTC), for the job times.
fn rfc3339(ms: i64) -> Option<String> {
    let t = time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(ms) * 1_000_000).ok()?;
    t.format(&time::format_description::well_known::Rfc3339)
        .ok()
}

/// A job's state as answered by `GET /v1/jobs/{id}` and listed by `GET /v1/jobs`.
#[derive(Clone, Debug, Serialize)]
pub struct JobStatus {
    /// Job id.
    pub id: String,
    /// What the job does.
    pub kind: String,
    /// `queued`, `running`, `done`, `failed` or `cancelled`.
    pub state: String,
    /// 0..1.
    pub progress: f64,
    /// The result JSON when done (null otherwise).
    pub result: Option<serde_json::Value>,
    /// Why it failed or that it was cancelled (null otherwise).
    pub error: Option<String>,
    /// When it was submitted (RFC 3339, UTC).
    pub created_at: Option<String>,
    /// When a worker took it (RFC 3339; null while queued).
    pub started_at: Option<String>,
    /// When it ended (RFC 3339; null while unfinished).
    pub finished_at: Option<String>,
}

impl JobStatus {
    fn of(rec: JobRecord, live: Option<f64>) -> JobStatus {
        let progress = match (rec.state.as_str(), live) {
            ("done", _) => 1.0,
            ("queued" | "running" | "storing", Some(p)) => p,
            _ => rec.progress,
        };
        let state = if rec.state == "storing" {
            "running".to_string()
        } else {
            rec.state
        };
        JobStatus {
            id: rec.id,
            kind: rec.kind,
            state,
            progress,
            result: rec.result,
            error: rec.error,
            created_at: rfc3339(rec.created_at_ms),
            started_at: rec.started_at_ms.and_then(rfc3339),
            finished_at: rec.finished_at_ms.and_then(rfc3339),
        }
    }
}

struct Inner {
    store: Store,
    workers: Arc<Semaphore>,
    admission: Arc<Semaphore>,
    worker_count: usize,
    queued: AtomicUsize,
    running: AtomicUsize,
    rejected: AtomicU64,
    live: Mutex<HashMap<String, Arc<Progress>>>,
    idle: Notify,
}

/// The worker pool. Cheap to clone.
#[derive(Clone)]
pub struct JobPool {
    inner: Arc<Inner>,
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
struct Count<'a>(&'a AtomicUsize);

impl<'a> Count<'a> {
    fn up(c: &'a AtomicUsize) -> Self {
        c.fetch_add(1, Ordering::Relaxed);
        Count(c)
    }
}

impl Drop for Count<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

/// The message stored for jobs a restart found unfinished.
pub const INTERRUPTED: &str =
    "interrupted: the server stopped (shutdown or crash) before this job finished; submit it again";

impl JobPool {
    /// Creates the pool (`workers` ≥ 1 running at once, `queue` more waiting) and marks the
    /// jobs this instance left unfinished at its last stop as failed.
    pub async fn start(store: Store, workers: usize, queue: usize) -> anyhow::Result<JobPool> {
        let workers = workers.max(1);
        let failed = store.fail_unfinished_jobs(INTERRUPTED).await?;
        if failed > 0 {
            tracing::warn!(
                failed,
                "jobs interrupted by the last shutdown are now marked failed"
            );
        }
        Ok(JobPool {
            inner: Arc::new(Inner {
                store,
                workers: Arc::new(Semaphore::new(workers)),
                admission: Arc::new(Semaphore::new(workers + queue)),
                worker_count: workers,
                queued: AtomicUsize::new(0),
                running: AtomicUsize::new(0),
                rejected: AtomicU64::new(0),
                live: Mutex::new(HashMap::new()),
                idle: Notify::new(),
            }),
        })
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
        tokio::task::spawn_blocking(move || {
            // Permits live with the work, not with the (cancellable) request future.
            let _permits = (admitted, worker);
            let _running = Count::up(&inner2.running);
            f()
        })
        .await
        .map_err(|e| Error::Worker(format!("worker failed: {e}")))
    }

    /// Long work: records a job and returns its id at once (answer `202 {"job": id}`);
    /// `f` reports progress 0..1 and returns the result JSON or an error sentence.
    /// Poll with `GET /v1/jobs/{id}`. [`Error::Full`] (503 + Retry-After) when the pool is full.
    ///
    /// Cancellation (`DELETE /v1/jobs/{id}`, [`JobPool::cancel`]): a job cancelled while
    /// queued never runs; a running one sees [`Progress::is_cancelled`] (set here, or within
    /// [`CANCEL_POLL`] when the cancel came through another instance), and whatever it returns
    /// is dropped. A job that stores something (a model) must pass [`Progress::commit`] first.
    pub async fn submit(
        &self,
        kind: &str,
        f: impl FnOnce(&Progress) -> Result<serde_json::Value, String> + Send + 'static,
    ) -> Result<String, Error> {
        let admitted = self.admit()?;
        let id = uuid::Uuid::now_v7().to_string();
        self.inner.store.insert_job(&id, kind).await?;
        let progress = Arc::new(Progress {
            gate: Some(Gate {
                store: self.inner.store.clone(),
                id: id.clone(),
                runtime: tokio::runtime::Handle::current(),
            }),
            ..Progress::default()
        });
        self.lock_live().insert(id.clone(), progress.clone());
        self.inner.queued.fetch_add(1, Ordering::Relaxed);
        let inner = self.inner.clone();
        let job_id = id.clone();
        tokio::spawn(async move {
            let worker = inner.workers.clone().acquire_owned().await;
            inner.queued.fetch_sub(1, Ordering::Relaxed);
            let outcome = match worker {
                Err(e) => Some(Err(format!("worker pool closed: {e}"))),
                Ok(worker) => match inner.store.start_job(&job_id).await {
                    Ok(false) => None, // cancelled while queued: never runs
                    started => {
                        if let Err(e) = started {
                            tracing::error!(job = %job_id, "cannot mark job running: {e:#}");
                        }
                        let p = progress.clone();
                        let inner2 = inner.clone();
                        let work = tokio::task::spawn_blocking(move || {
                            let _permits = (admitted, worker);
                            let _running = Count::up(&inner2.running);
                            f(&p)
                        });
                        let done = watch_for_cancel(&inner.store, &job_id, &progress, work).await;
                        Some(done.unwrap_or_else(|e| Err(format!("the job crashed: {e}"))))
                    }
                },
            };
            let saved = match &outcome {
                None => Ok(false),
                Some(Ok(v)) => {
                    inner
                        .store
                        .finish_job(&job_id, "done", 1.0, Some(v), None)
                        .await
                }
                Some(Err(msg)) => {
                    inner
                        .store
                        .finish_job(&job_id, "failed", progress.get(), None, Some(msg))
                        .await
                }
            };
            if let Err(e) = saved {
                tracing::error!(job = %job_id, "cannot store job outcome: {e:#}");
            }
            inner
                .live
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .remove(&job_id);
            inner.idle.notify_waiters();
        });
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

    /// Jobs newest first (`state` `queued`, `running`, `done`, `failed` or `cancelled`; `kind`
    /// as submitted), at most `limit`, with live progress for this instance's running ones.
    pub async fn list(
        &self,
        state: Option<&str>,
        kind: Option<&str>,
        limit: usize,
    ) -> anyhow::Result<Vec<JobStatus>> {
        let recs = self.inner.store.list_jobs(state, kind, limit).await?;
        let live = self.lock_live();
        Ok(recs
            .into_iter()
            .map(|r| {
                let p = live.get(&r.id).map(|p| p.get());
                JobStatus::of(r, p)
            })
            .collect())
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

    /// Number of worker slots.
    pub fn worker_count(&self) -> usize {
        self.inner.worker_count
    }

    /// Stops admitting work, waits up to `grace` for background jobs to end, then records
    /// the ones still unfinished as failed. Returns how many were cut off.
    pub async fn shutdown(&self, grace: Duration) -> anyhow::Result<u64> {
        self.inner.admission.close();
        let deadline = Instant::now() + grace;
        loop {
            let notified = self.inner.idle.notified();
            if self.lock_live().is_empty() {
                return Ok(0);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            let _ = tokio::time::timeout(left.min(Duration::from_millis(200)), notified).await;
        }
        let cut = self.inner.store.fail_unfinished_jobs(INTERRUPTED).await?;
        Ok(cut)
    }
}

/// Waits for a job's worker, looking every [`CANCEL_POLL`] whether its row was cancelled
/// (through another instance) and telling the worker so.
async fn watch_for_cancel<T>(
    store: &Store,
    id: &str,
    progress: &Progress,
    work: tokio::task::JoinHandle<T>,
) -> Result<T, tokio::task::JoinError> {
    tokio::pin!(work);
    let mut tick = tokio::time::interval(CANCEL_POLL);
    tick.tick().await;
    loop {
        tokio::select! {
            done = &mut work => return done,
            _ = tick.tick(), if !progress.is_cancelled() => {
                if let Ok(Some(state)) = store.job_state(id).await {
                    if state == "cancelled" {
                        progress.cancel();
                    }
                }
            }
        }
    }
}
