//! ISO 230-2 runs per machine axis: the table evaluated and the answer, as JSON, so that the
//! figures of runs before and after compensation can be listed side by side.

use anyhow::{Context, Result};
use sqlx::Row;

use super::database::{Store, now_ms};

/// One stored ISO 230-2 run.
#[derive(Clone, Debug)]
pub struct Iso230Run {
    /// Run id.
    pub id: String,
    /// Machine axis (`X`, `Y`, …).
    pub axis: String,
    /// The caller's label (e.g. "before compensation").
    pub label: Option<String>,
    /// When it was stored, Unix ms.
    pub created_at_ms: i64,
    /// The table evaluated (JSON).
    pub input: serde_json::Value,
    /// The answer (JSON).
    pub answer: serde_json::Value,
}

fn run_from_row(row: &sqlx::any::AnyRow) -> Result<Iso230Run> {
    let input: String = row.try_get("input")?;
    let answer: String = row.try_get("answer")?;
    Ok(Iso230Run {
        id: row.try_get("id")?,
        axis: row.try_get("axis")?,
        label: row.try_get("label")?,
        created_at_ms: row.try_get("created_at")?,
        input: serde_json::from_str(&input).context("stored ISO 230-2 input is not JSON")?,
        answer: serde_json::from_str(&answer).context("stored ISO 230-2 answer is not JSON")?,
    })
}

const COLUMNS: &str = "id, axis, label, input, answer, created_at";

impl Store {
    /// Stores a run of `machine`'s `axis`; returns the stored run. The machine must exist.
    ///
    /// `id`: `None` = a new id. `Some` (the id an `Idempotency-Key` derives, see
    /// `api::idempotency::KeyedId`): a retry of a request whose first try stored its run
    /// (and whose answer was lost with the instance that gave it) meets that run and returns
    /// it, not a twin (`ON CONFLICT DO NOTHING`, then a read).
    pub async fn put_iso230_run(
        &self,
        machine: &str,
        axis: &str,
        id: Option<&str>,
        label: Option<&str>,
        input: &serde_json::Value,
        answer: &serde_json::Value,
    ) -> Result<Iso230Run> {
        let id = id.map_or_else(|| uuid::Uuid::now_v7().to_string(), str::to_string);
        let now = now_ms();
        let inserted = sqlx::query(
            "INSERT INTO iso230_runs (machine, axis, id, label, input, answer, created_at) \
             VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (machine, axis, id) DO NOTHING",
        )
        .bind(machine.to_string())
        .bind(axis.to_string())
        .bind(id.clone())
        .bind(label.map(str::to_string))
        .bind(input.to_string())
        .bind(answer.to_string())
        .bind(now)
        .execute(&self.db)
        .await
        .with_context(|| format!("cannot store an ISO 230-2 run of {machine}/{axis}"))?
        .rows_affected();
        if inserted == 0 {
            return self
                .get_iso230_run(machine, axis, &id)
                .await?
                .with_context(|| format!("ISO 230-2 run {id} of {machine}/{axis} vanished"));
        }
        Ok(Iso230Run {
            id,
            axis: axis.to_string(),
            label: label.map(str::to_string),
            created_at_ms: now,
            input: input.clone(),
            answer: answer.clone(),
        })
    }

    /// The runs of `machine`'s `axis`, oldest first.
    pub async fn list_iso230_runs(&self, machine: &str, axis: &str) -> Result<Vec<Iso230Run>> {
        let rows = sqlx::query(sqlx::AssertSqlSafe(format!(
            "SELECT {COLUMNS} FROM iso230_runs WHERE machine = $1 AND axis = $2 \
             ORDER BY created_at, id"
        )))
        .bind(machine.to_string())
        .bind(axis.to_string())
        .fetch_all(&self.db)
        .await?;
        rows.iter().map(run_from_row).collect()
    }

    /// One run, or `None`.
    pub async fn get_iso230_run(
        &self,
        machine: &str,
        axis: &str,
        id: &str,
    ) -> Result<Option<Iso230Run>> {
        let row = sqlx::query(sqlx::AssertSqlSafe(format!(
            "SELECT {COLUMNS} FROM iso230_runs WHERE machine = $1 AND axis = $2 AND id = $3"
        )))
        .bind(machine.to_string())
        .bind(axis.to_string())
        .bind(id.to_string())
        .fetch_optional(&self.db)
        .await?;
        row.as_ref().map(run_from_row).transpose()
    }
}
