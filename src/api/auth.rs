//! Bearer-token authentication (a global middleware) and role extractors.
//!
//! Every `/v1` request is authenticated, and so are the dashboard's `/` and `/assets/`; the
//! resulting [`Role`] is stored in the request's extensions. A token comes as
//! `Authorization: Bearer TOKEN`, or as the password of `Basic` credentials (what a browser
//! sends after its log-in prompt for the dashboard). GETs and computing POSTs need only `read`; handlers that store data take
//! [`RequireWrite`] or [`RequireAdmin`]. As a safety net the middleware itself demands
//! `admin` for DELETE and `write` for PUT/PATCH. With no tokens configured every request is
//! `admin` (development mode; the server then binds loopback only).

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use axum::extract::{FromRequestParts, Request, State};
use axum::http::request::Parts;
use axum::http::{Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

use super::AppState;
use super::error::ApiError;

/// What a token may do. Ordered: `Read < Write < Admin`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Role {
    /// GETs and computing POSTs that store nothing (answered directly, never as a job).
    Read,
    /// Measurement uploads, and requests that queue a stored job.
    Write,
    /// Machine and surface definitions, training, deletes.
    Admin,
}

impl Role {
    /// Parses `read`, `write` or `admin` (case-insensitive).
    pub fn parse(s: &str) -> Option<Role> {
        match s.to_ascii_lowercase().as_str() {
            "read" => Some(Role::Read),
            "write" => Some(Role::Write),
            "admin" => Some(Role::Admin),
            _ => None,
        }
    }

    /// Lower-case name.
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Read => "read",
            Role::Write => "write",
            Role::Admin => "admin",
        }
    }
}

/// The configured tokens (stored as SHA-256 digests). Empty = development mode.
#[derive(Clone, Debug, Default)]
pub struct Tokens {
    by_digest: HashMap<[u8; 32], Role>,
    /// POSTs each read token may have in flight at once (`--read-token-concurrency`; 0 until
    /// set: no limit).
    read_limit: usize,
    /// POSTs in flight per read token.
    in_flight: Arc<Mutex<HashMap<[u8; 32], usize>>>,
}

/// A read token's place among its POSTs in flight; given back when dropped (the request
/// answered, or its client went away).
pub struct ReadSlot {
    key: [u8; 32],
    in_flight: Arc<Mutex<HashMap<[u8; 32], usize>>>,
}

impl Drop for ReadSlot {
    fn drop(&mut self) {
        let mut m = self.in_flight.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(n) = m.get_mut(&self.key) {
            *n -= 1;
            if *n == 0 {
                m.remove(&self.key);
            }
        }
    }
}

fn digest(token: &str) -> [u8; 32] {
    Sha256::digest(token.as_bytes()).into()
}

impl Tokens {
    /// Parses entries `TOKEN ROLE` (or `TOKEN:ROLE`) separated by newlines or commas;
    /// blank lines and `#` comments are skipped. Errors name the entry.
    pub fn parse(text: &str) -> anyhow::Result<Tokens> {
        let mut by_digest = HashMap::new();
        for (i, raw) in text.split(['\n', ',']).enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let mut parts = line
                .split(|c: char| c.is_whitespace() || c == ':')
                .filter(|s| !s.is_empty());
            let (Some(token), Some(role), None) = (parts.next(), parts.next(), parts.next()) else {
                anyhow::bail!("token entry {} is not `TOKEN ROLE`", i + 1);
            };
            let Some(role) = Role::parse(role) else {
                anyhow::bail!(
                    "token entry {}: role '{role}' is not one of read, write, admin",
                    i + 1
                );
            };
            by_digest.insert(digest(token), role);
        }
        Ok(Tokens {
            by_digest,
            ..Tokens::default()
        })
    }

    /// Bounds the POSTs (computations: compiles, simulations, diagnoses) each read token
    /// may have in flight at once to `n` (≥ 1): a read token cannot fill the worker pool.
    pub fn with_read_limit(mut self, n: usize) -> Tokens {
        self.read_limit = n.max(1);
        self
    }

    /// Takes a place for a POST of the read token `token`; `None` when it already has
    /// [`Tokens::with_read_limit`] POSTs in flight.
    fn read_slot(&self, token: &str) -> Option<ReadSlot> {
        let key = digest(token);
        let mut m = self.in_flight.lock().unwrap_or_else(|p| p.into_inner());
        let n = m.entry(key).or_insert(0);
        if self.read_limit > 0 && *n >= self.read_limit {
            return None;
        }
        *n += 1;
        Some(ReadSlot {
            key,
            in_flight: self.in_flight.clone(),
        })
    }

    /// Loads tokens from `spec`: the path of an existing file, or inline entries.
    pub fn load(spec: &str) -> anyhow::Result<Tokens> {
        let path = std::path::Path::new(spec);
        let tokens = if path.is_file() {
            let text = std::fs::read_to_string(path)
                .map_err(|e| anyhow::anyhow!("cannot read tokens file {spec}: {e}"))?;
            Tokens::parse(&text)?
        } else {
            Tokens::parse(spec)?
        };
        if tokens.is_empty() {
            anyhow::bail!("the tokens setting holds no `TOKEN ROLE` entry");
        }
        Ok(tokens)
    }

    /// True when no token is configured (development mode).
    pub fn is_empty(&self) -> bool {
        self.by_digest.is_empty()
    }

    /// The role of `token`, if it is configured.
    pub fn role_of(&self, token: &str) -> Option<Role> {
        self.by_digest.get(&digest(token)).copied()
    }
}

