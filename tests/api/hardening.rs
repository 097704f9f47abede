//! Door validation and admission (issue 13): physical ranges refused at the point they are
//! stored, measured points paired by order checked against their nominals, pool work turned
//! away before its body is read, the process-wide budget of body bytes, and storage that
//! refuses writes (507, `/healthz`, a read-only data dir at start).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use crate::helpers::*;

const SURF: &str = "/v1/machines/m/surfaces/s";

async fn impossible_values_are_refused_naming_field_and_range(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let up = format!("{SURF}/measurements");
    // A deviation of 1e308 mm, and one just past the plausibility limit.
    let mut d = vec![0.01; 12];
    d[7] = 1e308;
    let r = app.post_json(&up, &json!({"deviations": d})).await;
    assert_problem(r, 400, &["deviations[7]", "--max-deviation-mm", "5 mm"]).await;
    d[7] = -5.5;
    let r = app.post_json(&up, &json!({"deviations": d})).await;
    assert_problem(r, 400, &["deviations[7]", "-5.5"]).await;
    let r = app
        .post_raw(
            &up,
            "text/csv",
            "deviation\n0\n0\n0\n0\n0\n0\n0\n0\n0\n0\n0\n9\n",
        )
        .await;
    assert_problem(r, 400, &["deviations[11]"]).await;
    d[7] = 0.3;
    assert_eq!(
        app.post_json(&up, &json!({"deviations": d})).await.status(),
        201
    );
    // Tool radii: negative, zero, absurd; on the surface and in the compensation query.
    let mut surface = flat_surface(4, 3);
    for bad in [-1.0, 0.0, 1e6] {
        surface["tool_radius"] = json!(bad);
        let r = app.put_json(SURF, &surface).await;
        assert_problem(r, 400, &["tool_radius", "(0, 100]"]).await;
    }
    let list = app.get(&up).await.json::<Value>().await.unwrap();
    let id = list["measurements"][0]["id"].as_str().unwrap().to_string();
    let r = app
        .get(&format!(
            "{SURF}/compensation?measurement={id}&cl=true&tool_radius=-1"
        ))
        .await;
    assert_problem(r, 400, &["tool_radius", "-1", "(0, 100]"]).await;
    let r = app
        .get(&format!(
            "{SURF}/compensation?measurement={id}&cl=true&tool_radius=2"
        ))
        .await;
    // A radius in range passes the door (the 4 x 3 grid is then too small to decompose: 422).
    assert_ne!(r.status(), 400);
    // Coordinates beyond 100 m.
    let mut surface = flat_surface(4, 3);
    surface["nominal"]["grid"]["points"][5] = json!([1.0, 1e300, 0.0]);
    let r = app.put_json(SURF, &surface).await;
    assert_problem(r, 400, &["nominal.grid.points[5]", "100000 mm"]).await;
    // Nothing of the refused bodies was stored.
    let s = app.get(SURF).await.json::<Value>().await.unwrap();
    assert_eq!(s["tool_radius"], 3.0);
    assert_eq!(
        app.get(&up).await.json::<Value>().await.unwrap()["measurements"]
            .as_array()
            .unwrap()
            .len(),
        1
    );
}
on_both_backends!(impossible_values_are_refused_naming_field_and_range);

/// The plausibility limit is a setting, named in the refusal.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_deviation_limit_is_a_setting() {
    let app = spawn_app_with(|c| c.max_deviation_mm = 0.05).await;
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let up = format!("{SURF}/measurements");
    let r = app
        .post_json(&up, &json!({"deviations": [0.01, 0.02, 0.1, 0.0]}))
        .await;
    assert_problem(r, 400, &["deviations[2]", "±0.05 mm", "--max-deviation-mm"]).await;
    let r = app
        .post_json(&up, &json!({"deviations": [0.01, 0.02, 0.04, 0.0]}))
        .await;
    assert_eq!(r.status(), 201);
}

/// Measured points of a 4 × 3 flat grid (1 mm spacing) 0.02 mm above their nominals.
fn measured(nu: usize, nv: usize) -> Vec<[f64; 3]> {
    (0..nu * nv)
        .map(|k| [(k % nu) as f64 + 0.003, (k / nu) as f64, 0.02])
        .collect()
}

async fn reversed_or_shifted_points_are_refused(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let up = format!("{SURF}/measurements");
    let good = measured(4, 3);
    let mut reversed = good.clone();
    reversed.reverse();
    let r = app.post_json(&up, &json!({"points": reversed})).await;
    assert_problem(r, 422, &["points[0]", "reverse", "--max-tangential-mm"]).await;
    // One point missing at the start, the last one repeated to keep the count.
    let mut shifted = good[1..].to_vec();
    shifted.push(good[11]);
    let csv: String = std::iter::once("x,y,z\n".to_string())
        .chain(
            shifted
                .iter()
                .map(|p| format!("{},{},{}\n", p[0], p[1], p[2])),
        )
        .collect();
    let r = app.post_raw(&up, "text/csv", csv).await;
    assert_problem(r, 422, &["points[0]", "shifted by one point"]).await;
    // A point 1 mm off along the normal is a deviation, not a pairing problem.
    let r = app.post_json(&up, &json!({"points": good})).await;
    assert_eq!(r.status(), 201);
    let body = r.json::<Value>().await.unwrap();
    assert!(
        (body["max_abs"].as_f64().unwrap() - 0.02).abs() < 1e-12,
        "{body}"
    );
    assert_eq!(
        app.get(&up).await.json::<Value>().await.unwrap()["measurements"]
            .as_array()
            .unwrap()
            .len(),
        1,
        "the refused uploads were not stored"
    );
}
on_both_backends!(reversed_or_shifted_points_are_refused);

