//! Request extractors and edge validation: `ApiJson` and the `check_*` helpers (ids: `id.rs`).

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use serde::de::DeserializeOwned;

use super::error::{ApiError, ApiResult};

/// Like `axum::Json`, but every rejection is problem+json: 415 for a non-JSON
/// Content-Type, 413 for a body over the limit, 400 for malformed JSON or wrong fields
/// (the sentence names the line, column and field). Also a JSON response wrapper.
#[derive(Debug, Clone, Copy, Default)]
pub struct ApiJson<T>(pub T);

/// True when the request's Content-Type is `application/json` or `application/*+json`.
pub fn is_json(headers: &HeaderMap) -> bool {
    content_type(headers).is_some_and(|ct| {
        ct == "application/json" || (ct.starts_with("application/") && ct.ends_with("+json"))
    })
}

/// The request's media type, lower-cased, without parameters (`text/csv; charset=utf-8` → `text/csv`).
pub fn content_type(headers: &HeaderMap) -> Option<String> {
    headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(|v| {
            v.split(';')
                .next()
                .unwrap_or("")
                .trim()
                .to_ascii_lowercase()
        })
}

/// Whether a body that may come as JSON or CSV is CSV: `application/json` (or `+json`) is
/// JSON, `text/csv`, `text/plain` and `application/csv` are CSV; anything else is 415 with
/// `what` (the accepted shapes) in the sentence.
pub fn is_csv_body(headers: &HeaderMap, what: &str) -> ApiResult<bool> {
    match content_type(headers).as_deref() {
        Some("application/json") => Ok(false),
        Some(ct) if ct.starts_with("application/") && ct.ends_with("+json") => Ok(false),
        Some("text/csv" | "text/plain" | "application/csv") => Ok(true),
        _ => Err(ApiError::unsupported_media_type(format!(
            "send Content-Type: {what}"
        ))),
    }
}

/// Reads the whole body, mapping the body-limit rejection to 413 and any other read error to 400.
/// A body with a Content-Length (already checked against the limit by
/// `middleware::content_length_limit`) is read into one buffer of that size, so a large
/// upload is held once, not as chunks plus a contiguous copy (BENCHMARKS.md, "Concurrent
/// uploads").
pub async fn read_body(req: Request) -> ApiResult<Bytes> {
    use futures::StreamExt;
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<usize>().ok());
    if let Some(len) = declared {
        let mut buf = bytes::BytesMut::with_capacity(len);
        let mut chunks = req.into_body().into_data_stream();
        while let Some(chunk) = chunks.next().await {
            let chunk = chunk.map_err(|e| {
                ApiError::bad_request(format!("could not read the request body: {e}"))
            })?;
            if buf.len() + chunk.len() > len {
                return Err(ApiError::bad_request(format!(
                    "the request body is longer than its Content-Length ({len} bytes)"
                )));
            }
            buf.extend_from_slice(&chunk);
        }
        return Ok(buf.freeze());
    }
    Bytes::from_request(req, &()).await.map_err(|rej| {
        if rej.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::payload_too_large(
                "the request body is larger than this server accepts (see --max-body-bytes); \
                 split the upload or raise the limit",
            )
        } else {
            ApiError::bad_request(format!("could not read the request body: {rej}"))
        }
    })
}

/// Decodes JSON bytes into `T` with a 400 naming line, column and the serde message.
pub fn decode_json<T: DeserializeOwned>(bytes: &[u8]) -> ApiResult<T> {
    if bytes.is_empty() {
        return Err(ApiError::bad_request(
            "the request body is empty; send a JSON document",
        ));
    }
    serde_json::from_slice(bytes)
        .map_err(|e| ApiError::bad_request(format!("invalid JSON body: {e}")))
}

impl<T, S> FromRequest<S> for ApiJson<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, _state: &S) -> Result<Self, Self::Rejection> {
        if !is_json(req.headers()) {
            return Err(ApiError::unsupported_media_type(
                "send the body with Content-Type: application/json",
            ));
        }
        let bytes = read_body(req).await?;
        decode_json(&bytes).map(ApiJson)
    }
}

impl<T: Serialize> IntoResponse for ApiJson<T> {
    fn into_response(self) -> Response {
        match serde_json::to_vec(&self.0) {
            Ok(body) => (
                [(header::CONTENT_TYPE, "application/json")],
                Bytes::from(body),
            )
                .into_response(),
            Err(e) => {
                ApiError::internal(format!("could not encode the response: {e}")).into_response()
            }
        }
    }
}

/// Rejects a non-finite value in `xs`, naming the field and the index of the first bad one.
pub fn check_finite(field: &str, xs: &[f64]) -> ApiResult<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(i) => Err(ApiError::bad_request(format!(
            "{field}[{i}] is {}; every value must be a finite number",
            xs[i]
        ))),
    }
}

/// Rejects an empty point list or a non-finite coordinate (naming `field[i]`).
pub fn check_points(field: &str, pts: &[[f64; 3]]) -> ApiResult<()> {
    if pts.is_empty() {
        return Err(ApiError::bad_request(format!(
            "{field} is empty; send at least one [x, y, z] point"
        )));
    }
    match pts.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        None => Ok(()),
        Some(i) => Err(ApiError::bad_request(format!(
            "{field}[{i}] = {:?} has a non-finite coordinate; every coordinate must be a finite number in mm",
            pts[i]
        ))),
    }
}

/// Rejects `got != expected` with a sentence naming the field and both lengths.
pub fn check_len(field: &str, got: usize, expected: usize) -> ApiResult<()> {
    if got == expected {
        Ok(())
    } else {
        Err(ApiError::bad_request(format!(
            "{field} has {got} entries but {expected} are expected"
        )))
    }
}

/// Rejects an empty array (naming the field).
pub fn check_non_empty<T>(field: &str, xs: &[T]) -> ApiResult<()> {
    if xs.is_empty() {
        Err(ApiError::bad_request(format!(
            "{field} is empty; send at least one value"
        )))
    } else {
        Ok(())
    }
}
