//! Instances and their leases: which processes serving this database are alive.
//!
//! Every process registers a row in `instances` with a lease (`lease_ms`) and renews its
//! `heartbeat_at` well within it ([`Store::heartbeat`]). An instance whose heartbeat is
//! older than its lease is gone (crashed, killed, cut off from the database); any live
//! instance that notices ([`Store::reap_dead_instances`]) re-queues the jobs it was running
//! (when their input is stored and they have attempts left) and fails the rest. Times are
//! read on the database's clock, so the hosts' clocks do not matter.
//!
//! The lease is renewed on a connection of its own (a one-connection pool beside the
//! request pool), within a third of the lease: a request pool exhausted by slow queries does
//! not starve the heartbeat. The reaper runs in a task of its own, on a third connection
//! and with a timeout, so a lock it waits on never delays a renewal. A renewal only extends a lease that has not expired. An instance
//! whose lease lapsed fences itself ([`Store::fenced`]): it claims no job, its commits of
//! job results are refused (the database checks the lease in the same statement), and
//! `/healthz` and `/readyz` say so. Its jobs then go back to the queue like those of a
//! crashed instance, and it registers again on the next heartbeat, with no jobs.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use serde::Serialize;
use sqlx::AssertSqlSafe;

use super::database::Store;
use super::jobs::{GIVE_BACK, HAS_INPUT, MAX_CLAIMS};

/// What this process knows of its own lease (shared by every clone of its [`Store`]).
#[derive(Debug, Default)]
pub(crate) struct LeaseState {
    inner: Mutex<LeaseInner>,
}

#[derive(Debug, Default)]
struct LeaseInner {
    /// The lease, ms; 0 until registered.
    lease_ms: i64,
    /// When the last successful renewal (or registration) was sent: the lease holds for
    /// `lease_ms` from then. The database stamps the renewal later than this instant, so
    /// this process's view expires no later than the other instances' view.
    renewed: Option<Instant>,
    /// Renewals failed in a row, and the last failure.
    failures: u64,
    last_error: Option<String>,
}

impl LeaseState {
    fn lock(&self) -> std::sync::MutexGuard<'_, LeaseInner> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn renewed(&self, at: Instant, lease_ms: i64) {
        let mut l = self.lock();
        l.lease_ms = lease_ms;
        l.renewed = Some(at);
        l.failures = 0;
        l.last_error = None;
    }

    fn failed(&self, lease_ms: i64, error: String) {
        let mut l = self.lock();
        l.lease_ms = lease_ms;
        l.failures += 1;
        l.last_error = Some(error);
    }

    fn lapse(&self) {
        self.lock().renewed = None;
    }

    fn report(&self) -> LeaseReport {
        let l = self.lock();
        let registered = l.lease_ms > 0;
        let lease = Duration::from_millis(u64::try_from(l.lease_ms).unwrap_or(0));
        let age = l.renewed.map(|t| t.elapsed());
        let held = age.is_some_and(|a| a < lease);
        LeaseReport {
            registered,
            held,
            fenced: registered && !held,
            lease_ms: l.lease_ms,
            renewed_ms_ago: age.map(|a| u64::try_from(a.as_millis()).unwrap_or(u64::MAX)),
            failures_in_a_row: l.failures,
            last_error: l.last_error.clone(),
        }
    }
}

/// This instance's lease as `/healthz` reports it.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct LeaseReport {
    /// The instance registered (a store opened by a tool that runs no jobs never does).
    pub registered: bool,
    /// The last renewal is younger than the lease.
    pub held: bool,
    /// Registered but the lease lapsed: this instance claims no job and commits no job
    /// result until it has registered again.
    pub fenced: bool,
    /// The lease, ms (0 until registered).
    pub lease_ms: i64,
    /// Milliseconds since the last successful renewal was sent (`null`: none since the
    /// lease lapsed).
    pub renewed_ms_ago: Option<u64>,
    /// Renewals failed in a row.
    pub failures_in_a_row: u64,
    /// Why the last renewal failed, while renewals fail.
    pub last_error: Option<String>,
}

