//! `ApiError`: the only place that decides an HTTP status for an error, rendered as
//! RFC 9457 `application/problem+json`. Every `From<core::Error>` (and the worker pool's
//! and the codec's) lives here, beside the type, as in axum's error-handling example.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

use crate::{
    cam, codec, compensation, gap, geometry, jobs, metrology, motion, nn, signal, step_error,
    volumetric,
};

/// An error answered to an HTTP client. 4xx variants carry a sentence saying what to fix;
/// `Internal` carries the cause for the log only (the body stays opaque).
#[derive(Debug)]
pub enum ApiError {
    /// 400: malformed or invalid input.
    BadRequest(String),
    /// 401: missing or unknown token.
    Unauthorized(String),
    /// 403: the token's role is too weak.
    Forbidden(String),
    /// 404: unknown id or route.
    NotFound(String),
    /// 405: the route exists but not with this method.
    MethodNotAllowed(String),
    /// 406: the requested representation (Accept) is not offered.
    NotAcceptable(String),
    /// 409: the request conflicts with stored state.
    Conflict(String),
    /// 413: the body is larger than the configured limit.
    PayloadTooLarge(String),
    /// 415: unsupported Content-Type.
    UnsupportedMediaType(String),
    /// 422: well-formed but semantically unusable input.
    Unprocessable(String),
    /// 503: the worker pool is full, or the database is out for now (a cut connection, a
    /// failover); retry after the given seconds.
    Unavailable {
        /// What is busy, shown to the client.
        detail: String,
        /// Seconds the client should wait before retrying (the `Retry-After` header).
        retry_after_s: u64,
    },
    /// 503: the database is out for now (a cut connection, a failover, no free connection);
    /// `Retry-After: OUTAGE_RETRY_AFTER_S`. Counted apart from back-pressure in `/metrics`
    /// (`truecut_database_outage_answers_total`).
    DatabaseOutage(String),
    /// 507: the storage refused a write (full, read-only, forbidden); says what to free or fix.
    InsufficientStorage(String),
    /// 500: a bug or an infrastructure failure; the cause is logged, never shown.
    Internal(String),
}

/// Result type of every handler.
pub type ApiResult<T> = Result<T, ApiError>;

impl ApiError {
    /// 400 Bad Request with an actionable sentence.
    pub fn bad_request(detail: impl Into<String>) -> Self {
        ApiError::BadRequest(detail.into())
    }
    /// 401 Unauthorized.
    pub fn unauthorized(detail: impl Into<String>) -> Self {
        ApiError::Unauthorized(detail.into())
    }
    /// 403 Forbidden.
    pub fn forbidden(detail: impl Into<String>) -> Self {
        ApiError::Forbidden(detail.into())
    }
    /// 404 Not Found.
    pub fn not_found(detail: impl Into<String>) -> Self {
        ApiError::NotFound(detail.into())
    }
    /// 406 Not Acceptable.
    pub fn not_acceptable(detail: impl Into<String>) -> Self {
        ApiError::NotAcceptable(detail.into())
    }
    /// 409 Conflict.
    pub fn conflict(detail: impl Into<String>) -> Self {
        ApiError::Conflict(detail.into())
    }
    /// 413 Content Too Large.
    pub fn payload_too_large(detail: impl Into<String>) -> Self {
        ApiError::PayloadTooLarge(detail.into())
    }
    /// 415 Unsupported Media Type.
    pub fn unsupported_media_type(detail: impl Into<String>) -> Self {
        ApiError::UnsupportedMediaType(detail.into())
    }
    /// 422 Unprocessable Content.
    pub fn unprocessable(detail: impl Into<String>) -> Self {
        ApiError::Unprocessable(detail.into())
    }
    /// 503 Service Unavailable with `Retry-After: retry_after_s`.
    pub fn unavailable(detail: impl Into<String>, retry_after_s: u64) -> Self {
        ApiError::Unavailable {
            detail: detail.into(),
            retry_after_s,
        }
    }
    /// 500 Internal Server Error: logs `err`, answers an opaque body.
    pub fn internal(err: impl std::fmt::Display) -> Self {
        ApiError::Internal(err.to_string())
    }

