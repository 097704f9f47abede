//! HTTP end to end: auth matrix, health, metrics, request ids, body limit, the loopback
//! rule, and the real binary (`serve --demo`, graceful SIGTERM shutdown).

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::helpers::*;
use serde_json::{Value, json};

const TOKENS: &str = "r-tok read\nw-tok write\n# comment\na-tok admin\n";

async fn auth_matrix(app: TestApp) {
    let mut app = app;
    // Seed as admin.
    app.token = Some("a-tok".into());
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let up = "/v1/machines/m/surfaces/s/measurements";
    let devs = json!({"deviations": [0.0, 0.1, 0.2, 0.3]});

    // No token / unknown token: 401 with WWW-Authenticate; /healthz stays open.
    app.token = None;
    assert_eq!(app.get("/healthz").await.status(), 200);
    let r = app.get("/v1/machines").await;
    assert_eq!(r.headers()["www-authenticate"], "Bearer realm=\"truecut\"");
    assert_problem(r, 401, &["Authorization: Bearer"]).await;
    app.token = Some("wrong".into());
    assert_problem(app.get("/v1/machines/m").await, 401, &["not known"]).await;

    // read: GETs only.
    app.token = Some("r-tok".into());
    assert_eq!(app.get("/v1/machines/m").await.status(), 200);
    assert_eq!(app.get("/v1/machines/m/surfaces/s").await.status(), 200);
    assert_problem(app.post_json(up, &devs).await, 403, &["'write'", "'read'"]).await;
    assert_problem(
        app.put_json("/v1/machines/m2", &machine_xyz()).await,
        403,
        &["write"],
    )
    .await;
    assert_problem(app.delete("/v1/machines/m").await, 403, &["admin"]).await;

    // write: uploads, but no definitions or deletes.
    app.token = Some("w-tok".into());
    let r = app.post_json(up, &devs).await;
    assert_eq!(r.status(), 201);
    let id = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    assert_problem(
        app.put_json("/v1/machines/m2", &machine_xyz()).await,
        403,
        &["'admin'", "'write'"],
    )
    .await;
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/s2", &flat_surface(2, 2))
            .await,
        403,
        &["admin"],
    )
    .await;
    assert_problem(app.delete(&format!("{up}/{id}")).await, 403, &["admin"]).await;

    // admin: everything; lower-case scheme accepted.
    let r = app
        .client
        .delete(app.url(&format!("{up}/{id}")))
        .header("authorization", "bearer a-tok")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    app.token = Some("a-tok".into());
    assert_eq!(
        app.put_json("/v1/machines/m2", &machine_xyz())
            .await
            .status(),
        201
    );
    assert_eq!(app.delete("/v1/machines/m2").await.status(), 204);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn auth_matrix_with_tokens_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tokens");
    std::fs::write(&file, TOKENS).unwrap();
    let path = file.to_string_lossy().to_string();
    auth_matrix(spawn_app_with(|c| c.tokens = Some(path)).await).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn auth_matrix_with_inline_tokens_on_postgres() {
    if let Some(app) =
        spawn_app_pg_with(|c| c.tokens = Some("r-tok read, w-tok write, a-tok:admin".into())).await
    {
        auth_matrix(app).await;
    }
}

#[tokio::test]
async fn bad_token_settings_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = truecut::config::Config::new("127.0.0.1:0".parse().unwrap(), dir.path().into());
    c.tokens = Some("abc superuser".into());
    let err = truecut::server::start(&c)
        .await
        .err()
        .expect("must refuse")
        .to_string();
    assert!(
        err.contains("superuser") && err.contains("read, write, admin"),
        "{err}"
    );
    c.tokens = Some("lonely".into());
    let err = truecut::server::start(&c)
        .await
        .err()
        .expect("must refuse")
        .to_string();
    assert!(err.contains("TOKEN ROLE"), "{err}");
}

#[tokio::test]
async fn non_loopback_without_tokens_is_refused_and_allowed_with_tokens() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = truecut::config::Config::new("0.0.0.0:0".parse().unwrap(), dir.path().into());
    let err = truecut::server::start(&c)
        .await
        .err()
        .expect("must refuse")
        .to_string();
    assert!(
        err.contains("refusing to listen on 0.0.0.0:0") && err.contains("--tokens"),
        "{err}"
    );
    c.tokens = Some("a-tok admin".into());
    let server = truecut::server::start(&c)
        .await
        .expect("with tokens any address is fine");
    server.stop().await.unwrap();
}

