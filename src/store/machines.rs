//! Machine definitions: the JSON document exactly as PUT.

use anyhow::{Context, Result};
use serde::Serialize;
use sqlx::Row;

use super::database::{Store, now_ms};

/// One line of the machine list.
#[derive(Clone, Debug, Serialize)]
pub struct MachineSummary {
    /// Machine id.
    pub id: String,
    /// The stored definition.
    pub definition: serde_json::Value,
}

impl Store {
    /// Creates or replaces a machine; returns `true` when it was created.
    pub async fn put_machine(&self, machine: &str, definition: &serde_json::Value) -> Result<bool> {
        let body = definition.to_string();
        let now = now_ms();
        // Insert first, update when the id is taken: two PUTs of a new machine that race both
        // succeed (one creates, the other replaces), where update-then-insert let the second
        // insert fail on the taken key.
        let mut tx = self.db.begin().await?;
        let created = sqlx::query(
            "INSERT INTO machines (id, definition, created_at, updated_at) VALUES ($1, $2, $3, $4) \
             ON CONFLICT (id) DO NOTHING",
        )
        .bind(machine.to_string())
        .bind(body.clone())
        .bind(now)
        .bind(now)
        .execute(&mut *tx)
        .await?
        .rows_affected()
            == 1;
        if !created {
            sqlx::query("UPDATE machines SET definition = $1, updated_at = $2 WHERE id = $3")
                .bind(body)
                .bind(now)
                .bind(machine.to_string())
                .execute(&mut *tx)
                .await?;
        }
        tx.commit().await?;
        Ok(created)
    }

    /// The definition JSON exactly as PUT (unknown fields preserved), or `None`.
    pub async fn get_machine(&self, machine: &str) -> Result<Option<serde_json::Value>> {
        let row = sqlx::query("SELECT definition FROM machines WHERE id = $1")
            .bind(machine.to_string())
            .fetch_optional(&self.db)
            .await?;
        match row {
            None => Ok(None),
            Some(row) => {
                let text: String = row.try_get(0)?;
                Ok(Some(
                    serde_json::from_str(&text).context("stored machine definition is not JSON")?,
                ))
            }
        }
    }

    /// True when the machine exists (its definition is not read).
    pub async fn machine_exists(&self, machine: &str) -> Result<bool> {
        let n: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM machines WHERE id = $1")
            .bind(machine.to_string())
            .fetch_one(&self.db)
            .await?;
        Ok(n > 0)
    }

    /// Every machine, ordered by id.
    pub async fn list_machines(&self) -> Result<Vec<MachineSummary>> {
        let rows = sqlx::query("SELECT id, definition FROM machines ORDER BY id")
            .fetch_all(&self.db)
            .await?;
        rows.into_iter()
            .map(|row| {
                let id: String = row.try_get(0)?;
                let text: String = row.try_get(1)?;
                Ok(MachineSummary {
                    id,
                    definition: serde_json::from_str(&text)
                        .context("stored machine definition is not JSON")?,
                })
            })
            .collect()
    }

    /// Deletes a machine with its surfaces, measurements, documents, model records and
    /// model files; returns `false` if it did not exist.
    pub async fn delete_machine(&self, machine: &str) -> Result<bool> {
        let mut tx = self.db.begin().await?;
        // Children first: explicit deletes keep PostgreSQL and SQLite identical even where
        // a connection runs without foreign-key enforcement.
        for sql in [
            "DELETE FROM measurements WHERE machine = $1",
            "DELETE FROM surfaces WHERE machine = $1",
            "DELETE FROM docs WHERE machine = $1",
            "DELETE FROM model_versions WHERE machine = $1",
            "DELETE FROM models WHERE machine = $1",
            "DELETE FROM iso230_runs WHERE machine = $1",
        ] {
            sqlx::query(sql)
                .bind(machine.to_string())
                .execute(&mut *tx)
                .await?;
        }
        let n = sqlx::query("DELETE FROM machines WHERE id = $1")
            .bind(machine.to_string())
            .execute(&mut *tx)
            .await?
            .rows_affected();
        tx.commit().await?;
        self.models().remove_machine_files(machine).await?;
        Ok(n > 0)
    }
}
