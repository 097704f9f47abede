//! Admission before a body is read: the process-wide budget of request-body bytes in
//! flight, and shedding of pool work while the worker pool is full.
//!
//! Both run before any handler reads its body. Without the budget, 8 concurrent 120 MiB
//! uploads held about 1 GB resident; without the early shed, bodies that the full pool then
//! refused were read and parsed first, and goodput fell from 345 to 207 decompositions/s
//! between 32 and 48 connections (issue 13; figures after the change in BENCHMARKS.md,
//! "Concurrent uploads" and "Overload").

use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Request, State};
use axum::http::{Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use super::AppState;
use super::error::ApiError;

/// Bodies up to this size are not counted: they are bounded by the number of connections,
/// and a small request should not wait behind large uploads.
pub const UNCOUNTED_BODY_BYTES: u64 = 256 * 1024;

/// Granule of the budget (the semaphore counts KiB so that `u32` permits cover terabytes).
const UNIT: u64 = 1024;

/// Seconds a client turned away for lack of budget is told to wait.
pub const BUDGET_RETRY_AFTER_S: u64 = 2;

/// The process-wide budget of request-body bytes held at once.
#[derive(Debug)]
pub struct BodyBudget {
    units: Arc<Semaphore>,
    total_bytes: u64,
    max_body_bytes: u64,
    wait: Duration,
}

impl BodyBudget {
    /// A budget of `total_bytes`; a request waits at most `wait` for room. A body without
    /// Content-Length counts as `max_body_bytes`.
    pub fn new(total_bytes: u64, max_body_bytes: u64, wait: Duration) -> Self {
        let units = total_bytes
            .div_ceil(UNIT)
            .min(Semaphore::MAX_PERMITS as u64) as usize;
        BodyBudget {
            units: Arc::new(Semaphore::new(units)),
            total_bytes,
            max_body_bytes,
            wait,
        }
    }

    /// Bytes of budget free now.
    pub fn available_bytes(&self) -> u64 {
        self.units.available_permits() as u64 * UNIT
    }

    /// Bytes a request reserves: 0 without a body or with a small one, its declared
    /// Content-Length, or `max_body_bytes` for a body of unknown length (chunked).
    fn reservation(&self, req: &Request) -> u64 {
        let headers = req.headers();
        let declared = headers
            .get(header::CONTENT_LENGTH)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.trim().parse::<u64>().ok());
        let bytes = match declared {
            Some(len) => len,
            None if headers.contains_key(header::TRANSFER_ENCODING) => self.max_body_bytes,
            None => 0,
        };
        if bytes <= UNCOUNTED_BODY_BYTES {
            0
        } else {
            bytes.min(self.max_body_bytes.max(UNCOUNTED_BODY_BYTES))
        }
    }

    /// Waits up to the configured time for `bytes` of room. `Err` is the answer: 413 when
    /// the budget can never hold the body, 503 + Retry-After when it is full now.
    async fn reserve(&self, bytes: u64) -> Result<Option<OwnedSemaphorePermit>, ApiError> {
        if bytes == 0 {
            return Ok(None);
        }
        if bytes > self.total_bytes {
            return Err(ApiError::payload_too_large(format!(
                "the request body has {bytes} bytes but this server holds at most {} bytes of \
                 request bodies at once (--max-inflight-body-mb); split the upload",
                self.total_bytes
            )));
        }
        let units = u32::try_from(bytes.div_ceil(UNIT)).unwrap_or(u32::MAX);
        match tokio::time::timeout(self.wait, self.units.clone().acquire_many_owned(units)).await {
            Ok(Ok(permit)) => Ok(Some(permit)),
            Ok(Err(_closed)) => Err(ApiError::unavailable(
                "the server is shutting down; retry on another instance or after restart",
                BUDGET_RETRY_AFTER_S,
            )),
            Err(_elapsed) => Err(ApiError::unavailable(
                format!(
                    "other uploads fill this server's room for request bodies \
                     ({} MiB, --max-inflight-body-mb) and none left within {} s; retry in {} s",
                    self.total_bytes / (1024 * 1024),
                    self.wait.as_secs_f64(),
                    BUDGET_RETRY_AFTER_S
                ),
                BUDGET_RETRY_AFTER_S,
            )),
        }
    }
}

/// Middleware: reserves the request's body bytes from the process-wide [`BodyBudget`]
/// before the body is read, and keeps them until the answer is made (the parsed body lives
/// that long too).
pub async fn body_budget(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let bytes = state.body_budget.reservation(&req);
    match state.body_budget.reserve(bytes).await {
        Ok(permit) => {
            let resp = next.run(req).await;
            drop(permit);
            resp
        }
        Err(e) => e.into_response(),
    }
}

/// Whether a request runs on the worker pool: every POST except probe uploads
/// (`.../measurements`, which never wait for a worker), and the volumetric map PUT (a fit).
pub fn uses_pool(method: &Method, path: &str) -> bool {
    let path = path.trim_end_matches('/');
    (method == Method::POST && !path.ends_with("/measurements"))
        || (method == Method::PUT && path.ends_with("/volumetric-map"))
}

/// Middleware: while the worker pool is full, pool work is refused (503 + Retry-After)
/// before its body is read or parsed. A request let through may still be refused by the
/// pool itself when others took the last slot meanwhile.
///
/// A full pool first gets [`SHED_GRACE`] to free a slot (checked every [`SHED_POLL`]): a
/// client that retries at once (a load generator, a naive script) then sends at most one
/// request per connection and grace instead of thousands of refused bodies a second, whose
/// transfer and answers took the CPU the workers needed (BENCHMARKS.md, "Hardening":
/// goodput 126/s at 32 connections fell to 72/s at 48 with immediate refusals).
pub async fn shed_when_full(State(state): State<AppState>, req: Request, next: Next) -> Response {
    if uses_pool(req.method(), req.uri().path()) {
        let deadline = tokio::time::Instant::now() + SHED_GRACE;
        while !state.jobs.has_room() && tokio::time::Instant::now() < deadline {
            tokio::time::sleep(SHED_POLL).await;
        }
        if let Err(full) = state.jobs.check_room() {
            return ApiError::from(full).into_response();
        }
    }
    next.run(req).await
}

/// How long pool work waits for a free slot before it is refused (503 + Retry-After).
pub const SHED_GRACE: std::time::Duration = std::time::Duration::from_millis(100);
/// How often a waiting request looks for a free slot.
pub const SHED_POLL: std::time::Duration = std::time::Duration::from_millis(5);

#[cfg(test)]
mod tests;
