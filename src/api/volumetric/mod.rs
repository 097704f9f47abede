//! Volumetric error maps (openapi.yaml `/v1/machines/{machine}/volumetric-map`; Xiang et al. 2019
//! and Wang, Dai & Hong; ISO 230-1): `PUT/GET/DELETE /v1/machines/{machine}/volumetric-map`,
//! `POST .../predict`, `GET .../table` (compensation table CSV), `GET .../versions` and
//! `POST .../rollback` (every PUT keeps the previous maps). Also the one
//! `From<volumetric::Error> for ApiError` and [`load_map`] for other capabilities (the gap
//! diagnosis).
//!
//! Files: `request` (bodies, query strings and their limits, parsed into the core's
//! options), `answer` (response bodies), `handlers` (the handlers and the model store).

mod answer;
mod handlers;
mod request;

use axum::Router;
use axum::routing::{get, post};

use super::AppState;
use handlers::{delete_map, get_map, map_rollback, map_versions, predict, put_map, table};

pub use handlers::{MODEL_KIND, load_map};
pub use request::{MAX_EPOCHS, MAX_NODES, MAX_POINTS, MAX_SAMPLE_PASSES};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v1/machines/{machine}/volumetric-map",
            get(get_map).put(put_map).delete(delete_map),
        )
        .route(
            "/v1/machines/{machine}/volumetric-map/predict",
            post(predict),
        )
        .route("/v1/machines/{machine}/volumetric-map/table", get(table))
        .route(
            "/v1/machines/{machine}/volumetric-map/versions",
            get(map_versions),
        )
        .route(
            "/v1/machines/{machine}/volumetric-map/rollback",
            post(map_rollback),
        )
}
