//! `GET /healthz`: liveness and database readiness.

use axum::Router;
use axum::extract::State;
use axum::routing::get;
use serde_json::{Value, json};

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/healthz", get(healthz))
}

/// `200 {"status": "ok"}` when the database answers, 503 otherwise.
async fn healthz(State(state): State<AppState>) -> ApiResult<ApiJson<Value>> {
    state.store.ping().await.map_err(|e| {
        tracing::error!("health check: database unreachable: {e:#}");
        ApiError::unavailable("the database does not answer", 5)
    })?;
    Ok(ApiJson(
        json!({"status": "ok", "instance": state.store.instance()}),
    ))
}
