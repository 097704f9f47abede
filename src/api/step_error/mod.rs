//! Step error of ball-end finishing over HTTP (openapi.yaml `POST /v1/step-error` and the
//! `step-error-*` routes; Zhang et al. 2023): the exact
//! geometric route (`exact.rs`), sample generation (`samples.rs`), training / fine-tuning the
//! network as a job, prediction from it, its versions and rollback (`model.rs`). The work is the `step_error` core's
//! and the body decoding the `codec`'s; statuses are decided in `api/error.rs`.

mod exact;
mod model;
mod samples;

use axum::Router;
use axum::routing::{get, post};

use super::AppState;
use exact::exact;
use model::{delete_model, model_info, model_rollback, model_versions, predict, train};

pub use model::{TRAINING_JOB, training_runner};
use samples::{samples, surface_samples};

/// Segments answered synchronously by the sample routes (the exact route takes any count the
/// body limit lets through; openapi.yaml: sync up to 100,000).
pub const MAX_SYNC_SAMPLES: usize = 200_000;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/step-error", post(exact))
        .route("/v1/step-error/samples", post(samples))
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-samples",
            post(surface_samples),
        )
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-model",
            post(train).get(model_info).delete(delete_model),
        )
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-model/versions",
            get(model_versions),
        )
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-model/rollback",
            post(model_rollback),
        )
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-model/predict",
            post(predict),
        )
}
