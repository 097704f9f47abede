//! TLS to PostgreSQL (issue 41 item 8), against the TLS-only cluster of `.ci/pg_tls.sh`:
//! `eval "$(.ci/pg_tls.sh)"` sets `TRUECUT_TEST_PG_TLS` (a `sslmode=verify-full` URL with
//! the test CA as `sslrootcert`), `TRUECUT_TEST_PG_TLS_ROOT` and
//! `TRUECUT_TEST_PG_TLS_WRONG_ROOT` (an unrelated CA). The server itself says whether a
//! connection is encrypted (`pg_stat_ssl`), and refuses plain ones (`hostssl` only). Every
//! test prints SKIPPED without `TRUECUT_TEST_PG_TLS`. Run:
//! `cargo test --test api pg_tls -- --nocapture` (the refusals print how long they took).

use std::io::Write;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;
use sqlx::{Connection, Executor};
use truecut::store::{ConnectError, Store, TlsProblem};

use crate::service::start_binary_env;

/// Wait for the database that the refusal tests give [`Store::open_waiting`] (and the
/// binary's `TRUECUT_DB_WAIT_S`): a refusal that were retried would take all of it.
const WAIT: Duration = Duration::from_secs(20);

/// A refusal must come within this (one handshake, no retry loop).
const PROMPT: Duration = Duration::from_secs(3);

/// The TLS cluster of `.ci/pg_tls.sh`.
struct TlsCluster {
    /// `TRUECUT_TEST_PG_TLS` (verify-full with the right root).
    url: String,
    /// The URL up to its query (`postgres://postgres@127.0.0.1:5433/test`).
    base: String,
    /// The CA that signed the server's certificate.
    root: String,
    /// A CA that did not.
    wrong_root: String,
}

impl TlsCluster {
    /// The cluster, or `None` after printing SKIPPED (bypassing the harness's capture).
    fn from_env(test: &str) -> Option<TlsCluster> {
        let Ok(url) = std::env::var("TRUECUT_TEST_PG_TLS") else {
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED on PostgreSQL over TLS: {test}: TRUECUT_TEST_PG_TLS is not set \
                 (eval \"$(.ci/pg_tls.sh)\" starts a TLS-only cluster and sets it)"
            );
            return None;
        };
        let var = |name: &str| {
            std::env::var(name).unwrap_or_else(|_| panic!("TRUECUT_TEST_PG_TLS is set, {name} not"))
        };
        let base = url.split('?').next().unwrap().to_string();
        Some(TlsCluster {
            root: var("TRUECUT_TEST_PG_TLS_ROOT"),
            wrong_root: var("TRUECUT_TEST_PG_TLS_WRONG_ROOT"),
            url,
            base,
        })
    }

    /// The database URL with `query` (no leading `?`).
    fn with(&self, query: &str) -> String {
        format!("{}?{query}", self.base)
    }

    /// `url` and a fresh schema in it (dropped with the returned guard); `url` gains
    /// `options[search_path]`. The schema is created over the verified URL.
    async fn schema(&self, url: &str) -> (String, SchemaGuard) {
        let schema = format!("t_{}", uuid::Uuid::now_v7().simple());
        let mut conn = self.admin().await;
        conn.execute(sqlx::AssertSqlSafe(format!("CREATE SCHEMA {schema}")))
            .await
            .unwrap();
        let _ = conn.close().await;
        let guard = SchemaGuard {
            url: self.url.clone(),
            schema: schema.clone(),
        };
        (format!("{url}&options[search_path]={schema}"), guard)
    }

    /// A connection over the verified URL, for asking the server about its backends.
    async fn admin(&self) -> sqlx::PgConnection {
        sqlx::postgres::PgConnection::connect(&self.url)
            .await
            .expect("cannot connect to TRUECUT_TEST_PG_TLS")
    }
}

/// Drops a test schema when dropped.
struct SchemaGuard {
    url: String,
    schema: String,
}

