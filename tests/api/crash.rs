//! Crashes of the real binary (SIGKILL, or an abort injected right before a model's commit
//! with `TRUECUT_FAULT_CRASH_AT=model-commit`), on SQLite and on PostgreSQL: after a restart
//! there is no partial upload, no model beside a job reported failed, and every job is in a
//! clear state (re-queued and run again once the dead instance's lease expired).

use std::io::Write;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::instances::{PgSchema, seed, segments, start, train, train_long};

const FLAGS: [&str; 4] = ["--workers", "1", "--lease-s", "1"];

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