    /// The HTTP status of this error.
    pub fn status(&self) -> StatusCode {
        match self {
            ApiError::BadRequest(_) => StatusCode::BAD_REQUEST,
            ApiError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            ApiError::Forbidden(_) => StatusCode::FORBIDDEN,
            ApiError::NotFound(_) => StatusCode::NOT_FOUND,
            ApiError::MethodNotAllowed(_) => StatusCode::METHOD_NOT_ALLOWED,
            ApiError::NotAcceptable(_) => StatusCode::NOT_ACCEPTABLE,
            ApiError::Conflict(_) => StatusCode::CONFLICT,
            ApiError::PayloadTooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::UnsupportedMediaType(_) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ApiError::Unprocessable(_) => StatusCode::UNPROCESSABLE_ENTITY,
            ApiError::Unavailable { .. } | ApiError::DatabaseOutage(_) => {
                StatusCode::SERVICE_UNAVAILABLE
            }
            ApiError::InsufficientStorage(_) => StatusCode::INSUFFICIENT_STORAGE,
            ApiError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The sentence shown to the client.
    pub fn detail(&self) -> &str {
        match self {
            ApiError::BadRequest(d)
            | ApiError::Unauthorized(d)
            | ApiError::Forbidden(d)
            | ApiError::NotFound(d)
            | ApiError::MethodNotAllowed(d)
            | ApiError::NotAcceptable(d)
            | ApiError::Conflict(d)
            | ApiError::PayloadTooLarge(d)
            | ApiError::UnsupportedMediaType(d)
            | ApiError::Unprocessable(d)
            | ApiError::DatabaseOutage(d)
            | ApiError::InsufficientStorage(d) => d,
            ApiError::Unavailable { detail, .. } => detail,
            ApiError::Internal(_) => {
                "the server failed to handle this request; the cause is in its log"
            }
        }
    }
}

/// Problem type slug for a status (the `type` member is `https://truecut.dev/problems/<slug>`).
fn slug(status: StatusCode) -> &'static str {
    match status.as_u16() {
        400 => "bad-request",
        401 => "unauthorized",
        403 => "forbidden",
        404 => "not-found",
        405 => "method-not-allowed",
        406 => "not-acceptable",
        409 => "conflict",
        413 => "payload-too-large",
        415 => "unsupported-media-type",
        422 => "unprocessable",
        429 => "too-many-requests",
        503 => "unavailable",
        507 => "insufficient-storage",
        _ => "internal",
    }
}

/// A problem+json response for `status` with `detail` (also used to wrap framework rejections).
pub fn problem_response(status: StatusCode, detail: &str) -> Response {
    let body = serde_json::json!({
        "type": format!("https://truecut.dev/problems/{}", slug(status)),
        "title": status.canonical_reason().unwrap_or("Error"),
        "status": status.as_u16(),
        "detail": detail,
    });
    let mut resp = (status, body.to_string()).into_response();
    resp.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/problem+json"),
    );
    resp
}

/// 503 problem+json (with `Retry-After`) carrying a report as extension members (RFC 9457
/// §3.2): what `/healthz` and `/readyz` answer when this instance should not get requests.
/// `members` is a JSON object; its keys must not be the standard members.
pub fn unavailable_report(
    detail: &str,
    retry_after_s: u64,
    members: serde_json::Value,
) -> Response {
    let status = StatusCode::SERVICE_UNAVAILABLE;
    let mut body = serde_json::json!({
        "type": format!("https://truecut.dev/problems/{}", slug(status)),
        "title": status.canonical_reason().unwrap_or("Error"),
        "status": status.as_u16(),
        "detail": detail,
    });
    if let (Some(b), serde_json::Value::Object(m)) = (body.as_object_mut(), members) {
        for (k, v) in m {
            b.entry(k).or_insert(v);
        }
    }
    let mut resp = (status, body.to_string()).into_response();
    resp.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/problem+json"),
    );
    resp.headers_mut()
        .insert(header::RETRY_AFTER, HeaderValue::from(retry_after_s));
    resp
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = self.status();
        if let ApiError::Internal(cause) = &self {
            tracing::error!(%cause, "internal error");
        }
        let mut resp = problem_response(status, self.detail());
        match &self {
            ApiError::Unavailable { retry_after_s, .. } => {
                resp.headers_mut()
                    .insert(header::RETRY_AFTER, HeaderValue::from(*retry_after_s));
            }
            ApiError::DatabaseOutage(_) => {
                resp.headers_mut()
                    .insert(header::RETRY_AFTER, HeaderValue::from(OUTAGE_RETRY_AFTER_S));
                resp.extensions_mut().insert(OutageAnswer);
            }
            ApiError::Unauthorized(_) => {
                resp.headers_mut().insert(
                    header::WWW_AUTHENTICATE,
                    HeaderValue::from_static("Bearer realm=\"truecut\""),
                );
            }
            _ => {}
        }
        resp
    }
}

