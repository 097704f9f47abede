//! Contour error from G-code: `POST /v1/machines/{machine}/contour-error` (openapi.yaml;
//! Zhang & Chen 2025). The simulation is the motion core's, the answer's shape
//! [`crate::wire::contour`]'s (shared with `truecut contour --output`).

use axum::Router;
use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use serde::Deserialize;

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::lookup::require_machine_def;
use crate::api::id::PathIds;
use crate::motion::{
    DEFAULT_PERIOD_S, check_period, machine_for_simulation, predict_contour_error,
};
use crate::wire::contour::encode_answer;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/v1/machines/{machine}/contour-error", post(contour_error))
}

/// Most interpolation periods answered synchronously (openapi.yaml: sync up to 1,000,000).
pub const MAX_SYNC_PERIODS: usize = 1_000_000;

/// Body of the route.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContourRequest {
    /// The program text (ISO 6983 / Fanuc subset, Sinumerik TRAORI/TRAFOOF).
    pub gcode: String,
    /// Interpolation period, s (default 0.001).
    #[serde(default)]
    pub period_s: Option<f64>,
}

async fn contour_error(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    ApiJson(req): ApiJson<ContourRequest>,
) -> ApiResult<Response> {
    let def = require_machine_def(&state, &machine).await?;
    let period_s = req.period_s.unwrap_or(DEFAULT_PERIOD_S);
    check_period(period_s)?;
    if req.gcode.trim().is_empty() {
        return Err(ApiError::bad_request(
            "gcode is empty: send the program text, e.g. \"G1 X10 F600\"",
        ));
    }
    let m = machine_for_simulation(&machine, &def)?;
    let body = state
        .jobs
        .run(move || {
            predict_contour_error(&m, &req.gcode, period_s, MAX_SYNC_PERIODS)
                .map(|p| encode_answer(&m, &p))
        })
        .await??
        .map_err(ApiError::internal)?;
    Ok(([(header::CONTENT_TYPE, "application/json")], body).into_response())
}
