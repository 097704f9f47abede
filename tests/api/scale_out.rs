//! Several instances on one PostgreSQL database (CONTRACT v1.1), as deployed: two real
//! `truecut serve` processes with separate data dirs sharing one database. What one writes
//! the other serves; killing one mid-job re-queues only its own jobs; 100 jobs submitted to
//! both run exactly once. Run with `cargo test --test api scale_out:`; SKIPPED without
//! `TRUECUT_TEST_PG`.

use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::instances::{Instance, PgSchema, seed, segments, start, train, train_long};

async fn pair(pg: &PgSchema, flags: &[&str]) -> (Instance, Instance, [tempfile::TempDir; 2]) {
    let dirs = [tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap()];
    let a = start(dirs[0].path(), Some(&pg.url), flags, &[]).await;
    let b = start(dirs[1].path(), Some(&pg.url), flags, &[]).await;
    assert_ne!(a.id, b.id);
    (a, b, dirs)
}

/// A record, a model (with its versions, rollback and delete) and a job written through one
/// instance are served by the other.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn what_one_instance_writes_the_other_serves() {
    let Some(pg) = PgSchema::create("scale_out::what_one_instance_writes_the_other_serves").await
    else {
        return;
    };
    let (a, b, _dirs) = pair(&pg, &["--workers", "2", "--lease-s", "1"]).await;
    seed(&a).await;
    let (st, s) = b.get("/v1/machines/m/surfaces/s").await;
    assert_eq!(st, 200, "{s}");
    assert_eq!(s["nominal"]["grid"]["nu"], 5);

    // A model trained through A, by whichever instance claims the job, served by both.
    let segs = segments(&a, 4, 12).await;
    let job = train(&a, &segs, 3).await;
    let done = b
        .wait_job(&job, Duration::from_secs(60), |j| {
            j["state"] != "queued" && j["state"] != "running"
        })
        .await;
    assert_eq!(done["state"], "done", "{done}");
    assert_eq!(done["result"]["model_version"], 1, "{done}");
    assert!(done["instance"] == a.id.as_str() || done["instance"] == b.id.as_str());
    for inst in [&a, &b] {
        let (st, info) = inst.get("/v1/machines/m/surfaces/s/step-error-model").await;
        assert_eq!(st, 200, "{info}");
        let (st, p) = inst
            .send(
                "POST",
                "/v1/machines/m/surfaces/s/step-error-model/predict",
                &json!({"segments": segs.as_array().unwrap()[..3]}),
            )
            .await;
        assert_eq!(st, 200, "{p}");
        assert_eq!(p["step_errors"].as_array().unwrap().len(), 3);
    }
    // A second version through B; A lists both and rolls back; B serves the rollback.
    let job2 = train(&b, &segs, 3).await;
    let done2 = a
        .wait_job(&job2, Duration::from_secs(60), |j| {
            j["state"] == "done" || j["state"] == "failed"
        })
        .await;
    assert_eq!(done2["result"]["model_version"], 2, "{done2}");
    let (st, v) = a
        .get("/v1/machines/m/surfaces/s/step-error-model/versions")
        .await;
    assert_eq!(st, 200);
    assert_eq!(v["current"], 2);
    assert_eq!(v["versions"][0]["job"], job2.as_str());
    assert_eq!(v["versions"][1]["job"], job.as_str());
    let (st, r) = a
        .send(
            "POST",
            "/v1/machines/m/surfaces/s/step-error-model/rollback",
            &json!({"version": 1}),
        )
        .await;
    assert_eq!(st, 200, "{r}");
    let (_, v) = b
        .get("/v1/machines/m/surfaces/s/step-error-model/versions")
        .await;
    assert_eq!(v["current"], 1, "{v}");
    // Deleted through B, gone on A.
    assert_eq!(
        b.delete("/v1/machines/m/surfaces/s/step-error-model").await,
        204
    );
    let (st, _) = a.get("/v1/machines/m/surfaces/s/step-error-model").await;
    assert_eq!(st, 404);
    a.stop();
    b.stop();
}

