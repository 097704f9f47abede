//! Bounded job storage (issue 25 item 3): a finished job's input is dropped, jobs older than
//! `--job-retention` are pruned, and `GET /v1/jobs` pages with a cursor and leaves results
//! out unless `?result=true`. On SQLite and PostgreSQL.
//!
//! The 10,000 jobs are queued through the pool's own door (`JobPool::enqueue`, what
//! `POST /v1/decompose` calls above its synchronous size) rather than over HTTP, so that
//! they can be small (600-sample wavelet decompositions, ~12 KB of input and ~25 KB of
//! result each) and the test stays under a minute in a debug build; they are claimed, run,
//! recorded and pruned by the running server exactly as HTTP-submitted jobs are.

use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use truecut::jobs::JobPool;

use crate::helpers::*;

/// A 600-sample signal (mm) that differs per job: a tone and seeded noise.
fn signal(seed: u64) -> Vec<f64> {
    let mut s = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
    (0..600)
        .map(|i| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let noise = ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.002;
            0.01 * (i as f64 * 0.05).sin() + noise
        })
        .collect()
}

/// Queues `n` decomposition jobs (waiting while the queue is full) and waits for every job
/// to end; returns the bytes of input queued.
async fn run_jobs(pool: &JobPool, from: u64, n: u64) -> u64 {
    let mut bytes = 0;
    for i in from..from + n {
        let input = json!({"signal": signal(i), "method": "wavelet"}).to_string();
        bytes += input.len() as u64;
        loop {
            match pool.enqueue("decomposition", input.clone()).await {
                Ok(_) => break,
                Err(truecut::jobs::Error::Full { .. }) => {
                    tokio::time::sleep(Duration::from_millis(1)).await;
                }
                Err(e) => panic!("cannot queue a job: {e}"),
            }
        }
    }
    let t0 = Instant::now();
    loop {
        let mut open = 0;
        for state in ["queued", "running"] {
            open += pool
                .list(Some(state), None, 1, None, false)
                .await
                .unwrap()
                .jobs
                .len();
        }
        if open == 0 {
            return bytes;
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "jobs never ended");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// Bytes of every file under `dir` (the SQLite database, its WAL and the model files).
fn dir_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| match e.metadata() {
                    Ok(m) if m.is_dir() => dir_bytes(&e.path()),
                    Ok(m) => m.len(),
                    Err(_) => 0,
                })
                .sum()
        })
        .unwrap_or(0)
}

/// Bytes of the files directly under `dir` whose name ends with `suffix`.
fn dir_bytes_named(dir: &Path, suffix: &str) -> u64 {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .filter(|e| e.file_name().to_string_lossy().ends_with(suffix))
                .filter_map(|e| e.metadata().ok())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}

/// What the database takes for the jobs, and apart from it the SQLite WAL (bytes).
///
/// SQLite: the data dir without its `-wal` file, after the WAL has been checkpointed into the
/// database (all jobs have ended; `TRUNCATE`, tried up to five times). The WAL is the
/// checkpoints' lag behind the writes, not data: under load it grew to 11–26 MB and keeps its
/// size until truncated, and a checkpoint cannot always truncate it at once (a pooled
/// connection of the server may hold a read snapshot), so it is reported and bounded on its
/// own. PostgreSQL: the jobs table with its TOAST and indexes (`pg_total_relation_size`) plus
/// the data dir.
async fn storage_bytes(app: &TestApp) -> (u64, u64) {
    use sqlx::{Connection, Row};
    let Some(url) = app.config.database_url.as_deref() else {
        let dir = app.data_dir.path();
        let wal_before = dir_bytes_named(dir, "-wal");
        let db = dir.join("truecut.db");
        let mut conn =
            sqlx::sqlite::SqliteConnection::connect(&format!("sqlite://{}", db.display()))
                .await
                .unwrap();
        for _ in 0..5 {
            sqlx::raw_sql("PRAGMA busy_timeout = 2000; PRAGMA wal_checkpoint(TRUNCATE);")
                .execute(&mut conn)
                .await
                .unwrap();
            if dir_bytes_named(dir, "-wal") == 0 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(500)).await;
        }
        conn.close().await.unwrap();
        let wal = dir_bytes_named(dir, "-wal");
        let files = dir_bytes(dir) - wal;
        println!(
            "storage: WAL {wal_before} bytes before the checkpoint, {wal} after; {files} bytes of other files"
        );
        return (files, wal);
    };
    let files = dir_bytes(app.data_dir.path());
    let mut conn = sqlx::postgres::PgConnection::connect(url).await.unwrap();
    let row = sqlx::query("SELECT pg_total_relation_size('jobs')")
        .fetch_one(&mut conn)
        .await
        .unwrap();
    (files + u64::try_from(row.get::<i64, _>(0)).unwrap(), 0)
}

