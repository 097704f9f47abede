//! Unit tests of the Idempotency-Key rules that need no server.

use axum::http::HeaderValue;

use super::{MAX_KEY_LEN, ROUTES, parse_key};

#[test]
fn keys_quoted_or_bare_are_one_key() {
    let bare = parse_key(&HeaderValue::from_static("8e03978e-40d5-43e8")).unwrap();
    let quoted = parse_key(&HeaderValue::from_static("\"8e03978e-40d5-43e8\"")).unwrap();
    assert_eq!(bare, quoted);
    assert_eq!(bare, "8e03978e-40d5-43e8");
}

#[test]
fn bad_keys_are_refused_with_a_sentence() {
    let long = "k".repeat(MAX_KEY_LEN + 1);
    for bad in ["", "\"\"", "a b", "tab\there", long.as_str()] {
        let err = parse_key(&HeaderValue::from_str(bad).unwrap()).unwrap_err();
        assert_eq!(err.status(), 400, "{bad:?}");
        assert!(err.detail().contains("1 to 255"), "{}", err.detail());
    }
    let err = parse_key(&HeaderValue::from_bytes(b"caf\xc3\xa9").unwrap()).unwrap_err();
    assert_eq!(err.status(), 400);
    assert!(parse_key(&HeaderValue::from_str(&"k".repeat(MAX_KEY_LEN)).unwrap()).is_ok());
}

#[test]
fn honoured_routes_are_posts_of_the_router() {
    let mut seen = std::collections::HashSet::new();
    for r in ROUTES {
        assert!(r.starts_with("/v1/"), "{r}");
        assert!(seen.insert(r), "{r} twice");
    }
}

#[test]
fn a_digest_ended_twice_keeps_its_value() {
    use super::{DigestState, Fingerprint};
    let mut once = Fingerprint::new(Some("id=a"));
    once.update(b"body");
    let want = once.finish();
    let mut state = DigestState::Running(Fingerprint::new(Some("id=a")));
    state.update(b"bo");
    state.update(b"dy");
    state.end();
    state.end();
    state.update(b"more");
    match state {
        DigestState::Done(got) => assert_eq!(got, want),
        DigestState::Running(_) => panic!("not ended"),
    }
}
