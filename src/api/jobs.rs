//! `GET /v1/jobs/{id}`: state, progress and result of a background job.

use axum::Router;
use axum::extract::{Path, State};
use axum::routing::get;

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, check_id};
use crate::jobs::JobStatus;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/v1/jobs/{id}", get(get_job))
}

async fn get_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> ApiResult<ApiJson<JobStatus>> {
    check_id("job", &id)?;
    state
        .jobs
        .status(&id)
        .await?
        .map(ApiJson)
        .ok_or_else(|| ApiError::not_found(format!("job '{id}' does not exist")))
}
