//! Job records: state, result and error of background jobs, persisted so that a restart
//! reports jobs it interrupted as failed instead of losing them, and so that any instance
//! sharing the database can list or cancel them.
//!
//! States: `queued` → `running` → (`storing` →) `done` | `failed`, or `cancelled` from
//! `queued`, `running`. `storing` is the short window in which a job writes what it made (a
//! model); it is entered with a conditional update ([`Store::claim_job_commit`]) that races
//! atomically with [`Store::cancel_job`], so a cancelled job never stores anything and a job
//! that stored its model is not reported cancelled. Clients see `storing` as `running`.
//!
//! Ownership: a job with stored `input` is queued unowned (`owner = ''`) and taken by
//! whichever instance claims it first ([`Store::claim_job`]: `FOR UPDATE SKIP LOCKED` on
//! PostgreSQL, a conditional update on SQLite, so one claim wins); an in-process job (no
//! input) belongs to its submitter from the start. Every later write by the worker (progress,
//! commit gate, outcome) is fenced in the same statement: `owner` is still this instance,
//! `attempts` is still the claim the worker runs (its epoch: a job taken back and claimed
//! again, even by the same instance, refuses the earlier claim's writes), and this
//! instance's lease holds (`instances.rs`). So a worker whose job was taken away, or whose
//! instance lapsed, can no longer store anything.
//!
//! Stored input lives in its own table, `job_inputs` (one row per job that has one): kept in
//! `jobs`, it was rewritten with the row by every progress report on SQLite, which rewrites a
//! whole record on UPDATE (migrations/*/0005).
//!
//! Bounded storage (issue 25): a job's input is dropped as soon as it ends, and
//! [`Store::prune_jobs`] (`job_list.rs`, with the reads) deletes the jobs that ended longer ago than the retention, so the
//! table holds the unfinished jobs' inputs and the retained jobs' results, nothing more.

use anyhow::{Context, Result};
use serde::Serialize;
use sqlx::any::AnyRow;
use sqlx::{AssertSqlSafe, Row};

use super::database::{Store, now_ms};

/// A background job as stored.
#[derive(Clone, Debug, Serialize)]
pub struct JobRecord {
    /// Job id.
    pub id: String,
    /// What the job does (e.g. `step_error_training`).
    pub kind: String,
    /// `queued`, `running`, `storing`, `done`, `failed` or `cancelled`.
    pub state: String,
    /// Fraction done, 0..1 (last stored value).
    pub progress: f64,
    /// The result JSON when done.
    pub result: Option<serde_json::Value>,
    /// Why it failed.
    pub error: Option<String>,
    /// Creation time, Unix ms.
    pub created_at_ms: i64,
    /// Last change, Unix ms.
    pub updated_at_ms: i64,
    /// When a worker took it, Unix ms.
    pub started_at_ms: Option<i64>,
    /// When it ended (done, failed or cancelled), Unix ms.
    pub finished_at_ms: Option<i64>,
    /// The instance running it or that ran it last (empty while queued unclaimed).
    pub owner: String,
    /// How many times an instance claimed it (more than 1: taken back and run again).
    pub attempts: i64,
    /// The claims counted against the attempt limit ([`crate::jobs::MAX_ATTEMPTS`]): all
    /// but those given back through no fault of the job (a database outage, a lost claim
    /// answer, a graceful stop), so the crashes of instances running it plus the running
    /// claim.
    pub counted_attempts: i64,
    /// Its place in the order jobs were recorded (numbered by the database; the job list's
    /// cursor).
    pub seq: i64,
    /// The X-Request-Id of the request that queued it (none for jobs of earlier releases).
    pub request_id: Option<String>,
}

/// A job taken from the queue by [`Store::claim_job`].
#[derive(Clone, Debug)]
pub struct ClaimedJob {
    /// Job id.
    pub id: String,
    /// Its kind (names the runner).
    pub kind: String,
    /// Its stored input (JSON text).
    pub input: String,
    /// Which claim of the job this is (1 for the first): the epoch every later write by
    /// this worker carries, so a worker of an earlier claim can no longer write.
    pub attempts: i64,
    /// The X-Request-Id of the request that queued it, for the run's log lines.
    pub request_id: Option<String>,
}

