//! `Store`: opening the database (SQLite or PostgreSQL), migrations, the data dir.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use serde::Serialize;
use sqlx::AnyPool;
use sqlx::any::AnyPoolOptions;
use sqlx::migrate::{Migration, MigrationType, Migrator};
use sqlx::{Executor, SqlSafeStr};

use super::connect_error::{Attempt, ConnectError, check_tls_files, classify};
use super::instances::LeaseState;
use super::migrations::MigrationReport;
use super::models::ModelStore;

/// Which database holds the records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Embedded SQLite file (the default, `<data-dir>/truecut.db`).
    Sqlite,
    /// PostgreSQL (`postgres://` URL), shared by several instances.
    Postgres,
}

/// Connections of the request pool (SQLite, PostgreSQL).
const POOL_MAX: [u32; 2] = [8, 10];

/// Records and model files. Cheap to clone (pool handles and paths).
#[derive(Clone, Debug)]
pub struct Store {
    pub(crate) db: AnyPool,
    /// One connection for the lease alone (`instances.rs`): a busy request pool does not
    /// delay the heartbeat.
    pub(crate) hb_db: AnyPool,
    /// One connection for the reaper alone (`instances.rs`): looking for gone instances
    /// (which may wait on a lock of `jobs`) neither delays the heartbeat nor takes a
    /// connection from the requests.
    pub(crate) reap_db: AnyPool,
    pub(crate) lease: Arc<LeaseState>,
    backend: Backend,
    data_dir: PathBuf,
    instance: String,
    models: ModelStore,
    /// Nominal surfaces shared between requests (`surface_cache.rs`).
    pub(crate) surfaces: super::surface_cache::SurfaceCache,
    /// Taken by a measurement write of more than [`super::measurements::LARGE_WRITE`] bytes of
    /// BLOBs: such writes go one at a time, so the ones waiting hold their arrays only, not
    /// the encoded BLOBs and the driver's bound copies too.
    pub(crate) large_writes: Arc<tokio::sync::Mutex<()>>,
}

/// Milliseconds since the Unix epoch (record timestamps).
pub(crate) fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// Every migration of `backend`, in order; [`super::migrations`] applies them.
pub(crate) fn migrator(backend: Backend) -> Migrator {
    let scripts: [(i64, &'static str, &'static str); 7] = match backend {
        Backend::Sqlite => [
            (
                1,
                "init",
                include_str!("../../migrations/sqlite/0001_init.sql"),
            ),
            (
                2,
                "job_times",
                include_str!("../../migrations/sqlite/0002_job_times.sql"),
            ),
            (
                3,
                "scale_out",
                include_str!("../../migrations/sqlite/0003_scale_out.sql"),
            ),
            (
                4,
                "iso230_runs",
                include_str!("../../migrations/sqlite/0004_iso230_runs.sql"),
            ),
            (
                5,
                "job_inputs",
                include_str!("../../migrations/sqlite/0005_job_inputs.sql"),
            ),
            (
                6,
                "idempotency",
                include_str!("../../migrations/sqlite/0006_idempotency.sql"),
            ),
            (
                7,
                "job_claims_seq",
                include_str!("../../migrations/sqlite/0007_job_claims_seq.sql"),
            ),
        ],
        Backend::Postgres => [
            (
                1,
                "init",
                include_str!("../../migrations/postgres/0001_init.sql"),
            ),
            (
                2,
                "job_times",
                include_str!("../../migrations/postgres/0002_job_times.sql"),
            ),
            (
                3,
                "scale_out",
                include_str!("../../migrations/postgres/0003_scale_out.sql"),
            ),
            (
                4,
                "iso230_runs",
                include_str!("../../migrations/postgres/0004_iso230_runs.sql"),
            ),
            (
                5,
                "job_inputs",
                include_str!("../../migrations/postgres/0005_job_inputs.sql"),
            ),
            (
                6,
                "idempotency",
                include_str!("../../migrations/postgres/0006_idempotency.sql"),
            ),
            (
                7,
                "job_claims_seq",
                include_str!("../../migrations/postgres/0007_job_claims_seq.sql"),
            ),
        ],
    };
    Migrator::with_migrations(
        scripts
            .into_iter()
            .map(|(version, name, sql)| {
                Migration::new(
                    version,
                    Cow::Borrowed(name),
                    MigrationType::Simple,
                    sql.into_sql_str(),
                    false,
                )
            })
            .collect(),
    )
}

