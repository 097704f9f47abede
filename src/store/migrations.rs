//! Applying the schema's migrations (`migrations/sqlite`, `migrations/postgres`, listed in
//! `database.rs`), with a report of what was applied and of what the database holds that this
//! build does not know.
//!
//! A rolling upgrade runs the new release's migrations first (`truecut migrate`, the `migrate`
//! service of deploy/migrate.yaml), then replaces the instances one at a time. Meanwhile instances
//! of the previous release (re)start on a database holding migrations they do not know; sqlx's
//! migrator refuses that by default (`VersionMissing`), which would turn a restart during an
//! upgrade into an outage. Here unknown versions are left alone and reported (`serve` logs a
//! warning); a migration that failed half-way still stops the start. The other half of the bargain
//! is on the migrations: each one keeps the previous release working (it adds tables and columns
//! with defaults; removals wait for the release after).

use std::collections::BTreeSet;

use anyhow::{Context, Result};
use sqlx::AnyPool;
use sqlx::migrate::{Migrate, Migrator};

use super::database::Backend;

/// What applying the migrations found and did ([`super::migrate`], `Store::open`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MigrationReport {
    /// Migrations applied by this run (version, name), in order.
    pub applied: Vec<(i64, String)>,
    /// Versions recorded in the database that this build does not know: a newer release
    /// migrated it. They are left alone.
    pub unknown: Vec<i64>,
    /// The newest version this build knows.
    pub latest_known: i64,
}

/// This build's migrations of `backend` (`database.rs`), set to leave a newer release's
/// alone (see the module's documentation).
pub(crate) fn migrator(backend: Backend) -> Migrator {
    let mut migrator = super::database::migrator(backend);
    migrator.set_ignore_missing(true);
    migrator
}

/// Applies the migrations of this build that `db` lacks and reports them, with the versions
/// it holds that this build does not know. The migration lock (PostgreSQL: an advisory lock
/// on the database; SQLite serialises writers anyway) is held from listing the applied
/// versions to the end, so the report is this run's own even when instances migrate at once.
pub(crate) async fn apply(db: &AnyPool, backend: Backend) -> Result<MigrationReport> {
    let migrator = migrator(backend);
    let mut pooled = db
        .acquire()
        .await
        .context("cannot get a database connection to apply the migrations")?;
    let result = apply_locked(&migrator, &mut pooled).await;
    if result.is_err() {
        // The lock may still be held (sqlx returns early without releasing it): end the
        // session, which releases it, instead of giving the connection back to the pool.
        let _ = pooled.close().await;
    }
    result
}

async fn apply_locked(
    migrator: &Migrator,
    conn: &mut sqlx::AnyConnection,
) -> Result<MigrationReport> {
    conn.lock()
        .await
        .context("cannot take the database's migration lock")?;
    conn.ensure_migrations_table(&migrator.table_name)
        .await
        .context("cannot create the table of applied migrations")?;
    let before: BTreeSet<i64> = conn
        .list_applied_migrations(&migrator.table_name)
        .await
        .context("cannot list the applied migrations")?
        .into_iter()
        .map(|m| m.version)
        .collect();
    // Takes the lock again (it nests on PostgreSQL) and releases it once when done.
    migrator
        .run(&mut *conn)
        .await
        .context("database migration failed")?;
    conn.unlock()
        .await
        .context("cannot release the database's migration lock")?;
    Ok(report(migrator, &before))
}

/// What [`apply`] reports when the database held the versions `before`.
pub(crate) fn report(migrator: &Migrator, before: &BTreeSet<i64>) -> MigrationReport {
    let known: BTreeSet<i64> = migrator.iter().map(|m| m.version).collect();
    MigrationReport {
        applied: migrator
            .iter()
            .filter(|m| !m.migration_type.is_down_migration() && !before.contains(&m.version))
            .map(|m| (m.version, m.description.to_string()))
            .collect(),
        unknown: before.difference(&known).copied().collect(),
        latest_known: known.last().copied().unwrap_or(0),
    }
}

#[cfg(test)]
mod tests;