/// Sends the headers of a `len`-byte JSON body and `sent` bytes of it; returns the stream.
async fn start_upload(addr: &str, path: &str, len: usize, sent: usize) -> tokio::net::TcpStream {
    let host = addr.trim_start_matches("http://");
    let mut s = tokio::net::TcpStream::connect(host).await.unwrap();
    let head = format!(
        "POST {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n\
         Content-Length: {len}\r\n\r\n"
    );
    s.write_all(head.as_bytes()).await.unwrap();
    s.write_all(&vec![b' '; sent]).await.unwrap();
    s
}

async fn answer(s: &mut tokio::net::TcpStream, within: Duration) -> String {
    let mut buf = vec![0u8; 4096];
    let n = tokio::time::timeout(within, s.read(&mut buf))
        .await
        .expect("no answer in time")
        .unwrap();
    String::from_utf8_lossy(&buf[..n]).into_owned()
}

/// With every worker busy and no queue, pool work is refused before its body arrives.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_pool_turns_requests_away_before_reading_their_bodies() {
    let app = spawn_app_with(|c| c.queue = 0).await;
    let pool = app.server().state().jobs.clone();
    let release = hold_workers(&app).await;
    // 10 MB announced, nothing sent: the answer comes at once, not after the body.
    let t0 = Instant::now();
    let mut s = start_upload(&app.addr, "/v1/decompose", 10_000_000, 0).await;
    let text = answer(&mut s, Duration::from_secs(5)).await;
    assert!(text.starts_with("HTTP/1.1 503"), "{text}");
    assert!(
        text.to_ascii_lowercase().contains("retry-after: 2"),
        "{text}"
    );
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    // Uploads never wait for a worker, so they are not shed.
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let r = app
        .post_json(
            &format!("{SURF}/measurements"),
            &json!({"deviations": [0.0, 0.01, 0.02, 0.0]}),
        )
        .await;
    assert_eq!(r.status(), 201);
    release.store(true, Ordering::SeqCst);
    while pool.running() > 0 {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let r = app
        .post_json("/v1/decompose", &json!({"signal": vec![0.0; 64]}))
        .await;
    assert_eq!(r.status(), 200, "served again once a worker is free");
}

/// Two workers held busy by jobs that run until `release` is set.
async fn hold_workers(app: &TestApp) -> Arc<AtomicBool> {
    let pool = app.server().state().jobs.clone();
    let release = Arc::new(AtomicBool::new(false));
    for _ in 0..2 {
        let r = release.clone();
        pool.submit("hold", move |_| {
            while !r.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(5));
            }
            Ok(json!(null))
        })
        .await
        .unwrap();
    }
    while pool.running() < 2 {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    release
}

/// Bodies beyond the process-wide budget wait for room, then get 503 naming the setting;
/// the room comes back when the request holding it is answered.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_body_budget_bounds_bytes_in_flight() {
    let app = spawn_app_with(|c| {
        c.max_inflight_body_mb = 1;
        c.max_body_bytes = 1 << 20;
        c.body_timeout_s = 1.0;
        c.queue = 1;
    })
    .await;
    // The surface exists, so the upload below passes the door's existence check and waits
    // for body room.
    seed_machine_and_surface(&app, "m", "s", 4, 4).await;
    let release = hold_workers(&app).await;
    // A 700 kB decomposition (64 samples and white space) holds its room while it waits
    // in the queue for a worker.
    let mut body = serde_json::to_string(&json!({"signal": vec![0.5; 64]})).unwrap();
    body.push_str(&" ".repeat(700_000 - body.len()));
    let first = {
        let (client, url) = (app.client.clone(), app.url("/v1/decompose"));
        tokio::spawn(async move {
            client
                .post(url)
                .header("content-type", "application/json")
                .body(body)
                .send()
                .await
                .unwrap()
                .status()
        })
    };
    let pool = app.server().state().jobs.clone();
    while pool.queued() < 1 {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let budget = app.server().state().body_budget.clone();
    assert!(
        budget.available_bytes() < 400_000,
        "{}",
        budget.available_bytes()
    );
    // A 700 kB upload finds no room within the wait (the body timeout, 1 s).
    let path = "/v1/machines/m/surfaces/s/measurements";
    let t0 = Instant::now();
    let mut second = start_upload(&app.addr, path, 700_000, 10).await;
    let text = answer(&mut second, Duration::from_secs(5)).await;
    assert!(text.starts_with("HTTP/1.1 503"), "{text}");
    assert!(text.contains("--max-inflight-body-mb"), "{text}");
    assert!(
        t0.elapsed() >= Duration::from_millis(900),
        "{:?}",
        t0.elapsed()
    );
    // Small requests are not counted and go through meanwhile.
    assert_eq!(app.get("/healthz").await.status(), 200);
    release.store(true, Ordering::SeqCst);
    assert_eq!(first.await.unwrap(), 200);
    assert_eq!(budget.available_bytes(), 1 << 20);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_budget_below_the_body_limit_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let mut config =
        truecut::config::Config::new("127.0.0.1:0".parse().unwrap(), dir.path().into());
    config.max_inflight_body_mb = 1;
    let err = truecut::server::start(&config)
        .await
        .err()
        .expect("refused");
    assert!(err.to_string().contains("--max-inflight-body-mb"), "{err}");
    config.max_inflight_body_mb = 512;
    config.max_deviation_mm = -1.0;
    let err = truecut::server::start(&config)
        .await
        .err()
        .expect("refused");
    assert!(err.to_string().contains("--max-deviation-mm"), "{err}");
}