async fn storage_stays_bounded(app: TestApp) {
    let pool = app.server().state().jobs.clone();
    let store = app.server().state().store.clone();
    let t0 = Instant::now();
    // Rounds of 500 jobs; after each, the jobs that ended are pruned with the pruner's own
    // call (a retention of "before now"), so what is retained is the last round: the same
    // at both measurements, and independent of how fast this machine runs.
    const ROUND: u64 = 500;
    let prune = || async {
        store.prune_jobs(Duration::ZERO).await.unwrap();
    };
    // Warm-up: the database reaches its working size (pages, WAL, indexes).
    run_jobs(&pool, 0, ROUND).await;
    prune().await;
    run_jobs(&pool, ROUND, ROUND).await;
    let (before, _) = storage_bytes(&app).await;
    let retained_before = store.job_bytes().await.unwrap();
    let mut input_bytes = 0;
    for round in 0..10_000 / ROUND {
        prune().await;
        input_bytes += run_jobs(&pool, (round + 2) * ROUND, ROUND).await;
    }
    let (after, wal) = storage_bytes(&app).await;
    let held = store.job_bytes().await.unwrap();
    let took = t0.elapsed();
    let growth = after.saturating_sub(before);
    let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
    println!(
        "storage: 10,000 jobs ({:.1} MiB of input queued) grew the store by {growth} bytes \
         ({:.2} MiB; {before} -> {after}); retained: {} jobs, {} bytes of results ({:.2} MiB; \
         {} before), {} bytes of input; {took:?} for 11,000 jobs",
        mib(input_bytes),
        mib(growth),
        held.jobs,
        held.result_bytes,
        mib(held.result_bytes),
        retained_before.result_bytes,
        held.input_bytes,
    );
    if held.input_bytes != 0 {
        let kept: Vec<String> = sqlx::query_scalar(
            "SELECT j.id || ' ' || j.state || ' attempts ' || CAST(j.attempts AS TEXT) || ' ' || \
             COALESCE(j.error, '') FROM jobs j JOIN job_inputs i ON i.id = j.id",
        )
        .fetch_all(store.pool())
        .await
        .unwrap();
        panic!(
            "ended jobs kept their input ({} bytes): {kept:?}",
            held.input_bytes
        );
    }
    assert_eq!(held.jobs, ROUND, "the last round is what is retained");
    assert!(
        growth <= held.result_bytes,
        "the store grew by {growth} bytes, more than the {} bytes of retained results",
        held.result_bytes
    );
    // The WAL is the checkpoints' lag, not an accumulation of what was written.
    assert!(
        wal <= input_bytes / 2,
        "the WAL holds {wal} bytes after 10,000 jobs wrote {input_bytes} bytes of input: \
         checkpoints do not keep up"
    );
}
on_both_backends!(storage_stays_bounded, |c| {
    c.job_retention = std::time::Duration::ZERO;
    c.queue = 64;
});

