//! HTTP translation: the router, shared state, and one file per resource.
//!
//! Each resource file exposes `pub fn routes() -> Router<AppState>` with literal paths
//! (`.route("/v1/...", get(..))`); [`router`] merges them and adds the cross-cutting layers
//! (request id, tracing, metrics, body limit, problem+json, auth). The openapi test reads
//! the `.route("...")` literals of `src/api/*.rs` and compares them with `openapi.yaml`.

pub mod admission;
pub mod auth;
pub mod compensated;
pub mod compensation;
pub mod contour;
pub mod dashboard;
pub mod decomposition;
pub mod effects;
pub mod effects_program;
pub mod error;
pub mod extract;
pub mod gap;
pub mod health;
pub mod id;
pub mod idempotency;
pub mod intake;
pub mod iso230;
pub mod iso230_comp;
pub mod iso230_runs;
pub mod jobs;
pub mod lookup;
pub mod machines;
pub mod measurements;
pub mod metrics;
pub mod middleware;
pub mod model_versions;
pub mod pace;
pub mod ranges;
pub mod step_error;
pub mod surfaces;
pub mod upload;
pub mod version;
pub mod volumetric;

use std::sync::Arc;

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::http::Request;
use tower_http::compression::CompressionLayer;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::{DefaultOnResponse, TraceLayer};

pub use auth::{RequireAdmin, RequireWrite, Role, Tokens};
pub use error::{ApiError, ApiResult};
pub use extract::{ApiJson, check_finite, check_len, check_points};
pub use id::{Id, PathIds};
pub use lookup::{require_machine, require_machine_def, require_measurement, require_surface};

/// Shared state of every handler. Cheap to clone.
#[derive(Clone)]
pub struct AppState {
    /// Records and model files.
    pub store: crate::store::Store,
    /// Worker pool for CPU-heavy work.
    pub jobs: crate::jobs::JobPool,
    /// Configured bearer tokens (empty: development mode, everyone is admin).
    pub tokens: Arc<Tokens>,
    /// Request counters and latency histograms for `/metrics`.
    pub metrics: Arc<metrics::Metrics>,
    /// Largest accepted request body, bytes.
    pub max_body_bytes: usize,
    /// How fast a request body must arrive (`--body-timeout-s`, `--min-body-rate`; then 408).
    pub pace: pace::Pace,
    /// Request-body bytes the process holds at once (`--max-inflight-body-mb`).
    pub body_budget: Arc<admission::BodyBudget>,
    /// Plausibility limits of measured values (`--max-deviation-mm`, `--max-tangential-mm`).
    pub limits: ranges::Limits,
}

/// The whole HTTP API: every resource's `routes()` plus the cross-cutting layers.
pub fn router(state: AppState) -> Router {
    let max_body = state.max_body_bytes;
    Router::new()
        .merge(health::routes())
        .merge(dashboard::routes())
        .merge(metrics::routes())
        .merge(jobs::routes())
        .merge(machines::routes())
        .merge(surfaces::routes())
        .merge(measurements::routes())
        .merge(contour::routes())
        .merge(volumetric::routes())
        .merge(gap::routes())
        .merge(effects::routes())
        .merge(step_error::routes())
        .merge(decomposition::routes())
        .merge(compensation::routes())
        .merge(compensated::routes())
        .merge(iso230::routes())
        .merge(iso230_runs::routes())
        .merge(iso230_comp::routes())
        .fallback(middleware::fallback)
        // Innermost first: the problem+json rewrite covers framework rejections (405, path
        // errors); metrics see the final status. Everything up to the pace runs before a
        // body is read, cheapest first (outermost): the declared size, the token and role,
        // the records the path names, room on the worker pool, room for the body.
        .layer(axum::middleware::from_fn(middleware::problem_json))
        // Idempotency-Key: inside the pace and the budget, so a replay's body (read for its
        // digest) is held to them like any other.
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            idempotency::idempotent,
        ))
        // Room for the body (a chunked body takes room as it is read).
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            admission::body_budget,
        ))
        // The pace clock runs only while the client is awaited: time spent waiting for room
        // (the body's inner wrapper, above) is not charged to the client.
        .layer(axum::middleware::from_fn_with_state(
            state.pace,
            pace::paced_body,
        ))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            admission::shed_when_full,
        ))
        // The machine or surface the path names exists (a cheap query, no arrays read).
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            lookup::parents_exist,
        ))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::authenticate,
        ))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            metrics::track,
        ))
        .layer(axum::middleware::from_fn_with_state(
            max_body,
            middleware::content_length_limit,
        ))
        .layer(DefaultBodyLimit::max(max_body))
        .layer(CompressionLayer::new())
        .layer(axum::middleware::from_fn(middleware::scope_request_id))
        .layer(PropagateRequestIdLayer::x_request_id())
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(|req: &Request<_>| {
                    let id = req
                        .headers()
                        .get("x-request-id")
                        .and_then(|v| v.to_str().ok())
                        .unwrap_or("-");
                    tracing::info_span!("request", method = %req.method(), uri = %req.uri(), request_id = %id)
                })
                .on_response(DefaultOnResponse::new().level(tracing::Level::INFO)),
        )
        .layer(SetRequestIdLayer::x_request_id(MakeRequestUuid))
        .with_state(state)
}
