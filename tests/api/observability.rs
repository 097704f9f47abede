//! Observability (issue 41 item 9): JSON logs in which a job's lines name the request that
//! queued it, job outcome and run-time metrics, the lease in `/metrics`, and a job list
//! whose order (and cursor) is the database's, not an inserting host's clock.

use std::time::Duration;

use crate::helpers::*;
use serde_json::{Value, json};

/// Fields of a JSON log line's span named `name` (the current span or one of the list).
fn span_field<'a>(line: &'a Value, name: &str, field: &str) -> Option<&'a Value> {
    let mut spans: Vec<&Value> = line["spans"].as_array().into_iter().flatten().collect();
    spans.push(&line["span"]);
    spans
        .into_iter()
        .find(|s| s["name"] == name)
        .and_then(|s| s.get(field))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn json_logs_tie_a_job_to_its_request_and_metrics_count_it() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().to_string_lossy().to_string();
    let (mut child, base, logs) = crate::service::start_binary_logging(
        &[
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--data-dir",
            &data,
            "--log-format",
            "json",
        ],
        "info,sqlx=warn",
    );
    let client = reqwest::Client::new();
    let signal: Vec<f64> = (0..800)
        .map(|i| (f64::from(i) * 0.05).sin() + 0.01 * f64::from(i % 7))
        .collect();
    let r = client
        .post(format!("{base}/v1/decompose"))
        .header("x-request-id", "obs-req-41")
        .header("prefer", "respond-async")
        .json(&json!({ "signal": signal }))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202);
    assert_eq!(r.headers()["x-request-id"], "obs-req-41");
    let id = r.json::<Value>().await.unwrap()["job"]
        .as_str()
        .unwrap()
        .to_string();
    let mut job = Value::Null;
    for _ in 0..600 {
        job = client
            .get(format!("{base}/v1/jobs/{id}"))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if job["state"] == "done" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(job["state"], "done", "{job}");
    assert_eq!(job["request_id"], "obs-req-41", "{job}");
    // The answer names the VMD kernel that computed it (issue 41 item 9: cross-host bits).
    let kernel = job["result"]["kernel"].as_str();
    assert!(
        matches!(kernel, Some("avx2-fma" | "portable")),
        "{}",
        job["result"]["kernel"]
    );
    assert_eq!(
        (job["attempts"].as_i64(), job["counted_attempts"].as_i64()),
        (Some(1), Some(1))
    );

    // The job's "job ended" line names the job, its kind and the request that queued it.
    let mut ended = None;
    for _ in 0..100 {
        let lines = logs.lock().unwrap().clone();
        ended = lines
            .iter()
            .filter_map(|l| serde_json::from_str::<Value>(l).ok())
            .find(|l| {
                l["message"] == "job ended" && span_field(l, "job", "job") == Some(&json!(id))
            });
        if ended.is_some() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let ended = ended.unwrap_or_else(|| panic!("no 'job ended' line: {:#?}", logs.lock().unwrap()));
    assert_eq!(
        span_field(&ended, "job", "request_id"),
        Some(&json!("obs-req-41")),
        "{ended}"
    );
    assert_eq!(
        span_field(&ended, "job", "kind"),
        Some(&json!("decomposition")),
        "{ended}"
    );
    assert_eq!(ended["outcome"], "done", "{ended}");
    assert_eq!(ended["level"], "INFO", "{ended}");
    // Every log line is one JSON object (the address announcement goes before them).
    for line in logs.lock().unwrap().iter() {
        let v: Value = serde_json::from_str(line)
            .unwrap_or_else(|e| panic!("not a JSON log line ({e}): {line}"));
        assert!(
            v["timestamp"].is_string() && v["level"].is_string(),
            "{line}"
        );
    }

    let metrics = client
        .get(format!("{base}/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    for want in [
        "truecut_jobs_finished_total{kind=\"decomposition\",outcome=\"done\"} 1",
        "truecut_job_run_seconds_count{kind=\"decomposition\"} 1",
        "truecut_lease_held 1",
        "truecut_lease_fenced 0",
        "truecut_database_outage_answers_total 0",
    ] {
        assert!(metrics.contains(want), "no '{want}' in:\n{metrics}");
    }
    child.kill().unwrap();
    child.wait().unwrap();
}

/// A job recorded by an instance whose clock is an hour behind (its `created_at` an hour
/// old) still sorts first: the list's order and cursor are the database's numbering. Before
/// migration 0007 it sorted last, under every job an incremental reader (newest first, up
/// to the first job it knows) had already seen, so that reader never saw it. A walk that
/// began before it continues where it stopped, and a cursor of an earlier release still
/// works.
async fn the_job_list_order_is_the_databases_not_a_hosts_clock(app: TestApp) {
    let store = app.server().state().store.clone();
    for id in ["a", "b", "c"] {
        store.insert_job(id, "k", None).await.unwrap();
    }
    let ids = |v: &Value| -> Vec<String> {
        v["jobs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| j["id"].as_str().unwrap().to_string())
            .collect()
    };
    let page1: Value = app.get("/v1/jobs?limit=2").await.json().await.unwrap();
    assert_eq!(ids(&page1), ["c", "b"]);
    let next = page1["next"].as_str().unwrap().to_string();
    // Recorded now by a host whose clock is an hour behind.
    store.insert_job("late-clock", "k", None).await.unwrap();
    sqlx::query("UPDATE jobs SET created_at = created_at - 3600000 WHERE id = $1")
        .bind("late-clock")
        .execute(store.pool())
        .await
        .unwrap();
    let page2: Value = app
        .get(&format!("/v1/jobs?limit=2&cursor={next}"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(ids(&page2), ["a"], "the walk goes on where it stopped");
    assert!(page2["next"].is_null());
    let fresh: Value = app.get("/v1/jobs?limit=10").await.json().await.unwrap();
    assert_eq!(ids(&fresh), ["late-clock", "c", "b", "a"]);
    // A cursor of an earlier release (hex of `created_at ms:id`) goes on after its job.
    let b = store.get_job("b").await.unwrap().unwrap();
    let old = hex::encode(format!("{}:b", b.created_at_ms));
    let rest: Value = app
        .get(&format!("/v1/jobs?cursor={old}"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(ids(&rest), ["a"]);
    let gone = hex::encode("1:no-such-job");
    assert_problem(
        app.get(&format!("/v1/jobs?cursor={gone}")).await,
        400,
        &["cursor"],
    )
    .await;
}
on_both_backends!(the_job_list_order_is_the_databases_not_a_hosts_clock);