/// Marks a response that answered a database outage (for the metrics middleware).
#[derive(Clone, Copy, Debug)]
pub struct OutageAnswer;

/// Seconds a client is told to wait (`Retry-After`) after a database outage: the pool opens
/// a new connection on the next request, and a failover usually takes a few seconds.
pub const OUTAGE_RETRY_AFTER_S: u64 = 1;

impl From<anyhow::Error> for ApiError {
    /// A write the storage refused (full, read-only, forbidden: `store::storage_failure`)
    /// is 507 with a sentence; a database outage (a cut connection, a failover, no free
    /// connection: `store::database_outage`) is 503 with `Retry-After`, for the request can
    /// be sent again as it was; other store and infrastructure failures are 500s (`{:#}`
    /// keeps the cause chain in the log).
    fn from(err: anyhow::Error) -> Self {
        if let Some(failure) = crate::store::storage_failure(&err) {
            tracing::error!(cause = %format!("{err:#}"), "storage refused a write");
            return ApiError::InsufficientStorage(failure.to_string());
        }
        if let Some(outage) = crate::store::database_outage(&err) {
            tracing::warn!(cause = %format!("{err:#}"), "database outage: answered 503");
            return ApiError::DatabaseOutage(outage.to_string());
        }
        ApiError::Internal(format!("{err:#}"))
    }
}

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ApiError::Internal(cause) => write!(f, "500: {cause}"),
            other => write!(f, "{}: {}", other.status().as_u16(), other.detail()),
        }
    }
}

// ---------- every core error to a status (one file decides them all) ----------

/// A full pool or one shutting down is 503 + Retry-After, and so is work stopped at the
/// server's `--job-timeout` (the limit is the server's, not the input's fault); a failed
/// worker or an unrecorded job is a 500.
impl From<jobs::Error> for ApiError {
    fn from(e: jobs::Error) -> Self {
        match e {
            jobs::Error::Full { .. } | jobs::Error::ShuttingDown | jobs::Error::Stopped { .. } => {
                ApiError::unavailable(e.to_string(), jobs::RETRY_AFTER_S)
            }
            jobs::Error::Worker(cause) => ApiError::Internal(cause),
            jobs::Error::Store(err) => err.into(),
        }
    }
}

impl From<geometry::Error> for ApiError {
    fn from(e: geometry::Error) -> Self {
        use geometry::Error as G;
        match e {
            G::InSegment { index, source } => {
                let inner: ApiError = (*source).into();
                let detail = format!("segments[{index}]: {}", inner.detail());
                if inner.status() == StatusCode::BAD_REQUEST {
                    ApiError::bad_request(detail)
                } else {
                    ApiError::unprocessable(detail)
                }
            }
            G::NonFinite { .. } | G::InvalidParameter { .. } | G::Shape { .. } => {
                ApiError::bad_request(e.to_string())
            }
            G::TooFewPoints { .. }
            | G::DuplicatePoints { .. }
            | G::ZeroLengthStep
            | G::InconsistentRadius { .. } => ApiError::unprocessable(e.to_string()),
        }
    }
}

