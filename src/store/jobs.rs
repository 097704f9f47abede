//! Job records: state, result and error of background jobs, persisted so that a restart
//! reports jobs it interrupted as failed instead of losing them.

use anyhow::{Context, Result};
use serde::Serialize;
use sqlx::Row;

use super::database::{Store, now_ms};

/// A background job as stored.
#[derive(Clone, Debug, Serialize)]
pub struct JobRecord {
    /// Job id.
    pub id: String,
    /// What the job does (e.g. `step-error-training`).
    pub kind: String,
    /// `queued`, `running`, `done` or `failed`.
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

    /// Sets a job's state and progress (and result or error when it ends).
    pub async fn update_job(
        &self,
        id: &str,
        state: &str,
        progress: f64,
        result: Option<&serde_json::Value>,
        error: Option<&str>,
    ) -> Result<()> {
        sqlx::query(
            "UPDATE jobs SET state = $1, progress = $2, result = $3, error = $4, updated_at = $5 \
             WHERE id = $6",
        )
        .bind(state.to_string())
        .bind(progress)
        .bind(result.map(|r| r.to_string()))
        .bind(error.map(str::to_string))
        .bind(now_ms())
        .bind(id.to_string())
        .execute(&self.db)
        .await
        .context("cannot update the job")?;
        Ok(())
    }

    /// The job, or `None`.
    pub async fn get_job(&self, id: &str) -> Result<Option<JobRecord>> {
        let row = sqlx::query(
            "SELECT kind, state, progress, result, error, created_at, updated_at FROM jobs WHERE id = $1",
        )
        .bind(id.to_string())
        .fetch_optional(&self.db)
        .await?;
        let Some(row) = row else { return Ok(None) };
        let result: Option<String> = row.try_get(3)?;
        Ok(Some(JobRecord {
            id: id.to_string(),
            kind: row.try_get(0)?,
            state: row.try_get(1)?,
            progress: row.try_get(2)?,
            result: result
                .map(|r| serde_json::from_str::<serde_json::Value>(&r))
                .transpose()
                .context("stored job result is not JSON")?,
            error: row.try_get(4)?,
            created_at_ms: row.try_get(5)?,
            updated_at_ms: row.try_get(6)?,
        }))
    }

    /// Marks every queued or running job of this instance as failed with `reason`
    /// (at start-up: they were interrupted by a shutdown or crash). Returns how many.
    pub async fn fail_unfinished_jobs(&self, reason: &str) -> Result<u64> {
        let n = sqlx::query(
            "UPDATE jobs SET state = 'failed', error = $1, updated_at = $2 \
             WHERE owner = $3 AND state IN ('queued', 'running')",
        )
        .bind(reason.to_string())
        .bind(now_ms())
        .bind(self.instance().to_string())
        .execute(&self.db)
        .await?
        .rows_affected();
        Ok(n)
    }
}
