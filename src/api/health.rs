//! `GET /healthz` (liveness: the database, the lease, the storage) and `GET /readyz`
//! (readiness for a load balancer: route requests here or not).

use std::time::Duration;

use axum::Router;
use axum::extract::State;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::json;

use super::AppState;
use super::error::{ApiError, unavailable_report};
use super::extract::ApiJson;

/// How long the database probe of `/healthz` and `/readyz` may take (`SELECT 1` through the
/// request pool, waiting for a connection included).
pub const PROBE_LIMIT: Duration = Duration::from_secs(2);

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
}

/// `200 {"status", "instance", "host", "storage", "database", "lease"}`: `status` is `ok`,
/// `degraded` while the data dir takes no writes (reads still work, saves answer 507), or
/// `fenced` while this instance's lease has lapsed (it claims and commits no job; see
/// `store/instances.rs`). `503` problem+json carrying the same report, `status:
/// "unavailable"`, when the database does not answer within [`PROBE_LIMIT`].
async fn healthz(State(state): State<AppState>) -> Result<Response, ApiError> {
    let database = state.store.database_report(PROBE_LIMIT).await;
    let lease = state.store.lease();
    let dir = state.store.models().root().to_path_buf();
    let storage = tokio::task::spawn_blocking(move || crate::store::state_of(&dir))
        .await
        .map_err(ApiError::internal)?;
    let status = if !database.reachable {
        "unavailable"
    } else if lease.fenced {
        "fenced"
    } else if !storage.writable {
        "degraded"
    } else {
        "ok"
    };
    let report = json!({
        "status": status,
        "instance": state.store.instance(),
        "host": std::env::var("HOSTNAME").ok().filter(|h| !h.is_empty()),
        "storage": storage,
        "database": database,
        "lease": lease,
    });
    if let Some(why) = &database.error {
        tracing::error!("health check: database unreachable: {why}");
        let detail = format!("the database does not answer: {why}");
        return Ok(unavailable_report(&detail, 5, report));
    }
    Ok(ApiJson(report).into_response())
}

/// `200 {"ready": true, "instance"}` when this instance should get requests: the database
/// answers within [`PROBE_LIMIT`] and its lease holds (not fenced). Otherwise `503`
/// problem+json with `Retry-After` and the members `ready: false`, `instance` and `reasons`
/// (sentences). The storage does not count (a full data dir still serves reads; `/healthz`
/// reports it).
async fn readyz(State(state): State<AppState>) -> Response {
    let database = state.store.database_report(PROBE_LIMIT).await;
    let lease = state.store.lease();
    let mut reasons = Vec::new();
    if let Some(why) = &database.error {
        reasons.push(format!("the database does not answer: {why}"));
    }
    if lease.fenced {
        reasons.push(
            "this instance's lease lapsed (renewals failing): it is fenced until it registers \
             again"
                .to_string(),
        );
    }
    let instance = state.store.instance();
    if reasons.is_empty() {
        return ApiJson(json!({"ready": true, "instance": instance})).into_response();
    }
    unavailable_report(
        &format!("not ready: {}", reasons.join("; ")),
        5,
        json!({"ready": false, "instance": instance, "reasons": reasons}),
    )
}
