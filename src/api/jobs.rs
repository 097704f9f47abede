//! Background jobs: `GET /v1/jobs` (newest first, filtered), `GET /v1/jobs/{id}` (state,
//! progress, result, times) and `DELETE /v1/jobs/{id}` (cancel; CONTRACT v1.1), and the one
//! `202 Accepted` answer every job-submitting route gives ([`accepted`]).

use std::collections::HashMap;

use axum::Router;
use axum::extract::{Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::json;

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use crate::api::id::PathIds;
use crate::jobs::{Cancel, JobStatus, Runner};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/jobs", get(list_jobs))
        .route("/v1/jobs/{id}", get(get_job).delete(cancel_job))
}

/// Default and largest page of `GET /v1/jobs`.
pub const LIST_DEFAULT: usize = 100;
/// See [`LIST_DEFAULT`].
pub const LIST_MAX: usize = 1000;

const STATES: [&str; 5] = ["queued", "running", "done", "failed", "cancelled"];

/// The runner of every stored job kind, for [`crate::jobs::JobPool::serve`]: the kinds any
/// instance on the database can run (the door of each route queues them with its input).
pub fn runners(state: &AppState) -> HashMap<String, Runner> {
    HashMap::from([
        (
            super::decomposition::JOB_KIND.to_string(),
            super::decomposition::runner(),
        ),
        (
            super::gap::JOB_KIND.to_string(),
            super::gap::runner(state.clone()),
        ),
        (
            super::step_error::TRAINING_JOB.to_string(),
            super::step_error::training_runner(state.clone()),
        ),
    ])
}

/// `202 {"job": id}` with `Location: /v1/jobs/{id}` (CONTRACT v1.1).
pub fn accepted(id: &str) -> Response {
    (
        StatusCode::ACCEPTED,
        [(header::LOCATION, format!("/v1/jobs/{id}"))],
        ApiJson(json!({ "job": id })),
    )
        .into_response()
}

async fn list_jobs(
    State(state): State<AppState>,
    Query(query): Query<HashMap<String, String>>,
) -> ApiResult<ApiJson<serde_json::Value>> {
    const KNOWN: [&str; 3] = ["state", "kind", "limit"];
    if let Some(k) = query.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown query parameter '{k}': use state, kind or limit"
        )));
    }
    let wanted = query.get("state").map(String::as_str);
    if let Some(s) = wanted {
        if !STATES.contains(&s) {
            return Err(ApiError::bad_request(format!(
                "state '{s}' is not a job state: use one of {}",
                STATES.join(", ")
            )));
        }
    }
    let limit = match query.get("limit") {
        None => LIST_DEFAULT,
        Some(l) => match l.parse::<usize>() {
            Ok(n) if (1..=LIST_MAX).contains(&n) => n,
            _ => {
                return Err(ApiError::bad_request(format!(
                    "limit '{l}' must be a whole number from 1 to {LIST_MAX}"
                )));
            }
        },
    };
    let kind = query.get("kind").map(String::as_str);
    let jobs = state
        .jobs
        .list(wanted, kind, limit)
        .await
        .map_err(ApiError::internal)?;
    Ok(ApiJson(json!({ "jobs": jobs })))
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

async fn cancel_job(
    State(state): State<AppState>,
    PathIds([id]): PathIds<1>,
) -> ApiResult<ApiJson<JobStatus>> {
    match state.jobs.cancel(&id).await.map_err(ApiError::internal)? {
        Cancel::Cancelled(status) => Ok(ApiJson(status)),
        Cancel::Ended(status) => Err(ApiError::conflict(format!(
            "job '{id}' has already ended ({}) or is storing its result; nothing to cancel",
            status.state
        ))),
        Cancel::Unknown => Err(ApiError::not_found(format!("job '{id}' does not exist"))),
    }
}
