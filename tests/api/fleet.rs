//! Running several instances (issue 25, items 2 and 6): `/healthz` reports the database
//! (reachable, latency, the request pool's use) and this instance's lease; `/readyz`
//! answers a load balancer; an instance whose lease lapses fences itself and says so, then
//! registers again; models saved before migration 0003 (files in the data dir of the
//! instance that trained them) are copied into PostgreSQL when that instance starts, and
//! every instance serves them. PostgreSQL tests are SKIPPED without `TRUECUT_TEST_PG`.

use std::time::{Duration, Instant};

use serde_json::{Value, json};
use sha2::Digest;
use sqlx::{Connection, Executor};
use truecut::volumetric::{ShapeFamily, SyntheticMachine};

use crate::helpers::*;
use crate::instances::{PgSchema, start};

async fn json_of(app: &TestApp, path: &str) -> (u16, Value) {
    let r = app.get(path).await;
    let status = r.status().as_u16();
    (status, r.json().await.unwrap())
}

/// `/readyz` is 200 and names the instance `/healthz` names; `/healthz` reports the
/// database, the pool and a held lease.
async fn healthz_reports_database_and_lease(app: TestApp) {
    let (st, ready) = json_of(&app, "/readyz").await;
    assert_eq!(st, 200, "{ready}");
    assert_eq!(ready["ready"], true, "{ready}");
    let (st, h) = json_of(&app, "/healthz").await;
    assert_eq!(st, 200, "{h}");
    assert_eq!(h["status"], "ok", "{h}");
    assert_eq!(ready["instance"], h["instance"], "{ready} {h}");
    assert!(!h["instance"].as_str().unwrap().is_empty());

    let db = &h["database"];
    let pg = app.config.database_url.is_some();
    assert_eq!(db["backend"], if pg { "postgres" } else { "sqlite" }, "{h}");
    assert_eq!(db["reachable"], true, "{h}");
    let latency = db["latency_ms"].as_f64().unwrap();
    assert!((0.0..2000.0).contains(&latency), "{h}");
    let pool = &db["pool"];
    assert_eq!(pool["max"], if pg { 10 } else { 8 }, "{h}");
    let (open, in_use, idle) = (
        pool["open"].as_u64().unwrap(),
        pool["in_use"].as_u64().unwrap(),
        pool["idle"].as_u64().unwrap(),
    );
    assert!((1..=10).contains(&open) && in_use + idle == open, "{h}");

    let lease = &h["lease"];
    assert_eq!(lease["registered"], true, "{h}");
    assert_eq!(lease["held"], true, "{h}");
    assert_eq!(lease["fenced"], false, "{h}");
    assert_eq!(lease["lease_ms"], 10_000, "{h}");
    assert!(lease["renewed_ms_ago"].as_u64().unwrap() < 10_000, "{h}");
    assert_eq!(lease["failures_in_a_row"], 0, "{h}");
    assert!(lease["last_error"].is_null(), "{h}");

    // public, like /healthz: no token needed even when tokens are configured
    let r = app.client.get(app.url("/readyz")).send().await.unwrap();
    assert_eq!(r.status(), 200);
}
on_both_backends!(healthz_reports_database_and_lease);