impl Drop for SchemaGuard {
    fn drop(&mut self) {
        crate::helpers::drop_pg_schema(self.url.clone(), self.schema.clone());
    }
}

/// A started binary, killed when dropped (a failed assert leaves no server behind).
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if let Ok(None) = self.0.try_wait() {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
}

/// Whether the connection that answers on `pool` is encrypted, and with which protocol,
/// as the server sees it.
async fn ssl_of(pool: &sqlx::AnyPool) -> (bool, String) {
    sqlx::query_as::<_, (bool, String)>(
        "SELECT ssl, COALESCE(version, '') FROM pg_stat_ssl WHERE pid = pg_backend_pid()",
    )
    .fetch_one(pool)
    .await
    .unwrap()
}

/// [`Store::open_waiting`] with [`WAIT`] that must fail: its error and how long it took.
async fn open_refused(url: &str) -> (anyhow::Error, Duration) {
    let dir = tempfile::tempdir().unwrap();
    let t0 = Instant::now();
    let opened = Store::open_waiting(dir.path(), Some(url), WAIT).await;
    let took = t0.elapsed();
    match opened {
        Ok(_) => panic!("{url} opened"),
        Err(e) => (e, took),
    }
}

fn tls_problem(e: &anyhow::Error) -> Option<TlsProblem> {
    match e.downcast_ref::<ConnectError>()? {
        ConnectError::Tls { problem, .. } => Some(*problem),
        _ => None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_store_connects_over_verified_tls() {
    let Some(pg) = TlsCluster::from_env("the_store_connects_over_verified_tls") else {
        return;
    };
    let (url, _schema) = pg.schema(&pg.url).await;
    let dir = tempfile::tempdir().unwrap();
    // The function `serve` opens its database with (src/server.rs).
    let store = Store::open_waiting(dir.path(), Some(&url), Duration::ZERO)
        .await
        .expect("verify-full with the right root opens");
    let (ssl, version) = ssl_of(store.pool()).await;
    println!("verify-full: ssl = {ssl}, {version}");
    assert!(ssl, "the store's connection is not encrypted");
    assert!(version.starts_with("TLSv1."), "{version}");
    // The migrations ran through it.
    let tables: i64 = sqlx::query_scalar(
        "SELECT COUNT(*) FROM information_schema.tables \
         WHERE table_schema = current_schema() AND table_name = 'machines'",
    )
    .fetch_one(store.pool())
    .await
    .unwrap();
    assert_eq!(tables, 1);
    store.close().await;
    // What a new connection and a query cost (printed, not judged), against a plain
    // connection to the main cluster when TRUECUT_TEST_PG names it.
    let mut urls = vec![
        pg.with(&format!("sslmode=verify-full&sslrootcert={}", pg.root)),
        pg.with("sslmode=require"),
    ];
    if let Ok(plain) = std::env::var("TRUECUT_TEST_PG") {
        let plain = plain.split('?').next().unwrap().to_string();
        urls.push(format!("{plain}?sslmode=disable"));
    }
    for url in urls {
        let mut ms = Vec::new();
        for _ in 0..5 {
            let t0 = Instant::now();
            let conn = sqlx::postgres::PgConnection::connect(&url).await.unwrap();
            ms.push(t0.elapsed().as_secs_f64() * 1000.0);
            let _ = conn.close().await;
        }
        ms.sort_by(f64::total_cmp);
        println!("a new connection to {url}: median {:.1} ms", ms[2]);
        let mut conn = sqlx::postgres::PgConnection::connect(&url).await.unwrap();
        let t0 = Instant::now();
        for i in 0..50i64 {
            let _: (i64,) = sqlx::query_as("SELECT $1::int8")
                .bind(i)
                .fetch_one(&mut conn)
                .await
                .unwrap();
        }
        println!(
            "  then 50 queries on it: {:.1} ms",
            t0.elapsed().as_secs_f64() * 1000.0
        );
        let _ = conn.close().await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wrong_root_is_refused_at_once_with_what_to_check() {
    let Some(pg) = TlsCluster::from_env("a_wrong_root_is_refused_at_once_with_what_to_check")
    else {
        return;
    };
    let url = pg.with(&format!(
        "sslmode=verify-full&sslrootcert={}",
        pg.wrong_root
    ));
    let (e, took) = open_refused(&url).await;
    let sentence = format!("{e:#}");
    println!("wrong root refused in {} ms: {sentence}", took.as_millis());
    assert!(took < PROMPT, "took {took:?} (retried?): {sentence}");
    assert_eq!(
        tls_problem(&e),
        Some(TlsProblem::UnknownIssuer),
        "{sentence}"
    );
    assert!(
        sentence.starts_with("TLS to the database (postgres://postgres@127.0.0.1:"),
        "{sentence}"
    );
    assert!(sentence.contains("certificate"), "{sentence}");
    assert!(
        sentence.contains("set sslrootcert in the URL"),
        "{sentence}"
    );
    // The driver's own words come after, in the cause chain.
    assert!(sentence.contains("UnknownIssuer"), "{sentence}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_host_the_certificate_does_not_list_is_refused_at_once() {
    let Some(pg) = TlsCluster::from_env("a_host_the_certificate_does_not_list_is_refused_at_once")
    else {
        return;
    };
    // The cluster also listens on 127.0.0.2, which its certificate does not name.
    let other = pg.base.replacen("@127.0.0.1:", "@127.0.0.2:", 1);
    assert_ne!(other, pg.base, "TRUECUT_TEST_PG_TLS is not on 127.0.0.1");
    let port = pg
        .base
        .rsplit(':')
        .next()
        .unwrap()
        .split('/')
        .next()
        .unwrap();
    if std::net::TcpStream::connect(format!("127.0.0.2:{port}")).is_err() {
        println!("SKIPPED the host-name check: nothing listens on 127.0.0.2:{port}");
        return;
    }
    let url = format!("{other}?sslmode=verify-full&sslrootcert={}", pg.root);
    let (e, took) = open_refused(&url).await;
    let sentence = format!("{e:#}");
    println!("wrong host refused in {} ms: {sentence}", took.as_millis());
    assert!(took < PROMPT, "took {took:?} (retried?): {sentence}");
    assert_eq!(tls_problem(&e), Some(TlsProblem::WrongHost), "{sentence}");
    assert!(
        sentence.contains("not a name the server's certificate lists"),
        "{sentence}"
    );
    // verify-ca checks the CA only: the same address passes.
    let (url, _schema) = pg
        .schema(&format!(
            "{other}?sslmode=verify-ca&sslrootcert={}",
            pg.root
        ))
        .await;
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(dir.path(), Some(&url)).await.unwrap();
    assert!(ssl_of(store.pool()).await.0);
    store.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_binary_serves_over_verified_tls_and_every_backend_is_encrypted() {
    let Some(pg) =
        TlsCluster::from_env("the_binary_serves_over_verified_tls_and_every_backend_is_encrypted")
    else {
        return;
    };
    // A name of its own, so that only this binary's backends are counted.
    let app_name = format!("truecut-tls-{}", uuid::Uuid::now_v7().simple());
    let (url, _schema) = pg
        .schema(&format!("{}&application_name={app_name}", pg.url))
        .await;
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().to_string_lossy().to_string();
    let (child, base, _log) = start_binary_env(
        &["serve", "--addr", "127.0.0.1:0", "--data-dir", &data],
        "warn",
        &[("DATABASE_URL", &url)],
    );
    let mut child = KillOnDrop(child);
    truecut::cli::client::install_crypto_provider();
    let client = reqwest::Client::new();
    let machine = crate::helpers::machine_xyz();
    let r = client
        .put(format!("{base}/v1/machines/tls-m"))
        .json(&machine)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let got: Value = client
        .get(format!("{base}/v1/machines/tls-m"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(got["name"], machine["name"], "{got}");
    let health: Value = client
        .get(format!("{base}/healthz"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(health["database"]["backend"], "postgres", "{health}");
    assert_eq!(health["database"]["reachable"], true, "{health}");

    let mut admin = pg.admin().await;
    let (backends, encrypted): (i64, i64) = sqlx::query_as(
        "SELECT COUNT(*), COUNT(*) FILTER (WHERE s.ssl) \
         FROM pg_stat_activity a JOIN pg_stat_ssl s ON s.pid = a.pid \
         WHERE a.application_name = $1",
    )
    .bind(&app_name)
    .fetch_one(&mut admin)
    .await
    .unwrap();
    let _ = Command::new("kill")
        .args(["-TERM", &child.0.id().to_string()])
        .status();
    let status = child.0.wait().unwrap();
    println!("the binary's backends: {backends}, encrypted: {encrypted}");
    // The request pool, the heartbeat's and the reaper's connections at least.
    assert!(backends >= 3, "{backends} backends of {app_name}");
    assert_eq!(
        encrypted, backends,
        "a backend of the binary is not encrypted"
    );
    assert!(status.success(), "{status:?}");
    let _ = admin.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_binary_exits_at_once_on_a_wrong_root() {
    let Some(pg) = TlsCluster::from_env("the_binary_exits_at_once_on_a_wrong_root") else {
        return;
    };
    let url = pg.with(&format!(
        "sslmode=verify-full&sslrootcert={}",
        pg.wrong_root
    ));
    let dir = tempfile::tempdir().unwrap();
    let t0 = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_truecut"))
        .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
        .arg(dir.path())
        .env_remove("TRUECUT_TOKENS")
        .env("DATABASE_URL", &url)
        .env("TRUECUT_DB_WAIT_S", WAIT.as_secs().to_string())
        .output()
        .unwrap();
    let took = t0.elapsed();
    let err = String::from_utf8_lossy(&out.stderr);
    println!("the binary exited in {} ms: {err}", took.as_millis());
    assert!(!out.status.success());
    assert!(took < PROMPT, "took {took:?} (retried?): {err}");
    assert!(err.contains("TLS to the database"), "{err}");
    assert!(err.contains("sslrootcert"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sslmode_require_encrypts_without_a_root() {
    let Some(pg) = TlsCluster::from_env("sslmode_require_encrypts_without_a_root") else {
        return;
    };
    // Neither the URL nor the environment names a root: require checks no certificate.
    assert!(std::env::var_os("PGSSLROOTCERT").is_none());
    let (url, _schema) = pg.schema(&pg.with("sslmode=require")).await;
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(dir.path(), Some(&url)).await.unwrap();
    let (ssl, version) = ssl_of(store.pool()).await;
    println!("require: ssl = {ssl}, {version}");
    assert!(ssl);
    store.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_plain_connection_to_a_tls_only_server_is_refused_with_a_sentence() {
    let Some(pg) =
        TlsCluster::from_env("a_plain_connection_to_a_tls_only_server_is_refused_with_a_sentence")
    else {
        return;
    };
    let (e, took) = open_refused(&pg.with("sslmode=disable")).await;
    let sentence = format!("{e:#}");
    println!("plain refused in {} ms: {sentence}", took.as_millis());
    assert!(took < PROMPT, "took {took:?}: {sentence}");
    assert_eq!(tls_problem(&e), Some(TlsProblem::TlsRequired), "{sentence}");
    assert!(sentence.contains("without TLS"), "{sentence}");
    assert!(
        sentence.contains("sslmode=verify-full&sslrootcert="),
        "{sentence}"
    );
    // The server's own words follow.
    assert!(sentence.contains("no encryption"), "{sentence}");
}
