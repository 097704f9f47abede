//! Unit tests of the admission rules (the HTTP behaviour is in tests/api/admission.rs).

use super::*;

fn request(method: &str, headers: &[(&str, &str)]) -> Request {
    let mut b = axum::http::Request::builder()
        .method(method)
        .uri("/v1/decompose");
    for (k, v) in headers {
        b = b.header(*k, *v);
    }
    b.body(axum::body::Body::empty()).unwrap()
}

#[test]
fn pool_routes_are_the_posts_but_uploads_and_the_map_put() {
    assert!(uses_pool(&Method::POST, "/v1/decompose"));
    assert!(uses_pool(
        &Method::POST,
        "/v1/machines/m/surfaces/s/measurements/a/decomposition"
    ));
    assert!(!uses_pool(
        &Method::POST,
        "/v1/machines/m/surfaces/s/measurements"
    ));
    assert!(uses_pool(&Method::PUT, "/v1/machines/m/volumetric-map"));
    assert!(!uses_pool(&Method::PUT, "/v1/machines/m"));
    assert!(!uses_pool(&Method::GET, "/v1/decompose"));
}

#[test]
fn reservations_follow_the_declared_length() {
    let b = BodyBudget::new(10 << 20, 4 << 20, Duration::from_millis(10));
    assert_eq!(b.reservation(&request("GET", &[])), 0);
    assert_eq!(
        b.reservation(&request("POST", &[("content-length", "1000")])),
        0
    );
    assert_eq!(
        b.reservation(&request("POST", &[("content-length", "3000000")])),
        3_000_000
    );
    // Unknown length (chunked) takes nothing up front: its room grows as it is read
    // (`GrowingBody`); a lying header is capped at the largest body.
    assert_eq!(
        b.reservation(&request("POST", &[("transfer-encoding", "chunked")])),
        0
    );
    assert_eq!(
        b.reservation(&request("POST", &[("content-length", "99999999999")])),
        4 << 20
    );
}

#[tokio::test]
async fn a_full_budget_turns_away_after_the_wait_and_frees_on_drop() {
    let b = BodyBudget::new(8 << 20, 8 << 20, Duration::from_millis(20));
    let first = b.reserve(6 << 20).await.unwrap();
    assert!(first.is_some());
    assert_eq!(b.available_bytes(), 2 << 20);
    let refused = b.reserve(4 << 20).await.unwrap_err();
    assert_eq!(
        refused.status(),
        axum::http::StatusCode::SERVICE_UNAVAILABLE
    );
    assert!(refused.detail().contains("--max-inflight-body-mb"));
    drop(first);
    assert!(b.reserve(4 << 20).await.unwrap().is_some());
    let too_big = b.reserve(9 << 20).await.unwrap_err();
    assert_eq!(too_big.status(), axum::http::StatusCode::PAYLOAD_TOO_LARGE);
}

/// Reads a chunked body of `chunks` through a [`GrowingBody`] on `budget`; returns the bytes
/// read or the verdict's status, and the room held at the end (before the answer).
async fn grow(budget: Arc<BodyBudget>, chunks: Vec<usize>) -> (Result<u64, u16>, u64) {
    use futures::StreamExt;
    let stream = futures::stream::iter(
        chunks
            .into_iter()
            .map(|n| Ok::<_, std::io::Error>(Bytes::from(vec![b' '; n]))),
    );
    let growth = Growth::default();
    let body = GrowingBody {
        inner: axum::body::Body::from_stream(stream),
        budget: budget.clone(),
        read: 0,
        covered: UNCOUNTED_BODY_BYTES,
        pending: None,
        acquiring: None,
        growth: growth.clone(),
    };
    let mut data = axum::body::Body::new(body).into_data_stream();
    let mut n = 0;
    while let Some(c) = data.next().await {
        match c {
            Ok(c) => n += c.len() as u64,
            Err(_) => {
                let status = growth.lock().unwrap().verdict.take().unwrap().status();
                return (Err(status.as_u16()), budget_held(&budget));
            }
        }
    }
    (Ok(n), budget_held(&budget))
}

fn budget_held(b: &BodyBudget) -> u64 {
    b.total_bytes - b.available_bytes()
}

#[tokio::test]
async fn a_chunked_body_takes_room_as_it_is_read() {
    let b = Arc::new(BodyBudget::new(8 << 20, 6 << 20, Duration::from_millis(20)));
    // 3,500 KiB in 100 KiB chunks: 256 KiB free, then whole MiB steps: 4 MiB held.
    let (got, held) = grow(b.clone(), vec![100 << 10; 35]).await;
    assert_eq!(got, Ok(35 * (100 << 10)));
    assert_eq!(held, 4 << 20);
    // Past --max-body-bytes (6 MiB): 413.
    let (got, _) = grow(b.clone(), vec![1 << 20; 7]).await;
    assert_eq!(got, Err(413));
    // With 7 MiB held elsewhere, a body needing a second MiB finds no room: 503.
    let _other = b.reserve(7 << 20).await.unwrap();
    let (got, held) = grow(b.clone(), vec![1 << 20; 2]).await;
    assert_eq!(got, Err(503));
    assert_eq!(held, 8 << 20);
}
