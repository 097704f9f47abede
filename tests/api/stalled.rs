//! Stalled request bodies (CONTRACT v1.1): a body that stops arriving gets 408 once the
//! body timeout passes (1 s here, 30 s by default), and the server goes on serving.

use std::time::{Duration, Instant};

use crate::helpers::*;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// Sends the headers of a 100-byte JSON body and only 10 bytes of it, then waits.
async fn stall(addr: &str, method: &str, path: &str) -> (String, Duration) {
    let host = addr.trim_start_matches("http://");
    let mut s = tokio::net::TcpStream::connect(host).await.unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n\
         Content-Length: 100\r\n\r\n{{\"signal\":"
    );
    s.write_all(head.as_bytes()).await.unwrap();
    let t0 = Instant::now();
    let mut buf = vec![0u8; 4096];
    let n = tokio::time::timeout(Duration::from_secs(10), s.read(&mut buf))
        .await
        .expect("no answer within 10 s")
        .unwrap();
    (
        String::from_utf8_lossy(&buf[..n]).into_owned(),
        t0.elapsed(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_body_gets_408_and_frees_the_server() {
    let app = spawn_app_with(|c| c.body_timeout_s = 1.0).await;
    for (method, path) in [
        ("POST", "/v1/decompose"),
        ("PUT", "/v1/machines/m"),
        ("POST", "/v1/step-error"),
    ] {
        let (answer, took) = stall(&app.addr, method, path).await;
        println!("{path}: stalled body answered after {took:?} (timeout 1 s)");
        assert!(answer.starts_with("HTTP/1.1 408"), "{path}: {answer}");
        assert!(answer.contains("did not arrive within 1 s"), "{answer}");
        assert!(took >= Duration::from_millis(900) && took < Duration::from_secs(3));
    }
    // Nothing was stored and the service still answers.
    assert_eq!(app.get("/v1/machines/m").await.status(), 404);
    assert_eq!(app.get("/healthz").await.status(), 200);
    assert_eq!(app.server().state().jobs.running(), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_body_timeout_setting_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let mut config =
        truecut::config::Config::new("127.0.0.1:0".parse().unwrap(), dir.path().into());
    config.body_timeout_s = 0.0;
    let err = truecut::server::start(&config)
        .await
        .err()
        .expect("refused");
    assert!(err.to_string().contains("--body-timeout-s"), "{err}");
}
