//! Idempotency keys (the `Idempotency-Key` header, IETF httpapi draft): per (scope, key) the
//! request that holds the key while it runs, then its answer, kept [`IDEMPOTENCY_KEEP`] and
//! pruned by the periodic pruning task.
//!
//! A key is claimed by `INSERT ... ON CONFLICT DO NOTHING`: of requests that race, exactly one
//! claims it, whatever the backend and however many instances share the database.

use std::time::Duration;

use anyhow::{Context, Result};
use sqlx::Row;

use super::database::{Store, now_ms};

/// How long an answered key is kept (and replayed) before it is pruned: 24 h.
pub const IDEMPOTENCY_KEEP: Duration = Duration::from_secs(24 * 3600);

/// A key held this long by a request that never answered (its instance died) is taken over
/// by the next request with it: longer than any request may take (a 160 MiB body at the
/// slowest accepted rate, 64 KiB/s, takes 43 min).
pub const IN_FLIGHT_STALE: Duration = Duration::from_secs(3600);

/// The answer kept for a key.
#[derive(Clone, Debug, PartialEq)]
pub struct KeptAnswer {
    /// HTTP status.
    pub status: u16,
    /// The headers replayed with it (`Location`, `Content-Type`), as (name, value).
    pub headers: Vec<(String, String)>,
    /// The body, as sent.
    pub body: Vec<u8>,
}

/// What [`Store::claim_idempotency_key`] found.
#[derive(Clone, Debug, PartialEq)]
pub enum Claim {
    /// This request holds the key: answer it, then [`Store::keep_idempotent_answer`] or
    /// [`Store::release_idempotency_key`] with this claim.
    Claimed(String),
    /// Another request with the key has not been answered yet.
    InFlight,
    /// The key's first request was answered: its fingerprint and answer.
    Answered {
        /// Fingerprint of the first request (hex SHA-256 of its query and body).
        fingerprint: String,
        /// The first answer.
        answer: KeptAnswer,
    },
}

fn ms(d: Duration) -> i64 {
    i64::try_from(d.as_millis()).unwrap_or(i64::MAX)
}

impl Store {
    /// Claims `key` in `scope` for a new request, or says who has it: a request in flight, or
    /// the answered first request. A key answered longer than [`IDEMPOTENCY_KEEP`] ago (not
    /// yet pruned) counts as free; one in flight longer than [`IN_FLIGHT_STALE`] is taken over.
    pub async fn claim_idempotency_key(&self, scope: &str, key: &str) -> Result<Claim> {
        // `instance/uuid`: a key whose holder's instance is gone is taken over at once.
        let claim = format!("{}/{}", self.instance(), uuid::Uuid::now_v7());
        // A few turns: the row may be released or expire between the insert and the read.
        for _ in 0..5 {
            let now = now_ms();
            let inserted = sqlx::query(
                "INSERT INTO idempotency_keys (scope, key, claim, created_at) \
                 VALUES ($1, $2, $3, $4) ON CONFLICT (scope, key) DO NOTHING",
            )
            .bind(scope.to_string())
            .bind(key.to_string())
            .bind(claim.clone())
            .bind(now)
            .execute(&self.db)
            .await
            .context("cannot record an idempotency key")?
            .rows_affected();
            if inserted == 1 {
                return Ok(Claim::Claimed(claim));
            }
            let row = sqlx::query(
                "SELECT claim, status, fingerprint, headers, body, created_at \
                 FROM idempotency_keys WHERE scope = $1 AND key = $2",
            )
            .bind(scope.to_string())
            .bind(key.to_string())
            .fetch_optional(&self.db)
            .await?;
            let Some(row) = row else { continue };
            let holder: String = row.try_get(0)?;
            let status: Option<i64> = row.try_get(1)?;
            let created_at: i64 = row.try_get(5)?;
            let stale = match status {
                None => {
                    created_at < now - ms(IN_FLIGHT_STALE) || !self.holder_lives(&holder).await?
                }
                Some(_) => created_at < now - ms(IDEMPOTENCY_KEEP),
            };
            if stale {
                // Take the row over (if nobody else did meanwhile) as a new claim.
                let n = sqlx::query(
                    "UPDATE idempotency_keys SET claim = $1, created_at = $2, status = NULL, \
                     fingerprint = NULL, headers = NULL, body = NULL \
                     WHERE scope = $3 AND key = $4 AND claim = $5",
                )
                .bind(claim.clone())
                .bind(now)
                .bind(scope.to_string())
                .bind(key.to_string())
                .bind(holder)
                .execute(&self.db)
                .await?
                .rows_affected();
                if n == 1 {
                    return Ok(Claim::Claimed(claim));
                }
                continue;
            }
            let Some(status) = status else {
                return Ok(Claim::InFlight);
            };
            let headers: Option<String> = row.try_get(3)?;
            let headers: Vec<(String, String)> = match headers {
                Some(h) => {
                    serde_json::from_str(&h).context("stored answer headers are not JSON")?
                }
                None => Vec::new(),
            };
            return Ok(Claim::Answered {
                fingerprint: row.try_get::<Option<String>, _>(2)?.unwrap_or_default(),
                answer: KeptAnswer {
                    status: u16::try_from(status).context("stored answer status")?,
                    headers,
                    body: row.try_get::<Option<Vec<u8>>, _>(4)?.unwrap_or_default(),
                },
            });
        }
        anyhow::bail!("the idempotency key '{key}' changed hands five times while it was read")
    }

