//! Background jobs: `GET /v1/jobs` (newest first, filtered, paged with a cursor, results
//! only with `?result=true`), `GET /v1/jobs/{id}` (state, progress, result, times) and
//! `DELETE /v1/jobs/{id}` (cancel; CONTRACT v1.1), and the one `202 Accepted` answer every
//! job-submitting route gives ([`accepted`]).

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
/// Largest page of `GET /v1/jobs?result=true` (a result can be tens of MB: a decomposition
/// of 1,000,000 samples).
pub const LIST_MAX_WITH_RESULTS: usize = 100;

/// The opaque cursor of the page after the job numbered `seq` (the database's insertion
/// order, [`crate::store::JobRecord::seq`]): hex of `seq:<seq>`.
fn cursor(seq: i64) -> String {
    hex::encode(format!("seq:{seq}"))
}

/// What a cursor names: the page after a job's `seq`, or (a cursor of a release before
/// migration 0007, hex of `created_at ms:id`) after the job `id`.
#[derive(Debug, PartialEq)]
enum Cursor {
    Seq(i64),
    Job(String),
}

/// Reads a cursor made by [`cursor`] or by an earlier release; `None` for anything else.
fn parse_cursor(s: &str) -> Option<Cursor> {
    let bytes = hex::decode(s).ok()?;
    let text = String::from_utf8(bytes).ok()?;
    let (head, tail) = text.split_once(':')?;
    if head == "seq" {
        return tail.parse::<i64>().ok().map(Cursor::Seq);
    }
    head.parse::<i64>().ok()?;
    (!tail.is_empty() && tail.len() <= 64).then(|| Cursor::Job(tail.to_string()))
}

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
    const KNOWN: [&str; 5] = ["state", "kind", "limit", "cursor", "result"];
    if let Some(k) = query.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown query parameter '{k}': use state, kind, limit, cursor or result"
        )));
    }
    let with_result = match query.get("result").map(String::as_str) {
        None | Some("false") => false,
        Some("true") => true,
        Some(other) => {
            return Err(ApiError::bad_request(format!(
                "result '{other}' must be true or false"
            )));
        }
    };
    let unknown = |c: &str| {
        ApiError::bad_request(format!(
            "cursor '{c}' is not one this service gave: pass the 'next' of the previous \
             page as it was, or leave cursor out for the first page"
        ))
    };
    let after = match query.get("cursor") {
        None => None,
        Some(c) => match parse_cursor(c).ok_or_else(|| unknown(c))? {
            Cursor::Seq(seq) => Some(seq),
            // An earlier release's cursor names the page's last job: go on after it.
            Cursor::Job(id) => {
                let rec = state.store.get_job(&id).await?;
                Some(rec.ok_or_else(|| unknown(c))?.seq)
            }
        },
    };
    let wanted = query.get("state").map(String::as_str);
    if let Some(s) = wanted {
        if !STATES.contains(&s) {
            return Err(ApiError::bad_request(format!(
                "state '{s}' is not a job state: use one of {}",
                STATES.join(", ")
            )));
        }
    }
    let max = if with_result {
        LIST_MAX_WITH_RESULTS
    } else {
        LIST_MAX
    };
    let limit = match query.get("limit") {
        None => LIST_DEFAULT.min(max),
        Some(l) => match l.parse::<usize>() {
            Ok(n) if (1..=max).contains(&n) => n,
            _ => {
                let with = if with_result { " with result=true" } else { "" };
                return Err(ApiError::bad_request(format!(
                    "limit '{l}' must be a whole number from 1 to {max}{with}"
                )));
            }
        },
    };
    let kind = query.get("kind").map(String::as_str);
    let page = state
        .jobs
        .list(wanted, kind, limit, after, with_result)
        .await?;
    let mut jobs = serde_json::to_value(&page.jobs).map_err(ApiError::internal)?;
    if !with_result && let Some(list) = jobs.as_array_mut() {
        for job in list.iter_mut().filter_map(serde_json::Value::as_object_mut) {
            job.remove("result");
        }
    }
    let next = page.next.map(cursor);
    Ok(ApiJson(json!({ "jobs": jobs, "next": next })))
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
    match state.jobs.cancel(&id).await? {
        Cancel::Cancelled(status) => Ok(ApiJson(status)),
        Cancel::Ended(status) => Err(ApiError::conflict(format!(
            "job '{id}' has already ended ({}) or is storing its result; nothing to cancel",
            status.state
        ))),
        Cancel::Unknown => Err(ApiError::not_found(format!("job '{id}' does not exist"))),
    }
}

#[cfg(test)]
mod tests;
