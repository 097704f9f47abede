//! Record ids parsed at the door: [`Id`] (one id, from a body or a query) and [`PathIds`] (the
//! ids of a route's path, extracted straight from it).
//!
//! Why a type: an id names a row and, for trained models, a directory, so `.` and `..` must
//! never reach the store. Handlers and the lookups take `&Id`, so an unchecked string cannot get
//! there; the rule itself is the store's ([`crate::store::is_valid_id`]), shared with the CLI.

use std::fmt;
use std::ops::Deref;

use axum::extract::{FromRequestParts, RawPathParams};
use axum::http::request::Parts;

use super::error::{ApiError, ApiResult};

/// An id that passed [`crate::store::is_valid_id`]: `[A-Za-z0-9._-]{1,64}`, not `.` or `..`.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(transparent)]
pub struct Id(String);

impl Id {
    /// Parses `s`; `kind` names it in the 400 ("machine id 'a b' is invalid: ...").
    pub fn parse(kind: &str, s: &str) -> ApiResult<Id> {
        if crate::store::is_valid_id(s) {
            Ok(Id(s.to_string()))
        } else {
            let shown: String = s.chars().take(80).collect();
            Err(ApiError::bad_request(format!(
                "{kind} id '{shown}' is invalid: use 1 to 64 characters from A-Z a-z 0-9 . _ - \
                 (and not '.' or '..')"
            )))
        }
    }

    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The id as an owned string.
    pub fn into_string(self) -> String {
        self.0
    }
}

impl Deref for Id {
    type Target = str;
    fn deref(&self) -> &str {
        &self.0
    }
}

impl AsRef<str> for Id {
    fn as_ref(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for Id {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// The `N` ids of a route's path in order, e.g. `PathIds([machine, surface]): PathIds<2>` on
/// `/v1/machines/{machine}/surfaces/{surface}`. A bad id is a problem+json 400 naming its kind:
/// the path parameter's name, where `{id}` is a measurement after other ids and a job alone.
#[derive(Clone, Debug)]
pub struct PathIds<const N: usize>(pub [Id; N]);

impl<S: Send + Sync, const N: usize> FromRequestParts<S> for PathIds<N> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, Self::Rejection> {
        let params = RawPathParams::from_request_parts(parts, state)
            .await
            .map_err(|e| ApiError::bad_request(format!("the URL path is invalid: {e}")))?;
        let mut ids = Vec::with_capacity(N);
        for (i, (name, value)) in params.iter().enumerate() {
            let kind = match name {
                "id" if i > 0 => "measurement",
                "id" => "job",
                other => other,
            };
            ids.push(Id::parse(kind, value)?);
        }
        let n = ids.len();
        ids.try_into().map(PathIds).map_err(|_| {
            ApiError::internal(format!("route has {n} path ids but its handler takes {N}"))
        })
    }
}

#[cfg(test)]
mod tests;