/// Killing an instance mid-job (SIGKILL) re-queues only its own job, once its lease expired;
/// the other instance's running job goes on; a restart on the same data dir (a new instance)
/// leaves the live instance's job alone and runs the re-queued one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killing_an_instance_mid_job_requeues_only_its_jobs() {
    let Some(pg) =
        PgSchema::create("scale_out::killing_an_instance_mid_job_requeues_only_its_jobs").await
    else {
        return;
    };
    // One worker each, so the second long job must go to the other instance.
    let flags = ["--workers", "1", "--lease-s", "1"];
    let (a, b, dirs) = pair(&pg, &flags).await;
    seed(&a).await;
    let long = segments(&a, 40, 60).await;
    let job_a = train_long(&a, &long).await;
    let ja = a
        .wait_job(&job_a, Duration::from_secs(30), |j| j["state"] == "running")
        .await;
    let on_a = ja["instance"].as_str().unwrap().to_string();
    let job_b = train_long(&b, &long).await;
    let jb = b
        .wait_job(&job_b, Duration::from_secs(30), |j| j["state"] == "running")
        .await;
    let on_b = jb["instance"].as_str().unwrap().to_string();
    assert_ne!(on_a, on_b, "each instance runs one job");
    let (victim, survivor) = if on_a == a.id { (a, b) } else { (b, a) };
    let (victim_job, survivor_job) = if on_a == victim.id {
        (job_a.clone(), job_b.clone())
    } else {
        (job_b.clone(), job_a.clone())
    };
    // Progress of the victim's job, read through the survivor (stored in the row).
    let p0 = survivor
        .wait_job(&victim_job, Duration::from_secs(30), |j| {
            j["progress"].as_f64().unwrap() > 0.0
        })
        .await["progress"]
        .as_f64()
        .unwrap();
    assert!(p0 > 0.0);

    let victim_id = victim.id.clone();
    let victim_dir = victim.kill9();
    let t0 = Instant::now();
    let requeued = survivor
        .wait_job(&victim_job, Duration::from_secs(10), |j| {
            j["state"] == "queued"
        })
        .await;
    let failover = t0.elapsed();
    assert_eq!(requeued["attempts"], 1, "{requeued}");
    let other = survivor.job(&survivor_job).await;
    assert_eq!(other["state"], "running", "{other}");
    assert_eq!(other["instance"], survivor.id.as_str());
    assert_eq!(other["attempts"], 1);

    // A new instance on the dead one's data dir: the survivor's job is untouched, and the
    // new instance (the only free worker) runs the re-queued job.
    let restarted = start(&victim_dir, Some(&pg.url), &flags, &[]).await;
    assert_ne!(restarted.id, victim_id);
    let rerun = restarted
        .wait_job(&victim_job, Duration::from_secs(10), |j| {
            j["state"] == "running"
        })
        .await;
    assert_eq!(rerun["instance"], restarted.id.as_str(), "{rerun}");
    assert_eq!(rerun["attempts"], 2);
    let other = restarted.job(&survivor_job).await;
    assert_eq!(
        (
            other["state"].as_str(),
            other["instance"].as_str(),
            other["attempts"].as_i64()
        ),
        (Some("running"), Some(survivor.id.as_str()), Some(1)),
        "{other}"
    );
    println!(
        "two instances, lease 1 s: SIGKILL of {victim_id} → its job re-queued after {failover:?} \
         (goal: within lease + heartbeat = 1.33 s plus polling); the other's job kept running; \
         restarted instance took the job back (attempt 2)"
    );
    assert!(failover < Duration::from_secs(4), "{failover:?}");
    for j in [&victim_job, &survivor_job] {
        assert_eq!(survivor.delete(&format!("/v1/jobs/{j}")).await, 200);
    }
    let (st, _) = survivor
        .get("/v1/machines/m/surfaces/s/step-error-model")
        .await;
    assert_eq!(st, 404, "cancelled jobs stored no model");
    restarted.stop();
    survivor.stop();
    drop(dirs);
}

/// 100 jobs submitted alternately to two instances each run exactly once: every job ends
/// done after one claim, and the models they saved are versions 1..=100, each once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hundred_jobs_on_two_instances_run_exactly_once() {
    let Some(pg) =
        PgSchema::create("scale_out::a_hundred_jobs_on_two_instances_run_exactly_once").await
    else {
        return;
    };
    let (a, b, _dirs) = pair(&pg, &["--workers", "2", "--queue", "200", "--lease-s", "2"]).await;
    seed(&a).await;
    let segs = segments(&a, 3, 8).await;
    let t0 = Instant::now();
    let mut ids = Vec::new();
    for i in 0..100 {
        let inst = if i % 2 == 0 { &a } else { &b };
        ids.push(train(inst, &segs, 1).await);
    }
    let submitted = t0.elapsed();
    let mut jobs: Vec<Value> = Vec::new();
    for _ in 0..1200 {
        let (st, list) = b
            .get("/v1/jobs?kind=step_error_training&limit=100&result=true")
            .await;
        assert_eq!(st, 200);
        jobs = list["jobs"].as_array().unwrap().clone();
        if jobs.len() == 100
            && jobs
                .iter()
                .all(|j| j["state"] == "done" || j["state"] == "failed")
        {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let took = t0.elapsed();
    assert_eq!(jobs.len(), 100);
    let mut per_instance: BTreeMap<String, usize> = BTreeMap::new();
    let mut versions = BTreeSet::new();
    for j in &jobs {
        assert_eq!(j["state"], "done", "{j}");
        assert_eq!(j["attempts"], 1, "claimed more than once: {j}");
        *per_instance
            .entry(j["instance"].as_str().unwrap().to_string())
            .or_default() += 1;
        assert!(
            versions.insert(j["result"]["model_version"].as_i64().unwrap()),
            "{j}"
        );
    }
    assert_eq!(versions, (1..=100).collect::<BTreeSet<i64>>());
    assert!(
        per_instance.keys().all(|k| *k == a.id || *k == b.id),
        "{per_instance:?}"
    );
    // The database agrees: 100 done, the model's version counter at 100.
    use sqlx::Row;
    let mut conn = pg.connect().await;
    let row = sqlx::query(
        "SELECT (SELECT COUNT(*) FROM jobs WHERE state = 'done'), \
                (SELECT COUNT(*) FROM jobs WHERE attempts <> 1), \
                (SELECT last_version FROM models WHERE kind = 'step_error_nn')",
    )
    .fetch_one(&mut conn)
    .await
    .unwrap();
    let (done, reclaimed, last): (i64, i64, i64) = (row.get(0), row.get(1), row.get(2));
    assert_eq!((done, reclaimed, last), (100, 0, 100));
    println!(
        "100 training jobs, submitted alternately to A and B in {submitted:?}, all done after \
         {took:?}: each claimed once, model versions 1..=100 each once; ran on A {} and on B {}",
        per_instance.get(&a.id).copied().unwrap_or(0),
        per_instance.get(&b.id).copied().unwrap_or(0)
    );
    a.stop();
    b.stop();
}
