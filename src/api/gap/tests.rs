//! Unit tests of `crate::api::gap`.

use super::*;
use crate::gap::Effect;
use axum::http::StatusCode;

#[test]
fn rows_are_checked_and_transposed() {
    // The gap core checks the rows; api/error.rs answers its errors.
    let rows =
        |field: &str, rows: &[Vec<f64>]| gap::rows_to_columns(field, rows).map_err(ApiError::from);
    let c = rows("commanded", &[vec![1.0, 2.0], vec![3.0, 4.0]]).unwrap();
    assert_eq!(c, vec![vec![1.0, 3.0], vec![2.0, 4.0]]);
    let e = rows("commanded", &[vec![1.0, 2.0], vec![3.0]]).unwrap_err();
    assert!(e.detail().contains("commanded[1]"), "{}", e.detail());
    let e = rows("measured", &[]).unwrap_err();
    assert!(e.detail().contains("measured is empty"));
    let e = rows("commanded", &[vec![1.0; 4]]).unwrap_err();
    assert_eq!(e.status(), StatusCode::BAD_REQUEST);
}

#[test]
fn gap_errors_map_to_4xx() {
    let e: ApiError = gap::Error::Shape {
        field: "commanded".into(),
        reason: "x".into(),
    }
    .into();
    assert_eq!(e.status(), StatusCode::BAD_REQUEST);
    let e: ApiError = gap::Error::Servo {
        axis: "X".into(),
        source: crate::motion::Error::EmptyCommand,
    }
    .into();
    assert_eq!(e.status(), StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(Effect::None.name(), "none");
}
