//! Trained models, versioned and checksummed: in the database on PostgreSQL (so every
//! instance serves them), as files under `<data-dir>/models` on SQLite.
//!
//! Container (little-endian): magic `TRUECUTM` (8 bytes), format version `u32`, payload
//! length `u64`, SHA-256 of the payload (32 bytes), payload. Each save makes a new version
//! (1, 2, ...) of the model: a row in `model_versions` holding the container (`data`,
//! PostgreSQL) or naming the file `models/<machine>/machine/<kind>.v<N>.tcm` (or
//! `.../surfaces/<surface>/<kind>.v<N>.tcm`) written before it (SQLite: temp file, fsync,
//! rename, fsync of the directory). The `models` row names the version served; the last
//! [`VERSIONS_KEPT`] versions are kept for rollback ([`ModelStore::rollback`]).
//!
//! One database transaction records the version, points `models` at it and, for a job's
//! model, marks the job done ([`ModelStore::save_for_job`]): a crash anywhere before its
//! commit leaves the previous model served and the job unfinished (re-queued or failed by
//! the next instance), never a new model beside a job reported failed. An orphan file of an
//! uncommitted version is never read and is overwritten by the next save of that number.
//!
//! Fault injection for the crash tests: with `TRUECUT_FAULT_CRASH_AT=model-commit` the
//! process aborts right before that commit (after the file is written on SQLite).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use sha2::{Digest, Sha256};
use sqlx::AnyPool;

use super::database::{Backend, now_ms};

/// Version of the model file container written by this build.
pub const MODEL_FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"TRUECUTM";
const HEADER_LEN: usize = 8 + 4 + 8 + 32;
const TMP_MARK: &str = ".tmp-";

/// Versions of a model kept (the served one is always kept as well).
pub const VERSIONS_KEPT: i64 = 10;

/// Models of every machine and surface.
#[derive(Clone, Debug)]
pub struct ModelStore {
    root: PathBuf,
    pub(crate) db: AnyPool,
    backend: Backend,
    instance: String,
}

/// The job whose product a save stores: it ends `done` with `result` in the same
/// transaction ([`ModelStore::save_for_job`]).
#[derive(Clone, Copy, Debug)]
pub struct JobDone<'a> {
    /// The job's id (must be `storing` on this instance: [`super::Store::claim_job_commit`]).
    pub id: &'a str,
    /// Its result JSON.
    pub result: &'a serde_json::Value,
    /// The claim the saving worker runs (`Progress::epoch`): a worker of an earlier claim
    /// of the same job cannot save.
    pub epoch: i64,
}

