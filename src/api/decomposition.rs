//! Machining-error decomposition (openapi.yaml `POST /v1/decompose`; Chen et al. 2024):
//! `POST /v1/decompose` (stateless), `POST/GET .../measurements/{id}/decomposition`
//! (computed on the measurement's deviations, stored as its current decomposition).
//! Also the one `From<signal::Error> for ApiError`.

use std::sync::Arc;

use axum::Router;
use axum::extract::{Request, State};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use serde::Deserialize;
use serde_json::Value;

use super::AppState;
use super::auth::{RequireWrite, Role};
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, check_finite, decode_json, read_body};
use super::lookup::{require_measurement, require_surface};
use super::version::{Versioned, stamp};
use crate::api::id::PathIds;
use crate::jobs::{Progress, Runner};
use crate::signal::{self, DecomposeParams, Method, decompose};

/// Document kind under which a measurement's current decomposition is stored.
pub const DOC_KIND: &str = "decomposition";
/// Largest signal decomposed synchronously (openapi.yaml: sync up to 250,000 samples); larger
/// ones (up to [`signal::decompose::MAX_SAMPLES`]) run as a job (202).
pub const MAX_SYNC: usize = 250_000;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/decompose", post(post_decompose))
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/measurements/{id}/decomposition",
            post(post_measurement_decomposition).get(get_measurement_decomposition),
        )
}

/// Body of `POST /v1/decompose`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DecomposeRequest {
    signal: Vec<f64>,
    #[serde(default)]
    method: Method,
    #[serde(default)]
    params: DecomposeParams,
}

/// Body of `POST .../decomposition` (may be empty: defaults).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeasurementRequest {
    #[serde(default)]
    method: Method,
    #[serde(default)]
    params: DecomposeParams,
}

/// Kind of the stored decomposition job (its input: the `POST /v1/decompose` body).
pub const JOB_KIND: &str = "decomposition";

/// Runs a stored decomposition job on any instance: the input is the request body.
pub fn runner() -> Runner {
    Arc::new(|input: &str, p: &Progress| {
        let r: DecomposeRequest = serde_json::from_str(input)
            .map_err(|e| format!("the stored job input is not a decomposition request: {e}"))?;
        p.set(0.05);
        let d = decompose(&r.signal, r.method, &r.params).map_err(|e| e.to_string())?;
        serde_json::to_value(&d).map_err(|e| e.to_string())
    })
}

/// Runs a decomposition on the worker pool; when `job_input` (the request body, the
/// caller's role, and whether it asked for a job with `Prefer: respond-async`) is given and
/// the signal has more than [`MAX_SYNC`] samples or a job was asked for, a stored job (202)
/// that any instance may run. The direct
/// answer is the `Decomposition` itself, so the stateless route writes its JSON bytes in one
/// pass (no intermediate `serde_json::Value`: at 20,000 samples that pass cost as much as the
/// bytes).
async fn run(
    state: &AppState,
    x: Vec<f64>,
    method: Method,
    params: DecomposeParams,
    job_input: Option<(&[u8], Option<Role>, bool)>,
) -> ApiResult<Result<signal::Decomposition, Response>> {
    if x.len() > signal::decompose::MAX_SAMPLES {
        return Err(ApiError::payload_too_large(format!(
            "{} samples exceed the limit of {}; split the signal",
            x.len(),
            signal::decompose::MAX_SAMPLES
        )));
    }
    if let Some((body, role, asked)) = job_input
        && (x.len() > MAX_SYNC || asked)
    {
        let why = if asked {
            "the request asks for a job (Prefer: respond-async)".to_string()
        } else {
            format!(
                "the signal has {} samples, more than the {MAX_SYNC} answered directly",
                x.len()
            )
        };
        super::auth::may_queue_job(role, &why)?;
        let input = String::from_utf8(body.to_vec())
            .map_err(|_| ApiError::bad_request("the request body is not UTF-8 JSON"))?;
        let id = state.jobs.enqueue(JOB_KIND, input).await?;
        return Ok(Err(super::jobs::accepted(&id)));
    }
    let d = state
        .jobs
        .run(move || decompose(&x, method, &params))
        .await??;
    Ok(Ok(d))
}

async fn post_decompose(State(state): State<AppState>, req: Request) -> ApiResult<Response> {
    let role = req.extensions().get::<Role>().copied();
    let asked = super::auth::asks_for_job(req.headers());
    let body = read_body(req).await?;
    let r: DecomposeRequest = decode_json(&body)?;
    if r.signal.is_empty() {
        return Err(ApiError::bad_request(
            "signal is empty; send the machining error as {\"signal\": [mm, ...]} with at least 16 samples",
        ));
    }
    check_finite("signal", &r.signal)?;
    super::ranges::check_signal_mm("signal", &r.signal)?;
    match run(
        &state,
        r.signal,
        r.method,
        r.params,
        Some((&body, role, asked)),
    )
    .await?
    {
        Ok(v) => Ok(ApiJson(Versioned::new(v)).into_response()),
        Err(accepted) => Ok(accepted),
    }
}

async fn post_measurement_decomposition(
    State(state): State<AppState>,
    _write: RequireWrite,
    PathIds([machine, surface, id]): PathIds<3>,
    req: Request,
) -> ApiResult<Response> {
    let body = read_body(req).await?;
    let r: MeasurementRequest = if body.iter().all(|b| b.is_ascii_whitespace()) {
        MeasurementRequest::default()
    } else {
        decode_json(&body)?
    };
    let surf = require_surface(&state, &machine, &surface).await?;
    let m = require_measurement(&state, &machine, &surface, &id).await?;
    if m.deviations.len() != surf.nu * surf.nv {
        return Err(ApiError::conflict(format!(
            "measurement '{id}' has {} deviations but surface '{surface}' now has {} x {} points; \
             upload the measurement again for the current surface",
            m.deviations.len(),
            surf.nu,
            surf.nv
        )));
    }
    let mut params = r.params;
    if params.nu.is_some() || params.nv.is_some() {
        return Err(ApiError::bad_request(
            "params.nu/params.nv come from the surface's grid here; leave them out",
        ));
    }
    params.nu = Some(surf.nu);
    params.nv = Some(surf.nv);
    let key = format!("{surface}/{id}");
    // Always answered directly, so the result can be stored as the current decomposition.
    match run(&state, m.deviations, r.method, params, None).await? {
        Ok(d) => {
            let v = stamp(serde_json::to_value(&d).map_err(ApiError::internal)?);
            state.store.put_doc(&machine, DOC_KIND, &key, &v).await?;
            Ok(ApiJson(v).into_response())
        }
        Err(accepted) => Ok(accepted),
    }
}

async fn get_measurement_decomposition(
    State(state): State<AppState>,
    PathIds([machine, surface, id]): PathIds<3>,
) -> ApiResult<ApiJson<Value>> {
    require_measurement(&state, &machine, &surface, &id).await?;
    let key = format!("{surface}/{id}");
    match state.store.get_doc(&machine, DOC_KIND, &key).await? {
        Some(v) => Ok(ApiJson(v)),
        None => Err(ApiError::not_found(format!(
            "measurement '{id}' has no stored decomposition: POST \
             /v1/machines/{machine}/surfaces/{surface}/measurements/{id}/decomposition first"
        ))),
    }
}
