//! Instances and their leases: which processes serving this database are alive.
//!
//! Every process registers a row in `instances` with a lease (`lease_ms`) and renews its
//! `heartbeat_at` well within it ([`Store::heartbeat`]). An instance whose heartbeat is
//! older than its lease is gone (crashed, killed, cut off from the database); any live
//! instance that notices ([`Store::reap_dead_instances`]) re-queues the jobs it was running
//! (when their input is stored and they have attempts left) and fails the rest. Times are
//! read on the database's clock, so the hosts' clocks do not matter.

use anyhow::{Context, Result};
use sqlx::AssertSqlSafe;

use super::database::Store;

/// What [`Store::reap_dead_instances`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reaped {
    /// Jobs of gone instances put back in the queue (another instance will run them).
    pub requeued: u64,
    /// Jobs of gone instances marked failed (no stored input, or out of attempts).
    pub failed: u64,
    /// Gone instances removed from `instances`.
    pub instances: u64,
}

/// The job states a worker may be on (`queued` only for in-process jobs, which nobody
/// else can run).
const OWNED: &str = "('running', 'storing')";

impl Store {
    /// Registers this instance with a lease of `lease_ms` (renew it with [`Store::heartbeat`]
    /// at least every `lease_ms / 3`).
    pub async fn register_instance(&self, lease_ms: i64) -> Result<()> {
        let now = self.now_sql();
        let host = std::env::var("HOSTNAME").unwrap_or_default();
        sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO instances (id, host, started_at, heartbeat_at, lease_ms) \
             VALUES ($1, $2, {now}, {now}, $3)"
        )))
        .bind(self.instance().to_string())
        .bind(host)
        .bind(lease_ms)
        .execute(&self.db)
        .await
        .context("cannot register this instance")?;
        Ok(())
    }

    /// Renews this instance's lease. If another instance already judged it gone (its row was
    /// removed after a long stall), it registers again: the jobs it was running are no
    /// longer its own (their commit gate refuses), but it may take new ones.
    pub async fn heartbeat(&self, lease_ms: i64) -> Result<()> {
        let now = self.now_sql();
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE instances SET heartbeat_at = {now}, lease_ms = $1 WHERE id = $2"
        )))
        .bind(lease_ms)
        .bind(self.instance().to_string())
        .execute(&self.db)
        .await
        .context("cannot renew this instance's lease")?
        .rows_affected();
        if n == 0 {
            tracing::warn!(
                instance = self.instance(),
                "this instance's lease had expired and its row was removed; registering again"
            );
            self.register_instance(lease_ms).await?;
        }
        Ok(())
    }

    /// Removes this instance's row (graceful shutdown): the others know at once it is gone.
    pub async fn deregister_instance(&self) -> Result<()> {
        sqlx::query("DELETE FROM instances WHERE id = $1")
            .bind(self.instance().to_string())
            .execute(&self.db)
            .await?;
        Ok(())
    }

    /// Ids of the instances whose lease has not expired, this one included if registered.
    pub async fn live_instances(&self) -> Result<Vec<String>> {
        let now = self.now_sql();
        let rows: Vec<String> = sqlx::query_scalar(AssertSqlSafe(format!(
            "SELECT id FROM instances WHERE heartbeat_at + lease_ms >= {now} ORDER BY id"
        )))
        .fetch_all(&self.db)
        .await?;
        Ok(rows)
    }

    /// Re-queues or fails the unfinished jobs of every instance that is gone (lease expired,
    /// or never registered: rows of earlier builds), and forgets those instances. A job with
    /// stored input and fewer than `max_attempts` claims goes back to `queued`; the others
    /// (in-process jobs, or out of attempts) end `failed` with `reason`.
    pub async fn reap_dead_instances(&self, max_attempts: i64, reason: &str) -> Result<Reaped> {
        let now = self.now_sql();
        let live = format!("(SELECT id FROM instances WHERE heartbeat_at + lease_ms >= {now})");
        let mut tx = self.db.begin().await?;
        let requeued = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'queued', owner = '', progress = 0.0, started_at = NULL, \
             updated_at = $1 WHERE state IN {OWNED} AND input IS NOT NULL AND attempts < $2 \
             AND owner NOT IN {live}"
        )))
        .bind(super::database::now_ms())
        .bind(max_attempts)
        .execute(&mut *tx)
        .await?
        .rows_affected();
        let stamp = super::database::now_ms();
        let failed = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'failed', error = $1, updated_at = $2, finished_at = $3 \
             WHERE owner <> '' AND owner NOT IN {live} \
             AND (state IN {OWNED} OR (state = 'queued' AND input IS NULL))"
        )))
        .bind(reason.to_string())
        .bind(stamp)
        .bind(stamp)
        .execute(&mut *tx)
        .await?
        .rows_affected();
        let instances = sqlx::query(AssertSqlSafe(format!(
            "DELETE FROM instances WHERE heartbeat_at + lease_ms < {now}"
        )))
        .execute(&mut *tx)
        .await?
        .rows_affected();
        tx.commit().await?;
        Ok(Reaped {
            requeued,
            failed,
            instances,
        })
    }

    /// At a graceful stop: this instance's unfinished jobs that outlived the grace period go
    /// back to the queue (stored input, attempts left) or end `failed` with `reason`.
    pub async fn release_own_jobs(&self, max_attempts: i64, reason: &str) -> Result<Reaped> {
        let me = self.instance().to_string();
        let mut tx = self.db.begin().await?;
        let requeued = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'queued', owner = '', progress = 0.0, started_at = NULL, \
             updated_at = $1 WHERE state IN {OWNED} AND input IS NOT NULL AND attempts < $2 \
             AND owner = $3"
        )))
        .bind(super::database::now_ms())
        .bind(max_attempts)
        .bind(me.clone())
        .execute(&mut *tx)
        .await?
        .rows_affected();
        let stamp = super::database::now_ms();
        let failed = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'failed', error = $1, updated_at = $2, finished_at = $3 \
             WHERE owner = $4 AND (state IN {OWNED} OR state = 'queued')"
        )))
        .bind(reason.to_string())
        .bind(stamp)
        .bind(stamp)
        .bind(me)
        .execute(&mut *tx)
        .await?
        .rows_affected();
        tx.commit().await?;
        Ok(Reaped {
            requeued,
            failed,
            instances: 0,
        })
    }
}