    /// Keeps the answer of the request that holds `claim` on `key`, with the request's
    /// fingerprint. `false` when the claim was lost (taken over as stale).
    pub async fn keep_idempotent_answer(
        &self,
        scope: &str,
        key: &str,
        claim: &str,
        fingerprint: &str,
        answer: &KeptAnswer,
    ) -> Result<bool> {
        let n = sqlx::query(
            "UPDATE idempotency_keys SET status = $1, headers = $2, body = $3, fingerprint = $4 \
             WHERE scope = $5 AND key = $6 AND claim = $7 AND status IS NULL",
        )
        .bind(i64::from(answer.status))
        .bind(serde_json::to_string(&answer.headers)?)
        .bind(answer.body.clone())
        .bind(fingerprint.to_string())
        .bind(scope.to_string())
        .bind(key.to_string())
        .bind(claim.to_string())
        .execute(&self.db)
        .await
        .context("cannot keep the answer of an idempotency key")?
        .rows_affected();
        Ok(n == 1)
    }

    /// Lets go of `key` held by `claim` without an answer (the request failed or went away):
    /// the next request with the key runs anew.
    pub async fn release_idempotency_key(&self, scope: &str, key: &str, claim: &str) -> Result<()> {
        sqlx::query(
            "DELETE FROM idempotency_keys \
             WHERE scope = $1 AND key = $2 AND claim = $3 AND status IS NULL",
        )
        .bind(scope.to_string())
        .bind(key.to_string())
        .bind(claim.to_string())
        .execute(&self.db)
        .await?;
        Ok(())
    }

    /// Deletes the keys created more than `keep` ago (answered, or abandoned in flight);
    /// returns how many. Idempotent: any number of instances may prune one database.
    pub async fn prune_idempotency_keys(&self, keep: Duration) -> Result<u64> {
        let cutoff = now_ms() - ms(keep);
        let n = sqlx::query("DELETE FROM idempotency_keys WHERE created_at < $1")
            .bind(cutoff)
            .execute(&self.db)
            .await
            .context("cannot prune idempotency keys")?
            .rows_affected();
        Ok(n)
    }

    /// Whether the instance that holds an in-flight claim (`instance/uuid`) still holds its
    /// lease: a request of an instance that died (kill, crash) will never answer, so its key
    /// is free for the retry at once rather than after [`IN_FLIGHT_STALE`]. Claims without
    /// an instance (written before 2026-12-07) count as held.
    async fn holder_lives(&self, claim: &str) -> Result<bool> {
        let Some((instance, _)) = claim.split_once('/') else {
            return Ok(true);
        };
        let held = super::instances::lease_held_sql(self.backend(), "$1");
        let row = sqlx::query(sqlx::AssertSqlSafe(format!(
            "SELECT CAST(CASE WHEN {held} THEN 1 ELSE 0 END AS BIGINT)"
        )))
        .bind(instance.to_string())
        .fetch_one(&self.db)
        .await
        .context("cannot read the lease of an idempotency key's holder")?;
        Ok(row.try_get::<i64, _>(0)? == 1)
    }
}
