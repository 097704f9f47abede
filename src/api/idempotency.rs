//! The `Idempotency-Key` header (IETF httpapi draft "The Idempotency-Key HTTP Header Field")
//! on the POSTs that store a record or queue a job ([`ROUTES`]): a retry with the same key and
//! the same request gets the first answer again, marked `Idempotent-Replayed: true`, and
//! nothing is stored twice.
//!
//! - Same key, same request (query and body, by SHA-256), first answered: the first answer
//!   (status, body, `Location`, `Content-Type`), without running the handler.
//! - Same key, other request: 422. Same key while the first is still running: 409.
//! - A key is 1 to 255 visible ASCII characters (quoted or not: `"k"` and `k` are one key),
//!   else 400. Keys are scoped per route (method and path) and per token (per route when
//!   auth is off), kept 24 h ([`crate::store::IDEMPOTENCY_KEEP`]) and then pruned.
//! - Only answers that stored something (201, 202) are kept; any other answer lets go of the
//!   key, so a retry after a refusal or a failure runs anew. Without the header nothing
//!   changes.
//!
//! - A key whose first request's instance died (its lease lapsed) is taken over at once by
//!   the retry, which then runs anew; what it records without an id of the client's takes
//!   the id derived from the key ([`KeyedId`]), so a record or job the first try committed is
//!   met (replayed), not stored twice.
//!
//! The body reaches the handler as it arrives (uploads stay streamed); its digest is taken on
//! the way. A replay reads the whole body for its digest (through the same pace and budget).

use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use axum::body::Body;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

use super::AppState;
use super::error::ApiError;
use crate::store::{Claim, KeptAnswer, Store};

/// The request header.
pub const HEADER: &str = "idempotency-key";

/// The header of a replayed answer (`Idempotent-Replayed: true`).
pub const REPLAYED: &str = "idempotent-replayed";

/// Longest key, characters.
pub const MAX_KEY_LEN: usize = 255;

/// The POST routes that honour the header: every POST that stores a record (a measurement,
/// an ISO 230-2 run) or may queue a job (decompositions, gap diagnoses, compensated
/// programs, step-error training).
pub const ROUTES: [&str; 7] = [
    "/v1/machines/{machine}/surfaces/{surface}/measurements",
    "/v1/machines/{machine}/axes/{axis}/iso230-2",
    "/v1/decompose",
    "/v1/machines/{machine}/surfaces/{surface}/measurements/{id}/decomposition",
    "/v1/machines/{machine}/gap-diagnosis",
    "/v1/machines/{machine}/compensated-program",
    "/v1/machines/{machine}/surfaces/{surface}/step-error-model",
];

/// The id of what a keyed request records when it names none (a measurement without an
/// id, a job): derived from the key and its scope, so that a second try of the request
/// (after its first try's instance died holding the key, possibly after the record was
/// committed) meets the first try's record instead of storing a twin. A UUID version 8
/// whose bits are the first 122 of SHA-256(scope, newline, key) (RFC 9562 §5.8).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KeyedId(pub String);

/// [`KeyedId`] of `key` in `scope`.
fn keyed_id(scope: &str, key: &str) -> String {
    let digest = Sha256::digest(format!("{scope}\n{key}").as_bytes());
    let mut bytes = [0u8; 16];
    bytes.copy_from_slice(&digest[..16]);
    uuid::Uuid::new_v8(bytes).to_string()
}

/// Answer headers kept and replayed.
const KEPT_HEADERS: [header::HeaderName; 2] = [header::LOCATION, header::CONTENT_TYPE];

/// The key of an `Idempotency-Key` value: surrounding quotes (a structured-field string)
/// dropped; 400 unless 1 to [`MAX_KEY_LEN`] visible ASCII characters.
pub fn parse_key(value: &HeaderValue) -> Result<String, ApiError> {
    let refuse = || {
        ApiError::bad_request(format!(
            "the Idempotency-Key header must be 1 to {MAX_KEY_LEN} visible ASCII characters \
             (letters, digits, punctuation; no spaces), e.g. a UUID; send a new key for each \
             new request and the same key only to retry one"
        ))
    };
    let text = value.to_str().map_err(|_| refuse())?.trim();
    let key = text
        .strip_prefix('"')
        .and_then(|t| t.strip_suffix('"'))
        .unwrap_or(text);
    if key.is_empty()
        || key.len() > MAX_KEY_LEN
        || !key.bytes().all(|b| b.is_ascii_graphic() && b != b'"')
    {
        return Err(refuse());
    }
    Ok(key.to_string())
}

