//! Bounds on what a client can make the service hold (issue 41 item 9): the `method` label
//! of the request counter takes the standard methods and `other`, however many made-up
//! methods arrive; a connection that never finishes its headers is closed after
//! `--header-timeout-s` (slowloris), and a value outside its range is refused at start.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};

use crate::helpers::{spawn_app, spawn_app_with};

/// The `method` labels of `truecut_http_requests_total` and the number of its series.
async fn method_series(app: &crate::helpers::TestApp) -> (BTreeSet<String>, usize) {
    let text = app.get("/metrics").await.text().await.unwrap();
    let series: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("truecut_http_requests_total{"))
        .collect();
    let methods = series
        .iter()
        .map(|l| {
            let from = l.find("method=\"").unwrap() + 8;
            let len = l[from..].find('"').unwrap();
            l[from..from + len].to_string()
        })
        .collect();
    (methods, series.len())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn made_up_methods_share_one_label() {
    let app = spawn_app().await;
    assert_eq!(app.get("/healthz").await.status(), 200);
    let (_, before) = method_series(&app).await;
    for i in 0..20 {
        let method =
            reqwest::Method::from_bytes(format!("X{i}RANDOM{}", i * 7919).as_bytes()).unwrap();
        let path = if i % 2 == 0 {
            "/v1/machines"
        } else {
            "/healthz"
        };
        let r = app
            .client
            .request(method, app.url(path))
            .send()
            .await
            .unwrap();
        assert!(r.status().is_client_error(), "{}", r.status());
    }
    let (methods, after) = method_series(&app).await;
    let standard = [
        "GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS", "other",
    ];
    assert!(
        methods.iter().all(|m| standard.contains(&m.as_str())),
        "{methods:?}"
    );
    assert!(methods.contains("other"), "{methods:?}");
    // 20 made-up methods on two routes: at most a series per route and status, not per
    // method (before the fix: 20 new series).
    eprintln!("request-counter series: {before} before, {after} after 20 made-up methods");
    assert!(after - before <= 4, "{before} -> {after}");
}

/// Sends `head` on a new connection and returns how long until the server closes it (EOF or
/// reset), giving up after `limit`.
async fn time_to_close(addr: &str, head: &[u8], limit: Duration) -> Option<Duration> {
    let mut s = tokio::net::TcpStream::connect(addr.trim_start_matches("http://"))
        .await
        .unwrap();
    s.write_all(head).await.unwrap();
    let start = Instant::now();
    let mut buf = [0u8; 1024];
    loop {
        match tokio::time::timeout(limit.saturating_sub(start.elapsed()), s.read(&mut buf)).await {
            Err(_) => return None,
            Ok(Ok(0)) | Ok(Err(_)) => return Some(start.elapsed()),
            // An answer (hyper may answer 408) before it closes: keep reading.
            Ok(Ok(_)) => {}
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unfinished_headers_are_cut_off() {
    let app = spawn_app_with(|c| c.header_timeout_s = 1.0).await;
    // A partial request line, then nothing (slowloris).
    let took = time_to_close(&app.addr, b"GET /heal", Duration::from_secs(10))
        .await
        .expect("the connection was not closed within 10 s");
    eprintln!("partial request line: closed after {took:?} (--header-timeout-s 1)");
    assert!(took >= Duration::from_millis(900), "{took:?}");
    assert!(took <= Duration::from_secs(3), "{took:?}");
    // Headers trickling in (a line every 400 ms) are cut off too: the limit is on them all.
    let mut s = tokio::net::TcpStream::connect(app.addr.trim_start_matches("http://"))
        .await
        .unwrap();
    let start = Instant::now();
    s.write_all(b"GET /healthz HTTP/1.1\r\n").await.unwrap();
    let mut closed = None;
    for i in 0..20 {
        tokio::time::sleep(Duration::from_millis(400)).await;
        if s.write_all(format!("X-Slow-{i}: 1\r\n").as_bytes())
            .await
            .is_err()
        {
            closed = Some(start.elapsed());
            break;
        }
        let mut buf = [0u8; 256];
        if let Ok(Ok(0) | Err(_)) =
            tokio::time::timeout(Duration::from_millis(1), s.read(&mut buf)).await
        {
            closed = Some(start.elapsed());
            break;
        }
    }
    let closed = closed.expect("trickled headers kept the connection open for 8 s");
    assert!(closed <= Duration::from_secs(3), "{closed:?}");
    // A complete request is answered as before.
    assert_eq!(app.get("/healthz").await.status(), 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn header_timeout_outside_its_range_is_refused() {
    for bad in [0.0, 0.1, 601.0, f64::NAN] {
        let dir = tempfile::tempdir().unwrap();
        let mut config =
            truecut::config::Config::new("127.0.0.1:0".parse().unwrap(), dir.path().into());
        config.header_timeout_s = bad;
        let err = truecut::server::start(&config)
            .await
            .err()
            .expect("started with a bad --header-timeout-s");
        let text = format!("{err:#}");
        assert!(
            text.contains("--header-timeout-s must be between 0.5 and 600"),
            "{text}"
        );
    }
}