/// What [`Store::cancel_job`] found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CancelOutcome {
    /// The job was queued or running and is now `cancelled`.
    Cancelled,
    /// The job had already ended (or is storing its result): its state.
    Ended(String),
    /// No such job.
    Unknown,
}

/// The job states that count as unfinished (a worker may still be on them).
const UNFINISHED: &str = "('queued', 'running', 'storing')";

/// The condition "the job has stored input" on a row of `jobs`.
pub(super) const HAS_INPUT: &str = "id IN (SELECT id FROM job_inputs)";

/// The claims a job may have in all, whatever ended them. Claims given back through no
/// fault of the job do not count against the attempt limit (migrations/*/0007), so this
/// bound alone stops a job that keeps meeting outages or stops from circulating for ever:
/// past it, the job ends `failed` instead of going back to the queue.
pub const MAX_CLAIMS: i64 = 20;

/// `SET` clause giving a claim back to the queue through no fault of the job: it runs again
/// (from the start) and the claim is not counted against the attempt limit.
pub(super) const GIVE_BACK: &str = "state = 'queued', owner = '', progress = 0.0, \
     started_at = NULL, free_claims = free_claims + 1";

pub(super) const COLUMNS: &str = "id, kind, state, progress, result, error, created_at, updated_at, \
                       started_at, finished_at, owner, attempts, attempts - free_claims, seq, \
                       request_id";

pub(super) fn record(row: &AnyRow) -> Result<JobRecord> {
    let result: Option<String> = row.try_get(4)?;
    Ok(JobRecord {
        id: row.try_get(0)?,
        kind: row.try_get(1)?,
        state: row.try_get(2)?,
        progress: row.try_get(3)?,
        result: result
            .map(|r| serde_json::from_str::<serde_json::Value>(&r))
            .transpose()
            .context("stored job result is not JSON")?,
        error: row.try_get(5)?,
        created_at_ms: row.try_get(6)?,
        updated_at_ms: row.try_get(7)?,
        started_at_ms: row.try_get(8)?,
        finished_at_ms: row.try_get(9)?,
        owner: row.try_get(10)?,
        attempts: row.try_get(11)?,
        counted_attempts: row.try_get(12)?,
        seq: row.try_get(13)?,
        request_id: row.try_get(14)?,
    })
}

impl Store {
    /// Records a new queued job: with `input` (JSON text) any instance may claim it
    /// ([`Store::claim_job`]); without, it is this instance's in-process job.
    pub async fn insert_job(&self, id: &str, kind: &str, input: Option<&str>) -> Result<()> {
        self.insert_job_for(id, kind, input, None).await.map(|_| ())
    }