/// Global middleware (inside the pace and the body budget, outside the handlers): applies
/// the `Idempotency-Key` rules to POSTs on [`ROUTES`] that carry the header.
pub async fn idempotent(State(state): State<AppState>, req: Request, next: Next) -> Response {
    if req.method() != Method::POST {
        return next.run(req).await;
    }
    let Some(value) = req.headers().get(HEADER) else {
        return next.run(req).await;
    };
    let honoured = req
        .extensions()
        .get::<MatchedPath>()
        .is_some_and(|p| ROUTES.contains(&p.as_str()));
    if !honoured {
        return next.run(req).await;
    }
    let key = match parse_key(value) {
        Ok(k) => k,
        Err(e) => return e.into_response(),
    };
    let scope = scope_of(&state, &req);
    let claim = match state.store.claim_idempotency_key(&scope, &key).await {
        Ok(c) => c,
        Err(e) => return ApiError::from(e).into_response(),
    };
    match claim {
        Claim::InFlight => ApiError::conflict(format!(
            "a request with Idempotency-Key '{key}' is still being answered; retry once it has \
             been (the retry then gets its answer)"
        ))
        .into_response(),
        Claim::Answered {
            fingerprint,
            answer,
        } => {
            let (parts, body) = req.into_parts();
            let mut digest = Fingerprint::new(parts.uri.query());
            let mut body = body.into_data_stream();
            use futures::StreamExt as _;
            while let Some(chunk) = body.next().await {
                match chunk {
                    Ok(bytes) => digest.update(&bytes),
                    Err(e) => {
                        // The pace layer turns a stalled or slow body into its 408.
                        return ApiError::bad_request(format!("cannot read the request body: {e}"))
                            .into_response();
                    }
                }
            }
            if digest.finish() != fingerprint {
                return ApiError::unprocessable(format!(
                    "the Idempotency-Key '{key}' was already used on this route with another \
                     request body (or query); send a new key for a new request, or the same \
                     body to retry the first"
                ))
                .into_response();
            }
            replay(answer)
        }
        Claim::Claimed(claim) => {
            let id = keyed_id(&scope, &key);
            let mut req = req;
            req.extensions_mut().insert(KeyedId(id.clone()));
            crate::jobs::with_keyed_id(
                id,
                run_holding(state.store.clone(), scope, key, claim, req, next),
            )
            .await
        }
    }
}

/// Runs the request that holds the key; keeps its answer when it stored something (201,
/// 202), else lets go of the key. A request that goes away lets go of it too.
async fn run_holding(
    store: Store,
    scope: String,
    key: String,
    claim: String,
    req: Request,
    next: Next,
) -> Response {
    let mut guard = Release {
        store: store.clone(),
        held: Some((scope, key, claim)),
    };
    let mut state = DigestState::Running(Fingerprint::new(req.uri().query()));
    if http_body::Body::is_end_stream(req.body()) {
        // No body: a handler may never poll it.
        state.end();
    }
    let digest = Arc::new(Mutex::new(state));
    let req = req.map(|body| {
        Body::new(DigestBody {
            inner: body,
            digest: digest.clone(),
        })
    });
    let resp = next.run(req).await;
    let fingerprint = match &*digest.lock().expect("idempotency digest") {
        DigestState::Done(f) => Some(f.clone()),
        DigestState::Running(_) => None,
    };
    let keep = matches!(resp.status(), StatusCode::CREATED | StatusCode::ACCEPTED);
    let (Some(fingerprint), true) = (fingerprint, keep) else {
        // Nothing stored, or the body was not read to its end: the key is free again.
        if let Some((scope, key, claim)) = guard.held.take() {
            if let Err(e) = store.release_idempotency_key(&scope, &key, &claim).await {
                tracing::error!("cannot release an idempotency key: {e:#}");
            }
        }
        return resp;
    };
    let (parts, body) = resp.into_parts();
    // Answers that store something are small JSON bodies ({"id": ...}, {"job": ...}).
    let bytes = match axum::body::to_bytes(body, usize::MAX).await {
        Ok(b) => b,
        Err(e) => {
            return ApiError::internal(format!("cannot read the answer: {e}")).into_response();
        }
    };
    let answer = KeptAnswer {
        status: parts.status.as_u16(),
        headers: KEPT_HEADERS
            .iter()
            .filter_map(|name| {
                let v = parts.headers.get(name)?.to_str().ok()?;
                Some((name.as_str().to_string(), v.to_string()))
            })
            .collect(),
        body: bytes.to_vec(),
    };
    if let Some((scope, key, claim)) = guard.held.take() {
        match store
            .keep_idempotent_answer(&scope, &key, &claim, &fingerprint, &answer)
            .await
        {
            Ok(true) => {}
            Ok(false) => tracing::warn!(key, "an idempotency key was taken over before its answer"),
            Err(e) => {
                // The record is stored but its answer is not: let go of the key rather than
                // leave it "in flight" (409) until it goes stale; a retry then runs anew (and
                // an upload with an id is answered as a replay by its insert).
                tracing::error!("cannot keep the answer of an idempotency key: {e:#}");
                if let Err(e) = store.release_idempotency_key(&scope, &key, &claim).await {
                    tracing::error!("cannot release an idempotency key: {e:#}");
                }
            }
        }
    }
    Response::from_parts(parts, Body::from(bytes))
}

