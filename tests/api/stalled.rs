//! Stalled and slow request bodies (CONTRACT v1.1, issue 25): a body that stops arriving
//! gets 408 once the stall time passes (`--body-timeout-s`, 1 s here, 30 s by default), one
//! that arrives slower than `--min-body-rate` after the grace gets 408 too, and the server
//! goes on serving. A body at a good rate, and a small body on a slow link, pass.

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
        assert!(
            answer.contains("no byte for 1 s (--body-timeout-s)"),
            "{answer}"
        );
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

const UPLOAD: &str = "/v1/machines/m/surfaces/s/measurements";

/// Sends `body` as a CSV upload in `piece`-byte pieces, one every `every`, and returns the
/// answer's first line and the time from the headers to the answer. Stops sending when the
/// server has answered (or closed).
async fn trickle(addr: &str, body: &[u8], piece: usize, every: Duration) -> (String, Duration) {
    let host = addr.trim_start_matches("http://");
    let s = tokio::net::TcpStream::connect(host).await.unwrap();
    let (mut rd, mut wr) = s.into_split();
    let head = format!(
        "POST {UPLOAD} HTTP/1.1\r\nHost: {host}\r\nContent-Type: text/csv\r\n\
         Content-Length: {}\r\n\r\n",
        body.len()
    );
    wr.write_all(head.as_bytes()).await.unwrap();
    let t0 = Instant::now();
    let pieces: Vec<Vec<u8>> = body.chunks(piece).map(<[u8]>::to_vec).collect();
    let sender = tokio::spawn(async move {
        for p in pieces {
            if wr.write_all(&p).await.is_err() {
                return;
            }
            tokio::time::sleep(every).await;
        }
        let _ = wr.flush().await;
        // keep the write half open until the answer is read
        tokio::time::sleep(Duration::from_secs(60)).await;
    });
    let mut buf = vec![0u8; 8192];
    let n = tokio::time::timeout(Duration::from_secs(30), rd.read(&mut buf))
        .await
        .expect("no answer within 30 s")
        .unwrap();
    let took = t0.elapsed();
    sender.abort();
    let text = String::from_utf8_lossy(&buf[..n]).into_owned();
    (text, took)
}

/// 256 KiB/s minimum, 30 s stall time, a 2 x 2 surface to upload to.
async fn paced_app() -> TestApp {
    let app = spawn_app_with(|c| c.min_body_rate = 256 * 1024).await;
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    app
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_trickle_gets_408_and_a_body_at_a_good_rate_passes() {
    let app = paced_app().await;
    // 1 MiB at about 32 KiB/s (8 KiB every 250 ms): the allowance for b bytes is
    // 2 s + b / 256 KiB/s, so the body falls behind after about 2.3 s.
    let body = padded_deviation_csv(1 << 20);
    let (answer, took) = trickle(&app.addr, &body, 8 * 1024, Duration::from_millis(250)).await;
    println!(
        "trickle at 32 KiB/s answered after {took:?}: {}",
        answer.lines().next().unwrap_or("")
    );
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("arrived too slowly"), "{answer}");
    assert!(answer.contains("--min-body-rate"), "{answer}");
    assert!(
        took >= Duration::from_secs(2) && took < Duration::from_secs(6),
        "{took:?}"
    );
    // The same body at about 1 MiB/s (64 KiB every 60 ms) is stored.
    let (answer, took) = trickle(&app.addr, &body, 64 * 1024, Duration::from_millis(60)).await;
    println!("1 MiB at 1 MiB/s answered after {took:?}");
    assert!(answer.starts_with("HTTP/1.1 201"), "{answer}");
    assert_eq!(app.get("/healthz").await.status(), 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_small_body_on_a_slow_link_passes() {
    let app = paced_app().await;
    // 12 KiB at 4 KiB/s: far below the minimum rate, but a small body (at most 64 KiB) has
    // the whole stall time.
    let body = padded_deviation_csv(12 * 1024);
    let (answer, took) = trickle(&app.addr, &body, 1024, Duration::from_millis(250)).await;
    println!("12 KiB at 4 KiB/s answered after {took:?}");
    assert!(answer.starts_with("HTTP/1.1 201"), "{answer}");
    assert!(took >= Duration::from_secs(2), "{took:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_large_body_that_stalls_gets_408() {
    let app = spawn_app_with(|c| c.body_timeout_s = 1.0).await;
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    // 512 KiB sent at once, then nothing of the announced 4 MiB.
    let body = padded_deviation_csv(4 << 20);
    let host = app.addr.trim_start_matches("http://");
    let mut s = tokio::net::TcpStream::connect(host).await.unwrap();
    let head = format!(
        "POST {UPLOAD} HTTP/1.1\r\nHost: {host}\r\nContent-Type: text/csv\r\n\
         Content-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).await.unwrap();
    s.write_all(&body[..512 * 1024]).await.unwrap();
    let t0 = Instant::now();
    let mut buf = vec![0u8; 4096];
    let n = tokio::time::timeout(Duration::from_secs(10), s.read(&mut buf))
        .await
        .expect("no answer within 10 s")
        .unwrap();
    let answer = String::from_utf8_lossy(&buf[..n]);
    println!("stalled 4 MiB upload answered after {:?}", t0.elapsed());
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("stopped arriving"), "{answer}");
    assert!(t0.elapsed() < Duration::from_secs(4), "{:?}", t0.elapsed());
    let list: serde_json::Value = app.get(UPLOAD).await.json().await.unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 0, "{list}");
}

#[test]
fn a_bad_min_body_rate_is_refused_by_the_command_line() {
    use clap::Parser;
    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        config: truecut::config::Config,
    }
    let parsed = Cli::try_parse_from(["truecut", "--min-body-rate", "1MiB/s"]).unwrap();
    assert_eq!(parsed.config.min_body_rate, 1 << 20);
    let parsed = Cli::try_parse_from(["truecut", "--min-body-rate", "0"]).unwrap();
    assert_eq!(parsed.config.min_body_rate, 0);
    let err = Cli::try_parse_from(["truecut", "--min-body-rate", "fast"])
        .err()
        .expect("refused")
        .to_string();
    assert!(err.contains("the unit must be KiB or MiB"), "{err}");
}
