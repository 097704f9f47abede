//! Reading the jobs table: one job, its state, pages of the list in the database's order,
//! what the table holds, and the pruning of ended jobs (retention).

use anyhow::{Context, Result};
use serde::Serialize;
use sqlx::{AssertSqlSafe, Row};

use super::database::{Store, now_ms};
use super::jobs::{COLUMNS, JobRecord, record};

/// What the jobs table holds ([`Store::job_bytes`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct JobBytes {
    /// Job rows.
    pub jobs: u64,
    /// Bytes of stored inputs (only unfinished jobs keep theirs).
    pub input_bytes: u64,
    /// Bytes of stored results.
    pub result_bytes: u64,
}

impl Store {
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
    /// and of `kind`, at most `limit`, starting after `after_seq` (the `seq` of the last job
    /// of the previous page: numbered by the database in insertion order, so a job recorded
    /// after the walk began is never placed among the pages already read). `with_result`: also read each job's result (else
    /// `result` is `None`, and the stored results are not read at all).
    pub async fn list_jobs(
        &self,
        state: Option<&str>,
        kind: Option<&str>,
        limit: usize,
        after_seq: Option<i64>,
        with_result: bool,
    ) -> Result<Vec<JobRecord>> {
        let states: Vec<String> = match state {
            Some("running") => vec!["running".into(), "storing".into()],
            Some(s) => vec![s.to_string()],
            None => vec![],
        };
        let columns = if with_result {
            COLUMNS.to_string()
        } else {
            COLUMNS.replacen("result", "CAST(NULL AS TEXT)", 1)
        };
        let mut sql = format!("SELECT {columns} FROM jobs WHERE 1 = 1");
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
        if after_seq.is_some() {
            sql.push_str(&format!(" AND seq < ${}", arg + 1));
        }
        sql.push_str(&format!(" ORDER BY seq DESC LIMIT {}", limit.min(10_000)));
        let mut q = sqlx::query(AssertSqlSafe(sql));
        for s in states {
            q = q.bind(s);
        }
        if let Some(k) = kind {
            q = q.bind(k.to_string());
        }
        if let Some(seq) = after_seq {
            q = q.bind(seq);
        }
        let rows = q.fetch_all(&self.db).await?;
        rows.iter().map(record).collect()
    }

    /// Deletes the jobs that ended (done, failed, cancelled) more than `retention` ago, and
    /// drops the input of every ended job still holding one (jobs failed by an instance's
    /// takeover). Returns how many jobs were deleted. Idempotent, so any number of instances
    /// sharing the database may run it. After a deletion, on PostgreSQL the table is vacuumed
    /// (plain `VACUUM`, no lock beyond a normal write's) so the space is reused at once; on
    /// SQLite the write-ahead log is checkpointed and truncated.
    pub async fn prune_jobs(&self, retention: std::time::Duration) -> Result<u64> {
        let cutoff =
            now_ms().saturating_sub(i64::try_from(retention.as_millis()).unwrap_or(i64::MAX));
        let deleted = sqlx::query(
            "DELETE FROM jobs WHERE state IN ('done', 'failed', 'cancelled') \
             AND COALESCE(finished_at, updated_at) < $1",
        )
        .bind(cutoff)
        .execute(&self.db)
        .await
        .context("cannot delete old jobs")?
        .rows_affected();
        sqlx::query(
            "DELETE FROM job_inputs WHERE id IN \
             (SELECT id FROM jobs WHERE state IN ('done', 'failed', 'cancelled'))",
        )
        .execute(&self.db)
        .await
        .context("cannot drop the inputs of ended jobs")?;
        if deleted > 0 {
            match self.backend() {
                // VACUUM may not run in a transaction block: the simple query protocol.
                super::Backend::Postgres => sqlx::raw_sql("VACUUM jobs")
                    .execute(&self.db)
                    .await
                    .context("cannot vacuum the jobs table")?,
                // The freed pages are reused by later rows; the WAL, which only shrinks when
                // truncated, is brought back to empty (a busy reader just postpones it).
                super::Backend::Sqlite => sqlx::raw_sql("PRAGMA wal_checkpoint(TRUNCATE)")
                    .execute(&self.db)
                    .await
                    .context("cannot checkpoint the write-ahead log")?,
            };
        }
        Ok(deleted)
    }

    /// How many jobs the table holds and the bytes of their stored inputs and results.
    pub async fn job_bytes(&self) -> Result<JobBytes> {
        let row = sqlx::query(
            "SELECT COUNT(*), \
             CAST(COALESCE((SELECT SUM(LENGTH(input)) FROM job_inputs), 0) AS BIGINT), \
             CAST(COALESCE(SUM(LENGTH(result)), 0) AS BIGINT) FROM jobs",
        )
        .fetch_one(&self.db)
        .await
        .context("cannot measure the jobs table")?;
        let n =
            |i: usize| -> Result<u64> { Ok(u64::try_from(row.try_get::<i64, _>(i)?).unwrap_or(0)) };
        Ok(JobBytes {
            jobs: n(0)?,
            input_bytes: n(1)?,
            result_bytes: n(2)?,
        })
    }
}