/// The database as `/healthz` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct DatabaseReport {
    /// `sqlite` or `postgres`.
    pub backend: &'static str,
    /// `SELECT 1` answered within the probe's time limit.
    pub reachable: bool,
    /// Milliseconds `SELECT 1` took through the request pool (waiting for a connection
    /// included); `null` when it did not answer.
    pub latency_ms: Option<f64>,
    /// Why it did not answer.
    pub error: Option<String>,
    /// The request pool's connections.
    pub pool: PoolReport,
}

/// Connections of the request pool.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PoolReport {
    /// Most connections it opens.
    pub max: u32,
    /// Connections open now.
    pub open: u32,
    /// Open connections lent to a request now.
    pub in_use: u32,
    /// Open connections waiting for a request.
    pub idle: u32,
}

fn pool_options(backend: Backend, max: u32, acquire: Duration) -> AnyPoolOptions {
    let options = AnyPoolOptions::new()
        .max_connections(max)
        .acquire_timeout(acquire);
    if backend == Backend::Sqlite {
        options.after_connect(|conn, _meta| {
            Box::pin(async move {
                // WAL lets readers run beside the writer; NORMAL is durable in WAL mode
                // except for the last transactions on power loss.
                conn.execute(
                    "PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL; \
                     PRAGMA busy_timeout = 10000; PRAGMA foreign_keys = ON;",
                )
                .await?;
                Ok(())
            })
        })
    } else {
        options
    }
}

impl Store {
    /// Opens (creating if needed) the data dir and the database, and applies migrations;
    /// fails at once when the database does not answer ([`Store::open_waiting`] waits).
    ///
    /// `database_url`: `None` = SQLite file `truecut.db` in `data_dir`; `sqlite://...` or
    /// `postgres://...` otherwise. The data dir also holds `models/` (model files on SQLite).
    /// Each opened store is one instance with a fresh id ([`Store::instance`]): the owner
    /// of the jobs it runs, kept alive in the `instances` table by [`Store::heartbeat`].
    pub async fn open(data_dir: &Path, database_url: Option<&str>) -> Result<Store> {
        Self::open_waiting(data_dir, database_url, Duration::ZERO).await
    }