async fn health_metrics_request_id(app: TestApp) {
    let r = app.get("/healthz").await;
    assert_eq!(r.status(), 200);
    assert!(
        r.headers().contains_key("x-request-id"),
        "request id is echoed"
    );
    let health: Value = r.json().await.unwrap();
    assert_eq!(health["status"], "ok", "{health}");
    assert_eq!(
        health["instance"],
        app.server().state().store.instance(),
        "the instance id names this process (the `instance` of its jobs)"
    );
    assert_eq!(health["storage"]["writable"], true, "{health}");
    assert!(
        health["storage"]["free_bytes"].as_u64().unwrap() > 0,
        "{health}"
    );
    // A caller's request id is kept.
    let r = app
        .client
        .get(app.url("/healthz"))
        .header("x-request-id", "abc-123")
        .send()
        .await
        .unwrap();
    assert_eq!(r.headers()["x-request-id"], "abc-123");
    assert_eq!(
        app.put_json("/v1/machines/m", &machine_xyz())
            .await
            .status(),
        201
    );
    assert_eq!(app.get("/v1/machines/nope").await.status(), 404);
    let text = app.get("/metrics").await.text().await.unwrap();
    for needle in [
        "truecut_http_requests_total{route=\"/v1/machines/{machine}\",method=\"PUT\",status=\"201\"} 1",
        "truecut_http_requests_total{route=\"/v1/machines/{machine}\",method=\"GET\",status=\"404\"} 1",
        "truecut_http_requests_total{route=\"/healthz\",method=\"GET\",status=\"200\"} 2",
        "# TYPE truecut_http_request_duration_seconds histogram",
        "truecut_http_request_duration_seconds_bucket{route=\"/healthz\",le=\"+Inf\"} 2",
        "truecut_http_request_duration_seconds_count{route=\"/v1/machines/{machine}\"} 2",
        "truecut_jobs_queued 0",
        "truecut_jobs_running 0",
        "truecut_jobs_rejected_total 0",
    ] {
        assert!(text.contains(needle), "metrics lack {needle:?}:\n{text}");
    }
}
on_both_backends!(health_metrics_request_id);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oversize_bodies_get_413_and_nothing_is_written() {
    let app = spawn_app_with(|c| c.max_body_bytes = 4096).await;
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let big = json!({"deviations": vec![0.125; 2000]});
    assert_problem(
        app.post_json("/v1/machines/m/surfaces/s/measurements", &big)
            .await,
        413,
        &["4096"],
    )
    .await;
    let csv = format!("deviation\n{}", "0.125\n".repeat(2000));
    assert_problem(
        app.post_raw("/v1/machines/m/surfaces/s/measurements", "text/csv", csv)
            .await,
        413,
        &["at most"],
    )
    .await;
    let mut def = machine_xyz();
    def["notes"] = json!("x".repeat(5000));
    assert_problem(app.put_json("/v1/machines/m3", &def).await, 413, &["bytes"]).await;
    let list: Value = app
        .get("/v1/machines/m/surfaces/s/measurements")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(list["measurements"], json!([]));
    assert_problem(app.get("/v1/machines/m3").await, 404, &["m3"]).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_250k_point_csv_upload_round_trips() {
    let app = spawn_app().await;
    seed_machine_and_surface(&app, "m", "small", 2, 2).await;
    // 500 × 500 grid: the surface itself is 250,000 points.
    let r = app
        .put_json("/v1/machines/m/surfaces/big", &flat_surface(500, 500))
        .await;
    assert_eq!(r.status(), 201);
    let mut csv = String::from("id,x,y,z\n");
    for k in 0..250_000usize {
        let z = ((k % 1000) as f64 - 500.0) * 1e-5;
        csv.push_str(&format!("{k},{},{},{z}\n", k % 500, k / 500));
    }
    let r = app
        .post_raw(
            "/v1/machines/m/surfaces/big/measurements?id=full",
            "text/csv",
            csv,
        )
        .await;
    assert_eq!(r.status(), 201);
    let got: Value = app
        .get("/v1/machines/m/surfaces/big/measurements/full")
        .await
        .json()
        .await
        .unwrap();
    let devs = got["deviations"].as_array().unwrap();
    assert_eq!(devs.len(), 250_000);
    assert_eq!(got["n"], 250_000);
    assert!((devs[1234].as_f64().unwrap() - (234.0 - 500.0) * 1e-5).abs() < 1e-15);
    assert!((got["max_abs"].as_f64().unwrap() - 0.005).abs() < 1e-15);
}

/// Starts the real binary and returns (child, base URL) once it prints its address.
pub(crate) fn start_binary(args: &[&str]) -> (std::process::Child, String) {
    let (child, addr, _) = start_binary_logging(args, "warn");
    (child, addr)
}

/// [`start_binary`] with `RUST_LOG` = `log` and every stderr line kept (in order).
pub(crate) fn start_binary_logging(
    args: &[&str],
    log: &str,
) -> (
    std::process::Child,
    String,
    std::sync::Arc<std::sync::Mutex<Vec<String>>>,
) {
    start_binary_env(args, log, &[])
}

/// [`start_binary_logging`] with the environment variables `env` set (after `DATABASE_URL`,
/// `TRUECUT_TOKENS` and `TRUECUT_LOG_FORMAT` are removed, so `env` may set them).
pub(crate) fn start_binary_env(
    args: &[&str],
    log: &str,
    env: &[(&str, &str)],
) -> (
    std::process::Child,
    String,
    std::sync::Arc<std::sync::Mutex<Vec<String>>>,
) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_truecut"))
        .args(args)
        .env_remove("DATABASE_URL")
        .env_remove("TRUECUT_TOKENS")
        .env_remove("TRUECUT_LOG_FORMAT")
        .env("RUST_LOG", log)
        .envs(env.iter().copied())
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .expect("binary starts");
    let stderr = child.stderr.take().unwrap();
    let mut lines = BufReader::new(stderr).lines();
    let kept = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let addr = loop {
        let line = lines.next().expect("binary printed its address").unwrap();
        if let Some(rest) = line.strip_prefix("truecut listening on ") {
            break rest.split_whitespace().next().unwrap().to_string();
        }
        kept.lock().unwrap().push(line);
    };
    // Keep draining stderr so the child never blocks on a full pipe.
    let sink = kept.clone();
    std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            sink.lock().unwrap().push(line);
        }
    });
    (child, addr, kept)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn binary_serves_demo_and_exits_0_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().to_string_lossy().to_string();
    let (mut child, base) = start_binary(&[
        "serve",
        "--addr",
        "127.0.0.1:0",
        "--data-dir",
        &data,
        "--demo",
    ]);
    truecut::cli::client::install_crypto_provider();
    let client = reqwest::Client::new();
    let r = client
        .get(format!(
            "{base}/v1/machines/demo/surfaces/saddle/measurements/demo-1"
        ))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let m: Value = r.json().await.unwrap();
    assert_eq!(m["n"], 41 * 41);
    assert!(m["max_abs"].as_f64().unwrap() > 0.02 && m["max_abs"].as_f64().unwrap() < 0.04);
    let s: Value = client
        .get(format!("{base}/v1/machines/demo/surfaces/saddle"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(s["nominal"]["grid"]["nu"], 41);
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let mut exited = None;
    for _ in 0..100 {
        if let Some(st) = child.try_wait().unwrap() {
            exited = Some(st);
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let st = exited.unwrap_or_else(|| {
        let _ = child.kill();
        panic!("no exit within 10 s of SIGTERM")
    });
    assert!(st.success(), "exit status {st:?}");
    // Restarting with --demo on the same data dir keeps the data (loaded once).
    let (mut child, base) = start_binary(&[
        "serve",
        "--addr",
        "127.0.0.1:0",
        "--data-dir",
        &data,
        "--demo",
    ]);
    let list: Value = client
        .get(format!("{base}/v1/machines"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    // `demo` and `demo-vmc` (with its volumetric map), once each.
    assert_eq!(list["machines"].as_array().unwrap().len(), 2, "{list}");
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    assert!(child.wait().unwrap().success());
}

#[test]
fn binary_refuses_public_bind_without_tokens() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_truecut"))
        .args(["serve", "--addr", "0.0.0.0:0", "--data-dir"])
        .arg(dir.path())
        .env_remove("TRUECUT_TOKENS")
        .env_remove("DATABASE_URL")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("refusing to listen on 0.0.0.0:0"), "{err}");
}
