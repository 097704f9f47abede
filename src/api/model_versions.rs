//! Versions of a trained model over HTTP, the same for every model resource
//! (`.../step-error-model/versions`, `.../volumetric-map/versions` and their `rollback`):
//! the kept versions, newest first, with the one served; and rolling back to one of them.

use serde::Deserialize;
use serde_json::{Value, json};

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::id::Id;
use crate::store::{ModelVersions, Rollback};

/// Body of a `rollback` route.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RollbackRequest {
    /// The version to serve from now on (as listed by the `versions` route).
    pub version: i64,
}

/// Where a model lives, for the answers and the sentences.
pub struct ModelRef<'a> {
    /// Machine id.
    pub machine: &'a Id,
    /// Surface id for surface-level models.
    pub surface: Option<&'a Id>,
    /// Model kind in the store.
    pub kind: &'static str,
    /// The route's path up to the model (e.g. `/v1/machines/m/volumetric-map`).
    pub path: String,
    /// What trains it, for the 404 sentence (e.g. `PUT /v1/machines/m/volumetric-map`).
    pub made_by: String,
}

fn rfc3339(ms: i64) -> Option<String> {
    let t = time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(ms) * 1_000_000).ok()?;
    t.format(&time::format_description::well_known::Rfc3339)
        .ok()
}

fn answer(m: &ModelRef<'_>, v: ModelVersions) -> Value {
    let versions: Vec<Value> = v
        .versions
        .iter()
        .map(|x| {
            json!({
                "version": x.version,
                "created_at": rfc3339(x.created_at_ms),
                "sha256": x.sha256,
                "bytes": x.bytes,
                "format_version": x.format_version,
                "job": x.job,
            })
        })
        .collect();
    json!({
        "machine": m.machine.to_string(),
        "surface": m.surface.map(ToString::to_string),
        "kind": m.kind,
        "current": v.current,
        "versions": versions,
    })
}

fn missing(m: &ModelRef<'_>) -> ApiError {
    ApiError::not_found(format!(
        "there is no model at {}: make one with {}",
        m.path, m.made_by
    ))
}

/// `GET .../versions`: the kept versions, newest first, and `current` (the one served).
pub async fn list(state: &AppState, m: &ModelRef<'_>) -> ApiResult<Value> {
    let v = state
        .store
        .models()
        .versions(m.machine, m.surface.map(|s| &**s), m.kind)
        .await?
        .ok_or_else(|| missing(m))?;
    Ok(answer(m, v))
}

/// `POST .../rollback {"version": n}`: serves version `n` from now on (every instance), and
/// answers as `versions` does.
pub async fn rollback(
    state: &AppState,
    m: &ModelRef<'_>,
    req: RollbackRequest,
) -> ApiResult<Value> {
    if req.version < 1 {
        return Err(ApiError::bad_request(format!(
            "version must be a version number from {}/versions (1 or more), got {}",
            m.path, req.version
        )));
    }
    let models = state.store.models();
    let surface = m.surface.map(|s| &**s);
    match models
        .rollback(m.machine, surface, m.kind, req.version)
        .await?
    {
        Rollback::Done => {}
        Rollback::NoModel => return Err(missing(m)),
        Rollback::NoVersion(kept) => {
            let kept: Vec<String> = kept.iter().map(ToString::to_string).collect();
            return Err(ApiError::not_found(format!(
                "version {} of {} is not kept: roll back to one of {} (GET {}/versions)",
                req.version,
                m.path,
                kept.join(", "),
                m.path
            )));
        }
    }
    let v = models
        .versions(m.machine, surface, m.kind)
        .await?
        .ok_or_else(|| missing(m))?;
    Ok(answer(m, v))
}