impl From<nn::Error> for ApiError {
    fn from(e: nn::Error) -> Self {
        use nn::Error as N;
        match e {
            N::InvalidParameter { .. }
            | N::TooFewLayers(_)
            | N::EmptyLayer { .. }
            | N::NonFinite { .. } => ApiError::bad_request(e.to_string()),
            N::TooFewSamples { .. } | N::Diverged { .. } | N::Incompatible(_) | N::Shape { .. } => {
                ApiError::unprocessable(e.to_string())
            }
            N::Format(_) => ApiError::internal(e),
        }
    }
}

impl From<gap::Error> for ApiError {
    fn from(e: gap::Error) -> Self {
        match e {
            gap::Error::Servo { .. } => ApiError::unprocessable(format!(
                "{e}. Fix the machine's servo model with PUT /v1/machines/{{machine}}"
            )),
            gap::Error::Shape { .. }
            | gap::Error::NonFinite { .. }
            | gap::Error::Invalid { .. }
            | gap::Error::Request(_) => ApiError::bad_request(e.to_string()),
            gap::Error::TooManySamples { .. } => ApiError::payload_too_large(e.to_string()),
            gap::Error::MissingAxes { .. } => ApiError::unprocessable(e.to_string()),
            gap::Error::Align(_) => ApiError::unprocessable(e.to_string()),
            gap::Error::Effects(_) => ApiError::unprocessable(e.to_string()),
        }
    }
}

impl From<compensation::Error> for ApiError {
    fn from(e: compensation::Error) -> Self {
        use compensation::Error as E;
        match e {
            E::BadSize { .. } | E::BadToolRadius => ApiError::bad_request(e.to_string()),
            E::LengthMismatch { .. } => ApiError::conflict(format!(
                "{e}; the surface was redefined after this measurement: upload it again"
            )),
            E::NonFinite { .. } | E::ZeroNormal { .. } => ApiError::unprocessable(e.to_string()),
        }
    }
}

/// G-code and machine problems are the caller's to fix (422 naming line/code or field);
/// malformed numeric arguments and a machine definition refused at PUT are 400.
impl From<motion::Error> for ApiError {
    fn from(e: motion::Error) -> Self {
        use motion::Error as E;
        match e {
            E::UnsupportedCode { line, code } => ApiError::unprocessable(format!(
                "gcode line {line}: unsupported code {code}. Read: G0-G4 G15 G17-G21 G28 G30 \
                 G40-G43 G43.4 G44 G49 G50 G53-G59 G61 G61.1 G64 G67 G69 G73 G80-G83 G85 G90 \
                 G91 G90.1 G91.1 G93 G94 G98 G99 (contour-error and gap-diagnosis also G9 G5.1 \
                 G8), TRAORI/TRAFOOF, M codes, words X Y Z A C I J K R F N S T H D P Q L \
                 (B U V W while they keep one value)"
            )),
            E::Gcode { line, message } => {
                ApiError::unprocessable(format!("gcode line {line}: {message}"))
            }
            E::TooManyPeriods { .. } | E::EmptyProgram => ApiError::unprocessable(e.to_string()),
            E::InvalidServo { .. } | E::UnstableServo { .. } | E::InvalidMachine(_) => {
                ApiError::unprocessable(format!("machine definition: {e}"))
            }
            E::NotSimulable { .. } | E::Effects(_) => ApiError::unprocessable(e.to_string()),
            E::BadDefinition { .. } => ApiError::bad_request(e.to_string()),
            E::InvalidPeriod(_)
            | E::PeriodOutOfRange(_)
            | E::InvalidParameter { .. }
            | E::EmptyCommand
            | E::NonFiniteCommand { .. } => ApiError::bad_request(e.to_string()),
        }
    }
}

/// A program the reader refuses is the reader's answer (422 naming line and word); a bad
/// option or point is 400; an answer too long to write is 422.
impl From<cam::Error> for ApiError {
    fn from(e: cam::Error) -> Self {
        use cam::Error as E;
        match e {
            E::Read(inner) => inner.into(),
            E::Tolerance { .. } | E::NonFinite { .. } | E::Empty { .. } | E::Csv { .. } => {
                ApiError::bad_request(e.to_string())
            }
            E::TooLong { .. } => ApiError::unprocessable(e.to_string()),
            E::Contour(cam::predistort::Error::Motion(inner)) => inner.into(),
            E::Contour(cam::predistort::Error::Option { .. }) => {
                ApiError::bad_request(e.to_string())
            }
            E::Contour(_) => ApiError::unprocessable(e.to_string()),
        }
    }
}

