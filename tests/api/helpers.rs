//! Test helpers: spawn the real server in-process on 127.0.0.1:0 with a fresh data dir,
//! on SQLite (`spawn_app`) or PostgreSQL (`spawn_app_pg`, when `TRUECUT_TEST_PG` is set;
//! each app gets its own schema, dropped afterwards). Declared by `tests/api/main.rs`.
#![allow(dead_code, unused_macros)]

/// Defines `mod NAME { sqlite, postgres }` tests running `async fn NAME(app: TestApp)` on
/// both backends (the PostgreSQL one prints SKIPPED when TRUECUT_TEST_PG is unset).
/// `on_both_backends!(name, |c| c.queue = 0)` adjusts the configuration first.
/// `tests/api/main.rs` declares `helpers` first with `#[macro_use]`, so every module sees it.
macro_rules! on_both_backends {
    ($name:ident) => {
        mod $name {
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn sqlite() {
                super::$name(crate::helpers::spawn_app().await).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn postgres() {
                if let Some(app) = crate::helpers::spawn_app_pg().await {
                    super::$name(app).await;
                }
            }
        }
    };
    ($name:ident, $configure:expr) => {
        mod $name {
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn sqlite() {
                super::$name(crate::helpers::spawn_app_with($configure).await).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn postgres() {
                if let Some(app) = crate::helpers::spawn_app_pg_with($configure).await {
                    super::$name(app).await;
                }
            }
        }
    };
}

use std::io::Write;
use std::sync::Arc;

use truecut::config::Config;
use truecut::server::Server;

/// A running test server and a client for it.
pub struct TestApp {
    /// `http://127.0.0.1:PORT`
    pub addr: String,
    /// HTTP client (no default token; see [`TestApp::token`]).
    pub client: reqwest::Client,
    /// Bearer token the helper methods send, if any.
    pub token: Option<String>,
    /// The configuration the server was started with (same data dir on restart).
    pub config: Config,
    /// Keeps the temp data dir alive.
    pub data_dir: Arc<tempfile::TempDir>,
    server: Option<Server>,
    pg_schema: Option<(String, String)>,
}

fn fresh_config(dir: &tempfile::TempDir) -> Config {
    let mut config = Config::new("127.0.0.1:0".parse().unwrap(), dir.path().to_path_buf());
    config.workers = Some(2);
    config.shutdown_grace_s = 2;
    config
}

async fn launch(
    config: Config,
    data_dir: Arc<tempfile::TempDir>,
    pg_schema: Option<(String, String)>,
) -> TestApp {
    let server = truecut::server::start(&config)
        .await
        .expect("test server failed to start");
    // reqwest is built with rustls but no default crypto provider (Cargo.toml).
    truecut::cli::client::install_crypto_provider();
    TestApp {
        addr: format!("http://{}", server.addr()),
        client: reqwest::Client::new(),
        token: None,
        config,
        data_dir,
        server: Some(server),
        pg_schema,
    }
}

/// SQLite, port 0, fresh temp data dir, no tokens (every request is admin).
pub async fn spawn_app() -> TestApp {
    spawn_app_with(|_| {}).await
}

/// Like [`spawn_app`] after `configure` adjusts the configuration (tokens, limits, workers).
pub async fn spawn_app_with(configure: impl FnOnce(&mut Config)) -> TestApp {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut config = fresh_config(&dir);
    configure(&mut config);
    launch(config, Arc::new(dir), None).await
}

/// Says loudly (bypassing the test harness's output capture) that a PostgreSQL test is skipped.
pub fn announce_pg_skip(test: &str) {
    let _ = writeln!(
        std::io::stderr(),
        "SKIPPED on PostgreSQL: {test}: TRUECUT_TEST_PG is not set \
         (e.g. TRUECUT_TEST_PG=postgres://postgres@127.0.0.1:5432/test)"
    );
}

/// PostgreSQL from `TRUECUT_TEST_PG` in a fresh schema, or `None` (printing why).
pub async fn spawn_app_pg() -> Option<TestApp> {
    spawn_app_pg_with(|_| {}).await
}

/// Like [`spawn_app_pg`] after `configure` adjusts the configuration.
pub async fn spawn_app_pg_with(configure: impl FnOnce(&mut Config)) -> Option<TestApp> {
    let Ok(base) = std::env::var("TRUECUT_TEST_PG") else {
        announce_pg_skip(std::thread::current().name().unwrap_or("test"));
        return None;
    };
    let schema = format!("t_{}", uuid::Uuid::now_v7().simple());
    {
        use sqlx::{Connection, Executor};
        let mut conn = sqlx::postgres::PgConnection::connect(&base)
            .await
            .expect("cannot connect to TRUECUT_TEST_PG");
        conn.execute(sqlx::AssertSqlSafe(format!("CREATE SCHEMA {schema}")))
            .await
            .expect("cannot create test schema");
        let _ = conn.close().await;
    }
    let sep = if base.contains('?') { '&' } else { '?' };
    let url = format!("{base}{sep}options[search_path]={schema}");
    let dir = tempfile::tempdir().expect("temp dir");
    let mut config = fresh_config(&dir);
    config.database_url = Some(url);
    configure(&mut config);
    Some(launch(config, Arc::new(dir), Some((base, schema))).await)
}

impl TestApp {
    /// Full URL of `path`.
    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.addr, path)
    }

    pub fn auth(&self, rb: reqwest::RequestBuilder) -> reqwest::RequestBuilder {
        match &self.token {
            Some(t) => rb.bearer_auth(t),
            None => rb,
        }
    }

    /// GET `path`.
    pub async fn get(&self, path: &str) -> reqwest::Response {
        self.auth(self.client.get(self.url(path)))
            .send()
            .await
            .expect("request failed")
    }

    /// DELETE `path`.
    pub async fn delete(&self, path: &str) -> reqwest::Response {
        self.auth(self.client.delete(self.url(path)))
            .send()
            .await
            .expect("request failed")
    }

    /// PUT `path` with a JSON body.
    pub async fn put_json(&self, path: &str, body: &serde_json::Value) -> reqwest::Response {
        self.auth(self.client.put(self.url(path)).json(body))
            .send()
            .await
            .expect("request failed")
    }

    /// POST `path` with a JSON body.
    pub async fn post_json(&self, path: &str, body: &serde_json::Value) -> reqwest::Response {
        self.auth(self.client.post(self.url(path)).json(body))
            .send()
            .await
            .expect("request failed")
    }

    /// POST `path` with a raw body and Content-Type.
    pub async fn post_raw(
        &self,
        path: &str,
        content_type: &str,
        body: impl Into<reqwest::Body>,
    ) -> reqwest::Response {
        self.auth(
            self.client
                .post(self.url(path))
                .header("content-type", content_type)
                .body(body),
        )
        .send()
        .await
        .expect("request failed")
    }

    /// Polls `GET /v1/jobs/{id}` every 100 ms until the job is done (its JSON) or failed
    /// (panics); panics after 60 s.
    pub async fn wait_job(&self, id: &str) -> serde_json::Value {
        for _ in 0..600 {
            let r: serde_json::Value = self
                .get(&format!("/v1/jobs/{id}"))
                .await
                .json()
                .await
                .unwrap();
            match r["state"].as_str() {
                Some("done") => return r,
                Some("failed") => panic!("job failed: {r}"),
                _ => tokio::time::sleep(std::time::Duration::from_millis(100)).await,
            }
        }
        panic!("job {id} did not finish in 60 s");
    }

    /// The running server (store and jobs are reachable through `state()`).
    pub fn server(&self) -> &Server {
        self.server.as_ref().expect("server is stopped")
    }

    /// Graceful stop, then start again on the same data dir and database (new port).
    pub async fn restart(&mut self) {
        if let Some(s) = self.server.take() {
            s.stop().await.expect("graceful stop failed");
        }
        let server = truecut::server::start(&self.config)
            .await
            .expect("test server failed to restart");
        self.addr = format!("http://{}", server.addr());
        self.server = Some(server);
    }

    /// Graceful stop.
    pub async fn stop(mut self) {
        if let Some(s) = self.server.take() {
            s.stop().await.expect("graceful stop failed");
        }
    }
}

