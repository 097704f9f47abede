//! Job records: state, result and error of background jobs, persisted so that a restart
//! reports jobs it interrupted as failed instead of losing them, and so that any instance
//! sharing the database can list or cancel them.
//!
//! States: `queued` → `running` → (`storing` →) `done` | `failed`, or `cancelled` from
//! `queued`, `running`. `storing` is the short window in which a job writes what it made (a
//! model); it is entered with a conditional update ([`Store::claim_job_commit`]) that races
//! atomically with [`Store::cancel_job`], so a cancelled job never stores anything and a job
//! that stored its model is not reported cancelled. Clients see `storing` as `running`.

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

const COLUMNS: &str =
    "id, kind, state, progress, result, error, created_at, updated_at, started_at, finished_at";

fn record(row: &AnyRow) -> Result<JobRecord> {
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
    })
}

impl Store {
    /// Records a new queued job owned by this instance.
    pub async fn insert_job(&self, id: &str, kind: &str) -> Result<()> {
        let now = now_ms();
        sqlx::query(
            "INSERT INTO jobs (id, kind, state, progress, owner, created_at, updated_at) \
             VALUES ($1, $2, 'queued', 0.0, $3, $4, $5)",
        )
        .bind(id.to_string())
        .bind(kind.to_string())
        .bind(self.instance().to_string())
        .bind(now)
        .bind(now)
        .execute(&self.db)
        .await
        .context("cannot record the job")?;
        Ok(())
    }

    /// Marks a queued job running (start time now). False when it is no longer queued (it
    /// was cancelled meanwhile): the worker must then not run it.
    pub async fn start_job(&self, id: &str) -> Result<bool> {
        let now = now_ms();
        let n = sqlx::query(
            "UPDATE jobs SET state = 'running', started_at = $1, updated_at = $2 \
             WHERE id = $3 AND state = 'queued'",
        )
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .execute(&self.db)
        .await
        .context("cannot mark the job running")?
        .rows_affected();
        Ok(n == 1)
    }

    /// Moves a running job to `storing` just before it writes what it made. False when the
    /// job was cancelled (or is not running): the caller must then store nothing.
    pub async fn claim_job_commit(&self, id: &str) -> Result<bool> {
        let n = sqlx::query(
            "UPDATE jobs SET state = 'storing', updated_at = $1 WHERE id = $2 AND state = 'running'",
        )
        .bind(now_ms())
        .bind(id.to_string())
        .execute(&self.db)
        .await
        .context("cannot update the job")?
        .rows_affected();
        Ok(n == 1)
    }

    /// Ends an unfinished job as `done` (with its result) or `failed` (with its error). A job
    /// that was cancelled meanwhile keeps its `cancelled` state (returns false).
    pub async fn finish_job(
        &self,
        id: &str,
        state: &str,
        progress: f64,
        result: Option<&serde_json::Value>,
        error: Option<&str>,
    ) -> Result<bool> {
        let now = now_ms();
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = $1, progress = $2, result = $3, error = $4, updated_at = $5, \
             finished_at = $6 WHERE id = $7 AND state IN {UNFINISHED}"
        )))
        .bind(state.to_string())
        .bind(progress)
        .bind(result.map(|r| r.to_string()))
        .bind(error.map(str::to_string))
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .execute(&self.db)
        .await
        .context("cannot update the job")?
        .rows_affected();
        Ok(n == 1)
    }

    /// Cancels a queued or running job (any instance's): it ends `cancelled` at once and its
    /// worker, when it looks, stores nothing.
    pub async fn cancel_job(&self, id: &str) -> Result<CancelOutcome> {
        let now = now_ms();
        let n = sqlx::query(
            "UPDATE jobs SET state = 'cancelled', error = 'cancelled by a client', \
             updated_at = $1, finished_at = $2 WHERE id = $3 AND state IN ('queued', 'running')",
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

    /// The job's stored state only (cheap; the pool polls it to see remote cancellations).
    pub async fn job_state(&self, id: &str) -> Result<Option<String>> {
        let row = sqlx::query("SELECT state FROM jobs WHERE id = $1")
            .bind(id.to_string())
            .fetch_optional(&self.db)
            .await?;
        row.map(|r| r.try_get::<String, _>(0).map_err(Into::into))
            .transpose()
    }

    /// The job, or `None`.
    pub async fn get_job(&self, id: &str) -> Result<Option<JobRecord>> {
        let row = sqlx::query(AssertSqlSafe(format!(
            "SELECT {COLUMNS} FROM jobs WHERE id = $1"
        )))
        .bind(id.to_string())
        .fetch_optional(&self.db)
        .await?;
        row.as_ref().map(record).transpose()
    }

    /// Jobs newest first, optionally only those in `state` (`running` includes `storing`)
    /// and of `kind`, at most `limit`.
    pub async fn list_jobs(
        &self,
        state: Option<&str>,
        kind: Option<&str>,
        limit: usize,
    ) -> Result<Vec<JobRecord>> {
        let states: Vec<String> = match state {
            Some("running") => vec!["running".into(), "storing".into()],
            Some(s) => vec![s.to_string()],
            None => vec![],
        };
        let mut sql = format!("SELECT {COLUMNS} FROM jobs WHERE 1 = 1");
        let mut arg = 0;
        if !states.is_empty() {
            let marks: Vec<String> = states
                .iter()
                .map(|_| {
                    arg += 1;
                    format!("${arg}")
                })
                .collect();
            sql.push_str(&format!(" AND state IN ({})", marks.join(", ")));
        }
        if kind.is_some() {
            arg += 1;
            sql.push_str(&format!(" AND kind = ${arg}"));
        }
        sql.push_str(&format!(
            " ORDER BY created_at DESC, id DESC LIMIT {}",
            limit.min(10_000)
        ));
        let mut q = sqlx::query(AssertSqlSafe(sql));
        for s in states {
            q = q.bind(s);
        }
        if let Some(k) = kind {
            q = q.bind(k.to_string());
        }
        let rows = q.fetch_all(&self.db).await?;
        rows.iter().map(record).collect()
    }

    /// Marks every unfinished job of this instance as failed with `reason`
    /// (at start-up: they were interrupted by a shutdown or crash). Returns how many.
    pub async fn fail_unfinished_jobs(&self, reason: &str) -> Result<u64> {
        let now = now_ms();
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'failed', error = $1, updated_at = $2, finished_at = $3 \
             WHERE owner = $4 AND state IN {UNFINISHED}"
        )))
        .bind(reason.to_string())
        .bind(now)
        .bind(now)
        .bind(self.instance().to_string())
        .execute(&self.db)
        .await?
        .rows_affected();
        Ok(n)
    }
}