/// Header the dashboard sends with its state-changing requests. A request authenticated by
/// `Basic` credentials (which a browser attaches by itself) must carry it unless it is a
/// GET or HEAD: a page of another origin cannot add it without a CORS preflight, which this
/// server never grants, so it cannot ride on the operator's cached credentials.
pub const DASHBOARD_HEADER: &str = "x-truecut-dashboard";

/// True for the paths outside `/v1` that need a token too: the dashboard page and its assets.
fn is_dashboard(path: &str) -> bool {
    path == "/" || path.starts_with("/assets/")
}

/// The token presented: `Bearer TOKEN`, or `Basic` with the token as the password (any user
/// name), which is what a browser sends after its log-in prompt. `Err` for a header that is
/// neither.
pub(super) fn presented_token(value: &str) -> Result<(String, bool), &'static str> {
    if let Some(t) = value
        .strip_prefix("Bearer ")
        .or_else(|| value.strip_prefix("bearer "))
    {
        return Ok((t.trim().to_string(), false));
    }
    if let Some(b) = value
        .strip_prefix("Basic ")
        .or_else(|| value.strip_prefix("basic "))
    {
        use base64::Engine as _;
        let decoded = base64::engine::general_purpose::STANDARD
            .decode(b.trim())
            .map_err(|_| "the Basic credentials are not base64")?;
        let text = String::from_utf8(decoded).map_err(|_| "the Basic credentials are not UTF-8")?;
        let (_, password) = text
            .split_once(':')
            .ok_or("the Basic credentials are not USER:TOKEN")?;
        return Ok((password.trim().to_string(), true));
    }
    Err("send a token: Authorization: Bearer TOKEN")
}

/// 401 for `path`: on the dashboard with a `Basic` challenge, so that a browser asks for the
/// token; on `/v1` with the `Bearer` challenge of [`ApiError`].
fn unauthorized(dashboard: bool, detail: &str) -> Response {
    let mut resp = ApiError::unauthorized(detail).into_response();
    if dashboard {
        resp.headers_mut().insert(
            header::WWW_AUTHENTICATE,
            header::HeaderValue::from_static(
                "Basic realm=\"truecut dashboard: any user name, your token as the password\", charset=\"UTF-8\"",
            ),
        );
    }
    resp
}