impl Drop for TestApp {
    fn drop(&mut self) {
        if let Some((base, schema)) = self.pg_schema.take() {
            drop_pg_schema(base, schema);
        }
    }
}

/// Drops a test's PostgreSQL schema, from synchronous code (a `Drop`) that may run inside the
/// test's runtime: on a thread with its own runtime. Errors are ignored (the schema is
/// throw-away; a leftover one only costs space).
pub fn drop_pg_schema(base: String, schema: String) {
    let _ = std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .ok()?;
        rt.block_on(async {
            use sqlx::{Connection, Executor};
            let mut conn = sqlx::postgres::PgConnection::connect(&base).await.ok()?;
            conn.execute(sqlx::AssertSqlSafe(format!(
                "DROP SCHEMA IF EXISTS {schema} CASCADE"
            )))
            .await
            .ok()?;
            conn.close().await.ok()
        })
    })
    .join();
}

/// A `nu × nv` flat test surface (z = 0, normals +z) with grid spacing 1 mm.
pub fn flat_surface(nu: usize, nv: usize) -> serde_json::Value {
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for iv in 0..nv {
        for iu in 0..nu {
            points.push(serde_json::json!([iu as f64, iv as f64, 0.0]));
            normals.push(serde_json::json!([0.0, 0.0, 1.0]));
        }
    }
    serde_json::json!({"nominal": {"grid": {"nu": nu, "nv": nv, "points": points, "normals": normals}}, "tool_radius": 3.0})
}

