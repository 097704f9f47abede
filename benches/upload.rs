//! Upload throughput: a 250,000-point CSV probe upload end to end (HTTP → parse →
//! deviations → store) and read back, on SQLite and (with TRUECUT_TEST_PG) PostgreSQL;
//! plus the storage layout choice measured in the same run: one little-endian f64 BLOB per
//! measurement (what truecut does) against a row per point (the baseline).
//!
//! Run: `cargo bench --bench upload` (optionally `TRUECUT_TEST_PG=postgres://...`).

use std::time::{Duration, Instant};

use sqlx::Row;
use truecut::config::Config;
use truecut::store::{Measurement, Store};

const N_SIDE: usize = 500;
const N: usize = N_SIDE * N_SIDE;
const REPS: usize = 3;

fn surface_json() -> String {
    let mut points = String::with_capacity(N * 24);
    let mut normals = String::with_capacity(N * 12);
    for k in 0..N {
        let sep = if k == 0 { "" } else { "," };
        points.push_str(&format!("{sep}[{},{},0.0]", k % N_SIDE, k / N_SIDE));
        normals.push_str(&format!("{sep}[0,0,1]"));
    }
    format!(
        "{{\"nominal\":{{\"grid\":{{\"nu\":{N_SIDE},\"nv\":{N_SIDE},\"points\":[{points}],\"normals\":[{normals}]}}}}}}"
    )
}

fn probe_csv(seed: usize) -> String {
    let mut csv = String::with_capacity(N * 32);
    csv.push_str("Point;X;Y;Z\n");
    for k in 0..N {
        let z = (((k * 7919 + seed) % 2001) as f64 - 1000.0) * 1e-5;
        csv.push_str(&format!("P{k};{};{};{z}\n", k % N_SIDE, k / N_SIDE));
    }
    csv
}

fn median(mut xs: Vec<Duration>) -> Duration {
    xs.sort();
    xs[xs.len() / 2]
}

struct Figures {
    upload: Duration,
    read: Duration,
    blob_write: Duration,
    blob_read: Duration,
    rows_write: Duration,
    rows_read: Duration,
}