/// `GET /v1/jobs` pages: results only /// `GET /v1/jobs` pages: results only with `?result=true`, every job once, newest first,
/// `next` null on the last page.
async fn list_pages(app: TestApp) {
    let pool = app.server().state().jobs.clone();
    let mut ids = Vec::new();
    for i in 0..7 {
        let id = pool
            .submit("page", move |_| Ok(json!({"n": i})))
            .await
            .unwrap();
        app.wait_job(&id).await;
        ids.push(id);
    }
    ids.reverse(); // newest first

    let mut listed = Vec::new();
    let mut cursor: Option<String> = None;
    let mut pages = 0;
    loop {
        let path = match &cursor {
            Some(c) => format!("/v1/jobs?limit=3&cursor={c}"),
            None => "/v1/jobs?limit=3".to_string(),
        };
        let r = app.get(&path).await;
        assert_eq!(r.status(), 200);
        let page: Value = r.json().await.unwrap();
        pages += 1;
        for j in page["jobs"].as_array().unwrap() {
            assert!(
                j.get("result").is_none(),
                "result listed without ?result=true: {j}"
            );
            assert_eq!(j["state"], "done", "{j}");
            listed.push(j["id"].as_str().unwrap().to_string());
        }
        match page["next"].as_str() {
            Some(c) => cursor = Some(c.to_string()),
            None => {
                assert!(page["next"].is_null(), "{page}");
                break;
            }
        }
        assert!(pages < 10, "paging never ends");
    }
    assert_eq!(pages, 3, "7 jobs in pages of 3");
    assert_eq!(listed, ids, "every job once, newest first");

    let with: Value = app
        .get("/v1/jobs?limit=2&result=true")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(with["jobs"][0]["result"]["n"], 6, "{with}");
    assert_eq!(with["jobs"][1]["result"]["n"], 5, "{with}");
    let rest: Value = app
        .get(&format!(
            "/v1/jobs?limit=100&result=true&cursor={}",
            with["next"].as_str().unwrap()
        ))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(rest["jobs"].as_array().unwrap().len(), 5, "{rest}");
    assert_eq!(rest["jobs"][0]["result"]["n"], 4, "{rest}");
    assert!(rest["next"].is_null(), "{rest}");

    assert_problem(
        app.get("/v1/jobs?result=true&limit=101").await,
        400,
        &["limit", "100"],
    )
    .await;
    assert_problem(
        app.get("/v1/jobs?result=yes").await,
        400,
        &["result", "true"],
    )
    .await;
    assert_problem(
        app.get("/v1/jobs?cursor=zz").await,
        400,
        &["cursor", "next"],
    )
    .await;
}
on_both_backends!(list_pages);