/// Aborts the process at the named point when `TRUECUT_FAULT_CRASH_AT` says so (crash
/// tests against the real binary; see the module doc).
pub(crate) fn crash_point(name: &str) {
    if std::env::var("TRUECUT_FAULT_CRASH_AT").is_ok_and(|v| v == name) {
        tracing::error!("TRUECUT_FAULT_CRASH_AT={name}: aborting on purpose");
        std::process::abort();
    }
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
    pub(crate) fn new(root: PathBuf, db: AnyPool, backend: Backend, instance: String) -> Self {
        ModelStore {
            root,
            db,
            backend,
            instance,
        }
    }

    /// The root directory of the model files (SQLite).
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Where the models' bytes live: in the database (PostgreSQL) or in files (SQLite).
    pub fn in_database(&self) -> bool {
        self.backend == Backend::Postgres
    }

    /// Directory of a model's files (after validating every component).
    pub fn dir_of(&self, machine: &str, surface: Option<&str>, kind: &str) -> Result<PathBuf> {
        check_component("machine", machine)?;
        check_component("kind", kind)?;
        Ok(match surface {
            None => self.root.join(machine).join("machine"),
            Some(s) => {
                check_component("surface", s)?;
                self.root.join(machine).join("surfaces").join(s)
            }
        })
    }

    /// The file of version `version` of a model (SQLite keeps the bytes there).
    pub fn file_of(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
        version: i64,
    ) -> Result<PathBuf> {
        Ok(self
            .dir_of(machine, surface, kind)?
            .join(format!("{kind}.v{version}.tcm")))
    }

    /// Saves `payload` as a new version of the model `kind` of a machine (or of one of its
    /// surfaces) and serves it from now on. Returns the version number.
    pub async fn save(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
        payload: &[u8],
    ) -> Result<i64> {
        self.save_inner(machine, surface, kind, payload, None).await
    }

    /// Like [`ModelStore::save`] for a job's product: the job (in state `storing` on this
    /// instance) ends `done` with its result in the same transaction, so a crash leaves
    /// either both or neither. Errors if the job is no longer this instance's to finish.
    pub async fn save_for_job(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
        payload: &[u8],
        job: JobDone<'_>,
    ) -> Result<i64> {
        self.save_inner(machine, surface, kind, payload, Some(job))
            .await
    }

    async fn save_inner(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
        payload: &[u8],
        job: Option<JobDone<'_>>,
    ) -> Result<i64> {
        let dir = self.dir_of(machine, surface, kind)?;
        let contents = encode_model(payload);
        let sha = hex::encode(Sha256::digest(payload));
        let size = i64::try_from(payload.len())?;
        let now = now_ms();
        let surface_key = surface.unwrap_or("").to_string();
        macro_rules! key {
            ($q:expr) => {
                $q.bind(machine.to_string())
                    .bind(surface_key.clone())
                    .bind(kind.to_string())
            };
        }
        let mut tx = self.db.begin().await?;
        // The upsert takes the model row's lock until commit: concurrent saves of one model
        // (from any instance) get consecutive versions.
        let version: i64 = key!(sqlx::query(
            "INSERT INTO models (machine, surface, kind, format_version, sha256, bytes, \
             updated_at, version, last_version) VALUES ($1, $2, $3, $4, $5, $6, $7, 0, 1) \
             ON CONFLICT (machine, surface, kind) \
             DO UPDATE SET last_version = models.last_version + 1 RETURNING last_version",
        ))
        .bind(i64::from(MODEL_FORMAT_VERSION))
        .bind(sha.clone())
        .bind(size)
        .bind(now)
        .fetch_one(&mut *tx)
        .await
        .and_then(|row| sqlx::Row::try_get(&row, 0))
        .with_context(|| format!("cannot record model {kind} of machine {machine}"))?;
        let file = dir.join(format!("{kind}.v{version}.tcm"));
        let data = if self.in_database() {
            Some(contents)
        } else {
            let (d, f) = (dir.clone(), file.clone());
            tokio::task::spawn_blocking(move || write_atomically(&d, &f, &contents)).await??;
            None
        };
        let recorded = async {
            key!(sqlx::query(
                "INSERT INTO model_versions (machine, surface, kind, version, format_version, \
                 sha256, bytes, created_at, job, data) \
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
            ))
            .bind(version)
            .bind(i64::from(MODEL_FORMAT_VERSION))
            .bind(sha.clone())
            .bind(size)
            .bind(now)
            .bind(job.map(|j| j.id.to_string()))
            .bind(data)
            .execute(&mut *tx)
            .await?;
            key!(sqlx::query(
                "UPDATE models SET version = $4, format_version = $5, sha256 = $6, bytes = $7, \
                 updated_at = $8 WHERE machine = $1 AND surface = $2 AND kind = $3",
            ))
            .bind(version)
            .bind(i64::from(MODEL_FORMAT_VERSION))
            .bind(sha.clone())
            .bind(size)
            .bind(now)
            .execute(&mut *tx)
            .await?;
            if let Some(j) = job {
                // The result names the version the job made.
                let mut result = j.result.clone();
                if let Some(o) = result.as_object_mut() {
                    o.insert("model_version".into(), version.into());
                }
                // The fence: only while this instance's lease holds (`instances.rs`).
                let fence = super::instances::lease_held_sql(self.backend, "$5");
                let n = sqlx::query(sqlx::AssertSqlSafe(format!(
                    "UPDATE jobs SET state = 'done', progress = 1.0, result = $1, error = NULL, \
                     updated_at = $2, finished_at = $3 \
                     WHERE id = $4 AND owner = $5 AND state = 'storing' AND attempts = $6 \
                     AND {fence}"
                )))
                .bind(result.to_string())
                .bind(now)
                .bind(now)
                .bind(j.id.to_string())
                .bind(self.instance.clone())
                .bind(j.epoch)
                .execute(&mut *tx)
                .await?
                .rows_affected();
                if n != 1 {
                    bail!(
                        "job {} is no longer this instance's to finish (taken over, or this \
                         instance's lease expired)",
                        j.id
                    );
                }
                sqlx::query("DELETE FROM job_inputs WHERE id = $1")
                    .bind(j.id.to_string())
                    .execute(&mut *tx)
                    .await?;
            }
            let pruned = self.prune(&mut tx, machine, &surface_key, kind).await?;
            crash_point("model-commit");
            tx.commit().await?;
            Ok::<_, anyhow::Error>(pruned)
        }
        .await;
        match recorded {
            Ok(pruned) => {
                if !self.in_database() {
                    for v in pruned {
                        let old = dir.join(format!("{kind}.v{v}.tcm"));
                        if let Err(e) = std::fs::remove_file(&old)
                            && e.kind() != std::io::ErrorKind::NotFound
                        {
                            tracing::warn!("cannot remove old model file {}: {e}", old.display());
                        }
                    }
                }
                Ok(version)
            }
            Err(e) => {
                if !self.in_database() {
                    let _ = std::fs::remove_file(&file);
                }
                Err(e)
            }
        }
    }

    /// Deletes the versions beyond the newest [`VERSIONS_KEPT`] (never the served one);
    /// returns their numbers (their files go after the commit).
    async fn prune(
        &self,
        tx: &mut sqlx::Transaction<'static, sqlx::Any>,
        machine: &str,
        surface: &str,
        kind: &str,
    ) -> Result<Vec<i64>> {
        let old: Vec<i64> = sqlx::query_scalar(
            "SELECT v.version FROM model_versions v JOIN models m ON m.machine = v.machine \
             AND m.surface = v.surface AND m.kind = v.kind \
             WHERE v.machine = $1 AND v.surface = $2 AND v.kind = $3 AND v.version <> m.version \
             ORDER BY v.version DESC",
        )
        .bind(machine.to_string())
        .bind(surface.to_string())
        .bind(kind.to_string())
        .fetch_all(&mut **tx)
        .await?;
        let keep = usize::try_from(VERSIONS_KEPT - 1).unwrap_or(0);
        let drop: Vec<i64> = old.into_iter().skip(keep).collect();
        for v in &drop {
            sqlx::query(
                "DELETE FROM model_versions WHERE machine = $1 AND surface = $2 AND kind = $3 \
                 AND version = $4",
            )
            .bind(machine.to_string())
            .bind(surface.to_string())
            .bind(kind.to_string())
            .bind(*v)
            .execute(&mut **tx)
            .await?;
        }
        Ok(drop)
    }

    /// Loads the served version's payload: `Ok(None)` if none was saved, `Err` if it is
    /// corrupt, truncated, of an unknown format version, or recorded but missing.
    pub async fn load(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
    ) -> Result<Option<Vec<u8>>> {
        Ok(self
            .load_versioned(machine, surface, kind)
            .await?
            .map(|(_, payload)| payload))
    }

    /// [`ModelStore::load`] with the served version's number, read in the same query.
    pub async fn load_versioned(
        &self,
        machine: &str,
        surface: Option<&str>,
        kind: &str,
    ) -> Result<Option<(i64, Vec<u8>)>> {
        let dir = self.dir_of(machine, surface, kind)?;
        let row = sqlx::query(
            "SELECT m.version, v.data FROM models m LEFT JOIN model_versions v \
             ON v.machine = m.machine AND v.surface = m.surface AND v.kind = m.kind \
             AND v.version = m.version \
             WHERE m.machine = $1 AND m.surface = $2 AND m.kind = $3",
        )
        .bind(machine.to_string())
        .bind(surface.unwrap_or("").to_string())
        .bind(kind.to_string())
        .fetch_optional(&self.db)
        .await?;
        let Some(row) = row else {
            return Ok(None);
        };
        let version: i64 = sqlx::Row::try_get(&row, 0)?;
        let data: Option<Vec<u8>> = sqlx::Row::try_get(&row, 1)?;
        let file = dir.join(format!("{kind}.v{version}.tcm"));
        if let Some(bytes) = data {
            let name = format!("{machine}/{}/{kind} v{version}", surface.unwrap_or("-"));
            return decode_model(&bytes, Path::new(&name)).map(|p| Some((version, p)));
        }
        // Version 1 of a model saved before versions existed is the unversioned file.
        let legacy = dir.join(format!("{kind}.tcm"));
        let bytes = tokio::task::spawn_blocking(move || {
            for path in [&file, &legacy] {
                match std::fs::read(path) {
                    Ok(b) => return Ok(Some((b, path.clone()))),
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                    Err(e) => {
                        return Err(e).with_context(|| format!("cannot read {}", path.display()));
                    }
                }
                if version != 1 {
                    break;
                }
            }
            Ok(None)
        })
        .await??;
        match bytes {
            Some((b, path)) => decode_model(&b, &path).map(|p| Some((version, p))),
            None => bail!(
                "model {kind} version {version} of machine {machine} is recorded in the \
                 database but its file {} is missing (models of an instance on SQLite live \
                 in its data dir; instances sharing models need PostgreSQL)",
                dir.join(format!("{kind}.v{version}.tcm")).display()
            ),
        }
    }

    /// Deletes a model with every version (any instance may: the records are shared, and
    /// this instance's files go too); returns `false` if there was none.
    pub async fn delete(&self, machine: &str, surface: Option<&str>, kind: &str) -> Result<bool> {
        let dir = self.dir_of(machine, surface, kind)?;
        let mut tx = self.db.begin().await?;
        let mut n = 0;
        for sql in [
            "DELETE FROM model_versions WHERE machine = $1 AND surface = $2 AND kind = $3",
            "DELETE FROM models WHERE machine = $1 AND surface = $2 AND kind = $3",
        ] {
            n = sqlx::query(sql)
                .bind(machine.to_string())
                .bind(surface.unwrap_or("").to_string())
                .bind(kind.to_string())
                .execute(&mut *tx)
                .await?
                .rows_affected();
        }
        tx.commit().await?;
        let k = kind.to_string();
        let removed = tokio::task::spawn_blocking(move || remove_model_files(&dir, k)).await??;
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

/// Removes `<kind>.tcm` and every `<kind>.v<N>.tcm` in `dir`; true if any existed.
fn remove_model_files(dir: &Path, kind: String) -> Result<bool> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(e) => return Err(e.into()),
    };
    let prefix = format!("{kind}.v");
    let mut removed = false;
    for entry in entries {
        let name = entry?.file_name().to_string_lossy().into_owned();
        let versioned = name
            .strip_prefix(&prefix)
            .and_then(|r| r.strip_suffix(".tcm"))
            .is_some_and(|n| n.parse::<u64>().is_ok());
        if versioned || name == format!("{kind}.tcm") {
            std::fs::remove_file(dir.join(&name))?;
            removed = true;
        }
    }
    Ok(removed)
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
