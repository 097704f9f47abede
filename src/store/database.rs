//! `Store`: opening the database (SQLite or PostgreSQL), migrations, the data dir.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use sqlx::AnyPool;
use sqlx::any::AnyPoolOptions;
use sqlx::migrate::{Migration, MigrationType, Migrator};
use sqlx::{Executor, SqlSafeStr};

use super::models::ModelStore;

/// Which database holds the records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Embedded SQLite file (the default, `<data-dir>/truecut.db`).
    Sqlite,
    /// PostgreSQL (`postgres://` URL), shared by several instances.
    Postgres,
}

/// Records and model files. Cheap to clone (a pool handle and paths).
#[derive(Clone, Debug)]
pub struct Store {
    pub(crate) db: AnyPool,
    backend: Backend,
    data_dir: PathBuf,
    instance: String,
    models: ModelStore,
}

/// Milliseconds since the Unix epoch (record timestamps).
pub(crate) fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

fn migrator(backend: Backend) -> Migrator {
    let scripts: [(i64, &'static str, &'static str); 4] = match backend {
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

impl Store {
    /// Opens (creating if needed) the data dir and the database, and applies migrations.
    ///
    /// `database_url`: `None` = SQLite file `truecut.db` in `data_dir`; `sqlite://...` or
    /// `postgres://...` otherwise. The data dir also holds `models/` (model files on SQLite).
    /// Each opened store is one instance with a fresh id ([`Store::instance`]): the owner
    /// of the jobs it runs, kept alive in the `instances` table by [`Store::heartbeat`].
    pub async fn open(data_dir: &Path, database_url: Option<&str>) -> Result<Store> {
        std::fs::create_dir_all(data_dir)
            .with_context(|| format!("cannot create data dir {}", data_dir.display()))?;
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
            bail!("database URL must start with sqlite: or postgres:// (got '{url}')");
        };
        sqlx::any::install_default_drivers();
        let options = AnyPoolOptions::new()
            .max_connections(match backend {
                Backend::Sqlite => 8,
                Backend::Postgres => 10,
            })
            .acquire_timeout(Duration::from_secs(30));
        let options = if backend == Backend::Sqlite {
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
        };
        let db = options
            .connect(&url)
            .await
            .with_context(|| format!("cannot connect to the database ({})", redact(&url)))?;
        migrator(backend)
            .run(&db)
            .await
            .context("database migration failed")?;
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
        Ok(Store {
            db,
            backend,
            data_dir: data_dir.to_path_buf(),
            instance,
            models,
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

    /// Closes the pool (waits for connections to be returned).
    pub async fn close(&self) {
        self.db.close().await;
    }
}

/// See [`Store::now_sql`].
pub(crate) fn now_sql(backend: Backend) -> &'static str {
    match backend {
        Backend::Sqlite => "CAST(ROUND((julianday('now') - 2440587.5) * 86400000.0) AS INTEGER)",
        Backend::Postgres => "CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000 AS BIGINT)",
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
