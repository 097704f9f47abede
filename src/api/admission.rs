//! Admission before a body is read: the process-wide budget of request-body bytes in
//! flight, and shedding of pool work while the worker pool is full.
//!
//! Both run before any handler reads its body. Without the budget, 8 concurrent 120 MiB
//! uploads held about 1 GB resident; without the early shed, bodies that the full pool then
//! refused were read and parsed first, and goodput fell from 345 to 207 decompositions/s
//! between 32 and 48 connections (issue 13; figures after the change in BENCHMARKS.md,
//! "Concurrent uploads" and "Overload").

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::Bytes;
use axum::extract::{Request, State};
use axum::http::{Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use http_body::Frame;
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
    /// Content-Length (chunked) reserves its bytes as they arrive, up to `max_body_bytes`.
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

    /// Bytes a request reserves before its body is read: 0 without a body, with a small
    /// one or with a body of unknown length (chunked: `GrowingBody` reserves as it reads),
    /// else its declared Content-Length.
    fn reservation(&self, req: &Request) -> u64 {
        let bytes = declared_length(req).unwrap_or(0);
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
        self.check_total(bytes)?;
        Self::acquire(self.units.clone(), bytes, self.wait, self.total_bytes)
            .await
            .map(Some)
    }

    /// 413 when `bytes` exceed the whole budget.
    fn check_total(&self, bytes: u64) -> Result<(), ApiError> {
        if bytes > self.total_bytes {
            return Err(ApiError::payload_too_large(format!(
                "the request body has {bytes} bytes but this server holds at most {} bytes of \
                 request bodies at once (--max-inflight-body-mb); split the upload",
                self.total_bytes
            )));
        }
        Ok(())
    }

    /// Waits up to `wait` for `bytes` of room in `units` (a budget of `total_bytes`).
    async fn acquire(
        units: Arc<Semaphore>,
        bytes: u64,
        wait: Duration,
        total_bytes: u64,
    ) -> Result<OwnedSemaphorePermit, ApiError> {
        let n = u32::try_from(bytes.div_ceil(UNIT)).unwrap_or(u32::MAX);
        match tokio::time::timeout(wait, units.acquire_many_owned(n)).await {
            Ok(Ok(permit)) => Ok(permit),
            Ok(Err(_closed)) => Err(ApiError::unavailable(
                "the server is shutting down; retry on another instance or after restart",
                BUDGET_RETRY_AFTER_S,
            )),
            Err(_elapsed) => Err(ApiError::unavailable(
                format!(
                    "other uploads fill this server's room for request bodies \
                     ({} MiB, --max-inflight-body-mb) and none left within {} s; retry in {} s",
                    total_bytes / (1024 * 1024),
                    wait.as_secs_f64(),
                    BUDGET_RETRY_AFTER_S
                ),
                BUDGET_RETRY_AFTER_S,
            )),
        }
    }
}

/// The request's declared Content-Length.
fn declared_length(req: &Request) -> Option<u64> {
    req.headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
}

/// Middleware: reserves the request's body bytes from the process-wide [`BodyBudget`]
/// before the body is read (a declared length) or as it is read (a chunked body, see
/// `GrowingBody`), and keeps them until the answer is made (the parsed body lives that
/// long too). A chunked body that outgrows `--max-body-bytes` or the budget is answered 413,
/// one that finds no room in time 503 + Retry-After.
pub async fn body_budget(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let bytes = state.body_budget.reservation(&req);
    let permit = match state.body_budget.reserve(bytes).await {
        Ok(permit) => permit,
        Err(e) => return e.into_response(),
    };
    if declared_length(&req).is_some() {
        let resp = next.run(req).await;
        drop(permit);
        return resp;
    }
    let growing = Growth::default();
    let (parts, body) = req.into_parts();
    let body = axum::body::Body::new(GrowingBody {
        inner: body,
        budget: state.body_budget.clone(),
        read: 0,
        covered: UNCOUNTED_BODY_BYTES,
        pending: None,
        acquiring: None,
        growth: growing.clone(),
    });
    let resp = next.run(Request::from_parts(parts, body)).await;
    let mut growth = growing.lock().expect("body growth");
    match growth.verdict.take() {
        Some(e) => e.into_response(),
        None => resp,
    }
}

