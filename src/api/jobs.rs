//! `GET /v1/jobs/{id}`: state, progress and result of a background job.

use axum::Router;
use axum::extract::State;
use axum::routing::get;

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use crate::api::id::PathIds;
use crate::jobs::JobStatus;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/v1/jobs/{id}", get(get_job))
}

async fn get_job(
    State(state): State<AppState>,
    PathIds([id]): PathIds<1>,
) -> ApiResult<ApiJson<JobStatus>> {
    state
        .jobs
        .status(&id)
        .await?
        .map(ApiJson)
        .ok_or_else(|| ApiError::not_found(format!("job '{id}' does not exist")))
}
