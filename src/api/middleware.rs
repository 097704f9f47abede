//! Cross-cutting request handling: problem+json for every error, the early body-size
//! check, and the fallback for unknown routes (the pace of bodies: `pace.rs`).

use axum::body::to_bytes;
use axum::extract::{Request, State};
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::error::{ApiError, problem_response};

/// Answers 404 problem+json for a path no route matches.
pub async fn fallback(req: Request) -> Response {
    ApiError::not_found(format!(
        "no route {} {}; see openapi.yaml for the API",
        req.method(),
        req.uri().path()
    ))
    .into_response()
}

/// Rejects a request whose declared Content-Length exceeds the limit before reading it.
pub async fn content_length_limit(State(max): State<usize>, req: Request, next: Next) -> Response {
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if let Some(len) = declared
        && len > max as u64
    {
        return ApiError::payload_too_large(format!(
            "the request body has {len} bytes; this server accepts at most {max} \
             (see --max-body-bytes); split the upload"
        ))
        .into_response();
    }
    next.run(req).await
}

/// Rewrites error responses that are not problem+json yet (framework rejections such as
/// 405 or a malformed path) into problem+json, keeping their status and message.
pub async fn problem_json(req: Request, next: Next) -> Response {
    let method = req.method().clone();
    let resp = next.run(req).await;
    let status = resp.status();
    if !(status.is_client_error() || status.is_server_error()) {
        return resp;
    }
    let is_problem = resp
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|ct| ct.starts_with("application/problem+json"));
    if is_problem {
        return resp;
    }
    let (parts, body) = resp.into_parts();
    let text = to_bytes(body, 64 * 1024)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_string())
        .unwrap_or_default();
    let detail = match status {
        StatusCode::METHOD_NOT_ALLOWED => {
            format!("this route does not accept {method}; see openapi.yaml for its methods")
        }
        _ if status.is_server_error() => {
            tracing::error!(%status, body = %text, "framework error");
            "the server failed to handle this request; the cause is in its log".to_string()
        }
        _ if text.is_empty() => status.canonical_reason().unwrap_or("error").to_string(),
        _ => text,
    };
    let mut out = problem_response(status, &detail);
    for (name, value) in parts.headers.iter() {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            out.headers_mut().insert(name.clone(), value.clone());
        }
    }
    out
}

/// Middleware: serves the request inside [`crate::jobs::REQUEST_ID`] (its `X-Request-Id`,
/// set by the request-id layer), so a job it queues records the id and the job's log lines
/// name it.
pub async fn scope_request_id(req: Request, next: Next) -> Response {
    let id = req
        .headers()
        .get("x-request-id")
        .and_then(|v| v.to_str().ok())
        .map(str::to_string);
    match id {
        Some(id) => crate::jobs::REQUEST_ID.scope(id, next.run(req)).await,
        None => next.run(req).await,
    }
}