/// Jobs that ended longer ago than the retention are deleted by the running server, ended
/// jobs hold no input, and unfinished ones are never pruned.
async fn old_jobs_are_pruned(app: TestApp) {
    let pool = app.server().state().jobs.clone();
    let store = app.server().state().store.clone();
    let done = pool
        .submit("old", |_| Ok(json!({"big": "x".repeat(10_000)})))
        .await
        .unwrap();
    app.wait_job(&done).await;
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    let open = pool
        .submit("open", move |_| {
            let _ = rx.recv_timeout(Duration::from_secs(20));
            Ok(json!(1))
        })
        .await
        .unwrap();
    let t0 = Instant::now();
    while store.get_job(&done).await.unwrap().is_some() {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the ended job was never pruned"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    println!(
        "pruning: a job with --job-retention 1 s was deleted {:?} after it ended",
        t0.elapsed()
    );
    assert_eq!(app.get(&format!("/v1/jobs/{done}")).await.status(), 404);
    let j: Value = app
        .get(&format!("/v1/jobs/{open}"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(j["state"], "running", "an unfinished job was pruned: {j}");
    tx.send(()).unwrap();
    app.wait_job(&open).await;
}
on_both_backends!(old_jobs_are_pruned, |c| c.job_retention =
    std::time::Duration::from_secs(1));

/// A running job's progress report (every 250 ms) writes a few bytes, not its input. With the
/// input a column of `jobs`, SQLite rewrote the whole record on each report: a 5 MB input put
/// 10 MB into the write-ahead log four times a second, per running job. SQLite (the default;
/// PostgreSQL keeps large values out of line and never rewrote them).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn progress_reports_do_not_rewrite_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let store = truecut::store::Store::open(dir.path(), None).await.unwrap();
    store.register_instance(60_000).await.unwrap();
    let input = format!(
        "{{\"signal\": [{}]}}",
        vec!["0.1234567890"; 450_000].join(", ")
    );
    store
        .insert_job("big", "stored", Some(&input))
        .await
        .unwrap();
    let claimed = store.claim_job(&["stored".into()]).await.unwrap().unwrap();
    assert_eq!(claimed.input, input);
    assert_eq!(
        store.job_bytes().await.unwrap().input_bytes,
        input.len() as u64
    );
    // The log emptied first: it keeps its largest size, so growth shows only from empty.
    sqlx::raw_sql("PRAGMA wal_checkpoint(TRUNCATE)")
        .execute(store.pool())
        .await
        .unwrap();
    let wal = dir.path().join("truecut.db-wal");
    let wal_len = || std::fs::metadata(&wal).map_or(0, |m| m.len());
    let before = wal_len();
    assert_eq!(before, 0, "the write-ahead log was not emptied");
    for k in 0..10 {
        let p = f64::from(k) / 10.0;
        assert!(
            store
                .report_job_progress("big", claimed.attempts, p)
                .await
                .unwrap()
        );
    }
    let grown = wal_len().saturating_sub(before);
    println!(
        "ten progress reports of a job with {:.1} MB of input grew the WAL by {grown} bytes",
        input.len() as f64 / 1e6
    );
    assert!(grown < 256 * 1024, "the WAL grew by {grown} bytes");
    let done = json!({"ok": true});
    assert!(
        store
            .finish_job("big", claimed.attempts, "done", 1.0, Some(&done), None)
            .await
            .unwrap()
    );
    assert_eq!(store.job_bytes().await.unwrap().input_bytes, 0);
}

/// Migration 0005 moves the inputs of jobs still waiting into `job_inputs`: a database
/// made by the previous release (migrations 1–4) with a queued stored job opens, and the job
/// is claimed with its input intact.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn upgrade_keeps_the_input_of_a_waiting_job() {
    use sqlx::migrate::{Migration, MigrationType, Migrator};
    let dir = tempfile::tempdir().unwrap();
    let url = format!(
        "sqlite://{}?mode=rwc",
        dir.path().join("truecut.db").display()
    );
    {
        let old = sqlx::SqlitePool::connect(&url).await.unwrap();
        let scripts = [
            (
                1,
                "init",
                include_str!("../../migrations/sqlite/0001_init.sql"),
            ),
            (
                2,
                "job_times",
                include_str!("../../migrations/sqlite/0002_job_times.sql"),
            ),
            (
                3,
                "scale_out",
                include_str!("../../migrations/sqlite/0003_scale_out.sql"),
            ),
            (
                4,
                "iso230_runs",
                include_str!("../../migrations/sqlite/0004_iso230_runs.sql"),
            ),
        ];
        let migrations = scripts
            .into_iter()
            .map(|(v, name, sql)| {
                Migration::new(
                    v,
                    name.into(),
                    MigrationType::Simple,
                    sqlx::SqlStr::from_static(sql),
                    false,
                )
            })
            .collect();
        Migrator::with_migrations(migrations)
            .run(&old)
            .await
            .unwrap();
        sqlx::query(
            "INSERT INTO jobs (id, kind, state, progress, owner, created_at, updated_at, input) \
             VALUES ('waiting', 'stored', 'queued', 0.0, '', 1, 1, '{\"signal\": [1, 2, 3]}')",
        )
        .execute(&old)
        .await
        .unwrap();
        old.close().await;
    }
    let store = truecut::store::Store::open(dir.path(), None).await.unwrap();
    store.register_instance(60_000).await.unwrap();
    assert_eq!(store.count_queued_jobs().await.unwrap(), 1);
    let job = store.claim_job(&["stored".into()]).await.unwrap().unwrap();
    assert_eq!(
        (job.id.as_str(), job.input.as_str()),
        ("waiting", "{\"signal\": [1, 2, 3]}")
    );
}
