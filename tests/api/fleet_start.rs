//! What the fleet's containers run (compose.yaml), as the real binary: `truecut migrate`
//! applies the migrations and says which; `serve` (and `migrate`) go on when a newer release
//! has migrated the database (a rolling upgrade), but not past a migration that failed; the
//! tokens and the database password come from files. SQLite and PostgreSQL (SKIPPED without
//! `TRUECUT_TEST_PG`).

use std::path::Path;
use std::process::{Command, Output};

use sqlx::{Connection, Executor};

use crate::instances::{PgSchema, start};

/// Runs the binary (off the async runtime) with no database, token or secret setting from
/// the test's environment.
async fn truecut(args: &[&str], env: &[(&str, &str)]) -> Output {
    let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    let env: Vec<(String, String)> = env
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    tokio::task::spawn_blocking(move || {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_truecut"));
        cmd.args(&args).env("RUST_LOG", "warn");
        for var in [
            "DATABASE_URL",
            "TRUECUT_DATA_DIR",
            "TRUECUT_TOKENS",
            "TRUECUT_TOKENS_FILE",
            "TRUECUT_DATABASE_PASSWORD_FILE",
            "TRUECUT_DB_WAIT_S",
        ] {
            cmd.env_remove(var);
        }
        for (k, v) in env {
            cmd.env(k, v);
        }
        cmd.output().expect("the binary runs")
    })
    .await
    .unwrap()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `truecut migrate` on `data_dir` or `url`.
async fn migrate(data_dir: &Path, url: Option<&str>) -> Output {
    let mut args = vec!["migrate", "--data-dir", data_dir.to_str().unwrap()];
    if let Some(u) = url {
        args.extend(["--database-url", u]);
    }
    truecut(&args, &[]).await
}

/// Records migration `version` in sqlx's table as a newer release's `truecut migrate` would
/// (`success`: whether it went through).
async fn record_migration(data_dir: &Path, url: Option<&str>, version: i64, success: bool) {
    let sql = format!(
        "INSERT INTO _sqlx_migrations (version, description, success, checksum, execution_time) \
         VALUES ({version}, 'of a newer release', {success}, {}, 0)",
        if url.is_some() {
            "'\\x00'::bytea"
        } else {
            "x'00'"
        }
    );
    match url {
        Some(u) => {
            let mut c = sqlx::PgConnection::connect(u).await.unwrap();
            c.execute(sqlx::AssertSqlSafe(sql)).await.unwrap();
            c.close().await.unwrap();
        }
        None => {
            let file = data_dir.join("truecut.db");
            let mut c = sqlx::SqliteConnection::connect(&format!("sqlite://{}", file.display()))
                .await
                .unwrap();
            c.execute(sqlx::AssertSqlSafe(sql)).await.unwrap();
            c.close().await.unwrap();
        }
    }
}

/// The rolling upgrade on one database: migrate (all seven, then nothing), a newer release's
/// migration 0008 appears, `serve` of this release still starts and answers, `migrate` names
/// 0008 as left alone; a newer migration that failed half-way stops both.
async fn rolling_upgrade(url: Option<&str>) {
    let dir = tempfile::tempdir().unwrap();
    let first = migrate(dir.path(), url).await;
    assert!(first.status.success(), "{}", stderr(&first));
    let text = stdout(&first);
    let applied: Vec<&str> = text.lines().filter(|l| l.starts_with("applied ")).collect();
    assert_eq!(
        applied,
        [
            "applied 0001 init",
            "applied 0002 job_times",
            "applied 0003 scale_out",
            "applied 0004 iso230_runs",
            "applied 0005 job_inputs",
            "applied 0006 idempotency",
            "applied 0007 job_claims_seq",
        ],
        "{text}"
    );

    let again = migrate(dir.path(), url).await;
    assert!(again.status.success(), "{}", stderr(&again));
    assert_eq!(
        stdout(&again),
        "nothing to apply: the database has every migration of this release (up to 0007)\n"
    );

    record_migration(dir.path(), url, 8, true).await;
    let serve_dir = tempfile::tempdir().unwrap();
    let instance = start(
        if url.is_some() {
            serve_dir.path()
        } else {
            dir.path()
        },
        url,
        &[],
        &[],
    )
    .await;
    let (status, health) = instance.get("/healthz").await;
    assert_eq!(status, 200, "{health}");
    let (status, _) = instance
        .send(
            "PUT",
            "/v1/machines/m1",
            &serde_json::json!({"kinematics": "xyz"}),
        )
        .await;
    assert_eq!(status, 201, "{}", instance.log());
    assert!(
        instance.log().contains("does not know"),
        "serve warns about the newer migration: {}",
        instance.log()
    );
    instance.stop();

    let after = migrate(dir.path(), url).await;
    assert!(after.status.success(), "{}", stderr(&after));
    assert!(
        stdout(&after).contains("left alone: 0008 (applied by a newer release"),
        "{}",
        stdout(&after)
    );

    record_migration(dir.path(), url, 9, false).await;
    let failed = migrate(dir.path(), url).await;
    assert_eq!(failed.status.code(), Some(1), "{}", stdout(&failed));
    assert!(
        stderr(&failed).contains("migration"),
        "a half-applied migration stops it: {}",
        stderr(&failed)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rolling_upgrade_sqlite() {
    rolling_upgrade(None).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rolling_upgrade_postgres() {
    let Some(schema) = PgSchema::create("fleet_start::rolling_upgrade_postgres").await else {
        return;
    };
    rolling_upgrade(Some(&schema.url)).await;
}

/// The tokens come from TRUECUT_TOKENS_FILE: its token is accepted, others are not; a
/// missing file stops the start with a sentence naming it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tokens_from_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let tokens = dir.path().join("tokens");
    std::fs::write(&tokens, "# generated\n9c0e6a11d2 admin\n").unwrap();
    let data = dir.path().join("data");
    let instance = start(
        &data,
        None,
        &[],
        &[("TRUECUT_TOKENS_FILE", tokens.to_str().unwrap())],
    )
    .await;
    let client = reqwest::Client::new();
    let url = format!("{}/v1/machines", instance.base);
    let anonymous = client.get(&url).send().await.unwrap();
    assert_eq!(anonymous.status(), 401);
    let admin = client
        .get(&url)
        .bearer_auth("9c0e6a11d2")
        .send()
        .await
        .unwrap();
    assert_eq!(admin.status(), 200);
    instance.stop();

    let missing = dir.path().join("no-such-tokens");
    let out = truecut(
        &[
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--data-dir",
            data.to_str().unwrap(),
        ],
        &[("TRUECUT_TOKENS_FILE", missing.to_str().unwrap())],
    )
    .await;
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains("cannot read the tokens file") && err.contains("no-such-tokens"),
        "{err}"
    );
}

/// A password file needs a PostgreSQL URL; an unreadable one is named. Both before any
/// connection is tried.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn database_password_file_errors_are_sentences() {
    let dir = tempfile::tempdir().unwrap();
    let pw = dir.path().join("db-password");
    std::fs::write(&pw, "s3cret\n").unwrap();
    let data = dir.path().to_str().unwrap();

    let sqlite = truecut(
        &["migrate", "--data-dir", data],
        &[("TRUECUT_DATABASE_PASSWORD_FILE", pw.to_str().unwrap())],
    )
    .await;
    assert_eq!(sqlite.status.code(), Some(1));
    assert!(
        stderr(&sqlite).contains("needs --database-url (DATABASE_URL) of PostgreSQL"),
        "{}",
        stderr(&sqlite)
    );

    let gone = dir.path().join("gone");
    let unreadable = truecut(
        &[
            "migrate",
            "--database-url",
            "postgres://truecut@127.0.0.1:1/truecut",
            "--database-password-file",
            gone.to_str().unwrap(),
        ],
        &[],
    )
    .await;
    assert_eq!(unreadable.status.code(), Some(1));
    let err = stderr(&unreadable);
    assert!(
        err.contains("cannot read the database password file")
            && err.contains(gone.to_str().unwrap()),
        "{err}"
    );
}
