//! The state of the storage under the service: whether the data dir takes writes and how
//! much room it has, and which failures of a save are the storage's (a full disk, a
//! read-only or forbidden data dir) rather than a bug. `api` answers those 507 with a
//! sentence instead of an opaque 500, and `/healthz` reports [`StorageState`].

use std::io::ErrorKind;
use std::path::{Path, PathBuf};

/// Why the storage refused a write.
#[non_exhaustive]
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StorageFailure {
    /// No space left on the device (ENOSPC, EDQUOT, SQLITE_FULL, PostgreSQL 53100).
    #[error(
        "the storage is full: {0}. Free space on the data dir's disk (or the database's) and retry"
    )]
    Full(String),
    /// The file system or database takes no writes (EROFS, SQLITE_READONLY, PostgreSQL 25006).
    #[error(
        "the storage is read-only: {0}. Remount it read-write (or point --data-dir elsewhere) and retry"
    )]
    ReadOnly(String),
    /// The service may not write there (EACCES, EPERM: permissions, an immutable dir).
    #[error(
        "the service may not write to its storage: {0}. Give it write access to the data dir and retry"
    )]
    Forbidden(String),
}

/// The storage failure behind `err`, if any cause in its chain is one: an I/O error of
/// kind storage-full, read-only or permission-denied, or a database error with such a code.
pub fn storage_failure(err: &anyhow::Error) -> Option<StorageFailure> {
    err.chain().find_map(|cause| {
        if let Some(io) = cause.downcast_ref::<std::io::Error>() {
            return classify_io(io, &format!("{err:#}"));
        }
        if let Some(sqlx::Error::Io(io)) = cause.downcast_ref::<sqlx::Error>() {
            return classify_io(io, &format!("{err:#}"));
        }
        if let Some(sqlx::Error::Database(db)) = cause.downcast_ref::<sqlx::Error>() {
            return classify_db_code(db.code().as_deref(), db.message());
        }
        None
    })
}

/// ENOSPC (28), EDQUOT (122), EROFS (30), EACCES (13), EPERM (1) by kind or OS code.
fn classify_io(io: &std::io::Error, what: &str) -> Option<StorageFailure> {
    let what = what.to_string();
    match (io.kind(), io.raw_os_error()) {
        (ErrorKind::StorageFull, _) | (_, Some(28 | 122)) => Some(StorageFailure::Full(what)),
        (ErrorKind::ReadOnlyFilesystem, _) | (_, Some(30)) => Some(StorageFailure::ReadOnly(what)),
        (ErrorKind::PermissionDenied, _) | (_, Some(1 | 13)) => {
            Some(StorageFailure::Forbidden(what))
        }
        _ => None,
    }
}

/// SQLite primary result codes 13 (FULL) and 8 (READONLY), also inside an extended code
/// (low byte); PostgreSQL SQLSTATE 53100 (disk_full) and 25006 (read_only_sql_transaction).
fn classify_db_code(code: Option<&str>, message: &str) -> Option<StorageFailure> {
    let code = code?;
    let what = format!("the database answered: {message}");
    match code {
        "53100" => return Some(StorageFailure::Full(what)),
        "25006" => return Some(StorageFailure::ReadOnly(what)),
        _ => {}
    }
    match code.parse::<u32>().ok()? & 0xff {
        13 => Some(StorageFailure::Full(what)),
        8 => Some(StorageFailure::ReadOnly(what)),
        _ => None,
    }
}

/// What `/healthz` says of the storage.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StorageState {
    /// Whether a probe file could be written, flushed and removed in the data dir.
    pub writable: bool,
    /// Bytes free to the service on the data dir's file system (None if unknown).
    pub free_bytes: Option<u64>,
    /// Why the data dir takes no writes (None when writable).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
}

/// Writes, flushes and removes a probe file in `dir`; the failure names the path and cause.
pub fn probe_writable(dir: &Path) -> Result<(), StorageFailure> {
    let probe: PathBuf = dir.join(format!(".write-probe-{}", uuid::Uuid::now_v7().simple()));
    let result = (|| -> std::io::Result<()> {
        use std::io::Write;
        let mut f = std::fs::File::create(&probe)?;
        f.write_all(b"truecut")?;
        f.sync_all()
    })();
    let _ = std::fs::remove_file(&probe);
    result.map_err(|e| {
        let what = format!("cannot write in data dir {}: {e}", dir.display());
        classify_io(&e, &what).unwrap_or(StorageFailure::Forbidden(what))
    })
}

/// Checks at start that the data dir exists (creating it) and takes writes; the error is a
/// sentence naming the path and the cause, so a read-only data dir stops the start at once.
pub fn check_data_dir(dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| {
        anyhow::anyhow!(
            "cannot create the data dir {}: {e}; create it writable or choose another with \
             --data-dir (TRUECUT_DATA_DIR)",
            dir.display()
        )
    })?;
    probe_writable(dir).map_err(|f| {
        anyhow::anyhow!(
            "the data dir {} takes no writes ({f}); the database and model files live there. \
             Choose a writable --data-dir (TRUECUT_DATA_DIR)",
            dir.display()
        )
    })
}

/// The storage state of `dir` (created if missing): a write probe and the free bytes (statvfs).
pub fn state_of(dir: &Path) -> StorageState {
    let _ = std::fs::create_dir_all(dir);
    let probe = probe_writable(dir);
    StorageState {
        writable: probe.is_ok(),
        free_bytes: free_bytes(dir),
        detail: probe.err().map(|f| f.to_string()),
    }
}

/// Bytes available to an unprivileged user on the file system holding `dir` (statvfs
/// `f_bavail × f_frsize`), None where it cannot be asked.
#[cfg(unix)]
pub fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let path = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    let mut st = std::mem::MaybeUninit::<libc::statvfs>::uninit();
    // SAFETY: `path` is a NUL-terminated string that outlives the call, and `st` points to
    // writable memory of the size statvfs fills; it is read only when the call succeeded.
    let rc = unsafe { libc::statvfs(path.as_ptr(), st.as_mut_ptr()) };
    if rc != 0 {
        return None;
    }
    // SAFETY: statvfs returned 0, so it initialised `st`.
    let st = unsafe { st.assume_init() };
    #[allow(clippy::unnecessary_cast)] // the field types differ between platforms
    Some((st.f_bavail as u64).saturating_mul(st.f_frsize as u64))
}

/// Free bytes are not asked for on this platform.
#[cfg(not(unix))]
pub fn free_bytes(_dir: &Path) -> Option<u64> {
    None
}

#[cfg(test)]
mod tests;
