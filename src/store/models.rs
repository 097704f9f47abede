//! Trained-model files under `<data-dir>/models`, written atomically and checksummed.
//!
//! Layout: `models/<machine>/machine/<kind>.tcm` for machine-level models and
//! `models/<machine>/surfaces/<surface>/<kind>.tcm` for surface-level ones.
//! File format (little-endian): magic `TRUECUTM` (8 bytes), format version `u32`,
//! payload length `u64`, SHA-256 of the payload (32 bytes), payload.
//! A save writes a temp file in the same directory, fsyncs it, renames it over the old
//! file and fsyncs the directory: a crash at any point leaves either the old or the new
//! model, never a mix. Each save is also recorded in the `models` table.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use sha2::{Digest, Sha256};
use sqlx::AnyPool;

use super::database::now_ms;

/// Version of the model file container written by this build.
pub const MODEL_FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"TRUECUTM";
const HEADER_LEN: usize = 8 + 4 + 8 + 32;
const TMP_MARK: &str = ".tmp-";

/// Model files of every machine and surface.
#[derive(Clone, Debug)]
pub struct ModelStore {
    root: PathBuf,
    db: AnyPool,
}

/// True when `s` can name a record and a file: `[A-Za-z0-9._-]{1,64}`, and not `.` or `..`
/// (which name directories). The one id rule of the service: the HTTP `Id` and the CLI use it.
pub fn is_valid_id(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s != "."
        && s != ".."
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

/// A path component must be an id ([`is_valid_id`]).
fn check_component(what: &str, s: &str) -> Result<()> {
    if !is_valid_id(s) {
        bail!("model {what} '{s}' is not a valid id");
    }
    Ok(())
}

/// Wraps a payload in the versioned, checksummed container.
pub(crate) fn encode_model(payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&MODEL_FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&Sha256::digest(payload));
    out.extend_from_slice(payload);
    out
}

/// Checks and unwraps a container; errors say what is wrong (corruption, truncation, version).
pub(crate) fn decode_model(bytes: &[u8], path: &Path) -> Result<Vec<u8>> {
    let p = path.display();
    if bytes.len() < HEADER_LEN || &bytes[..8] != MAGIC {
        bail!("model file {p} is corrupt: missing truecut header");
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into()?);
    if version != MODEL_FORMAT_VERSION {
        bail!(
            "model file {p} has format version {version}; this build reads version {MODEL_FORMAT_VERSION}"
        );
    }
    let len = u64::from_le_bytes(bytes[12..20].try_into()?);
    let payload = &bytes[HEADER_LEN..];
    if payload.len() as u64 != len {
        bail!(
            "model file {p} is corrupt: header says {len} payload bytes, file has {}",
            payload.len()
        );
    }
    if Sha256::digest(payload)[..] != bytes[20..52] {
        bail!("model file {p} is corrupt: SHA-256 checksum mismatch");
    }
    Ok(payload.to_vec())
}

fn write_atomically(dir: &Path, file: &Path, contents: &[u8]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let name = file
        .file_name()
        .and_then(|n| n.to_str())
        .context("model path has no file name")?;
    let tmp = dir.join(format!(
        ".{name}{TMP_MARK}{}",
        uuid::Uuid::now_v7().simple()
    ));
    let result = (|| -> Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(contents)?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, file)?;
        std::fs::File::open(dir)?.sync_all()?;
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(|| format!("cannot write model file {}", file.display()))
}

impl ModelStore {
    pub(crate) fn new(root: PathBuf, db: AnyPool) -> ModelStore {
        ModelStore { root, db }
    }

    /// The root directory of the model files.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Directory and file path of a model (after validating every component).
    pub fn path_of(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
    ) -> Result<(PathBuf, PathBuf)> {
        check_component("machine", machine)?;
        check_component("kind", kind)?;
        let dir = match surface {
            None => self.root.join(machine).join("machine"),
            Some(s) => {
                check_component("surface", s)?;
                self.root.join(machine).join("surfaces").join(s)
            }
        };
        let file = dir.join(format!("{kind}.tcm"));
        Ok((dir, file))
    }

