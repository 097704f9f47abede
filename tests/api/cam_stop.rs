//! Issue 41 item 2: cam and motion work stops like the signal cores' (`numeric::stop`
//! checks in interpolation, the servo simulation, the contour distance and the
//! pre-distortion's solver). A contour pre-distortion of a 120-corner zigzag is ~30 s of
//! work on a quiet 2-core machine: cancelled as a job, left by its client, or past
//! `--job-timeout`, its worker is free again within 2 s, and SIGTERM ends the process
//! within its grace even while such a request runs.

use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::helpers::*;

const PROGRAM: &str = "/v1/machines/m/compensated-program";

/// A zigzag finishing pass at F2000 with `2 × passes` corners (40 mm strokes, 2 mm steps).
fn zigzag(passes: usize) -> String {
    let mut lines = vec![
        "G90 G17 G21".to_string(),
        "G0 X0 Y0".into(),
        "G1 Z-1 F300".into(),
    ];
    for i in 0..passes {
        let x = if i % 2 == 0 { 40 } else { 0 };
        lines.push(format!("G1 X{x} Y{} F2000", 2 * i));
        lines.push(format!("G1 X{x} Y{}", 2 * i + 2));
    }
    lines.join("\n")
}

/// Machine `m`: a kv 40 cascade on X, Y, Z.
async fn cascade_machine(app: &TestApp) {
    let cascade = json!({"kv": 40.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    let def = json!({"name": "cascade", "kinematics": "xyz",
        "axes": {"X": cascade, "Y": cascade, "Z": cascade}});
    assert!(
        app.put_json("/v1/machines/m", &def)
            .await
            .status()
            .is_success()
    );
}

fn long_compile() -> Value {
    json!({"gcode": zigzag(60), "contour": true, "volumetric": false})
}

/// Waits until `n` workers are busy (60 s at most).
async fn wait_running(app: &TestApp, n: usize) {
    let pool = app.server().state().jobs.clone();
    let t0 = Instant::now();
    while pool.running() < n {
        assert!(t0.elapsed() < Duration::from_secs(60), "never {n} running");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// How long until no worker is busy (30 s at most).
async fn until_idle(app: &TestApp, t0: Instant) -> Duration {
    let pool = app.server().state().jobs.clone();
    while pool.running() > 0 && t0.elapsed() < Duration::from_secs(30) {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    t0.elapsed()
}

/// Two contour compilations as jobs on a 2-worker pool, cancelled: a small synchronous
/// request is served within 2 s (the trial: 46.7 s), both workers free; then a
/// synchronous compilation whose client gives up after 1 s frees its worker within 2 s.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancel_and_a_gone_client_stop_contour_compilations() {
    let app = spawn_app().await;
    cascade_machine(&app).await;
    assert_eq!(app.server().state().jobs.worker_count(), 2);
    let mut ids = Vec::new();
    for _ in 0..2 {
        let r = app
            .auth(app.client.post(app.url(PROGRAM)))
            .header("prefer", "respond-async")
            .json(&long_compile())
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 202);
        let body: Value = r.json().await.unwrap();
        ids.push(body["job"].as_str().unwrap().to_string());
    }
    wait_running(&app, 2).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let t0 = Instant::now();
    for id in &ids {
        assert_eq!(app.delete(&format!("/v1/jobs/{id}")).await.status(), 200);
    }
    let small = json!({"gcode": "G1 X5 F600\nG1 X10", "contour": true, "volumetric": false});
    let r = app.post_json(PROGRAM, &small).await;
    let served = t0.elapsed();
    assert_eq!(r.status(), 200);
    let freed = until_idle(&app, t0).await;
    println!(
        "cancel: two 120-corner contour compilations cancelled; a sync request served \
         {served:?} after the first DELETE, workers free after {freed:?} (goal < 2 s)"
    );
    assert!(served < Duration::from_secs(2), "served after {served:?}");
    assert!(
        freed < Duration::from_secs(2),
        "workers freed after {freed:?}"
    );
    for id in &ids {
        let j: Value = app
            .get(&format!("/v1/jobs/{id}"))
            .await
            .json()
            .await
            .unwrap();
        assert_eq!(j["state"], "cancelled", "{j}");
    }

    // A client that stops waiting: its compilation stops too.
    let gone = app
        .auth(app.client.post(app.url(PROGRAM)))
        .timeout(Duration::from_secs(1))
        .json(&long_compile())
        .send()
        .await;
    assert!(gone.is_err(), "the compile answered within 1 s");
    let t0 = Instant::now();
    let freed = until_idle(&app, t0).await;
    println!("disconnect: the worker was free {freed:?} after the client left (goal < 2 s)");
    assert!(
        freed < Duration::from_secs(2),
        "worker freed after {freed:?}"
    );
}

/// `--job-timeout` (1 s) stops a synchronous contour compilation: 503 naming the limit,
/// within 3 s of the request, and the worker is free.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn job_timeout_stops_a_contour_compilation() {
    let app = spawn_app_with(|c| c.job_timeout = Duration::from_secs(1)).await;
    cascade_machine(&app).await;
    let t0 = Instant::now();
    let r = app.post_json(PROGRAM, &long_compile()).await;
    let answered = t0.elapsed();
    let status = r.status().as_u16();
    let body: Value = r.json().await.unwrap();
    println!("timeout: a 1 s --job-timeout answered {status} after {answered:?}");
    assert_eq!(status, 503, "{body}");
    assert!(
        body["detail"].as_str().unwrap().contains("--job-timeout"),
        "{body}"
    );
    assert!(
        answered < Duration::from_secs(3),
        "answered after {answered:?}"
    );
    assert!(until_idle(&app, Instant::now()).await < Duration::from_secs(2));
}

/// SIGTERM while a synchronous contour compilation runs: the process ends within its grace
/// (`--shutdown-grace-s 2`) and a second, not after the compilation's ~30 s.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_ends_the_process_within_its_grace_during_a_compilation() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().to_string_lossy().to_string();
    let (mut child, base) = crate::service::start_binary(&[
        "serve",
        "--addr",
        "127.0.0.1:0",
        "--data-dir",
        &data,
        "--shutdown-grace-s",
        "2",
    ]);
    let client = reqwest::Client::new();
    let cascade = json!({"kv": 40.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    let def = json!({"name": "cascade", "kinematics": "xyz",
        "axes": {"X": cascade, "Y": cascade, "Z": cascade}});
    let r = client
        .put(format!("{base}/v1/machines/m"))
        .json(&def)
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success());
    let url = format!("{base}{PROGRAM}");
    let waiting = tokio::spawn(async move { client.post(url).json(&long_compile()).send().await });
    tokio::time::sleep(Duration::from_secs(1)).await;
    assert!(!waiting.is_finished(), "the compile answered within 1 s");
    let t0 = Instant::now();
    let status = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let exited = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        if t0.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("still running 20 s after SIGTERM (grace 2 s)");
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let took = t0.elapsed();
    println!("SIGTERM during a contour compilation: exited {exited:?} after {took:?} (grace 2 s)");
    assert!(took < Duration::from_secs(4), "exited after {took:?}");
    waiting.abort();
}

/// A read token holds at most `--read-token-concurrency` (default 1) computations at once:
/// a second POST of the same read token answers 429 with Retry-After while its first
/// compile runs; a write token is not held back, and once the first request is gone (its
/// client gave up) the read token computes again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_read_token_holds_one_computation_at_a_time() {
    let app =
        spawn_app_with(|c| c.tokens = Some("r-tok read, w-tok write, a-tok admin".into())).await;
    let cascade = json!({"kv": 40.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    let def = json!({"name": "cascade", "kinematics": "xyz",
        "axes": {"X": cascade, "Y": cascade, "Z": cascade}});
    let r = app
        .client
        .put(app.url("/v1/machines/m"))
        .bearer_auth("a-tok")
        .json(&def)
        .send()
        .await
        .unwrap();
    let st = r.status();
    assert!(st.is_success(), "{st}: {}", r.text().await.unwrap());
    let post = |token: &'static str, body: Value| {
        app.client
            .post(app.url(PROGRAM))
            .bearer_auth(token)
            .json(&body)
    };
    let first = tokio::spawn(
        post("r-tok", long_compile())
            .timeout(Duration::from_secs(3))
            .send(),
    );
    wait_running(&app, 1).await;
    let small = json!({"gcode": "G1 X5 F600\nG1 X10", "contour": true, "volumetric": false});
    let r = post("r-tok", small.clone()).send().await.unwrap();
    assert_eq!(r.status(), 429);
    assert_eq!(r.headers()["retry-after"], "1");
    let body: Value = r.json().await.unwrap();
    assert!(
        body["detail"]
            .as_str()
            .unwrap()
            .contains("--read-token-concurrency"),
        "{body}"
    );
    assert_eq!(
        post("w-tok", small.clone()).send().await.unwrap().status(),
        200
    );
    assert!(
        first.await.unwrap().is_err(),
        "the long compile answered within 3 s"
    );
    // The server sees the client gone within milliseconds; then the token's place is free.
    let t0 = Instant::now();
    loop {
        let st = post("r-tok", small.clone()).send().await.unwrap().status();
        if st == 200 {
            break;
        }
        assert_eq!(st, 429);
        assert!(
            t0.elapsed() < Duration::from_secs(2),
            "the place stayed taken"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}