/// SQL condition: the instance `id_param` (a bind mark such as `$5`) holds an unexpired
/// lease on the database's clock. The statements committing a job's result carry it: the
/// fence a lapsed instance cannot pass.
pub(crate) fn lease_held_sql(backend: super::Backend, id_param: &str) -> String {
    let now = super::database::now_sql(backend);
    format!(
        "EXISTS (SELECT 1 FROM instances WHERE id = {id_param} \
         AND heartbeat_at + lease_ms >= {now})"
    )
}

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
    /// at least every `lease_ms / 3`). Runs on the heartbeat's own connection.
    pub async fn register_instance(&self, lease_ms: i64) -> Result<()> {
        let sent = Instant::now();
        let now = self.now_sql();
        let host = std::env::var("HOSTNAME").unwrap_or_default();
        sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO instances (id, host, started_at, heartbeat_at, lease_ms) \
             VALUES ($1, $2, {now}, {now}, $3)"
        )))
        .bind(self.instance().to_string())
        .bind(host)
        .bind(lease_ms)
        .execute(&self.hb_db)
        .await
        .context("cannot register this instance")?;
        self.lease.renewed(sent, lease_ms);
        Ok(())
    }

    /// Renews this instance's lease, on the heartbeat's own connection and within a third of
    /// the lease (a renewal that takes longer counts as failed). Only an unexpired lease is
    /// renewed:
    /// - renewed: the lease holds for `lease_ms` from when the renewal was sent;
    /// - the lease had expired but its row is still there: this instance stays fenced and
    ///   answers `Ok`, so that the caller's next [`Store::reap_dead_instances`] puts its jobs
    ///   back in the queue (or fails them) and removes its row, as for a crashed instance;
    /// - the row is gone (an instance reaped it): it registers again, with no jobs (the
    ///   jobs it was running are no longer its own: their commits are refused).
    ///
    /// A failure is recorded for `/healthz`; the lease lapses on its own when renewals keep
    /// failing ([`Store::fenced`]).
    pub async fn heartbeat(&self, lease_ms: i64) -> Result<()> {
        let limit = Duration::from_millis(u64::try_from(lease_ms / 3).unwrap_or(0).max(100));
        let result = match tokio::time::timeout(limit, self.renew(lease_ms)).await {
            Ok(r) => r,
            Err(_) => Err(anyhow::anyhow!(
                "renewing the lease took longer than {} ms (a third of the lease)",
                limit.as_millis()
            )),
        };
        if let Err(e) = &result {
            self.lease.failed(lease_ms, format!("{e:#}"));
            if self.fenced() {
                tracing::error!(
                    instance = self.instance(),
                    "lease lapsed (renewals failing: {e:#}): this instance claims and commits \
                     no job until it has registered again"
                );
            }
        }
        result
    }

    async fn renew(&self, lease_ms: i64) -> Result<()> {
        let sent = Instant::now();
        let now = self.now_sql();
        let n = sqlx::query(AssertSqlSafe(format!(
            "UPDATE instances SET heartbeat_at = {now}, lease_ms = $1 \
             WHERE id = $2 AND heartbeat_at + lease_ms >= {now}"
        )))
        .bind(lease_ms)
        .bind(self.instance().to_string())
        .execute(&self.hb_db)
        .await
        .context("cannot renew this instance's lease")?
        .rows_affected();
        if n == 1 {
            self.lease.renewed(sent, lease_ms);
            return Ok(());
        }
        let row: Option<i64> = sqlx::query_scalar("SELECT lease_ms FROM instances WHERE id = $1")
            .bind(self.instance().to_string())
            .fetch_optional(&self.hb_db)
            .await
            .context("cannot read this instance's lease")?;
        if row.is_some() {
            self.lease.lapse();
            tracing::warn!(
                instance = self.instance(),
                "this instance's lease expired before it was renewed: fenced; its jobs go back \
                 to the queue and it registers again at the next heartbeat"
            );
            return Ok(());
        }
        tracing::warn!(
            instance = self.instance(),
            "this instance's lease had expired and its row was removed; registering again"
        );
        self.register_instance(lease_ms).await
    }

    /// True when this instance registered and its lease lapsed (no renewal within the lease,
    /// on this process's clock): it must not claim jobs or commit their results.
    pub fn fenced(&self) -> bool {
        self.lease.report().fenced
    }

    /// This instance's lease (for `/healthz`).
    pub fn lease(&self) -> LeaseReport {
        self.lease.report()
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
    /// stored input goes back to `queued` when fewer than `max_attempts` of its claims count
    /// (this one does: its instance crashed; [`super::jobs::MAX_CLAIMS`] bounds them all);
    /// the others (in-process jobs, or out of attempts) end `failed` with `reason`.
    ///
    /// Runs on a connection of its own (never the request pool's nor the heartbeat's), so a
    /// lock held on `jobs` or an exhausted request pool delays only this; callers bound it
    /// with a timeout (dropping the future rolls the transaction back).
    pub async fn reap_dead_instances(&self, max_attempts: i64, reason: &str) -> Result<Reaped> {
        let now = self.now_sql();
        let live = format!("(SELECT id FROM instances WHERE heartbeat_at + lease_ms >= {now})");
        let mut tx = self.reap_db.begin().await?;
        let requeued = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'queued', owner = '', progress = 0.0, started_at = NULL, \
             updated_at = $1 WHERE state IN {OWNED} AND {HAS_INPUT} \
             AND attempts - free_claims < $2 AND attempts < {MAX_CLAIMS} AND owner NOT IN {live}"
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
             AND (state IN {OWNED} OR (state = 'queued' AND NOT {HAS_INPUT}))"
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
    /// back to the queue (stored input, fewer than [`super::jobs::MAX_CLAIMS`] claims; the
    /// stop is not counted against the attempt limit) or end `failed` with `reason`.
    pub async fn release_own_jobs(&self, reason: &str) -> Result<Reaped> {
        let me = self.instance().to_string();
        let mut tx = self.db.begin().await?;
        let requeued = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET {GIVE_BACK}, updated_at = $1 WHERE state IN {OWNED} \
             AND {HAS_INPUT} AND attempts < {MAX_CLAIMS} AND owner = $2"
        )))
        .bind(super::database::now_ms())
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

    /// Jobs the database says this instance runs (`running` or `storing`) but none of its
    /// workers does (`live`: the ids its workers hold), untouched for `quiet_ms`: a worker
    /// that ended without its outcome recorded (a final write refused by an error that is not
    /// an outage, e.g. a read-only transaction right after a failover). They go back to the
    /// queue (stored input, fewer than [`super::jobs::MAX_CLAIMS`] claims; not counted
    /// against the attempt limit) or end `failed` with `reason`, so no job stays `running`
    /// with no one working on it. On the reaper's connection.
    pub async fn release_orphans(
        &self,
        live: &[String],
        quiet_ms: i64,
        reason: &str,
    ) -> Result<Reaped> {
        let marks: Vec<String> = (0..live.len()).map(|i| format!("${}", i + 4)).collect();
        let not_live = if marks.is_empty() {
            String::new()
        } else {
            format!(" AND id NOT IN ({})", marks.join(", "))
        };
        let now = super::database::now_ms();
        let orphan = format!("owner = $2 AND state IN {OWNED} AND updated_at < $3{not_live}");
        let mut tx = self.reap_db.begin().await?;
        let sql = format!(
            "UPDATE jobs SET {GIVE_BACK}, updated_at = $1 WHERE {orphan} AND {HAS_INPUT} \
             AND attempts < {MAX_CLAIMS}"
        );
        let mut q = sqlx::query(AssertSqlSafe(sql))
            .bind(now)
            .bind(self.instance().to_string())
            .bind(now - quiet_ms);
        for id in live {
            q = q.bind(id.clone());
        }
        let requeued = q.execute(&mut *tx).await?.rows_affected();
        // $1 is the error here, the stamp goes last.
        let stamp_mark = live.len() + 4;
        let sql = format!(
            "UPDATE jobs SET state = 'failed', error = $1, updated_at = ${stamp_mark}, \
             finished_at = ${stamp_mark} WHERE {orphan}"
        );
        let mut q = sqlx::query(AssertSqlSafe(sql))
            .bind(reason.to_string())
            .bind(self.instance().to_string())
            .bind(now - quiet_ms);
        for id in live {
            q = q.bind(id.clone());
        }
        let failed = q.bind(now).execute(&mut *tx).await?.rows_affected();
        tx.commit().await?;
        Ok(Reaped {
            requeued,
            failed,
            instances: 0,
        })
    }
}