/// The kept answer, marked as a replay.
fn replay(answer: KeptAnswer) -> Response {
    let status = StatusCode::from_u16(answer.status).unwrap_or(StatusCode::OK);
    let mut resp = (status, answer.body).into_response();
    let headers = resp.headers_mut();
    headers.remove(header::CONTENT_TYPE);
    for (name, value) in answer.headers {
        if let (Ok(n), Ok(v)) = (
            header::HeaderName::try_from(name),
            HeaderValue::try_from(value),
        ) {
            headers.insert(n, v);
        }
    }
    headers.insert(REPLAYED, HeaderValue::from_static("true"));
    resp
}

/// The scope of a key: a digest of the caller's token (none when auth is off), the method
/// and the path.
fn scope_of(state: &AppState, req: &Request) -> String {
    let caller = if state.tokens.is_empty() {
        "-".to_string()
    } else {
        let token = req
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| super::auth::presented_token(v).ok())
            .map(|(t, _)| t)
            .unwrap_or_default();
        hex::encode(&Sha256::digest(token.as_bytes())[..16])
    };
    format!("{caller} {} {}", req.method(), req.uri().path())
}

/// SHA-256 of a request's query and body.
struct Fingerprint(Sha256);

impl Fingerprint {
    fn new(query: Option<&str>) -> Self {
        let mut h = Sha256::new();
        let q = query.unwrap_or("");
        h.update((q.len() as u64).to_le_bytes());
        h.update(q.as_bytes());
        Fingerprint(h)
    }

    fn update(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }

    fn finish(self) -> String {
        hex::encode(self.0.finalize())
    }
}

enum DigestState {
    Running(Fingerprint),
    Done(String),
}

impl DigestState {
    fn update(&mut self, bytes: &[u8]) {
        if let DigestState::Running(f) = self {
            f.update(bytes);
        }
    }

    /// Ends the digest (again: no change).
    fn end(&mut self) {
        if let DigestState::Running(_) = self
            && let DigestState::Running(f) =
                std::mem::replace(self, DigestState::Done(String::new()))
        {
            *self = DigestState::Done(f.finish());
        }
    }
}

/// The request body, digested as the handler reads it.
struct DigestBody {
    inner: Body,
    digest: Arc<Mutex<DigestState>>,
}

impl http_body::Body for DigestBody {
    type Data = bytes::Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>> {
        let frame = std::task::ready!(Pin::new(&mut self.inner).poll_frame(cx));
        let mut digest = self.digest.lock().expect("idempotency digest");
        match &frame {
            Some(Ok(f)) => {
                if let Some(data) = f.data_ref() {
                    digest.update(data);
                }
                if self.inner.is_end_stream() {
                    digest.end();
                }
            }
            None => digest.end(),
            Some(Err(_)) => {}
        }
        drop(digest);
        Poll::Ready(frame)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

/// Lets go of a held key if the request goes away before it is answered.
struct Release {
    store: Store,
    held: Option<(String, String, String)>,
}

impl Drop for Release {
    fn drop(&mut self) {
        if let Some((scope, key, claim)) = self.held.take()
            && let Ok(runtime) = tokio::runtime::Handle::try_current()
        {
            let store = self.store.clone();
            runtime.spawn(async move {
                if let Err(e) = store.release_idempotency_key(&scope, &key, &claim).await {
                    tracing::error!("cannot release an idempotency key: {e:#}");
                }
            });
        }
    }
}

#[cfg(test)]
mod tests;