/// A tmpfs mounted on `dir` with `options`, unmounted on drop; None (the test prints
/// SKIPPED) where this process may not mount, as for a non-root CI runner.
struct Tmpfs(std::path::PathBuf);

impl Tmpfs {
    fn mount(dir: &std::path::Path, options: &str) -> Option<Tmpfs> {
        let ok = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs"])
            .arg(dir)
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then(|| Tmpfs(dir.to_path_buf()))
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount")
            .arg("-l")
            .arg(&self.0)
            .status();
    }
}

/// A full disk: model saves and record writes answer 507 with a sentence, `/healthz`
/// reports the storage as not writable.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_answers_507_and_healthz_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let Some(_mount) = Tmpfs::mount(dir.path(), "size=4m") else {
        println!("SKIPPED a_full_disk_answers_507: this process may not mount a tmpfs");
        return;
    };
    let mut config =
        truecut::config::Config::new("127.0.0.1:0".parse().unwrap(), dir.path().into());
    config.workers = Some(2);
    let server = truecut::server::start(&config).await.unwrap();
    let base = format!("http://{}", server.addr());
    truecut::cli::client::install_crypto_provider();
    let client = reqwest::Client::new();
    let r = client
        .put(format!("{base}/v1/machines/m"))
        .json(&machine_xyz())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    // Fill the disk.
    let filler = dir.path().join("filler");
    let mut f = std::fs::File::create(&filler).unwrap();
    let chunk = vec![0u8; 64 * 1024];
    while std::io::Write::write_all(&mut f, &chunk).is_ok() {}
    drop(f);
    // A volumetric map: the fit runs, its save finds no room.
    let mut nodes = Vec::new();
    let mut errors = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            for k in 0..4 {
                let p = [i as f64 * 100.0, j as f64 * 100.0, k as f64 * -50.0];
                nodes.push(p);
                errors.push([1e-5 * p[0], -2e-5 * p[1], 1e-5 * p[2]]);
            }
        }
    }
    let r = client
        .put(format!("{base}/v1/machines/m/volumetric-map"))
        .json(&json!({"nodes": nodes, "errors": errors, "model": "trilinear"}))
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    let body = r.json::<Value>().await.unwrap();
    assert_eq!(status, 507, "{body}");
    assert!(
        body["detail"].as_str().unwrap().contains("storage is full"),
        "{body}"
    );
    let h = client
        .get(format!("{base}/healthz"))
        .send()
        .await
        .unwrap()
        .json::<Value>()
        .await
        .unwrap();
    assert_eq!(h["status"], "degraded", "{h}");
    assert_eq!(h["storage"]["writable"], false, "{h}");
    assert_eq!(h["storage"]["free_bytes"], 0, "{h}");
    // Room again: saves work again.
    std::fs::remove_file(&filler).unwrap();
    let h = client.get(format!("{base}/healthz")).send().await.unwrap();
    assert_eq!(
        h.json::<Value>().await.unwrap()["storage"]["writable"],
        true
    );
    server.stop().await.unwrap();
}

/// A read-only data dir stops the start at once with a sentence naming path and cause.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_read_only_data_dir_fails_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let Some(_mount) = Tmpfs::mount(dir.path(), "ro,size=1m") else {
        println!("SKIPPED a_read_only_data_dir_fails_at_start: this process may not mount");
        return;
    };
    let config = truecut::config::Config::new("127.0.0.1:0".parse().unwrap(), dir.path().into());
    let t0 = Instant::now();
    let err = truecut::server::start(&config)
        .await
        .err()
        .expect("refused");
    let text = format!("{err:#}");
    assert!(text.contains(&dir.path().display().to_string()), "{text}");
    assert!(text.contains("read-only"), "{text}");
    assert!(text.contains("--data-dir"), "{text}");
    assert!(t0.elapsed() < Duration::from_secs(2));
}