    /// Saves `payload` as the model `kind` of a machine (or of one of its surfaces),
    /// atomically, replacing any previous one, and records it in the database.
    pub async fn save(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
        payload: &[u8],
    ) -> Result<()> {
        let (dir, file) = self.path_of(machine, surface, kind)?;
        let contents = encode_model(payload);
        let sha = hex::encode(Sha256::digest(payload));
        tokio::task::spawn_blocking(move || write_atomically(&dir, &file, &contents)).await??;
        let now = now_ms();
        let surface_key = surface.unwrap_or("").to_string();
        let mut tx = self.db.begin().await?;
        let updated = sqlx::query(
            "UPDATE models SET format_version = $1, sha256 = $2, bytes = $3, updated_at = $4 \
             WHERE machine = $5 AND surface = $6 AND kind = $7",
        )
        .bind(i64::from(MODEL_FORMAT_VERSION))
        .bind(sha.clone())
        .bind(i64::try_from(payload.len())?)
        .bind(now)
        .bind(machine.to_string())
        .bind(surface_key.clone())
        .bind(kind.to_string())
        .execute(&mut *tx)
        .await?
        .rows_affected();
        if updated == 0 {
            sqlx::query(
                "INSERT INTO models (machine, surface, kind, format_version, sha256, bytes, updated_at) \
                 VALUES ($1, $2, $3, $4, $5, $6, $7)",
            )
            .bind(machine.to_string())
            .bind(surface_key)
            .bind(kind.to_string())
            .bind(i64::from(MODEL_FORMAT_VERSION))
            .bind(sha)
            .bind(i64::try_from(payload.len())?)
            .bind(now)
            .execute(&mut *tx)
            .await
            .with_context(|| format!("cannot record model {kind} of machine {machine}"))?;
        }
        tx.commit().await?;
        Ok(())
    }

    /// Loads a model's payload: `Ok(None)` if none was saved, `Err` if the file is corrupt,
    /// truncated, of an unknown format version, or recorded but missing.
    pub async fn load(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
    ) -> Result<Option<Vec<u8>>> {
        let (_, file) = self.path_of(machine, surface, kind)?;
        let path = file.clone();
        let bytes = tokio::task::spawn_blocking(move || match std::fs::read(&path) {
            Ok(b) => Ok(Some(b)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e),
        })
        .await?
        .with_context(|| format!("cannot read model file {}", file.display()))?;
        match bytes {
            Some(b) => decode_model(&b, &file).map(Some),
            None => {
                let recorded: i64 = sqlx::query_scalar(
                    "SELECT COUNT(*) FROM models WHERE machine = $1 AND surface = $2 AND kind = $3",
                )
                .bind(machine.to_string())
                .bind(surface.unwrap_or("").to_string())
                .bind(kind.to_string())
                .fetch_one(&self.db)
                .await?;
                if recorded > 0 {
                    bail!(
                        "model file {} is recorded in the database but missing",
                        file.display()
                    );
                }
                Ok(None)
            }
        }
    }

    /// Deletes a model file and its record; returns `false` if there was none.
    pub async fn delete(&self, machine: &str, surface: Option<&str>, kind: &str) -> Result<bool> {
        let (_, file) = self.path_of(machine, surface, kind)?;
        let n = sqlx::query("DELETE FROM models WHERE machine = $1 AND surface = $2 AND kind = $3")
            .bind(machine.to_string())
            .bind(surface.unwrap_or("").to_string())
            .bind(kind.to_string())
            .execute(&self.db)
            .await?
            .rows_affected();
        let removed = match tokio::fs::remove_file(&file).await {
            Ok(()) => true,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
            Err(e) => return Err(e.into()),
        };
        Ok(n > 0 || removed)
    }

    /// Removes every model file of a machine (records are deleted by the caller).
    pub(crate) async fn remove_machine_files(&self, machine: &str) -> Result<()> {
        check_component("machine", machine)?;
        remove_dir_if_exists(self.root.join(machine)).await
    }

    /// Removes every model file of a surface (records are deleted by the caller).
    pub(crate) async fn remove_surface_files(&self, machine: &str, surface: &str) -> Result<()> {
        check_component("machine", machine)?;
        check_component("surface", surface)?;
        remove_dir_if_exists(self.root.join(machine).join("surfaces").join(surface)).await
    }

    /// Deletes temp files left by writes interrupted by a crash (run at start-up, before
    /// any save). Returns how many were removed.
    pub fn sweep_temp_files(&self) -> Result<usize> {
        fn walk(dir: &Path, removed: &mut usize) -> std::io::Result<()> {
            let entries = match std::fs::read_dir(dir) {
                Ok(e) => e,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
                Err(e) => return Err(e),
            };
            for entry in entries {
                let entry = entry?;
                let path = entry.path();
                if entry.file_type()?.is_dir() {
                    walk(&path, removed)?;
                } else if entry.file_name().to_string_lossy().contains(TMP_MARK) {
                    std::fs::remove_file(&path)?;
                    *removed += 1;
                }
            }
            Ok(())
        }
        let mut removed = 0;
        walk(&self.root, &mut removed)
            .with_context(|| format!("cannot sweep {}", self.root.display()))?;
        Ok(removed)
    }
}

async fn remove_dir_if_exists(dir: PathBuf) -> Result<()> {
    match tokio::fs::remove_dir_all(&dir).await {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(anyhow::Error::from(e).context(format!("cannot remove {}", dir.display()))),
    }
}

#[cfg(test)]
mod tests;
