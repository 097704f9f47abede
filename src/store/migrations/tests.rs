//! Unit tests of `crate::store::migrations`: the report, and a database migrated by a newer
//! release on SQLite (PostgreSQL: `tests/api/migrate.rs`).

use std::collections::BTreeSet;
use std::time::Duration;

use sqlx::Connection;

use super::{migrator, report};
use crate::store::{Backend, Store, migrate};

#[test]
fn the_report_names_what_was_missing_and_what_is_unknown() {
    let m = migrator(Backend::Sqlite);
    let fresh = report(&m, &BTreeSet::new());
    let versions: Vec<i64> = fresh.applied.iter().map(|(v, _)| *v).collect();
    assert_eq!(versions, (1..=7).collect::<Vec<_>>());
    assert_eq!(fresh.applied[0].1, "init");
    assert_eq!(fresh.applied[6].1, "job_claims_seq");
    assert!(fresh.unknown.is_empty());
    assert_eq!(fresh.latest_known, 7);

    let later = report(&m, &[1, 2, 3, 4, 5, 6, 7, 8, 12].into_iter().collect());
    assert!(later.applied.is_empty());
    assert_eq!(later.unknown, [8, 12]);

    let partly = report(&m, &[1, 2, 3, 4, 5].into_iter().collect());
    assert_eq!(
        partly.applied,
        [
            (6, "idempotency".to_string()),
            (7, "job_claims_seq".to_string())
        ]
    );
}

#[test]
fn both_backends_know_the_same_versions_and_leave_newer_ones_alone() {
    let (lite, pg) = (migrator(Backend::Sqlite), migrator(Backend::Postgres));
    let names = |m: &sqlx::migrate::Migrator| -> Vec<(i64, String)> {
        m.iter()
            .map(|x| (x.version, x.description.to_string()))
            .collect()
    };
    assert_eq!(names(&lite), names(&pg));
    assert!(lite.ignore_missing && pg.ignore_missing);
}

/// Marks a migration of a newer release as applied, as that release's `truecut migrate`
/// would have (sqlx's own table).
async fn record_newer_migration(db_file: &std::path::Path, version: i64) {
    let mut conn = sqlx::SqliteConnection::connect(&format!("sqlite://{}", db_file.display()))
        .await
        .unwrap();
    sqlx::query(
        "INSERT INTO _sqlx_migrations (version, description, success, checksum, execution_time) \
         VALUES ($1, 'from a newer release', TRUE, x'00', 0)",
    )
    .bind(version)
    .execute(&mut conn)
    .await
    .unwrap();
    conn.close().await.unwrap();
}

#[tokio::test]
async fn migrate_applies_once_and_a_newer_release_does_not_stop_the_start() {
    let dir = tempfile::tempdir().unwrap();
    let first = migrate(dir.path(), None, Duration::ZERO).await.unwrap();
    assert_eq!(first.applied.len(), 7, "{first:?}");
    assert!(first.unknown.is_empty());

    let second = migrate(dir.path(), None, Duration::ZERO).await.unwrap();
    assert!(second.applied.is_empty(), "{second:?}");

    record_newer_migration(&dir.path().join("truecut.db"), 8).await;
    let third = migrate(dir.path(), None, Duration::ZERO).await.unwrap();
    assert!(third.applied.is_empty(), "{third:?}");
    assert_eq!(third.unknown, [8]);

    // what `serve` opens: it starts, and the database still says version 8 is applied
    let store = Store::open(dir.path(), None).await.unwrap();
    let newest: i64 = sqlx::query_scalar("SELECT MAX(version) FROM _sqlx_migrations")
        .fetch_one(store.pool())
        .await
        .unwrap();
    assert_eq!(newest, 8);
    store.close().await;
}

#[tokio::test]
async fn a_failed_migration_still_stops_the_start() {
    let dir = tempfile::tempdir().unwrap();
    migrate(dir.path(), None, Duration::ZERO).await.unwrap();
    let db_file = dir.path().join("truecut.db");
    let mut conn = sqlx::SqliteConnection::connect(&format!("sqlite://{}", db_file.display()))
        .await
        .unwrap();
    // a newer release's migration that failed half-way (sqlx records it unsuccessful)
    sqlx::query(
        "INSERT INTO _sqlx_migrations (version, description, success, checksum, execution_time) \
         VALUES (9, 'failed', FALSE, x'00', 0)",
    )
    .execute(&mut conn)
    .await
    .unwrap();
    conn.close().await.unwrap();
    let err = Store::open(dir.path(), None).await.unwrap_err();
    assert!(format!("{err:#}").contains("migration"), "{err:#}");
}