/// What a `GrowingBody` shares with its middleware: the room it holds (kept until the
/// answer is made) and why it stopped, if it did.
#[derive(Default)]
struct GrowthState {
    permits: Vec<OwnedSemaphorePermit>,
    verdict: Option<ApiError>,
}

type Growth = Arc<std::sync::Mutex<GrowthState>>;

/// Room a chunked body takes at a time beyond what it holds.
pub const GROWTH_STEP_BYTES: u64 = 1 << 20;

/// Waiting for room for the next step.
type Acquiring = Pin<Box<dyn Future<Output = Result<OwnedSemaphorePermit, ApiError>> + Send>>;

/// A chunked body that reserves budget for what it has read, [`GROWTH_STEP_BYTES`] at a
/// time beyond the first [`UNCOUNTED_BODY_BYTES`], waiting up to the budget's wait for
/// room; it fails past `--max-body-bytes` or the budget (413) or without room (503).
struct GrowingBody {
    inner: axum::body::Body,
    budget: Arc<BodyBudget>,
    /// Bytes read so far.
    read: u64,
    /// Bytes the held room covers (the uncounted first bytes included).
    covered: u64,
    /// A chunk read while room for it is awaited.
    pending: Option<Bytes>,
    acquiring: Option<Acquiring>,
    growth: Growth,
}

/// The error a `GrowingBody` read ends with (the answer is the verdict).
#[derive(Debug, thiserror::Error)]
#[error("the request body found no room in this server's budget")]
struct NoRoom;

impl GrowingBody {
    fn fail(&mut self, e: ApiError) -> Poll<Option<Result<Frame<Bytes>, axum::BoxError>>> {
        self.growth.lock().expect("body growth").verdict = Some(e);
        Poll::Ready(Some(Err(NoRoom.into())))
    }
}

impl http_body::Body for GrowingBody {
    type Data = Bytes;
    type Error = axum::BoxError;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Self::Error>>> {
        if let Some(acquiring) = self.acquiring.as_mut() {
            let got = std::task::ready!(acquiring.as_mut().poll(cx));
            self.acquiring = None;
            return match got {
                Ok(permit) => {
                    self.covered += permit.num_permits() as u64 * UNIT;
                    self.growth
                        .lock()
                        .expect("body growth")
                        .permits
                        .push(permit);
                    let chunk = self.pending.take().unwrap_or_default();
                    Poll::Ready(Some(Ok(Frame::data(chunk))))
                }
                Err(e) => self.fail(e),
            };
        }
        let frame = std::task::ready!(Pin::new(&mut self.inner).poll_frame(cx));
        let chunk = match frame {
            Some(Ok(f)) => match f.into_data() {
                Ok(chunk) => chunk,
                Err(f) => return Poll::Ready(Some(Ok(f))),
            },
            other => return Poll::Ready(other.map(|f| f.map_err(Into::into))),
        };
        self.read += chunk.len() as u64;
        let max = self.budget.max_body_bytes;
        if self.read > max {
            return self.fail(ApiError::payload_too_large(format!(
                "the request body is longer than {max} bytes, the most this server accepts \
                 (--max-body-bytes); split the upload"
            )));
        }
        if self.read <= self.covered {
            return Poll::Ready(Some(Ok(Frame::data(chunk))));
        }
        let total = self.budget.total_bytes;
        let want = (self.read - UNCOUNTED_BODY_BYTES)
            .next_multiple_of(GROWTH_STEP_BYTES)
            .min(total);
        if let Err(e) = self.budget.check_total(self.read - UNCOUNTED_BODY_BYTES) {
            return self.fail(e);
        }
        let step = want + UNCOUNTED_BODY_BYTES - self.covered;
        self.pending = Some(chunk);
        self.acquiring = Some(Box::pin(BodyBudget::acquire(
            self.budget.units.clone(),
            step,
            self.budget.wait,
            total,
        )));
        self.poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.pending.is_none() && self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
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