/// A 3-axis machine definition with servo models.
pub fn machine_xyz() -> serde_json::Value {
    serde_json::json!({"name": "test mill", "kinematics": "xyz",
        "axes": {"X": {"kv": 30.0, "kff": 0.5}, "Y": {"kv": 30.0}, "Z": {"kv": 25.0, "kp_v": 300.0, "ti_v": 0.01, "tc": 0.001}}})
}

/// Creates machine `m` and an `nu × nv` flat surface `s` on it; panics on failure.
pub async fn seed_machine_and_surface(app: &TestApp, m: &str, s: &str, nu: usize, nv: usize) {
    let r = app
        .put_json(&format!("/v1/machines/{m}"), &machine_xyz())
        .await;
    assert!(r.status().is_success(), "PUT machine: {}", r.status());
    let r = app
        .put_json(
            &format!("/v1/machines/{m}/surfaces/{s}"),
            &flat_surface(nu, nv),
        )
        .await;
    assert!(r.status().is_success(), "PUT surface: {}", r.status());
}

/// Asserts a problem+json error with `status` whose detail contains every `needle`.
pub async fn assert_problem(
    resp: reqwest::Response,
    status: u16,
    needles: &[&str],
) -> serde_json::Value {
    let got = resp.status().as_u16();
    let ct = resp
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_string();
    let text = resp.text().await.unwrap_or_default();
    assert_eq!(got, status, "status (body: {text})");
    assert!(
        ct.starts_with("application/problem+json"),
        "content-type {ct} (body: {text})"
    );
    let body: serde_json::Value = serde_json::from_str(&text).expect("problem body is JSON");
    assert_eq!(body["status"], status, "{body}");
    assert!(
        body["type"].is_string() && body["title"].is_string(),
        "{body}"
    );
    let detail = body["detail"].as_str().unwrap_or("");
    for n in needles {
        assert!(detail.contains(n), "detail {detail:?} lacks {n:?}");
    }
    body
}

/// A deviation CSV for a 2 x 2 surface, padded with comment lines to exactly `len` bytes
/// (at least 64): a large body that is cheap to parse and store.
pub fn padded_deviation_csv(len: usize) -> Vec<u8> {
    let mut csv = b"deviation\n0.01\n0.02\n0.0\n-0.01\n".to_vec();
    loop {
        let room = len - csv.len();
        let line = if room >= 2048 { 1024 } else { room };
        csv.extend_from_slice(b"# ");
        csv.resize(csv.len() + line - 3, b'x');
        csv.push(b'\n');
        if line == room {
            return csv;
        }
    }
}

/// Opens a connection and sends the head of `method path` with `headers` (each `Name: value`);
/// returns the stream to send the body on.
pub async fn raw_request(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[&str],
) -> tokio::net::TcpStream {
    use tokio::io::AsyncWriteExt;
    let host = addr.trim_start_matches("http://");
    let mut s = tokio::net::TcpStream::connect(host).await.unwrap();
    let mut head = format!("{method} {path} HTTP/1.1\r\nHost: {host}\r\n");
    for h in headers {
        head.push_str(h);
        head.push_str("\r\n");
    }
    head.push_str("\r\n");
    s.write_all(head.as_bytes()).await.unwrap();
    s
}

/// The start of the answer on `s` (up to 8 KiB), or a panic when none comes `within`.
pub async fn raw_answer(s: &mut tokio::net::TcpStream, within: std::time::Duration) -> String {
    use tokio::io::AsyncReadExt;
    let mut buf = vec![0u8; 8192];
    let n = tokio::time::timeout(within, s.read(&mut buf))
        .await
        .expect("no answer in time")
        .unwrap();
    String::from_utf8_lossy(&buf[..n]).into_owned()
}
