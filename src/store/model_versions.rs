//! The versions of a model: listing them and rolling back to one (see `models.rs` for how
//! versions are made and kept).

use anyhow::Result;
use serde::Serialize;
use sqlx::Row;

use super::models::ModelStore;

/// One saved version of a model.
#[derive(Clone, Debug, Serialize)]
pub struct ModelVersion {
    /// Version number (1 for the first save, then 2, 3, ...).
    pub version: i64,
    /// Version of the container format.
    pub format_version: i64,
    /// SHA-256 of the payload, hex.
    pub sha256: String,
    /// Payload size in bytes.
    pub bytes: i64,
    /// When it was saved, Unix ms.
    pub created_at_ms: i64,
    /// The job that made it, if a job did.
    pub job: Option<String>,
}

/// A model's kept versions, newest first, and the one served.
#[derive(Clone, Debug, Serialize)]
pub struct ModelVersions {
    /// The version served now.
    pub current: i64,
    /// Kept versions, newest first.
    pub versions: Vec<ModelVersion>,
}

/// What [`ModelStore::rollback`] did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Rollback {
    /// The model now serves that version.
    Done,
    /// There is no such model.
    NoModel,
    /// The model exists but that version is not kept: the versions that are.
    NoVersion(Vec<i64>),
}

impl ModelStore {
    /// The machines that have a machine-level model (no surface) of `kind`, in one query (for
    /// listing machines with what they have).
    pub async fn machines_with(&self, kind: &str) -> Result<std::collections::HashSet<String>> {
        let rows: Vec<String> =
            sqlx::query_scalar("SELECT machine FROM models WHERE surface = $1 AND kind = $2")
                .bind(String::new())
                .bind(kind.to_string())
                .fetch_all(&self.db)
                .await?;
        Ok(rows.into_iter().collect())
    }

    /// The model's kept versions, or `None` if there is no such model.
    pub async fn versions(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
    ) -> Result<Option<ModelVersions>> {
        self.dir_of(machine, surface, kind)?;
        let surface = surface.unwrap_or("").to_string();
        let current: Option<i64> = sqlx::query_scalar(
            "SELECT version FROM models WHERE machine = $1 AND surface = $2 AND kind = $3",
        )
        .bind(machine.to_string())
        .bind(surface.clone())
        .bind(kind.to_string())
        .fetch_optional(&self.db)
        .await?;
        let Some(current) = current else {
            return Ok(None);
        };
        let rows = sqlx::query(
            "SELECT version, format_version, sha256, bytes, created_at, job FROM model_versions \
             WHERE machine = $1 AND surface = $2 AND kind = $3 ORDER BY version DESC",
        )
        .bind(machine.to_string())
        .bind(surface)
        .bind(kind.to_string())
        .fetch_all(&self.db)
        .await?;
        let versions = rows
            .iter()
            .map(|r| -> Result<ModelVersion> {
                Ok(ModelVersion {
                    version: r.try_get(0)?,
                    format_version: r.try_get(1)?,
                    sha256: r.try_get(2)?,
                    bytes: r.try_get(3)?,
                    created_at_ms: r.try_get(4)?,
                    job: r.try_get(5)?,
                })
            })
            .collect::<Result<_>>()?;
        Ok(Some(ModelVersions { current, versions }))
    }

    /// Serves version `version` of the model from now on (on every instance). The versions
    /// made after it are kept, so a rollback can itself be undone; the next save makes a
    /// new version after the highest one.
    pub async fn rollback(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
        version: i64,
    ) -> Result<Rollback> {
        let Some(all) = self.versions(machine, surface, kind).await? else {
            return Ok(Rollback::NoModel);
        };
        let Some(v) = all.versions.iter().find(|v| v.version == version) else {
            return Ok(Rollback::NoVersion(
                all.versions.iter().map(|v| v.version).collect(),
            ));
        };
        // Conditional on the version still existing (a concurrent save may prune it).
        let n = sqlx::query(
            "UPDATE models SET version = $1, format_version = $2, sha256 = $3, bytes = $4, \
             updated_at = $5 WHERE machine = $6 AND surface = $7 AND kind = $8 AND EXISTS \
             (SELECT 1 FROM model_versions WHERE machine = $6 AND surface = $7 AND kind = $8 \
             AND version = $1)",
        )
        .bind(version)
        .bind(v.format_version)
        .bind(v.sha256.clone())
        .bind(v.bytes)
        .bind(super::database::now_ms())
        .bind(machine.to_string())
        .bind(surface.unwrap_or("").to_string())
        .bind(kind.to_string())
        .execute(&self.db)
        .await?
        .rows_affected();
        Ok(if n == 1 {
            Rollback::Done
        } else {
            Rollback::NoVersion(all.versions.iter().map(|v| v.version).collect())
        })
    }
}