    /// [`Store::insert_job`] for the request whose X-Request-Id is `request_id`. False when
    /// a job with this id exists already (a retry of a keyed submission): nothing is written.
    pub async fn insert_job_for(
        &self,
        id: &str,
        kind: &str,
        input: Option<&str>,
        request_id: Option<&str>,
    ) -> Result<bool> {
        let now = now_ms();
        let owner = if input.is_some() { "" } else { self.instance() };
        let mut tx = self.db.begin().await.context("cannot record the job")?;
        // `seq` is the database's: PostgreSQL's column default takes the next value of its
        // sequence; SQLite, whose writers are serialised, numbers it in the statement.
        let seq = match self.backend() {
            super::Backend::Postgres => "DEFAULT",
            super::Backend::Sqlite => "(SELECT COALESCE(MAX(seq), 0) + 1 FROM jobs)",
        };
        let inserted = sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO jobs (id, kind, state, progress, owner, created_at, updated_at, seq, \
             request_id) VALUES ($1, $2, 'queued', 0.0, $3, $4, $5, {seq}, $6) \
             ON CONFLICT (id) DO NOTHING"
        )))
        .bind(id.to_string())
        .bind(kind.to_string())
        .bind(owner.to_string())
        .bind(now)
        .bind(now)
        .bind(request_id.map(str::to_string))
        .execute(&mut *tx)
        .await
        .context("cannot record the job")?
        .rows_affected();
        if inserted == 0 {
            return Ok(false);
        }
        if let Some(input) = input {
            sqlx::query("INSERT INTO job_inputs (id, input) VALUES ($1, $2)")
                .bind(id.to_string())
                .bind(input.to_string())
                .execute(&mut *tx)
                .await
                .context("cannot store the job's input")?;
        }
        tx.commit().await.context("cannot record the job")?;
        Ok(true)
    }

    /// Marks a queued job of this instance running (start time now): its epoch (the claim
    /// number, see the module doc), or `None` when it is no longer queued here (it was
    /// cancelled meanwhile): the worker must then not run it.
    pub async fn start_job(&self, id: &str) -> Result<Option<i64>> {
        let now = now_ms();
        let n: Option<i64> = sqlx::query_scalar(
            "UPDATE jobs SET state = 'running', started_at = $1, updated_at = $2, \
             attempts = attempts + 1 WHERE id = $3 AND state = 'queued' AND owner = $4 \
             RETURNING attempts",
        )
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .bind(self.instance().to_string())
        .fetch_optional(&self.db)
        .await
        .context("cannot mark the job running")?;
        Ok(n)
    }

    /// The epoch of a job this instance runs (`running` or `storing`, owned here), `None`
    /// otherwise: after a [`Store::start_job`] whose answer was lost (the connection cut),
    /// tells whether it took effect.
    pub async fn running_here(&self, id: &str) -> Result<Option<i64>> {
        let n: Option<i64> = sqlx::query_scalar(
            "SELECT attempts FROM jobs WHERE id = $1 AND owner = $2 \
             AND state IN ('running', 'storing')",
        )
        .bind(id.to_string())
        .bind(self.instance().to_string())
        .fetch_optional(&self.db)
        .await
        .context("cannot read the job")?;
        Ok(n)
    }

    /// Takes the oldest queued job with stored input whose kind is in `kinds`, marking it
    /// running on this instance; `None` when there is none. On PostgreSQL the row is chosen
    /// with `FOR UPDATE SKIP LOCKED`, so instances claiming at once take different jobs; on
    /// SQLite writes are serialised and the update is conditional on the job still being
    /// queued. Either way a job is claimed by one instance at a time.
    /// An instance whose lease lapsed claims nothing ([`Store::fenced`]).
    pub async fn claim_job(&self, kinds: &[String]) -> Result<Option<ClaimedJob>> {
        if kinds.is_empty() || self.fenced() {
            return Ok(None);
        }
        let marks: Vec<String> = (0..kinds.len()).map(|i| format!("${}", i + 4)).collect();
        let lock = match self.backend() {
            super::Backend::Postgres => " FOR UPDATE SKIP LOCKED",
            super::Backend::Sqlite => "",
        };
        let sql = format!(
            "UPDATE jobs SET state = 'running', owner = $1, started_at = $2, updated_at = $3, \
             attempts = attempts + 1 \
             WHERE state = 'queued' AND id = (SELECT id FROM jobs WHERE state = 'queued' \
             AND {HAS_INPUT} AND kind IN ({}) ORDER BY created_at, id LIMIT 1{lock}) \
             RETURNING id, kind, attempts, request_id",
            marks.join(", ")
        );
        let now = now_ms();
        let mut q = sqlx::query(AssertSqlSafe(sql))
            .bind(self.instance().to_string())
            .bind(now)
            .bind(now);
        for k in kinds {
            q = q.bind(k.clone());
        }
        let Some(row) = q
            .fetch_optional(&self.db)
            .await
            .context("cannot claim a job")?
        else {
            return Ok(None);
        };
        let id: String = row.try_get(0)?;
        let (kind, attempts) = (row.try_get(1)?, row.try_get(2)?);
        let request_id: Option<String> = row.try_get(3)?;
        let input: Option<String> =
            sqlx::query_scalar("SELECT input FROM job_inputs WHERE id = $1")
                .bind(id.clone())
                .fetch_optional(&self.db)
                .await
                .context("cannot read the claimed job's input")?;
        // No input: the job was cancelled between the claim and this read (its input goes
        // when it ends), so there is nothing to run.
        Ok(input.map(|input| ClaimedJob {
            id,
            kind,
            input,
            attempts,
            request_id,
        }))
    }

    /// Queued jobs with stored input (waiting for any instance's worker).
    pub async fn count_queued_jobs(&self) -> Result<u64> {
        let n: i64 = sqlx::query_scalar(AssertSqlSafe(format!(
            "SELECT COUNT(*) FROM jobs WHERE state = 'queued' AND {HAS_INPUT}"
        )))
        .fetch_one(&self.db)
        .await?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    /// Stores a running job's progress, so every instance can answer it. False when the job
    /// is no longer running on this instance in claim `epoch` (cancelled, or taken back
    /// after this instance was judged gone) or this instance's lease lapsed: its worker
    /// should stop.
    pub async fn report_job_progress(&self, id: &str, epoch: i64, progress: f64) -> Result<bool> {
        let fence = super::instances::lease_held_sql(self.backend(), "$4");
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET progress = $1, updated_at = $2 \
             WHERE id = $3 AND owner = $4 AND attempts = $5 AND state IN ('running', 'storing') \
             AND {fence}"
        )))
        .bind(progress)
        .bind(now_ms())
        .bind(id.to_string())
        .bind(self.instance().to_string())
        .bind(epoch)
        .execute(&self.db)
        .await?
        .rows_affected();
        Ok(n == 1)
    }

    /// Moves a running job of this instance (claim `epoch`) to `storing` just before it
    /// writes what it made. False when the job was cancelled (or is not running here in
    /// that claim), or when this instance's lease expired (the fence, checked by the
    /// database in the same statement; the job then goes back to the queue like a crashed
    /// instance's): the caller must then store nothing.
    pub async fn claim_job_commit(&self, id: &str, epoch: i64) -> Result<bool> {
        let fence = super::instances::lease_held_sql(self.backend(), "$3");
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'storing', updated_at = $1 \
             WHERE id = $2 AND state = 'running' AND owner = $3 AND attempts = $4 AND {fence}"
        )))
        .bind(now_ms())
        .bind(id.to_string())
        .bind(self.instance().to_string())
        .bind(epoch)
        .execute(&self.db)
        .await
        .context("cannot update the job")?
        .rows_affected();
        Ok(n == 1)
    }

    /// Ends an unfinished job of this instance (claim `epoch`) as `done` (with its result)
    /// or `failed` (with its error). A job that was cancelled or taken back meanwhile keeps
    /// its state, and so does every job of an instance whose lease lapsed (returns false).
    /// Idempotent: a retry after an answer lost to a cut connection changes nothing.
    pub async fn finish_job(
        &self,
        id: &str,
        epoch: i64,
        state: &str,
        progress: f64,
        result: Option<&serde_json::Value>,
        error: Option<&str>,
    ) -> Result<bool> {
        let now = now_ms();
        let fence = super::instances::lease_held_sql(self.backend(), "$8");
        // The outcome and the input's removal commit together: a retry after a failed
        // removal would match no row (the job has ended) and leave the input behind.
        let mut tx = self.db.begin().await.context("cannot update the job")?;
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = $1, progress = $2, result = $3, error = $4, updated_at = $5, \
             finished_at = $6 WHERE id = $7 AND owner = $8 AND attempts = $9 \
             AND state IN {UNFINISHED} AND {fence}"
        )))
        .bind(state.to_string())
        .bind(progress)
        .bind(result.map(|r| r.to_string()))
        .bind(error.map(str::to_string))
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .bind(self.instance().to_string())
        .bind(epoch)
        .execute(&mut *tx)
        .await
        .context("cannot update the job")?
        .rows_affected();
        if n == 1 {
            sqlx::query("DELETE FROM job_inputs WHERE id = $1")
                .bind(id.to_string())
                .execute(&mut *tx)
                .await
                .context("cannot drop the job's input")?;
        }
        tx.commit().await.context("cannot update the job")?;
        Ok(n == 1)
    }

    /// Puts a stored job this instance runs (claim `epoch`) back in the queue, for any
    /// instance to run again: its work met a database outage and could not store its
    /// outcome. False when it is not this instance's to give back (cancelled, taken back,
    /// in-process: no stored input) or when it had [`MAX_CLAIMS`] claims. The claim is
    /// not counted against the attempt limit (the outage is not the job's fault).
    pub async fn requeue_job(&self, id: &str, epoch: i64) -> Result<bool> {
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET {GIVE_BACK}, \
             updated_at = $1 WHERE id = $2 AND owner = $3 AND attempts = $4 \
             AND state IN ('running', 'storing') AND {HAS_INPUT} AND attempts < {MAX_CLAIMS}"
        )))
        .bind(now_ms())
        .bind(id.to_string())
        .bind(self.instance().to_string())
        .bind(epoch)
        .execute(&self.db)
        .await
        .context("cannot put the job back in the queue")?
        .rows_affected();
        Ok(n == 1)
    }

    /// Puts back in the queue the stored jobs the database says this instance runs but
    /// which are not in `running` (the ids of the jobs its workers run): claims whose answer
    /// was lost to a cut connection, which no worker of this instance will ever run. Call
    /// from the claim loop only (between claims). Returns how many. The lost claims are not
    /// counted against the attempt limit; a job past [`MAX_CLAIMS`] stays for the orphan
    /// sweep ([`Store::release_orphans`]), which fails it.
    pub async fn release_lost_claims(&self, running: &[String]) -> Result<u64> {
        let marks: Vec<String> = (0..running.len()).map(|i| format!("${}", i + 3)).collect();
        let not_in = if marks.is_empty() {
            String::new()
        } else {
            format!(" AND id NOT IN ({})", marks.join(", "))
        };
        let sql = format!(
            "UPDATE jobs SET {GIVE_BACK}, updated_at = $1 WHERE owner = $2 \
             AND state = 'running' AND {HAS_INPUT} AND attempts < {MAX_CLAIMS}{not_in}"
        );
        let mut q = sqlx::query(AssertSqlSafe(sql))
            .bind(now_ms())
            .bind(self.instance().to_string());
        for id in running {
            q = q.bind(id.clone());
        }
        let n = q
            .execute(&self.db)
            .await
            .context("cannot release lost claims")?
            .rows_affected();
        Ok(n)
    }

    /// Cancels a queued or running job (any instance's): it ends `cancelled` at once and its
    /// worker, when it looks, stores nothing. The caller then drops its input
    /// ([`Store::drop_job_input`]; [`Store::prune_jobs`] drops any an interruption left).
    pub async fn cancel_job(&self, id: &str) -> Result<CancelOutcome> {
        let now = now_ms();
        let n = sqlx::query(
            "UPDATE jobs SET state = 'cancelled', error = 'cancelled by a client', \
             updated_at = $1, finished_at = $2 \
             WHERE id = $3 AND state IN ('queued', 'running')",
        )
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .execute(&self.db)
        .await
        .context("cannot cancel the job")?
        .rows_affected();
        if n == 1 {
            return Ok(CancelOutcome::Cancelled);
        }
        Ok(match self.get_job(id).await? {
            Some(rec) => CancelOutcome::Ended(rec.state),
            None => CancelOutcome::Unknown,
        })
    }

    /// Drops the stored input of job `id` (no-op when it has none): called once the job
    /// ended, by [`Store::finish_job`] and after [`Store::cancel_job`].
    pub async fn drop_job_input(&self, id: &str) -> Result<()> {
        sqlx::query("DELETE FROM job_inputs WHERE id = $1")
            .bind(id.to_string())
            .execute(&self.db)
            .await
            .context("cannot drop the job's input")?;
        Ok(())
    }
}
