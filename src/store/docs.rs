//! Generic per-machine JSON documents (e.g. kind `decomposition`, key `surface/measurement`).

use anyhow::{Context, Result};
use sqlx::Row;

use super::database::{Store, now_ms};

impl Store {
    /// Creates or replaces the document `(machine, kind, key)`. The machine must exist.
    pub async fn put_doc(
        &self,
        machine: &str,
        kind: &str,
        key: &str,
        body: &serde_json::Value,
    ) -> Result<()> {
        let text = body.to_string();
        let now = now_ms();
        // Insert first, update when the key is taken: two writes that race both succeed.
        let mut tx = self.db.begin().await?;
        let inserted = sqlx::query(
            "INSERT INTO docs (machine, kind, key, body, updated_at) VALUES ($1, $2, $3, $4, $5) \
             ON CONFLICT (machine, kind, key) DO NOTHING",
        )
        .bind(machine.to_string())
        .bind(kind.to_string())
        .bind(key.to_string())
        .bind(text.clone())
        .bind(now)
        .execute(&mut *tx)
        .await
        .with_context(|| format!("cannot store document {kind}/{key} of machine {machine}"))?
        .rows_affected();
        if inserted == 0 {
            sqlx::query(
                "UPDATE docs SET body = $1, updated_at = $2 \
                 WHERE machine = $3 AND kind = $4 AND key = $5",
            )
            .bind(text)
            .bind(now)
            .bind(machine.to_string())
            .bind(kind.to_string())
            .bind(key.to_string())
            .execute(&mut *tx)
            .await?;
        }
        tx.commit().await?;
        Ok(())
    }

    /// The document `(machine, kind, key)`, or `None`.
    pub async fn get_doc(
        &self,
        machine: &str,
        kind: &str,
        key: &str,
    ) -> Result<Option<serde_json::Value>> {
        let row =
            sqlx::query("SELECT body FROM docs WHERE machine = $1 AND kind = $2 AND key = $3")
                .bind(machine.to_string())
                .bind(kind.to_string())
                .bind(key.to_string())
                .fetch_optional(&self.db)
                .await?;
        match row {
            None => Ok(None),
            Some(row) => {
                let text: String = row.try_get(0)?;
                Ok(Some(
                    serde_json::from_str(&text).context("stored document is not JSON")?,
                ))
            }
        }
    }

    /// Deletes the document; returns `false` if it did not exist.
    pub async fn delete_doc(&self, machine: &str, kind: &str, key: &str) -> Result<bool> {
        let n = sqlx::query("DELETE FROM docs WHERE machine = $1 AND kind = $2 AND key = $3")
            .bind(machine.to_string())
            .bind(kind.to_string())
            .bind(key.to_string())
            .execute(&self.db)
            .await?
            .rows_affected();
        Ok(n > 0)
    }
}
