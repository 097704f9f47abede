//! Tests of the id rule at the HTTP door.

use super::*;

#[test]
fn ids_follow_the_store_rule() {
    for ok in ["m1", "a.b", "A_b-9", &"x".repeat(64), "..."] {
        assert_eq!(Id::parse("machine", ok).unwrap().as_str(), ok);
    }
    for bad in ["", ".", "..", "a b", "a/b", &"x".repeat(65), "é"] {
        let e = Id::parse("machine", bad).unwrap_err();
        assert_eq!(e.status(), axum::http::StatusCode::BAD_REQUEST);
        assert!(e.detail().contains("machine id"), "{}", e.detail());
    }
}