/// Polls `/healthz` every 100 ms until `want(body)` or `timeout` (panics then).
async fn wait_health(app: &TestApp, timeout: Duration, want: impl Fn(&Value) -> bool) -> Value {
    let t0 = Instant::now();
    loop {
        let (_, h) = json_of(app, "/healthz").await;
        if want(&h) {
            return h;
        }
        assert!(
            t0.elapsed() < timeout,
            "not as expected after {timeout:?}: {h}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// The heartbeat stalls (another session holds this instance's lease row locked): the
/// renewals time out after a third of the lease, the lease lapses, `/healthz` says
/// `fenced` and `/readyz` answers 503, while the request pool still serves requests. When
/// the lock goes, the instance's expired row is reaped and it registers again: ready. A
/// job queued while it was fenced waits, and runs once it has registered again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_heartbeat_fences_the_instance_until_it_registers_again() {
    let Some(app) = spawn_app_pg_with(|c| c.lease_s = 1.0).await else {
        return;
    };
    let (_, h) = json_of(&app, "/healthz").await;
    let id = h["instance"].as_str().unwrap().to_string();
    assert_eq!(h["lease"]["lease_ms"], 1000, "{h}");

    let url = app.config.database_url.clone().unwrap();
    let mut conn = sqlx::postgres::PgConnection::connect(&url).await.unwrap();
    conn.execute("BEGIN").await.unwrap();
    sqlx::query("SELECT id FROM instances WHERE id = $1 FOR UPDATE")
        .bind(&id)
        .fetch_one(&mut conn)
        .await
        .unwrap();

    let h = wait_health(&app, Duration::from_secs(10), |h| h["status"] == "fenced").await;
    assert_eq!(h["lease"]["fenced"], true, "{h}");
    assert_eq!(h["lease"]["held"], false, "{h}");
    assert!(
        h["lease"]["failures_in_a_row"].as_u64().unwrap() >= 1,
        "{h}"
    );
    let err = h["lease"]["last_error"].as_str().unwrap();
    assert!(err.contains("a third of the lease"), "{h}");
    // The request pool is not the heartbeat's: the database still answers requests.
    assert_eq!(h["database"]["reachable"], true, "{h}");
    let (st, ready) = json_of(&app, "/readyz").await;
    assert_eq!(st, 503, "{ready}");
    assert_eq!(ready["ready"], false);
    assert!(
        ready["reasons"][0].as_str().unwrap().contains("lease"),
        "{ready}"
    );
    seed_machine_and_surface(&app, "m", "s", 5, 5).await; // records: written while fenced
    let r = app
        .post_json(
            "/v1/step-error/samples",
            &json!({"surface": {"reference": 1},
                    "plan": {"tool_radius_mm": 5.0, "lines": 3, "points_per_line": 8}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let segments = r.json::<Value>().await.unwrap()["segments"].clone();
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s/step-error-model",
            &json!({"tool_radius": 5.0, "segments": segments, "epochs": 3, "hidden": [4]}),
        )
        .await;
    assert_eq!(r.status(), 202);
    let job = r.json::<Value>().await.unwrap()["job"]
        .as_str()
        .unwrap()
        .to_string();
    // A free worker claims a queued job within 250 ms; a fenced instance claims none.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let j: Value = app
        .get(&format!("/v1/jobs/{job}"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(j["state"], "queued", "a fenced instance claimed a job: {j}");

    conn.execute("ROLLBACK").await.unwrap();
    let h = wait_health(&app, Duration::from_secs(10), |h| h["status"] == "ok").await;
    assert_eq!(h["lease"]["held"], true, "{h}");
    assert_eq!(
        h["instance"],
        id.as_str(),
        "the same instance registered again"
    );
    let (st, _) = json_of(&app, "/readyz").await;
    assert_eq!(st, 200);
    let rows: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM instances WHERE id = $1")
        .bind(&id)
        .fetch_one(&mut conn)
        .await
        .unwrap();
    assert_eq!(rows, 1, "registered again");
    // Registered again, it claims the job.
    let done = app.wait_job(&job).await;
    assert_eq!(done["instance"], id.as_str(), "{done}");
}

/// Issue 41 item 1: the lease never waits on the request pool or a lock. Another session
/// holds `jobs` and `measurements` locked for 15 s while 12 list requests wait on the lock
/// (the request pool has 10 connections): the heartbeat keeps renewing on its own
/// connection, the reaper (on a third one, with a timeout) waits apart, and the running job
/// is neither fenced nor re-queued: it ends `done` on its first attempt once the locks go.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn locks_and_an_exhausted_request_pool_leave_the_lease_held() {
    let Some(app) = spawn_app_pg_with(|c| c.lease_s = 1.0).await else {
        return;
    };
    seed_machine_and_surface(&app, "m", "s", 5, 5).await;
    let r = app
        .post_json(
            "/v1/step-error/samples",
            &json!({"surface": {"reference": 1},
                    "plan": {"tool_radius_mm": 5.0, "lines": 3, "points_per_line": 8}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let segments = r.json::<Value>().await.unwrap()["segments"].clone();
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s/step-error-model",
            &json!({"tool_radius": 5.0, "segments": segments, "epochs": 3000, "preset": "paper"}),
        )
        .await;
    assert_eq!(r.status(), 202);
    let job = r.json::<Value>().await.unwrap()["job"]
        .as_str()
        .unwrap()
        .to_string();
    let t0 = Instant::now();
    loop {
        let (_, j) = json_of(&app, &format!("/v1/jobs/{job}")).await;
        if j["state"] == "running" {
            break;
        }
        assert_eq!(j["state"], "queued", "{j}");
        assert!(t0.elapsed() < Duration::from_secs(20), "never claimed: {j}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }

    let url = app.config.database_url.clone().unwrap();
    let mut conn = sqlx::postgres::PgConnection::connect(&url).await.unwrap();
    conn.execute("BEGIN").await.unwrap();
    conn.execute("LOCK TABLE jobs, measurements IN ACCESS EXCLUSIVE MODE")
        .await
        .unwrap();
    let waiting: Vec<_> = (0..12)
        .map(|_| {
            let client = app.client.clone();
            let url = app.url("/v1/machines/m/surfaces/s/measurements");
            tokio::spawn(async move { client.get(url).send().await.map(|r| r.status().as_u16()) })
        })
        .collect();
    let held_for = Duration::from_secs(15);
    let t0 = Instant::now();
    let mut polls = 0;
    while t0.elapsed() < held_for {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let (_, h) = json_of(&app, "/healthz").await;
        assert_eq!(
            h["lease"]["held"],
            true,
            "lease lost after {:.1} s with the locks held: {h}",
            t0.elapsed().as_secs_f64()
        );
        polls += 1;
    }
    println!("lease held at all {polls} polls over {held_for:?} of locks and a full pool");
    conn.execute("ROLLBACK").await.unwrap();
    for w in waiting {
        assert_eq!(w.await.unwrap().unwrap(), 200);
    }
    let done = app.wait_job(&job).await;
    assert_eq!(done["state"], "done", "{done}");
    assert_eq!(done["attempts"], 1, "the job was not taken back: {done}");
    let (_, h) = json_of(&app, "/healthz").await;
    assert_eq!(h["status"], "ok", "{h}");
}

/// Issue 41 item 5: no job stays `running` with no live owner working on it. Two jobs are
/// recorded as this (live) instance's and running, but none of its workers runs them (as
/// after a final write refused by an error that is not an outage): within a few leases the
/// reaper puts the one with stored input back in the queue, where a worker runs it to
/// `done`, and fails the in-process one with a sentence.
async fn orphaned_jobs_of_a_live_instance_are_taken_back(app: TestApp) {
    let store = app.server().state().store.clone();
    let me = store.instance().to_string();
    let stored_id = uuid::Uuid::now_v7().to_string();
    let inproc_id = uuid::Uuid::now_v7().to_string();
    let input = serde_json::to_string(
        &json!({"signal": (0..512).map(|i| (i as f64 * 0.1).sin() * 1e-3).collect::<Vec<_>>()}),
    )
    .unwrap();
    store
        .insert_job(&stored_id, "decomposition", Some(&input))
        .await
        .unwrap();
    store
        .insert_job(&inproc_id, "compensated-program", None)
        .await
        .unwrap();
    for id in [&stored_id, &inproc_id] {
        sqlx::query(
            "UPDATE jobs SET state = 'running', owner = $1, attempts = 1, updated_at = 0 \
             WHERE id = $2",
        )
        .bind(me.clone())
        .bind(id.clone())
        .execute(store.pool())
        .await
        .unwrap();
    }
    let t0 = Instant::now();
    let inproc = loop {
        let (_, j) = json_of(&app, &format!("/v1/jobs/{inproc_id}")).await;
        if j["state"] != "running" {
            break j;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "still running: {j}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    println!("orphans taken back after {:?} (lease 1 s)", t0.elapsed());
    assert_eq!(inproc["state"], "failed", "{inproc}");
    assert!(
        inproc["error"]
            .as_str()
            .unwrap()
            .contains("could not be recorded"),
        "{inproc}"
    );
    let stored = app.wait_job(&stored_id).await;
    assert_eq!(stored["state"], "done", "{stored}");
}
on_both_backends!(orphaned_jobs_of_a_live_instance_are_taken_back, |c| c
    .lease_s =
    1.0);

/// A volumetric map saved the way releases before migration 0003 saved models on
/// PostgreSQL (the file `models/m/machine/volumetric_map.tcm` in the data dir of the
/// instance that trained it; the database recording version 1 without its bytes) is
/// served by an instance with another data dir once the first has started again: the copy
/// runs at start-up, checks the checksum, and runs once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn models_saved_before_0003_are_copied_into_the_database() {
    let Some(pg) = PgSchema::create("fleet::models_saved_before_0003_are_copied").await else {
        return;
    };
    let dirs: Vec<_> = (0..4).map(|_| tempfile::tempdir().unwrap()).collect();

    // A map fitted on SQLite: its file is a model container as every release wrote it.
    let lone = start(dirs[0].path(), None, &[], &[]).await;
    let (st, _) = lone.send("PUT", "/v1/machines/m", &machine_xyz()).await;
    assert_eq!(st, 201);
    let synthetic = SyntheticMachine::new(8, ShapeFamily::TrendAndWaviness);
    let d = synthetic.measure_grid([4, 3, 3], 3);
    let body = json!({"nodes": d.nodes, "errors": d.errors, "model": "kinematic",
                      "tool_offset_mm": synthetic.tool_offset_mm});
    let (st, fitted) = lone
        .send("PUT", "/v1/machines/m/volumetric-map", &body)
        .await;
    assert_eq!(st, 201, "{fitted}");
    let (st, map) = lone.get("/v1/machines/m/volumetric-map").await;
    assert_eq!(st, 200, "{map}");
    lone.stop();
    let file = dirs[0]
        .path()
        .join("models/m/machine/volumetric_map.v1.tcm");
    let container = std::fs::read(&file).unwrap();

    // The PostgreSQL fleet's schema; then the rows migration 0003 left for the old model.
    let first = start(dirs[1].path(), Some(&pg.url), &[], &[]).await;
    let (st, _) = first.send("PUT", "/v1/machines/m", &machine_xyz()).await;
    assert_eq!(st, 201);
    first.stop();
    let payload = &container[52..];
    let sha: String = container[20..52]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let mut conn = pg.connect().await;
    for (table, extra) in [("models", ", 1, 1"), ("model_versions", ", 1")] {
        let cols = if table == "models" {
            "machine, surface, kind, format_version, sha256, bytes, updated_at, version, last_version"
        } else {
            "machine, surface, kind, format_version, sha256, bytes, created_at, version"
        };
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "INSERT INTO {table} ({cols}) VALUES ('m', '', 'volumetric_map', 1, $1, $2, 0{extra})"
        )))
        .bind(&sha)
        .bind(payload.len() as i64)
        .execute(&mut conn)
        .await
        .unwrap();
    }
    // The old layout: the unversioned file in the training instance's data dir.
    let old_dir = dirs[2].path().join("models/m/machine");
    std::fs::create_dir_all(&old_dir).unwrap();
    std::fs::write(old_dir.join("volumetric_map.tcm"), &container).unwrap();

    // Before the training instance starts, another one cannot serve the model.
    let other = start(dirs[3].path(), Some(&pg.url), &[], &[]).await;
    let (st, before) = other.get("/v1/machines/m/volumetric-map").await;
    assert_eq!(st, 500, "{before}");

    let trainer = start(dirs[2].path(), Some(&pg.url), &[], &[]).await;
    assert!(
        trainer
            .log()
            .contains("copied models saved before migration 0003"),
        "{}",
        trainer.log()
    );
    let (st, served) = other.get("/v1/machines/m/volumetric-map").await;
    assert_eq!(st, 200, "{served}");
    assert_eq!(served, map, "the copy serves the same map");
    let stored: Vec<u8> = sqlx::query_scalar(
        "SELECT data FROM model_versions WHERE machine = 'm' AND kind = 'volumetric_map'",
    )
    .fetch_one(&mut conn)
    .await
    .unwrap();
    assert_eq!(stored, container);
    trainer.stop();

    // Idempotent: a restart copies nothing more.
    let again = start(dirs[2].path(), Some(&pg.url), &[], &[]).await;
    assert!(
        !again.log().contains("copied models saved before"),
        "{}",
        again.log()
    );
    again.stop();
    other.stop();
}

/// A file that does not match what the database recorded (another payload under the old
/// name) is not copied: the model stays unserved elsewhere and the log says why.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_file_with_another_checksum_is_not_copied() {
    let Some(pg) = PgSchema::create("fleet::a_file_with_another_checksum_is_not_copied").await
    else {
        return;
    };
    let dirs: Vec<_> = (0..2).map(|_| tempfile::tempdir().unwrap()).collect();
    let first = start(dirs[0].path(), Some(&pg.url), &[], &[]).await;
    let (st, _) = first.send("PUT", "/v1/machines/m", &machine_xyz()).await;
    assert_eq!(st, 201);
    first.stop();
    let mut conn = pg.connect().await;
    let payload = b"not the recorded payload";
    for (table, cols, extra) in [
        (
            "models",
            "machine, surface, kind, format_version, sha256, bytes, updated_at, version, last_version",
            ", 1, 1",
        ),
        (
            "model_versions",
            "machine, surface, kind, format_version, sha256, bytes, created_at, version",
            ", 1",
        ),
    ] {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "INSERT INTO {table} ({cols}) VALUES ('m', '', 'volumetric_map', 1, $1, $2, 0{extra})"
        )))
        .bind("00".repeat(32))
        .bind(payload.len() as i64)
        .execute(&mut conn)
        .await
        .unwrap();
    }
    // A well-formed container (its own checksum right) of another payload.
    let mut container = b"TRUECUTM".to_vec();
    container.extend_from_slice(&1u32.to_le_bytes());
    container.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    container.extend_from_slice(&sha2::Sha256::digest(payload));
    container.extend_from_slice(payload);
    let dir = dirs[1].path().join("models/m/machine");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("volumetric_map.tcm"), &container).unwrap();
    let inst = start(dirs[1].path(), Some(&pg.url), &[], &[]).await;
    assert!(
        inst.log().contains("not copied into the database"),
        "{}",
        inst.log()
    );
    let data: Option<Vec<u8>> =
        sqlx::query_scalar("SELECT data FROM model_versions WHERE machine = 'm'")
            .fetch_one(&mut conn)
            .await
            .unwrap();
    assert!(data.is_none());
    inst.stop();
}