    /// Like [`Store::open`], retrying the first connection for up to `wait` (every second)
    /// while the database does not answer: an instance started beside its database (a
    /// compose file) waits for it instead of exiting. A database that answers with an
    /// error (bad password, unknown database) fails at once, and so does TLS that cannot be
    /// set up (a certificate refused, a server without TLS, a certificate file that cannot be
    /// read): [`ConnectError`] says what to check (`connect_error.rs`).
    ///
    /// On PostgreSQL, models saved before migration 0003 (files in this instance's data
    /// dir) are copied into the database ([`ModelStore::copy_files_into_database`]).
    pub async fn open_waiting(
        data_dir: &Path,
        database_url: Option<&str>,
        wait: Duration,
    ) -> Result<Store> {
        std::fs::create_dir_all(data_dir)
            .with_context(|| format!("cannot create data dir {}", data_dir.display()))?;
        let (url, backend) = resolve_url(data_dir, database_url)?;
        let idx = usize::from(backend == Backend::Postgres);
        let shown = redact(&url);
        let db = connect_waiting(&url, backend, POOL_MAX[idx], wait).await?;
        let hb_db = pool_options(backend, 1, Duration::from_secs(5))
            .connect(&url)
            .await
            .map_err(|e| connect_failure(e, &shown))?;
        let reap_db = pool_options(backend, 1, Duration::from_secs(5))
            .connect(&url)
            .await
            .map_err(|e| connect_failure(e, &shown))?;
        let migrated = super::migrations::apply(&db, backend).await?;
        if !migrated.applied.is_empty() {
            tracing::info!(applied = ?migrated.applied, "applied database migrations");
        }
        if !migrated.unknown.is_empty() {
            tracing::warn!(
                unknown = ?migrated.unknown,
                latest_known = migrated.latest_known,
                "the database holds migrations this release does not know (a newer release \
                 migrated it, as in a rolling upgrade); serving on: a release's migrations keep \
                 the release before it working"
            );
        }
        let instance = uuid::Uuid::now_v7().to_string();
        let models = ModelStore::new(
            data_dir.join("models"),
            db.clone(),
            backend,
            instance.clone(),
        );
        let swept = models.sweep_temp_files()?;
        if swept > 0 {
            tracing::warn!(
                swept,
                "removed temp model files left by an interrupted write"
            );
        }
        if models.in_database() {
            models.copy_files_into_database().await?;
        }
        Ok(Store {
            db,
            hb_db,
            reap_db,
            lease: Arc::new(LeaseState::default()),
            backend,
            data_dir: data_dir.to_path_buf(),
            instance,
            models,
            surfaces: Default::default(),
            large_writes: Arc::default(),
        })
    }

    /// The model file store.
    pub fn models(&self) -> &ModelStore {
        &self.models
    }

    /// The connection pool (for benches and maintenance tools; routes use the typed methods).
    pub fn pool(&self) -> &AnyPool {
        &self.db
    }

    /// Which database backs this store.
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// The data directory.
    pub fn data_dir(&self) -> &Path {
        &self.data_dir
    }

    /// This instance's id: fresh for every opened store (one per process), the owner of the
    /// jobs it runs. (Earlier builds kept one id per data dir in `<data-dir>/instance-id`;
    /// that file is no longer read.)
    pub fn instance(&self) -> &str {
        &self.instance
    }

    /// SQL for "now" in Unix ms on the database's clock: leases are judged by one clock
    /// whatever the hosts' clocks say.
    pub(crate) fn now_sql(&self) -> &'static str {
        now_sql(self.backend)
    }

    /// Checks that the database answers (for readiness).
    pub async fn ping(&self) -> Result<()> {
        sqlx::query("SELECT 1").execute(&self.db).await?;
        Ok(())
    }

    /// Probes the database through the request pool (`SELECT 1`, at most `limit`) and
    /// reports it with the pool's use (for `/healthz` and `/readyz`).
    pub async fn database_report(&self, limit: Duration) -> DatabaseReport {
        let t0 = Instant::now();
        let probe = tokio::time::timeout(limit, self.ping()).await;
        let took = t0.elapsed().as_secs_f64() * 1000.0;
        let (reachable, latency_ms, error) = match probe {
            Ok(Ok(())) => (true, Some((took * 1000.0).round() / 1000.0), None),
            Ok(Err(e)) => (false, None, Some(format!("{e:#}"))),
            Err(_) => (
                false,
                None,
                Some(format!(
                    "no answer within {} ms (database down, or every connection busy)",
                    limit.as_millis()
                )),
            ),
        };
        let open = self.db.size();
        let idle = u32::try_from(self.db.num_idle()).unwrap_or(open).min(open);
        DatabaseReport {
            backend: match self.backend {
                Backend::Sqlite => "sqlite",
                Backend::Postgres => "postgres",
            },
            reachable,
            latency_ms,
            error,
            pool: PoolReport {
                max: self.db.options().get_max_connections(),
                open,
                in_use: open - idle,
                idle,
            },
        }
    }

    /// Closes the pools (waits for connections to be returned).
    pub async fn close(&self) {
        self.db.close().await;
        self.hb_db.close().await;
        self.reap_db.close().await;
    }
}

