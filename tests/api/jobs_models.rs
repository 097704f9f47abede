//! Worker pool (back-pressure, progress, results, jobs interrupted by a restart) and the
//! model store (atomic files, checksums, corruption detection), on SQLite and PostgreSQL.

use std::sync::mpsc;
use std::time::Duration;

use crate::helpers::*;
use axum::response::IntoResponse;
use serde_json::{Value, json};
use truecut::api::ApiError;
use truecut::jobs::JobPool;
use truecut::store::Store;

/// Polls `cond` every 10 ms for up to 5 s.
async fn eventually(what: &str, mut cond: impl FnMut() -> bool) {
    for _ in 0..500 {
        if cond() {
            return;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    panic!("timed out waiting for {what}");
}

async fn job_json(app: &TestApp, id: &str) -> Value {
    let r = app.get(&format!("/v1/jobs/{id}")).await;
    assert_eq!(r.status(), 200);
    r.json().await.unwrap()
}

async fn back_pressure(app: TestApp) {
    // 2 workers (helpers' default) and queue 0: the third concurrent item is refused.
    let server = app.server();
    let pool = server.state().jobs.clone();
    let (release_tx, release_rx) = mpsc::channel::<()>();
    let release_rx = std::sync::Arc::new(std::sync::Mutex::new(release_rx));
    let mut holders = Vec::new();
    for _ in 0..2 {
        let p = pool.clone();
        let rx = release_rx.clone();
        holders.push(tokio::spawn(async move {
            p.run(move || rx.lock().unwrap().recv().unwrap()).await
        }));
    }
    eventually("two running", || pool.running() == 2).await;
    // The pool answers its own error; api/error.rs makes it 503 + Retry-After.
    let err = pool.run(|| 1).await.expect_err("pool is full");
    assert!(
        matches!(err, truecut::jobs::Error::Full { workers: 2 }),
        "{err}"
    );
    let resp = ApiError::from(err).into_response();
    assert_eq!(resp.status(), 503);
    assert_eq!(resp.headers()["retry-after"], "2");
    let err = pool
        .submit("x", |_| Ok(json!(1)))
        .await
        .expect_err("pool is full");
    assert_eq!(ApiError::from(err).status(), 503);
    // The gauges and the rejection counter show in /metrics.
    let text = reqwest::get(format!("http://{}/metrics", server.addr()))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(text.contains("truecut_jobs_running 2"), "{text}");
    assert!(text.contains("truecut_jobs_rejected_total 2"), "{text}");
    release_tx.send(()).unwrap();
    release_tx.send(()).unwrap();
    for h in holders {
        h.await.unwrap().unwrap();
    }
    assert_eq!(pool.run(|| 41 + 1).await.unwrap(), 42);
}
on_both_backends!(back_pressure, |c| c.queue = 0);

async fn job_lifecycle(app: TestApp) {
    let pool = app.server().state().jobs.clone();
    let (go_tx, go_rx) = mpsc::channel::<()>();
    let id = pool
        .submit("test-work", move |p| {
            p.set(0.25);
            go_rx.recv().map_err(|e| e.to_string())?;
            p.set(0.75);
            Ok(json!({"answer": 42}))
        })
        .await
        .unwrap();
    let mut seen = Value::Null;
    for _ in 0..500 {
        seen = job_json(&app, &id).await;
        if seen["state"] == "running" && seen["progress"] == 0.25 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(seen["state"], "running", "{seen}");
    assert_eq!(seen["progress"], 0.25);
    go_tx.send(()).unwrap();
    for _ in 0..500 {
        seen = job_json(&app, &id).await;
        if seen["state"] == "done" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(seen["state"], "done", "{seen}");
    assert_eq!(seen["progress"], 1.0);
    assert_eq!(seen["result"], json!({"answer": 42}));
    assert_eq!(seen["kind"], "test-work");

    // Failures and panics end as failed with a reason.
    let failing = pool
        .submit("test-fail", |_| Err("the input was bad".to_string()))
        .await
        .unwrap();
    let panicking = pool.submit("test-panic", |_| panic!("boom")).await.unwrap();
    for (id, needle) in [(failing, "the input was bad"), (panicking, "crashed")] {
        for _ in 0..500 {
            seen = job_json(&app, &id).await;
            if seen["state"] == "failed" {
                break;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert_eq!(seen["state"], "failed", "{seen}");
        assert!(seen["error"].as_str().unwrap().contains(needle), "{seen}");
    }
    // A panic in a synchronous run is a 500, not a crash.
    let err = pool.run(|| -> u8 { panic!("boom") }).await.err().unwrap();
    assert_eq!(ApiError::from(err).status(), 500);
    assert_problem(app.get("/v1/jobs/nope").await, 404, &["job 'nope'"]).await;
}
on_both_backends!(job_lifecycle);

async fn jobs_interrupted_by_shutdown_show_failed(app: TestApp) {
    let mut app = app;
    let pool = app.server().state().jobs.clone();
    let (go_tx, go_rx) = mpsc::channel::<()>();
    let id = pool
        .submit("long", move |_| {
            let _ = go_rx.recv();
            Ok(json!(null))
        })
        .await
        .unwrap();
    eventually("job running", || pool.running() == 1).await;
    // Graceful stop: the job does not end within the grace period (2 s in tests).
    app.restart().await;
    let seen = job_json(&app, &id).await;
    assert_eq!(seen["state"], "failed", "{seen}");
    assert!(
        seen["error"].as_str().unwrap().contains("interrupted"),
        "{seen}"
    );
    go_tx.send(()).unwrap();
}
on_both_backends!(jobs_interrupted_by_shutdown_show_failed);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jobs_in_flight_at_a_crash_show_failed_after_restart() {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(dir.path(), None).await.unwrap();
    let pool = JobPool::start(store.clone(), 1, 4).await.unwrap();
    let (go_tx, go_rx) = mpsc::channel::<()>();
    let (started_tx, started_rx) = mpsc::channel::<()>();
    let running = pool
        .submit("long", move |_| {
            started_tx.send(()).unwrap();
            let _ = go_rx.recv();
            Ok(json!(null))
        })
        .await
        .unwrap();
    started_rx.recv_timeout(Duration::from_secs(5)).unwrap();
    let queued = pool.submit("queued", |_| Ok(json!(null))).await.unwrap();
    assert_eq!(pool.status(&queued).await.unwrap().unwrap().state, "queued");
    // "Crash": no shutdown; a new process opens the same data dir.
    let store2 = Store::open(dir.path(), None).await.unwrap();
    let pool2 = JobPool::start(store2, 1, 4).await.unwrap();
    for id in [&running, &queued] {
        let st = pool2.status(id).await.unwrap().unwrap();
        assert_eq!(st.state, "failed", "{st:?}");
        assert!(st.error.unwrap().contains("interrupted"));
    }
    // Another instance (other data dir) does not touch this instance's jobs.
    let other = tempfile::tempdir().unwrap();
    let s3 = Store::open(other.path(), None).await.unwrap();
    assert_eq!(s3.fail_unfinished_jobs("x").await.unwrap(), 0);
    go_tx.send(()).unwrap();
}

async fn model_store(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let store = app.server().state().store.clone();
    let models = store.models();
    let payload: Vec<u8> = (0..10_000u32)
        .flat_map(|i| (i as f32).to_le_bytes())
        .collect();
    assert_eq!(models.load("m", Some("s"), "net").await.unwrap(), None);
    models.save("m", Some("s"), "net", &payload).await.unwrap();
    models
        .save("m", None, "map", b"machine-level")
        .await
        .unwrap();
    assert_eq!(
        models.load("m", Some("s"), "net").await.unwrap().unwrap(),
        payload
    );
    assert_eq!(
        models.load("m", None, "map").await.unwrap().unwrap(),
        b"machine-level"
    );
    // Replacing keeps exactly one file and no temp files.
    models.save("m", Some("s"), "net", b"v2").await.unwrap();
    let (dir, file) = models.path_of("m", Some("s"), "net").unwrap();
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into())
        .collect();
    assert_eq!(names, vec!["net.tcm".to_string()]);
    // A crash mid-write leaves a partial temp file: the previous model still loads,
    // and the next start sweeps the temp file.
    let tmp = dir.join(".net.tcm.tmp-0123456789");
    std::fs::write(&tmp, b"TRUECUTM partial").unwrap();
    assert_eq!(
        models.load("m", Some("s"), "net").await.unwrap().unwrap(),
        b"v2"
    );
    // Corruption: a flipped payload byte, a truncated file, a foreign file.
    let good = std::fs::read(&file).unwrap();
    let mut bad = good.clone();
    *bad.last_mut().unwrap() ^= 1;
    std::fs::write(&file, &bad).unwrap();
    let err = models
        .load("m", Some("s"), "net")
        .await
        .unwrap_err()
        .to_string();
    assert!(err.contains("checksum"), "{err}");
    std::fs::write(&file, &good[..good.len() - 1]).unwrap();
    let err = models
        .load("m", Some("s"), "net")
        .await
        .unwrap_err()
        .to_string();
    assert!(err.contains("corrupt"), "{err}");
    std::fs::write(&file, b"{\"weights\": []}").unwrap();
    let err = models
        .load("m", Some("s"), "net")
        .await
        .unwrap_err()
        .to_string();
    assert!(err.contains("corrupt"), "{err}");
    // Recorded in the database but the file vanished: an error, not "no model".
    std::fs::remove_file(&file).unwrap();
    let err = models
        .load("m", Some("s"), "net")
        .await
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing"), "{err}");
    // Bad components and unknown machines are refused.
    assert!(models.save("m", Some("../x"), "net", b"1").await.is_err());
    assert!(models.save("nope", None, "net", b"1").await.is_err());
    // Restart sweeps the temp file; deleting the machine removes its model files.
    let mut app = app;
    app.restart().await;
    assert!(!tmp.exists(), "temp file swept at start");
    let store = app.server().state().store.clone();
    assert_eq!(
        store
            .models()
            .load("m", None, "map")
            .await
            .unwrap()
            .unwrap(),
        b"machine-level"
    );
    assert_eq!(app.delete("/v1/machines/m").await.status(), 204);
    assert!(!store.models().root().join("m").exists());
    assert_eq!(store.models().load("m", None, "map").await.unwrap(), None);
}
on_both_backends!(model_store);

async fn documents(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    seed_machine_and_surface(&app, "m", "s_x", 2, 2).await;
    let store = app.server().state().store.clone();
    store
        .put_doc("m", "decomposition", "s/a", &json!({"v": 1}))
        .await
        .unwrap();
    store
        .put_doc("m", "decomposition", "s/a", &json!({"v": 2}))
        .await
        .unwrap();
    store
        .put_doc("m", "decomposition", "s_x/a", &json!({"v": 3}))
        .await
        .unwrap();
    store
        .put_doc("m", "decomposition", "sax/a", &json!({"v": 4}))
        .await
        .unwrap();
    assert_eq!(
        store.get_doc("m", "decomposition", "s/a").await.unwrap(),
        Some(json!({"v": 2}))
    );
    assert_eq!(store.get_doc("m", "other", "s/a").await.unwrap(), None);
    assert_eq!(app.delete("/v1/machines/m/surfaces/s").await.status(), 204);
    assert_eq!(
        store.get_doc("m", "decomposition", "s/a").await.unwrap(),
        None
    );
    assert_eq!(
        store.get_doc("m", "decomposition", "s_x/a").await.unwrap(),
        Some(json!({"v": 3}))
    );
    // `_` is a LIKE wildcard: deleting surface "s_x" must not touch "sax/...".
    assert_eq!(
        app.delete("/v1/machines/m/surfaces/s_x").await.status(),
        204
    );
    assert_eq!(
        store.get_doc("m", "decomposition", "s_x/a").await.unwrap(),
        None
    );
    assert_eq!(
        store.get_doc("m", "decomposition", "sax/a").await.unwrap(),
        Some(json!({"v": 4}))
    );
    assert!(
        store
            .delete_doc("m", "decomposition", "sax/a")
            .await
            .unwrap()
    );
    assert_eq!(
        store.get_doc("m", "decomposition", "sax/a").await.unwrap(),
        None
    );
    assert!(
        store.put_doc("nope", "k", "x", &json!(1)).await.is_err(),
        "machine must exist"
    );
}
on_both_backends!(documents);
