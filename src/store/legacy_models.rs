//! Models saved before migration 0003 on PostgreSQL: their bytes are a file in the data dir
//! of the instance that trained them (`models/<machine>/.../<kind>.tcm`), and migration
//! 0003 recorded them as version 1 with no bytes in the database. Such an instance copies
//! them into the database when it starts, so that every instance serves them.

use std::path::PathBuf;

use anyhow::{Context, Result};
use sha2::{Digest, Sha256};
use sqlx::Row;

use super::models::{ModelStore, decode_model};

/// A version whose bytes the database does not hold.
struct Missing {
    machine: String,
    surface: String,
    kind: String,
    version: i64,
    sha256: String,
    bytes: i64,
}

/// Why a file was not copied (logged; the version stays as it was).
fn verify(payload: &[u8], m: &Missing) -> Result<(), String> {
    if i64::try_from(payload.len()).ok() != Some(m.bytes) {
        return Err(format!(
            "it holds {} payload bytes, the database recorded {}",
            payload.len(),
            m.bytes
        ));
    }
    let sha = hex::encode(Sha256::digest(payload));
    if !sha.eq_ignore_ascii_case(&m.sha256) {
        return Err(format!(
            "its SHA-256 is {sha}, the database recorded {}",
            m.sha256
        ));
    }
    Ok(())
}

impl ModelStore {
    /// Copies into the database the model versions whose bytes are only in a file of this
    /// data dir (PostgreSQL; models saved before migration 0003). A file is copied when its
    /// container checks (header, format version, SHA-256 of the payload) and its payload
    /// matches the SHA-256 and size the database recorded; otherwise it is left and logged.
    /// Idempotent: only versions without bytes are written, each in one statement
    /// conditional on still having none, so instances starting at once copy each version
    /// once. The files stay (the database is read first from now on). Returns how many
    /// versions were copied.
    pub async fn copy_files_into_database(&self) -> Result<usize> {
        let rows = sqlx::query(
            "SELECT machine, surface, kind, version, sha256, bytes FROM model_versions \
             WHERE data IS NULL ORDER BY machine, surface, kind, version",
        )
        .fetch_all(&self.db)
        .await
        .context("cannot list the model versions saved before migration 0003")?;
        let missing: Vec<Missing> = rows
            .iter()
            .map(|r| -> Result<Missing> {
                Ok(Missing {
                    machine: r.try_get(0)?,
                    surface: r.try_get(1)?,
                    kind: r.try_get(2)?,
                    version: r.try_get(3)?,
                    sha256: r.try_get(4)?,
                    bytes: r.try_get(5)?,
                })
            })
            .collect::<Result<_>>()?;
        let mut copied = 0;
        for m in &missing {
            let surface = (!m.surface.is_empty()).then_some(m.surface.as_str());
            let Ok(dir) = self.dir_of(&m.machine, surface, &m.kind) else {
                tracing::warn!(
                    machine = %m.machine,
                    surface = %m.surface,
                    kind = %m.kind,
                    "a model recorded without bytes has an invalid id; not copied"
                );
                continue;
            };
            // Version 1 of a model saved before versions existed is the unversioned file.
            let mut files = vec![dir.join(format!("{}.v{}.tcm", m.kind, m.version))];
            if m.version == 1 {
                files.push(dir.join(format!("{}.tcm", m.kind)));
            }
            let Some((path, contents)) =
                tokio::task::spawn_blocking(move || read_first(files)).await??
            else {
                continue; // another instance's data dir holds it
            };
            let checked = decode_model(&contents, &path)
                .map_err(|e| format!("{e:#}"))
                .and_then(|payload| verify(&payload, m));
            if let Err(why) = checked {
                tracing::error!(
                    file = %path.display(),
                    "model {} v{} of machine {} not copied into the database: {why}",
                    m.kind,
                    m.version,
                    m.machine
                );
                continue;
            }
            let n = sqlx::query(
                "UPDATE model_versions SET data = $1 WHERE machine = $2 AND surface = $3 \
                 AND kind = $4 AND version = $5 AND data IS NULL",
            )
            .bind(contents)
            .bind(m.machine.clone())
            .bind(m.surface.clone())
            .bind(m.kind.clone())
            .bind(m.version)
            .execute(&self.db)
            .await
            .with_context(|| format!("cannot copy {} into the database", path.display()))?
            .rows_affected();
            if n == 1 {
                tracing::info!(file = %path.display(), "model copied into the database");
                copied += 1;
            }
        }
        if copied > 0 {
            tracing::warn!(
                copied,
                "copied models saved before migration 0003 from this data dir into the \
                 database: every instance serves them now"
            );
        }
        Ok(copied)
    }
}

/// The contents of the first of `files` that exists.
fn read_first(files: Vec<PathBuf>) -> Result<Option<(PathBuf, Vec<u8>)>> {
    for path in files {
        match std::fs::read(&path) {
            Ok(b) => return Ok(Some((path, b))),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e).with_context(|| format!("cannot read {}", path.display())),
        }
    }
    Ok(None)
}
