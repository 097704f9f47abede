//! Bounded worker pool for CPU-heavy work, off the async runtime.
//!
//! At most `workers` closures run at once (on tokio's blocking threads); at most
//! `workers + queue` are admitted (running or waiting). Beyond that callers get
//! [`Error::Full`] (answered 503 + Retry-After by `api`) instead of piling up. Background
//! jobs ([`JobPool::submit`]) are
//! recorded in the database; the ones a shutdown or crash interrupted are marked failed
//! when the instance starts again ([`JobPool::start`]).

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio::sync::{Notify, OwnedSemaphorePermit, Semaphore};

use crate::store::Store;

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

/// Progress of a background job, a fraction in 0..1, shared with the running closure.
#[derive(Debug, Default)]
pub struct Progress {
    bits: AtomicU64,
}

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
}

/// A job's state as answered by `GET /v1/jobs/{id}`.
#[derive(Clone, Debug, Serialize)]
pub struct JobStatus {
    /// Job id.
    pub id: String,
    /// What the job does.
    pub kind: String,
    /// `queued`, `running`, `done` or `failed`.
    pub state: String,
    /// 0..1.
    pub progress: f64,
    /// The result JSON when done (null otherwise).
    pub result: Option<serde_json::Value>,
    /// Why it failed (null otherwise).
    pub error: Option<String>,
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
    pub async fn submit(
        &self,
        kind: &str,
        f: impl FnOnce(&Progress) -> Result<serde_json::Value, String> + Send + 'static,
    ) -> Result<String, Error> {
        let admitted = self.admit()?;
        let id = uuid::Uuid::now_v7().to_string();
        self.inner.store.insert_job(&id, kind).await?;
        let progress = Arc::new(Progress::default());
        self.lock_live().insert(id.clone(), progress.clone());
        self.inner.queued.fetch_add(1, Ordering::Relaxed);
        let inner = self.inner.clone();
        let job_id = id.clone();
        tokio::spawn(async move {
            let worker = inner.workers.clone().acquire_owned().await;
            inner.queued.fetch_sub(1, Ordering::Relaxed);
            let outcome = match worker {
                Err(e) => Err(format!("worker pool closed: {e}")),
                Ok(worker) => {
                    if let Err(e) = inner
                        .store
                        .update_job(&job_id, "running", 0.0, None, None)
                        .await
                    {
                        tracing::error!(job = %job_id, "cannot mark job running: {e:#}");
                    }
                    let p = progress.clone();
                    let inner2 = inner.clone();
                    tokio::task::spawn_blocking(move || {
                        let _permits = (admitted, worker);
                        let _running = Count::up(&inner2.running);
                        f(&p)
                    })
                    .await
                    .unwrap_or_else(|e| Err(format!("the job crashed: {e}")))
                }
            };
            let saved = match &outcome {
                Ok(v) => {
                    inner
                        .store
                        .update_job(&job_id, "done", 1.0, Some(v), None)
                        .await
                }
                Err(msg) => {
                    inner
                        .store
                        .update_job(&job_id, "failed", progress.get(), None, Some(msg))
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

    fn lock_live(&self) -> std::sync::MutexGuard<'_, HashMap<String, Arc<Progress>>> {
        self.inner.live.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The job's state, with live progress for jobs running in this instance.
    pub async fn status(&self, id: &str) -> anyhow::Result<Option<JobStatus>> {
        let Some(rec) = self.inner.store.get_job(id).await? else {
            return Ok(None);
        };
        let live = self.lock_live().get(id).map(|p| p.get());
        let progress = match (rec.state.as_str(), live) {
            ("done", _) => 1.0,
            (_, Some(p)) => p,
            _ => rec.progress,
        };
        Ok(Some(JobStatus {
            id: rec.id,
            kind: rec.kind,
            state: rec.state,
            progress,
            result: rec.result,
            error: rec.error,
        }))
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
