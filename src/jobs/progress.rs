//! A job's progress, its cancellation flag and commit gate ([`Progress`]), and its state as
//! answered ([`JobStatus`]).

use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::time::Duration;

use serde::Serialize;

use crate::store::{JobRecord, Store};

/// Progress of a background job, a fraction in 0..1, shared with the running closure, and
/// its cancellation: [`Progress::is_cancelled`] tells long work to stop, and
/// [`Progress::commit`] is the gate a job passes just before it stores what it made.
#[derive(Debug, Default)]
pub struct Progress {
    bits: AtomicU64,
    cancelled: AtomicBool,
    timed_out: AtomicBool,
    retry: AtomicBool,
    gate: Option<Gate>,
}

/// Where [`Progress::commit`] claims the right to store: the job's row.
#[derive(Debug)]
pub(super) struct Gate {
    pub(super) store: Store,
    pub(super) id: String,
    pub(super) runtime: tokio::runtime::Handle,
    /// The claim of the job this worker runs (0 until it starts): every write it makes is
    /// conditional on it (`store/jobs.rs`).
    pub(super) epoch: AtomicI64,
}

/// The job was cancelled: it must stop and store nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the job was cancelled")]
pub struct Cancelled;

impl Progress {
    /// A job's progress whose [`Progress::commit`] goes through `gate`.
    pub(super) fn with_gate(gate: Gate) -> Progress {
        Progress {
            gate: Some(gate),
            ..Progress::default()
        }
    }

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

    /// The job's id (`None` for a bare `Progress`, e.g. in tests).
    pub fn job_id(&self) -> Option<&str> {
        self.gate.as_ref().map(|g| g.id.as_str())
    }

    /// The claim of the job this worker runs (1 for the first; 0 for a bare `Progress`):
    /// what a write of the job's outcome must carry (`store::JobDone::epoch`).
    pub fn epoch(&self) -> i64 {
        self.gate
            .as_ref()
            .map_or(0, |g| g.epoch.load(Ordering::Relaxed))
    }

    pub(super) fn set_epoch(&self, epoch: i64) {
        if let Some(g) = &self.gate {
            g.epoch.store(epoch, Ordering::Relaxed);
        }
    }

    /// Says that the work failed because the database was unreachable (a cut connection,
    /// a failover): the job is then put back in the queue to run again (when its input is
    /// stored) instead of ending `failed`.
    pub fn retry_later(&self) {
        self.retry.store(true, Ordering::Relaxed);
    }

    /// True once [`Progress::retry_later`] was called.
    pub fn wants_retry(&self) -> bool {
        self.retry.load(Ordering::Relaxed)
    }

    /// True once the job must stop: a client cancelled it (`DELETE /v1/jobs/{id}` on any
    /// instance) or it ran longer than `--job-timeout` ([`Progress::timed_out`]).
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }

    /// True when the job was stopped because it ran longer than `--job-timeout`.
    pub fn timed_out(&self) -> bool {
        self.timed_out.load(Ordering::Relaxed)
    }

    pub(super) fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
    }

    /// Stops the job for running longer than `timeout`.
    pub(super) fn time_out(&self) {
        self.timed_out.store(true, Ordering::Relaxed);
        self.cancel();
    }

    /// The error sentence of a job its should-stop check ended.
    pub(super) fn stop_sentence(&self, timeout: Option<Duration>) -> String {
        match (self.timed_out(), timeout) {
            (true, Some(t)) => format!(
                "stopped: the job ran longer than the server's --job-timeout ({} s); \
                 split the input or ask the operator for a longer timeout",
                t.as_secs_f64()
            ),
            _ => "the job was cancelled".to_string(),
        }
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
        match g
            .runtime
            .block_on(g.store.claim_job_commit(&g.id, self.epoch()))
        {
            Ok(true) => Ok(()),
            Ok(false) => {
                self.cancel();
                Err(Cancelled)
            }
            Err(e) => {
                // Cannot tell: refuse to store rather than store behind a cancellation; a
                // database outage puts the job back in the queue.
                tracing::warn!(job = %g.id, "cannot claim the job's commit: {e:#}");
                if crate::store::database_outage(&e).is_some() {
                    self.retry_later();
                }
                Err(Cancelled)
            }
        }
    }
}

/// What [`JobPool::cancel`](super::JobPool::cancel) did.
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
    /// The instance running it or that ran it last (null while queued unclaimed).
    pub instance: Option<String>,
    /// How many times an instance took it (more than 1: taken back and run again).
    pub attempts: i64,
    /// The claims counted against the limit of [`super::MAX_ATTEMPTS`]: the crashes of
    /// instances running it, plus the running claim. Claims given back through no fault of
    /// the job (a database outage, a lost claim answer, a graceful stop) do not count.
    pub counted_attempts: i64,
    /// The X-Request-Id of the request that queued it (the `request_id` of its log lines).
    pub request_id: Option<String>,
}

impl JobStatus {
    pub(super) fn of(rec: JobRecord, live: Option<f64>) -> JobStatus {
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
            instance: Some(rec.owner).filter(|o| !o.is_empty()),
            attempts: rec.attempts,
            counted_attempts: rec.counted_attempts,
            request_id: rec.request_id,
        }
    }
}
