//! Bearer-token authentication (a global middleware) and role extractors.
//!
//! Every `/v1` request is authenticated; the resulting [`Role`] is stored in the request's
//! extensions. GETs and computing POSTs need only `read`; handlers that store data take
//! [`RequireWrite`] or [`RequireAdmin`]. As a safety net the middleware itself demands
//! `admin` for DELETE and `write` for PUT/PATCH. With no tokens configured every request is
//! `admin` (development mode; the server then binds loopback only).

use std::collections::HashMap;
use std::sync::Arc;

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
    /// GETs and computing POSTs that store nothing.
    Read,
    /// Measurement uploads.
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
        Ok(Tokens { by_digest })
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

/// Global middleware: authenticates `/v1` requests, stores the [`Role`] in the extensions.
pub async fn authenticate(State(state): State<AppState>, mut req: Request, next: Next) -> Response {
    if !req.uri().path().starts_with("/v1") {
        return next.run(req).await;
    }
    let role = if state.tokens.is_empty() {
        Role::Admin
    } else {
        let presented = req
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| {
                v.strip_prefix("Bearer ")
                    .or_else(|| v.strip_prefix("bearer "))
            })
            .map(str::trim);
        match presented {
            None => {
                return ApiError::unauthorized("send a token: Authorization: Bearer TOKEN")
                    .into_response();
            }
            Some(token) => match state.tokens.role_of(token) {
                Some(role) => role,
                None => {
                    return ApiError::unauthorized("the bearer token is not known to this server")
                        .into_response();
                }
            },
        }
    };
    let needed = match *req.method() {
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
    next.run(req).await
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