/// Global middleware: authenticates `/v1` requests and the dashboard (`/`, `/assets/`),
/// stores the [`Role`] in the extensions.
pub async fn authenticate(State(state): State<AppState>, mut req: Request, next: Next) -> Response {
    let path = req.uri().path();
    let dashboard = is_dashboard(path);
    if !path.starts_with("/v1") && !dashboard {
        return next.run(req).await;
    }
    let mut presented = None;
    let role = if state.tokens.is_empty() {
        Role::Admin
    } else {
        let Some(value) = req
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
        else {
            return unauthorized(dashboard, "send a token: Authorization: Bearer TOKEN");
        };
        let (token, basic) = match presented_token(value) {
            Ok(t) => t,
            Err(detail) => return unauthorized(dashboard, detail),
        };
        let Some(role) = state.tokens.role_of(&token) else {
            return unauthorized(dashboard, "the bearer token is not known to this server");
        };
        if basic
            && !matches!(*req.method(), Method::GET | Method::HEAD)
            && !req.headers().contains_key(DASHBOARD_HEADER)
        {
            return ApiError::forbidden(format!(
                "a request authenticated by Basic credentials must carry the header \
                 {DASHBOARD_HEADER} (the dashboard sends it); scripts should send \
                 Authorization: Bearer TOKEN"
            ))
            .into_response();
        }
        presented = Some(token);
        role
    };
    let needed = match *req.method() {
        // A request that asks to run as a job (RFC 7240) stores one: write, refused before
        // its body is read.
        Method::POST if asks_for_job(req.headers()) => Role::Write,
        // A probe upload (up to --max-body-bytes) is refused before it takes room for its
        // body; the handler's `RequireWrite` says the same.
        Method::POST
            if req
                .uri()
                .path()
                .trim_end_matches('/')
                .ends_with("/measurements") =>
        {
            Role::Write
        }
        // Cancelling a job is the submitter's business (write), not an administrator's.
        Method::DELETE if req.uri().path().starts_with("/v1/jobs/") => Role::Write,
        Method::DELETE => Role::Admin,
        Method::PUT | Method::PATCH => Role::Write,
        _ => Role::Read,
    };
    if role < needed {
        return forbidden(role, needed).into_response();
    }
    req.extensions_mut().insert(role);
    // A read token's POSTs are computations it does not store: bounded per token, so one
    // read token cannot hold every worker.
    let _slot = match presented {
        Some(token) if role == Role::Read && req.method() == Method::POST => {
            match state.tokens.read_slot(&token) {
                Some(slot) => Some(slot),
                None => return too_many(state.tokens.read_limit),
            }
        }
        _ => None,
    };
    next.run(req).await
}

/// 429 with `Retry-After: 1` for a read token already at its limit of POSTs in flight.
fn too_many(limit: usize) -> Response {
    let mut resp = super::error::problem_response(
        axum::http::StatusCode::TOO_MANY_REQUESTS,
        &format!(
            "this read token already has {limit} computation(s) running (the server's \
             --read-token-concurrency); wait for an answer before sending the next, or use a \
             write token"
        ),
    );
    resp.headers_mut().insert(
        header::RETRY_AFTER,
        axum::http::HeaderValue::from_static("1"),
    );
    resp
}

/// True when the request asks to be answered by a job (`Prefer: respond-async`, RFC 7240).
pub fn asks_for_job(headers: &header::HeaderMap) -> bool {
    headers
        .get_all("prefer")
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|p| p.trim().eq_ignore_ascii_case("respond-async"))
}

/// 403 unless `role` may queue a stored job (`write` or `admin`): a stored job holds its
/// input (up to --max-body-bytes) in the database until it ends, so a `read` token may
/// only ask for direct answers. `what` says why this request would be a job.
pub fn may_queue_job(role: Option<Role>, what: &str) -> Result<(), ApiError> {
    match role {
        Some(have) if have < Role::Write => Err(ApiError::forbidden(format!(
            "{what}, so it would queue a stored job, which needs a token with role 'write' or \
             higher; yours has role '{}'. Send a smaller request for a direct answer, or use a \
             write token",
            have.as_str()
        ))),
        _ => Ok(()),
    }
}

fn forbidden(have: Role, need: Role) -> ApiError {
    ApiError::forbidden(format!(
        "this needs a token with role '{}' or higher; yours has role '{}'",
        need.as_str(),
        have.as_str()
    ))
}

fn role_at_least(parts: &Parts, need: Role) -> Result<Role, ApiError> {
    match parts.extensions.get::<Role>() {
        None => Err(ApiError::unauthorized(
            "send a token: Authorization: Bearer TOKEN",
        )),
        Some(&have) if have < need => Err(forbidden(have, need)),
        Some(&have) => Ok(have),
    }
}

/// Extractor: the request's token has role `write` or `admin` (else 403).
#[derive(Debug, Clone, Copy)]
pub struct RequireWrite;

/// Extractor: the request's token has role `admin` (else 403).
#[derive(Debug, Clone, Copy)]
pub struct RequireAdmin;

impl<S: Send + Sync> FromRequestParts<S> for RequireWrite {
    type Rejection = ApiError;
    async fn from_request_parts(parts: &mut Parts, _state: &S) -> Result<Self, Self::Rejection> {
        role_at_least(parts, Role::Write).map(|_| RequireWrite)
    }
}

impl<S: Send + Sync> FromRequestParts<S> for RequireAdmin {
    type Rejection = ApiError;
    async fn from_request_parts(parts: &mut Parts, _state: &S) -> Result<Self, Self::Rejection> {
        role_at_least(parts, Role::Admin).map(|_| RequireAdmin)
    }
}

/// Shared handle on the configured tokens.
pub type SharedTokens = Arc<Tokens>;
