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
    // Unknown length counts as the largest body; a lying header is capped at it too.
    assert_eq!(
        b.reservation(&request("POST", &[("transfer-encoding", "chunked")])),
        4 << 20
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
