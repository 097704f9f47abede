//! `GET /healthz`: liveness, database readiness and the storage state.

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

/// `200 {"status": "ok", "storage": {...}}` when the database answers, 503 otherwise.
/// `storage` says whether the data dir takes writes (a probe file) and its free bytes;
/// `status` is `"degraded"` while it takes none (reads still work, saves answer 507).
async fn healthz(State(state): State<AppState>) -> ApiResult<ApiJson<Value>> {
    state.store.ping().await.map_err(|e| {
        tracing::error!("health check: database unreachable: {e:#}");
        ApiError::unavailable("the database does not answer", 5)
    })?;
    let dir = state.store.models().root().to_path_buf();
    let storage = tokio::task::spawn_blocking(move || crate::store::state_of(&dir))
        .await
        .map_err(ApiError::internal)?;
    let status = if storage.writable { "ok" } else { "degraded" };
    Ok(ApiJson(json!({
        "status": status,
        "instance": state.store.instance(),
        "storage": storage
    })))
}