/// Applies this build's migrations to the database (the same `database_url` and data dir as
/// [`Store::open`]) and reports what it applied and which newer versions it left alone,
/// without opening a store (no data-dir sweep, no model copy, no instance): `truecut migrate`,
/// the step before a rolling upgrade. Waits up to `wait` for a database that does not answer
/// yet, as [`Store::open_waiting`] does.
pub async fn migrate(
    data_dir: &Path,
    database_url: Option<&str>,
    wait: Duration,
) -> Result<MigrationReport> {
    if database_url.is_none() {
        std::fs::create_dir_all(data_dir)
            .with_context(|| format!("cannot create data dir {}", data_dir.display()))?;
    }
    let (url, backend) = resolve_url(data_dir, database_url)?;
    let db = connect_waiting(&url, backend, 1, wait).await?;
    let report = super::migrations::apply(&db, backend).await;
    db.close().await;
    report
}

/// The URL to connect to (`None`: SQLite file `truecut.db` in `data_dir`) and its backend.
fn resolve_url(data_dir: &Path, database_url: Option<&str>) -> Result<(String, Backend)> {
    let url = match database_url {
        Some(u) => u.to_string(),
        None => format!(
            "sqlite://{}?mode=rwc",
            data_dir.join("truecut.db").display()
        ),
    };
    let backend = if url.starts_with("sqlite:") {
        Backend::Sqlite
    } else if url.starts_with("postgres://") || url.starts_with("postgresql://") {
        Backend::Postgres
    } else {
        bail!(
            "database URL must start with sqlite: or postgres:// (got '{}')",
            redact(&url)
        );
    };
    sqlx::any::install_default_drivers();
    Ok((url, backend))
}

/// A pool of at most `max` connections to `url`, retrying the first connection every second
/// for up to `wait` while the database does not answer (refused, unresolved, starting up);
/// an answer such as a bad password fails at once, and so does TLS that cannot be set up
/// ([`ConnectError`]).
async fn connect_waiting(url: &str, backend: Backend, max: u32, wait: Duration) -> Result<AnyPool> {
    let deadline = Instant::now() + wait;
    let shown = redact(url);
    if backend == Backend::Postgres {
        check_tls_files(url, &shown)?;
    }
    loop {
        match pool_options(backend, max, Duration::from_secs(30))
            .connect(url)
            .await
        {
            Ok(db) => return Ok(db),
            Err(e) if Instant::now() < deadline && classify(&e) == Attempt::Unreachable => {
                tracing::warn!("the database ({shown}) does not answer yet, retrying: {e}");
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
            Err(e) => return Err(connect_failure(e, &shown)),
        }
    }
}

/// See [`Store::now_sql`].
pub(crate) fn now_sql(backend: Backend) -> &'static str {
    match backend {
        Backend::Sqlite => "CAST(ROUND((julianday('now') - 2440587.5) * 86400000.0) AS INTEGER)",
        Backend::Postgres => "CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000 AS BIGINT)",
    }
}

/// The error of a failed first connection: a TLS failure as [`ConnectError::Tls`] (its
/// sentence says what to check), anything else with the database named.
fn connect_failure(e: sqlx::Error, shown_url: &str) -> anyhow::Error {
    match classify(&e) {
        Attempt::Tls(problem) => ConnectError::Tls {
            url: shown_url.to_string(),
            problem,
            source: e,
        }
        .into(),
        Attempt::Unreachable | Attempt::Refused => {
            anyhow::Error::new(e).context(format!("cannot connect to the database ({shown_url})"))
        }
    }
}

/// Hides a password in a database URL for error messages.
fn redact(url: &str) -> String {
    match (url.find("://"), url.find('@')) {
        (Some(s), Some(at)) if at > s => {
            let creds = &url[s + 3..at];
            match creds.find(':') {
                Some(c) => format!("{}{}:***{}", &url[..s + 3], &creds[..c], &url[at..]),
                None => url.to_string(),
            }
        }
        _ => url.to_string(),
    }
}

#[cfg(test)]
mod tests;