impl From<signal::Error> for ApiError {
    fn from(e: signal::Error) -> Self {
        use signal::Error as E;
        match e {
            E::NonFinite { .. }
            | E::BadParam { .. }
            | E::UnknownWavelet(_)
            | E::GridMismatch { .. } => ApiError::bad_request(e.to_string()),
            E::TooShort { .. } | E::Overflow { .. } => ApiError::unprocessable(e.to_string()),
        }
    }
}

impl From<volumetric::Error> for ApiError {
    fn from(e: volumetric::Error) -> Self {
        use volumetric::Error as E;
        match e {
            E::Empty { .. }
            | E::LengthMismatch { .. }
            | E::NonFinite { .. }
            | E::UnknownModel(_)
            | E::InvalidOption { .. }
            | E::Csv { .. }
            | E::AxisLine { .. }
            | E::TableTooLarge { .. } => ApiError::bad_request(e.to_string()),
            E::TooFewNodes { .. } | E::FlatAxis { .. } | E::NotAGrid { .. } => {
                ApiError::unprocessable(e.to_string())
            }
            E::Fit(_) => ApiError::unprocessable(format!(
                "the map could not be fitted to these nodes ({e}); check them for outliers or try another model"
            )),
            E::ModelFormat(_) => ApiError::internal(e),
        }
    }
}

/// A body the segment decoder refuses is the caller's to fix: 400 with its sentence.
impl From<codec::DecodeError> for ApiError {
    fn from(e: codec::DecodeError) -> Self {
        ApiError::BadRequest(e.0)
    }
}

/// Labelling and training failures as their core's (geometry, nn); too few samples to split
/// is 422, and so is a stored model from a newer truecut (retrain it); unreadable model
/// metadata is the server's fault (500).
impl From<step_error::Error> for ApiError {
    fn from(e: step_error::Error) -> Self {
        use step_error::Error as E;
        match e {
            E::Geometry(e) => e.into(),
            E::Nn(e) => e.into(),
            E::TooFewToSplit => ApiError::unprocessable(e.to_string()),
            E::Metadata(_) => ApiError::internal(e),
            E::NewerModel { .. } => ApiError::unprocessable(e.to_string()),
            E::Cancelled => ApiError::conflict(e.to_string()),
        }
    }
}

/// Malformed numbers and shapes are 400; a table or run with too few targets or cycles to
/// compute the figures, or points that make no circle, are 422 (well-formed, unusable).
impl From<metrology::Error> for ApiError {
    fn from(e: metrology::Error) -> Self {
        use metrology::Error as E;
        match e {
            E::NonFinite { .. }
            | E::LengthMismatch { .. }
            | E::DuplicateTarget { .. }
            | E::Invalid { .. } => ApiError::bad_request(e.to_string()),
            E::TooFew { .. }
            | E::Degenerate { .. }
            | E::MissingReadings { .. }
            | E::CorrectionTooLarge { .. }
            | E::Unresolvable { .. } => ApiError::unprocessable(e.to_string()),
        }
    }
}

#[cfg(test)]
mod outage_tests {
    use super::*;

    #[test]
    fn a_database_outage_is_503_with_retry_after_and_marked_for_the_metrics() {
        let err = anyhow::Error::from(sqlx::Error::PoolTimedOut).context("cannot read the job");
        let api = ApiError::from(err);
        assert!(matches!(api, ApiError::DatabaseOutage(_)), "{api}");
        let resp = api.into_response();
        assert_eq!(resp.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(resp.headers()[header::RETRY_AFTER], "1");
        assert!(resp.extensions().get::<OutageAnswer>().is_some());
        // Back-pressure 503s are not outages.
        let full = ApiError::unavailable("all workers are busy", 2).into_response();
        assert!(full.extensions().get::<OutageAnswer>().is_none());
    }
}
