//! The door before the body (issue 25): auth, id, existence and size checks answer before a
//! body is read; a `read` token cannot queue stored jobs; a chunked body takes room in the
//! body budget as it arrives, not the largest body's worth.

use std::time::{Duration, Instant};

use crate::helpers::*;
use serde_json::{Value, json};
use tokio::io::AsyncWriteExt;

const MIB: usize = 1 << 20;

/// Announces a `len`-byte body, sends 1 KiB of it, and returns the answer and its delay.
async fn announce(
    app: &TestApp,
    method: &str,
    path: &str,
    headers: &[&str],
    len: usize,
) -> (String, Duration) {
    let cl = format!("Content-Length: {len}");
    let mut all: Vec<&str> = headers.to_vec();
    all.push(&cl);
    let mut s = raw_request(&app.addr, method, path, &all).await;
    s.write_all(&padded_deviation_csv(1024)).await.unwrap();
    let t0 = Instant::now();
    let answer = raw_answer(&mut s, Duration::from_secs(10)).await;
    (answer, t0.elapsed())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unknown_records_and_oversize_bodies_are_answered_before_the_body_is_read() {
    let app = spawn_app().await;
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let csv = ["Content-Type: text/csv"];
    // A 120 MiB upload to an unknown surface: 404 at once, the body never read.
    let (answer, took) = announce(
        &app,
        "POST",
        "/v1/machines/m/surfaces/nope/measurements",
        &csv,
        120 * MIB,
    )
    .await;
    println!("120 MiB upload to an unknown surface answered after {took:?}");
    assert!(answer.starts_with("HTTP/1.1 404"), "{answer}");
    assert!(
        answer.contains("surface 'nope' of machine 'm' does not exist"),
        "{answer}"
    );
    assert!(took < Duration::from_secs(2), "{took:?}");
    // ... to an unknown machine, on another route with a body.
    let json = ["Content-Type: application/json"];
    let (answer, took) = announce(
        &app,
        "POST",
        "/v1/machines/ghost/gap-diagnosis",
        &json,
        100 * MIB,
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 404"), "{answer}");
    assert!(
        answer.contains("machine 'ghost' does not exist"),
        "{answer}"
    );
    assert!(took < Duration::from_secs(2), "{took:?}");
    // A CSV upload whose id (from the query) is taken: 409 before the body.
    let r = app
        .post_raw(
            "/v1/machines/m/surfaces/s/measurements?id=taken",
            "text/csv",
            padded_deviation_csv(200),
        )
        .await;
    assert_eq!(r.status(), 201);
    let (answer, took) = announce(
        &app,
        "POST",
        "/v1/machines/m/surfaces/s/measurements?id=taken",
        &csv,
        120 * MIB,
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 409"), "{answer}");
    assert!(took < Duration::from_secs(2), "{took:?}");
    // An invalid id: 400 before the body.
    let (answer, _) = announce(
        &app,
        "POST",
        "/v1/machines/m/surfaces/s/measurements?id=a%20b",
        &csv,
        120 * MIB,
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 400"), "{answer}");
    // Over --max-body-bytes: 413 at once.
    let (answer, took) = announce(
        &app,
        "POST",
        "/v1/machines/m/surfaces/s/measurements",
        &csv,
        200 * MIB,
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    assert!(answer.contains("--max-body-bytes"), "{answer}");
    assert!(took < Duration::from_secs(2), "{took:?}");
    // Nothing is held afterwards.
    let budget = app.server().state().body_budget.clone();
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(budget.available_bytes(), 160 * MIB as u64);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_read_token_cannot_queue_a_stored_job() {
    let mut app =
        spawn_app_with(|c| c.tokens = Some("a-tok admin,w-tok write,r-tok read".into())).await;
    app.token = Some("a-tok".into());
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    // An upload with a read token: 403 before its 100 MiB body.
    let (answer, took) = announce(
        &app,
        "POST",
        "/v1/machines/m/surfaces/s/measurements",
        &["Content-Type: text/csv", "Authorization: Bearer r-tok"],
        100 * MIB,
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
    assert!(took < Duration::from_secs(2), "{took:?}");
    // A program compensation asked as a job (Prefer: respond-async): 403 before the body.
    let (answer, took) = announce(
        &app,
        "POST",
        "/v1/machines/m/compensated-program",
        &[
            "Content-Type: application/json",
            "Prefer: respond-async",
            "Authorization: Bearer r-tok",
        ],
        10 * MIB,
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
    assert!(answer.contains("role 'write'"), "{answer}");
    assert!(took < Duration::from_secs(2), "{took:?}");
    // A decomposition above the direct limit would be a stored job: 403 for read, 202 for write.
    let n = truecut::api::decomposition::MAX_SYNC + 1;
    let signal: Vec<f64> = (0..n).map(|i| ((i % 100) as f64) * 1e-4).collect();
    let body = json!({"signal": signal});
    app.token = Some("r-tok".into());
    assert_problem(
        app.post_json("/v1/decompose", &body).await,
        403,
        &[
            "more than the 250000 answered directly",
            "role 'write'",
            "yours has role 'read'",
        ],
    )
    .await;
    // The read token still gets direct answers.
    let r = app
        .post_json("/v1/decompose", &json!({"signal": vec![0.001; 64]}))
        .await;
    assert_eq!(r.status(), 200);
    app.token = Some("w-tok".into());
    let r = app.post_json("/v1/decompose", &body).await;
    assert_eq!(r.status(), 202);
    let job: Value = r.json().await.unwrap();
    let id = job["job"].as_str().expect("job id").to_string();
    let r = app.delete(&format!("/v1/jobs/{id}")).await;
    assert!(r.status().is_success(), "{}", r.status());
}

/// Sends `data` as one chunk of a chunked body; false once the server has closed.
async fn chunk(s: &mut (impl tokio::io::AsyncWrite + Unpin), data: &[u8]) -> bool {
    s.write_all(format!("{:x}\r\n", data.len()).as_bytes())
        .await
        .is_ok()
        && s.write_all(data).await.is_ok()
        && s.write_all(b"\r\n").await.is_ok()
}

/// Sends `body` as a chunked upload in 256 KiB chunks while reading the answer (so that it
/// is read even when the server closes before the body is sent); returns the answer.
async fn chunked_upload(addr: &str, path: &str, body: Vec<u8>) -> String {
    use tokio::io::AsyncReadExt;
    let s = raw_request(
        addr,
        "POST",
        path,
        &["Content-Type: text/csv", "Transfer-Encoding: chunked"],
    )
    .await;
    let (mut rd, mut wr) = s.into_split();
    let sender = tokio::spawn(async move {
        for piece in body.chunks(256 * 1024) {
            if !chunk(&mut wr, piece).await {
                return;
            }
        }
        let _ = wr.write_all(b"0\r\n\r\n").await;
        tokio::time::sleep(Duration::from_secs(30)).await;
    });
    let mut buf = vec![0u8; 8192];
    let n = tokio::time::timeout(Duration::from_secs(10), rd.read(&mut buf))
        .await
        .expect("no answer in time")
        .unwrap();
    sender.abort();
    String::from_utf8_lossy(&buf[..n]).into_owned()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_chunked_body_takes_room_for_what_it_has_sent() {
    let app = spawn_app_with(|c| {
        c.max_body_bytes = 8 * MIB;
        c.max_inflight_body_mb = 8;
        c.body_timeout_s = 1.5;
    })
    .await;
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let budget = app.server().state().body_budget.clone();
    let path = "/v1/machines/m/surfaces/s/measurements";
    let headers = ["Content-Type: text/csv", "Transfer-Encoding: chunked"];
    // A chunked upload that has sent 3 MiB holds about 3 MiB (it used to hold 8, the
    // largest body), in 1 MiB steps past the first 256 KiB.
    let body = padded_deviation_csv(4 * MIB);
    let mut first = raw_request(&app.addr, "POST", path, &headers).await;
    for piece in body[..3 * MIB].chunks(256 * 1024) {
        assert!(chunk(&mut first, piece).await);
    }
    let deadline = Instant::now() + Duration::from_secs(5);
    while budget.available_bytes() > 5 * MIB as u64 && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let held = 8 * MIB as u64 - budget.available_bytes();
    println!("a chunked body with 3 MiB sent holds {held} bytes of the 8 MiB budget");
    assert_eq!(held, 3 * MIB as u64);
    // A second chunked upload of 6 MiB finds no room for its growth: 503 + Retry-After after
    // the wait (--body-timeout-s), while the first keeps sending.
    let addr = app.addr.clone();
    let second =
        tokio::spawn(
            async move { chunked_upload(&addr, path, padded_deviation_csv(6 * MIB)).await },
        );
    let mut sent = 3 * MIB;
    let t0 = Instant::now();
    while !second.is_finished() && t0.elapsed() < Duration::from_secs(8) {
        assert!(chunk(&mut first, &body[sent..sent + 4 * 1024]).await);
        sent += 4 * 1024;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let answer = second.await.unwrap();
    println!(
        "the second chunked upload was answered after {:?}",
        t0.elapsed()
    );
    assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
    assert!(
        answer.to_ascii_lowercase().contains("retry-after: 2"),
        "{answer}"
    );
    assert!(answer.contains("--max-inflight-body-mb"), "{answer}");
    // The first completes and is stored; the room is free again.
    assert!(chunk(&mut first, &body[sent..]).await);
    first.write_all(b"0\r\n\r\n").await.unwrap();
    let answer = raw_answer(&mut first, Duration::from_secs(5)).await;
    assert!(answer.starts_with("HTTP/1.1 201"), "{answer}");
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(budget.available_bytes(), 8 * MIB as u64);
    // A chunked body longer than --max-body-bytes: 413 once it passes it.
    let answer = chunked_upload(&app.addr, path, padded_deviation_csv(9 * MIB)).await;
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    assert!(answer.contains("--max-body-bytes"), "{answer}");
}