async fn run(label: &str, database_url: Option<String>) -> anyhow::Result<Figures> {
    let dir = tempfile::tempdir()?;
    let mut config = Config::new("127.0.0.1:0".parse()?, dir.path().to_path_buf());
    config.database_url = database_url;
    let server = truecut::server::start(&config).await?;
    let base = format!("http://{}", server.addr());
    truecut::cli::client::install_crypto_provider();
    let client = reqwest::Client::new();
    let r = client
        .put(format!("{base}/v1/machines/bench"))
        .header("content-type", "application/json")
        .body(r#"{"kinematics":"xyz"}"#)
        .send()
        .await?;
    anyhow::ensure!(r.status().is_success(), "PUT machine: {}", r.status());
    let r = client
        .put(format!("{base}/v1/machines/bench/surfaces/s"))
        .header("content-type", "application/json")
        .body(surface_json())
        .send()
        .await?;
    anyhow::ensure!(r.status().is_success(), "PUT surface: {}", r.status());

    let mut uploads = Vec::new();
    let mut reads = Vec::new();
    for rep in 0..REPS {
        let csv = probe_csv(rep);
        let t = Instant::now();
        let r = client
            .post(format!(
                "{base}/v1/machines/bench/surfaces/s/measurements?id=m{rep}"
            ))
            .header("content-type", "text/csv")
            .body(csv)
            .send()
            .await?;
        anyhow::ensure!(
            r.status() == 201,
            "upload: {} {}",
            r.status(),
            r.text().await?
        );
        uploads.push(t.elapsed());
        let t = Instant::now();
        let body = client
            .get(format!(
                "{base}/v1/machines/bench/surfaces/s/measurements/m{rep}"
            ))
            .send()
            .await?
            .bytes()
            .await?;
        let v: serde_json::Value = serde_json::from_slice(&body)?;
        anyhow::ensure!(v["deviations"].as_array().map(Vec::len) == Some(N));
        reads.push(t.elapsed());
    }

    // Storage layouts, same database, same data.
    let store: Store = server.state().store.clone();
    let devs: Vec<f64> = (0..N)
        .map(|k| ((k * 31 % 1001) as f64 - 500.0) * 1e-5)
        .collect();
    let (mut bw, mut br, mut rw, mut rr) = (vec![], vec![], vec![], vec![]);
    sqlx::query(
        "CREATE TABLE bench_rows (measurement TEXT NOT NULL, k BIGINT NOT NULL, \
         deviation DOUBLE PRECISION NOT NULL, PRIMARY KEY (measurement, k))",
    )
    .execute(store.pool())
    .await?;
    for rep in 0..REPS {
        let id = format!("b{rep}");
        let m = Measurement::new(id.clone(), "bench".into(), "s".into(), devs.clone(), None);
        let t = Instant::now();
        store.insert_measurement(&m).await?;
        bw.push(t.elapsed());
        let t = Instant::now();
        let back = store
            .get_measurement("bench", "s", &id)
            .await?
            .expect("stored");
        br.push(t.elapsed());
        anyhow::ensure!(back.deviations == devs);

        // Baseline: a row per point, multi-row INSERTs of 1000 rows in one transaction.
        let t = Instant::now();
        let mut tx = store.pool().begin().await?;
        for chunk in devs.chunks(1000).enumerate() {
            let (c, values) = chunk;
            let mut sql =
                String::from("INSERT INTO bench_rows (measurement, k, deviation) VALUES ");
            for i in 0..values.len() {
                let p = 3 * i;
                if i > 0 {
                    sql.push(',');
                }
                sql.push_str(&format!("(${}, ${}, ${})", p + 1, p + 2, p + 3));
            }
            let mut q = sqlx::query(sqlx::AssertSqlSafe(sql));
            for (i, d) in values.iter().enumerate() {
                q = q.bind(id.clone()).bind((c * 1000 + i) as i64).bind(*d);
            }
            q.execute(&mut *tx).await?;
        }
        tx.commit().await?;
        rw.push(t.elapsed());
        let t = Instant::now();
        let rows =
            sqlx::query("SELECT deviation FROM bench_rows WHERE measurement = $1 ORDER BY k")
                .bind(id.clone())
                .fetch_all(store.pool())
                .await?;
        let back: Vec<f64> = rows
            .iter()
            .map(|r| r.try_get::<f64, _>(0))
            .collect::<Result<_, _>>()?;
        rr.push(t.elapsed());
        anyhow::ensure!(back == devs);
    }
    server.stop().await?;
    let f = Figures {
        upload: median(uploads),
        read: median(reads),
        blob_write: median(bw),
        blob_read: median(br),
        rows_write: median(rw),
        rows_read: median(rr),
    };
    let pps = |d: Duration| N as f64 / d.as_secs_f64();
    println!("== {label}: {N} points, median of {REPS}");
    println!(
        "  CSV upload end to end   {:>8.1} ms  {:>12.0} points/s",
        f.upload.as_secs_f64() * 1e3,
        pps(f.upload)
    );
    println!(
        "  JSON read-back          {:>8.1} ms  {:>12.0} points/s",
        f.read.as_secs_f64() * 1e3,
        pps(f.read)
    );
    println!(
        "  store write: BLOB {:>8.2} ms | row per point {:>8.1} ms | ratio {:>6.1}x",
        f.blob_write.as_secs_f64() * 1e3,
        f.rows_write.as_secs_f64() * 1e3,
        f.rows_write.as_secs_f64() / f.blob_write.as_secs_f64()
    );
    println!(
        "  store read:  BLOB {:>8.2} ms | row per point {:>8.1} ms | ratio {:>6.1}x",
        f.blob_read.as_secs_f64() * 1e3,
        f.rows_read.as_secs_f64() * 1e3,
        f.rows_read.as_secs_f64() / f.blob_read.as_secs_f64()
    );
    let rows_e2e = f.upload - f.blob_write + f.rows_write;
    println!(
        "  upload end to end if stored row per point (estimate): {:>12.0} points/s (BLOB is {:.1}x faster)",
        pps(rows_e2e),
        rows_e2e.as_secs_f64() / f.upload.as_secs_f64()
    );
    Ok(f)
}

fn main() -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    rt.block_on(async {
        run("SQLite (embedded)", None).await?;
        match std::env::var("TRUECUT_TEST_PG") {
            Ok(base) => {
                use sqlx::{Connection, Executor};
                let schema = format!("bench_{}", uuid::Uuid::now_v7().simple());
                let mut conn = sqlx::postgres::PgConnection::connect(&base).await?;
                conn.execute(sqlx::AssertSqlSafe(format!("CREATE SCHEMA {schema}"))).await?;
                let sep = if base.contains('?') { '&' } else { '?' };
                let result = run("PostgreSQL", Some(format!("{base}{sep}options[search_path]={schema}"))).await;
                conn.execute(sqlx::AssertSqlSafe(format!("DROP SCHEMA {schema} CASCADE"))).await?;
                result?;
            }
            Err(_) => println!("== PostgreSQL: skipped (set TRUECUT_TEST_PG=postgres://postgres@127.0.0.1:5432/test)"),
        }
        anyhow::Ok(())
    })
}
