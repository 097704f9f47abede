//! Real `truecut serve` processes for the scale-out and crash tests: start the built binary
//! on a free port with its own data dir, talk to it over HTTP, kill it with SIGKILL (a
//! crash) or SIGTERM; a fresh PostgreSQL schema several processes share (dropped after).
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

/// One running binary.
pub struct Instance {
    child: Child,
    /// `http://127.0.0.1:PORT`
    pub base: String,
    /// Its data dir (kept for a restart on the same one).
    pub data_dir: PathBuf,
    /// Its instance id (from `/healthz`).
    pub id: String,
    log: Arc<Mutex<Vec<String>>>,
    client: reqwest::Client,
}

/// Starts `truecut serve` on 127.0.0.1:0 with `data_dir`, the database `url` (None:
/// SQLite in the data dir), extra flags and environment; waits until it answers.
pub async fn start(
    data_dir: &Path,
    url: Option<&str>,
    flags: &[&str],
    env: &[(&str, &str)],
) -> Instance {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_truecut"));
    cmd.args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
        .arg(data_dir)
        .args(flags)
        .env_remove("DATABASE_URL")
        .env_remove("TRUECUT_TOKENS")
        .env_remove("TRUECUT_FAULT_CRASH_AT")
        .env("RUST_LOG", "warn")
        .stderr(Stdio::piped())
        .stdout(Stdio::null());
    if let Some(u) = url {
        cmd.args(["--database-url", u]);
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().expect("the binary starts");
    let stderr = child.stderr.take().unwrap();
    let log = Arc::new(Mutex::new(Vec::new()));
    let (tx, rx) = std::sync::mpsc::channel();
    let log2 = log.clone();
    std::thread::spawn(move || {
        let mut tx = Some(tx);
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if let Some(rest) = line.strip_prefix("truecut listening on ")
                && let Some(t) = tx.take()
            {
                let _ = t.send(rest.split_whitespace().next().unwrap_or("").to_string());
            }
            log2.lock().unwrap().push(line);
        }
    });
    let addr = match rx.recv_timeout(Duration::from_secs(60)) {
        Ok(a) => a,
        Err(_) => {
            let _ = child.kill();
            panic!(
                "the binary did not start: {}",
                log.lock().unwrap().join("\n")
            );
        }
    };
    truecut::cli::client::install_crypto_provider();
    let client = reqwest::Client::new();
    let base = addr; // "http://127.0.0.1:PORT"
    let health: Value = client
        .get(format!("{base}/healthz"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    Instance {
        child,
        base,
        data_dir: data_dir.to_path_buf(),
        id: health["instance"].as_str().unwrap().to_string(),
        log,
        client,
    }
}

impl Instance {
    /// GET `path` → (status, JSON or null).
    pub async fn get(&self, path: &str) -> (u16, Value) {
        let r = self
            .client
            .get(format!("{}{path}", self.base))
            .send()
            .await
            .unwrap();
        let status = r.status().as_u16();
        (status, r.json().await.unwrap_or(Value::Null))
    }

    /// A method with a JSON body → (status, JSON or null).
    pub async fn send(&self, method: &str, path: &str, body: &Value) -> (u16, Value) {
        let m = reqwest::Method::from_bytes(method.as_bytes()).unwrap();
        let r = self
            .client
            .request(m, format!("{}{path}", self.base))
            .json(body)
            .send()
            .await
            .unwrap();
        let status = r.status().as_u16();
        (status, r.json().await.unwrap_or(Value::Null))
    }

    /// DELETE `path` → status.
    pub async fn delete(&self, path: &str) -> u16 {
        self.client
            .delete(format!("{}{path}", self.base))
            .send()
            .await
            .unwrap()
            .status()
            .as_u16()
    }

    /// The job as this instance answers it.
    pub async fn job(&self, id: &str) -> Value {
        let (status, j) = self.get(&format!("/v1/jobs/{id}")).await;
        assert_eq!(status, 200, "{j}");
        j
    }

    /// Polls the job every 50 ms until `done(job)` or `timeout` (panics then).
    pub async fn wait_job(
        &self,
        id: &str,
        timeout: Duration,
        done: impl Fn(&Value) -> bool,
    ) -> Value {
        let t0 = Instant::now();
        loop {
            let j = self.job(id).await;
            if done(&j) {
                return j;
            }
            assert!(
                t0.elapsed() < timeout,
                "job {id} not as expected after {timeout:?}: {j}\n{}",
                self.log()
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    /// What the process wrote on stderr so far.
    pub fn log(&self) -> String {
        self.log.lock().unwrap().join("\n")
    }

    /// SIGKILL: a crash (no shutdown, no lease released). Waits for the process to end.
    pub fn kill9(mut self) -> PathBuf {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
        self.data_dir.clone()
    }

    /// SIGTERM and wait for a clean exit.
    pub fn stop(mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(20) {
            if let Ok(Some(st)) = self.child.try_wait() {
                assert!(st.success(), "exit {st:?}: {}", self.log());
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        panic!("no exit within 20 s of SIGTERM");
    }

    /// Waits for the process to end by itself (e.g. an injected crash); its exit status.
    pub fn wait_exit(&mut self, timeout: Duration) -> std::process::ExitStatus {
        let t0 = Instant::now();
        while t0.elapsed() < timeout {
            if let Ok(Some(st)) = self.child.try_wait() {
                return st;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        panic!(
            "the process did not exit within {timeout:?}: {}",
            self.log()
        );
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A fresh schema in `TRUECUT_TEST_PG`, dropped when this is dropped; `None` (printing
/// SKIPPED) without it.
pub struct PgSchema {
    base: String,
    schema: String,
    /// URL whose connections use the schema.
    pub url: String,
}

impl PgSchema {
    /// Creates the schema.
    pub async fn create(test: &str) -> Option<PgSchema> {
        let Ok(base) = std::env::var("TRUECUT_TEST_PG") else {
            crate::helpers::announce_pg_skip(test);
            return None;
        };
        let schema = format!("t_{}", uuid::Uuid::now_v7().simple());
        use sqlx::{Connection, Executor};
        let mut conn = sqlx::postgres::PgConnection::connect(&base).await.unwrap();
        conn.execute(sqlx::AssertSqlSafe(format!("CREATE SCHEMA {schema}")))
            .await
            .unwrap();
        let _ = conn.close().await;
        let sep = if base.contains('?') { '&' } else { '?' };
        let url = format!("{base}{sep}options[search_path]={schema}");
        Some(PgSchema { base, schema, url })
    }

    /// A connection to the schema (for checks the HTTP API does not answer).
    pub async fn connect(&self) -> sqlx::PgConnection {
        use sqlx::Connection;
        sqlx::postgres::PgConnection::connect(&self.url)
            .await
            .unwrap()
    }
}

impl Drop for PgSchema {
    fn drop(&mut self) {
        crate::helpers::drop_pg_schema(self.base.clone(), self.schema.clone());
    }
}

/// Creates machine `m` with a flat 5 × 5 surface `s` through `inst`.
pub async fn seed(inst: &Instance) {
    let (st, _) = inst
        .send("PUT", "/v1/machines/m", &crate::helpers::machine_xyz())
        .await;
    assert_eq!(st, 201);
    let (st, _) = inst
        .send(
            "PUT",
            "/v1/machines/m/surfaces/s",
            &crate::helpers::flat_surface(5, 5),
        )
        .await;
    assert_eq!(st, 201);
}

/// Training segments from the stateless sample route: `lines` × `points` on the reference
/// surface (about lines × (points − 1) segments).
pub async fn segments(inst: &Instance, lines: usize, points: usize) -> Value {
    let (st, s) = inst
        .send(
            "POST",
            "/v1/step-error/samples",
            &json!({"surface": {"reference": 1}, "plan": {"tool_radius_mm": 5.0, "lines": lines, "points_per_line": points}}),
        )
        .await;
    assert_eq!(st, 200, "{s}");
    s["segments"].clone()
}

/// Queues a training of the step-error network of m/s through `inst`; the job id.
pub async fn train(inst: &Instance, segments: &Value, epochs: usize) -> String {
    let (st, r) = inst
        .send(
            "POST",
            "/v1/machines/m/surfaces/s/step-error-model",
            &json!({"tool_radius": 5.0, "segments": segments, "epochs": epochs, "hidden": [8]}),
        )
        .await;
    assert_eq!(st, 202, "{r}");
    r["job"].as_str().unwrap().to_string()
}

/// Queues a training that runs until cancelled (the paper's preset: no early stopping,
/// 20,000 epochs); the job id.
pub async fn train_long(inst: &Instance, segments: &Value) -> String {
    let (st, r) = inst
        .send(
            "POST",
            "/v1/machines/m/surfaces/s/step-error-model",
            &json!({"tool_radius": 5.0, "segments": segments, "epochs": 20000, "preset": "paper"}),
        )
        .await;
    assert_eq!(st, 202, "{r}");
    r["job"].as_str().unwrap().to_string()
}
