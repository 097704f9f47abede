//! Crashes of the real binary (SIGKILL, or an abort injected right before a model's commit
//! with `TRUECUT_FAULT_CRASH_AT=model-commit`), on SQLite and on PostgreSQL: after a restart
//! there is no partial upload, no model beside a job reported failed, and every job is in a
//! clear state (re-queued and run again once the dead instance's lease expired), and a re-run
//! decomposition gives the same bits as one never interrupted.

use std::io::Write;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::instances::{PgSchema, seed, segments, start, train, train_long};

const FLAGS: [&str; 4] = ["--workers", "1", "--lease-s", "2"];

/// Runs `body` on SQLite, and on PostgreSQL (when `TRUECUT_TEST_PG` is set).
macro_rules! on_both {
    ($name:ident) => {
        mod $name {
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn sqlite() {
                super::$name(None).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn postgres() {
                if let Some(pg) =
                    crate::instances::PgSchema::create(concat!("crash::", stringify!($name))).await
                {
                    super::$name(Some(&pg)).await;
                }
            }
        }
    };
}

fn url(pg: Option<&PgSchema>) -> Option<&str> {
    pg.map(|p| p.url.as_str())
}

/// SIGKILL while a measurement upload is half sent: after a restart nothing of it is stored,
/// and the same upload then succeeds.
async fn upload_killed_mid_body(pg: Option<&PgSchema>) {
    let dir = tempfile::tempdir().unwrap();
    let inst = start(dir.path(), url(pg), &FLAGS, &[]).await;
    seed(&inst).await;
    let body = format!("{{\"deviations\": [{}]}}", vec!["0.001"; 25].join(", "));
    let addr = inst.base.trim_start_matches("http://").to_string();
    let mut conn = std::net::TcpStream::connect(&addr).unwrap();
    write!(
        conn,
        "POST /v1/machines/m/surfaces/s/measurements HTTP/1.1\r\nHost: {addr}\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .unwrap();
    conn.write_all(&body.as_bytes()[..body.len() / 2]).unwrap();
    conn.flush().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let dir_path = inst.kill9();
    let inst = start(&dir_path, url(pg), &FLAGS, &[]).await;
    let (st, list) = inst.get("/v1/machines/m/surfaces/s/measurements").await;
    assert_eq!(st, 200);
    assert_eq!(list["measurements"], serde_json::json!([]), "{list}");
    let (st, m) = inst
        .send(
            "POST",
            "/v1/machines/m/surfaces/s/measurements",
            &serde_json::from_str::<Value>(&body).unwrap(),
        )
        .await;
    assert_eq!(st, 201, "{m}");
    assert_eq!(m["n"], 25);
    inst.stop();
}
on_both!(upload_killed_mid_body);

/// An abort between writing a model and the commit that records it and marks its job done:
/// after a restart the previous version is served, the job is not failed, and it runs again
/// to a new version (whose number the crashed save had not taken).
async fn model_save_killed_before_commit(pg: Option<&PgSchema>) {
    let dir = tempfile::tempdir().unwrap();
    let inst = start(dir.path(), url(pg), &FLAGS, &[]).await;
    seed(&inst).await;
    let segs = segments(&inst, 3, 8).await;
    let first = train(&inst, &segs, 2).await;
    let j = inst
        .wait_job(&first, Duration::from_secs(60), |j| j["state"] == "done")
        .await;
    assert_eq!(j["result"]["model_version"], 1);
    inst.stop();

    let mut crashing = start(
        dir.path(),
        url(pg),
        &FLAGS,
        &[("TRUECUT_FAULT_CRASH_AT", "model-commit")],
    )
    .await;
    let second = train(&crashing, &segs, 2).await;
    let status = crashing.wait_exit(Duration::from_secs(60));
    assert!(!status.success(), "the injected crash aborts: {status:?}");
    let log = crashing.log();
    assert!(log.contains("aborting on purpose"), "{log}");
    drop(crashing);
    let orphan = dir.path().join("models/m/surfaces/s/step_error_nn.v2.tcm");
    if pg.is_none() {
        assert!(
            orphan.exists(),
            "SQLite: the crash came after the file was written"
        );
    }

    let t0 = Instant::now();
    let inst = start(dir.path(), url(pg), &FLAGS, &[]).await;
    let (_, v) = inst
        .get("/v1/machines/m/surfaces/s/step-error-model/versions")
        .await;
    assert_eq!(
        v["current"], 1,
        "the uncommitted version is not served: {v}"
    );
    assert_eq!(v["versions"].as_array().unwrap().len(), 1, "{v}");
    let j = inst
        .wait_job(&second, Duration::from_secs(60), |j| {
            j["state"] == "done" || j["state"] == "failed"
        })
        .await;
    assert_eq!(j["state"], "done", "{j}");
    assert_eq!(j["attempts"], 2, "{j}");
    assert_eq!(j["result"]["model_version"], 2, "{j}");
    println!(
        "model save killed before commit ({}): job re-run and done as version 2 {:?} after restart",
        if pg.is_some() { "PostgreSQL" } else { "SQLite" },
        t0.elapsed()
    );
    let (_, v) = inst
        .get("/v1/machines/m/surfaces/s/step-error-model/versions")
        .await;
    assert_eq!(v["current"], 2, "{v}");
    assert_eq!(v["versions"][0]["job"], second.as_str(), "{v}");
    assert_eq!(v["versions"][1]["job"], first.as_str(), "{v}");
    let (st, _) = inst.get("/v1/machines/m/surfaces/s/step-error-model").await;
    assert_eq!(st, 200);
    inst.stop();
}
on_both!(model_save_killed_before_commit);

/// SIGKILL mid-job: after a restart the job is not left "running" on a dead instance: once
/// the lease expired it is re-queued and runs again (attempt 2); cancelled, it stores nothing.
async fn job_killed_mid_run(pg: Option<&PgSchema>) {
    let dir = tempfile::tempdir().unwrap();
    let inst = start(dir.path(), url(pg), &FLAGS, &[]).await;
    seed(&inst).await;
    let long = segments(&inst, 40, 60).await;
    let id = train_long(&inst, &long).await;
    inst.wait_job(&id, Duration::from_secs(30), |j| {
        j["state"] == "running" && j["progress"].as_f64().unwrap_or(0.0) > 0.0
    })
    .await;
    let path = inst.kill9();
    let t0 = Instant::now();
    let inst = start(&path, url(pg), &FLAGS, &[]).await;
    let j = inst
        .wait_job(&id, Duration::from_secs(10), |j| j["attempts"] == 2)
        .await;
    println!(
        "job killed mid-run ({}): running again (attempt 2) {:?} after the restart began",
        if pg.is_some() { "PostgreSQL" } else { "SQLite" },
        t0.elapsed()
    );
    assert_eq!(j["instance"], inst.id.as_str(), "{j}");
    assert_eq!(inst.delete(&format!("/v1/jobs/{id}")).await, 200);
    let j = inst.job(&id).await;
    assert_eq!(j["state"], "cancelled", "{j}");
    let (st, _) = inst.get("/v1/machines/m/surfaces/s/step-error-model").await;
    assert_eq!(st, 404, "no model from a killed or cancelled job");
    inst.stop();
}
on_both!(job_killed_mid_run);

/// Issue 25 (same input, same bits): SIGKILL while a stored decomposition runs; after the
/// restart the job runs again (attempt 2, alone on a fresh process) and its result equals,
/// bit for bit, the same input decomposed undisturbed in this test's own process (beside
/// whatever other tests run there), and names the version that computed it.
async fn decomposition_killed_mid_run_gives_the_same_bits(pg: Option<&PgSchema>) {
    let dir = tempfile::tempdir().unwrap();
    let inst = start(dir.path(), url(pg), &FLAGS, &[]).await;
    let signal = crate::decomposition::long_signal(250_001, 3);
    let params = serde_json::json!({"vmd": {"max_iter": 60}});
    let body = serde_json::json!({"signal": signal, "params": params});
    let (st, r) = inst.send("POST", "/v1/decompose", &body).await;
    assert_eq!(st, 202, "{r}");
    let id = r["job"].as_str().unwrap().to_string();
    inst.wait_job(&id, Duration::from_secs(30), |j| j["state"] != "queued")
        .await;
    let path = inst.kill9();
    let inst = start(&path, url(pg), &FLAGS, &[]).await;
    let j = inst
        .wait_job(&id, Duration::from_secs(120), |j| {
            j["state"] == "done" || j["state"] == "failed"
        })
        .await;
    assert_eq!(j["state"], "done", "{j}");
    assert_eq!(j["attempts"], 2, "killed while running, so run again: {j}");
    // The service's input is the JSON text: the signal as serde_json reads it back (its
    // default float parsing may land one unit in the last place off the nearest double).
    let text = serde_json::to_string(&signal).unwrap();
    let read: Vec<f64> = serde_json::from_str(&text).unwrap();
    let moved = (0..read.len())
        .filter(|&i| read[i].to_bits() != signal[i].to_bits())
        .count();
    println!(
        "{moved} of {} samples read back from JSON differ",
        read.len()
    );
    let signal = read;
    let p: truecut::signal::DecomposeParams = serde_json::from_value(params).unwrap();
    let undisturbed = tokio::task::spawn_blocking(move || {
        truecut::signal::decompose(&signal, truecut::signal::Method::CoarseToFine, &p)
    })
    .await
    .unwrap()
    .unwrap();
    // The job's result was stored as JSON text and read back twice (from the database, then
    // from the answer), so the undisturbed one goes the same way.
    let mut undisturbed = serde_json::to_value(&undisturbed).unwrap();
    for _ in 0..2 {
        undisturbed = serde_json::from_str(&undisturbed.to_string()).unwrap();
    }
    crate::decomposition::same_numbers(
        "re-run after kill -9 vs undisturbed",
        &j["result"],
        &undisturbed,
    );
    assert_eq!(j["result"]["truecut_version"], truecut::version(), "{j}");
    inst.stop();
}
on_both!(decomposition_killed_mid_run_gives_the_same_bits);
