//! Handlers of the volumetric-map resource: fit and store (PUT), read (GET), delete,
//! predict and the compensation table, with the model-store access they share.

use std::collections::HashMap;

use axum::extract::{Query, Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};

use super::answer::{PredictResponse, summary};
use super::request::{
    MAX_NODES, MAX_POINTS, MAX_SAMPLE_PASSES, MapRequest, PredictRequest, fit_options,
    options_from_query, parse_counts, parse_query, parse_triple,
};
use crate::api::AppState;
use crate::api::auth::RequireAdmin;
use crate::api::error::{ApiError, ApiResult};
use crate::api::extract::{ApiJson, check_points, decode_json, is_csv_body, read_body};
use crate::api::id::{Id, PathIds};
use crate::api::lookup::require_machine;
use crate::api::model_versions::{self, ModelRef, RollbackRequest};
use crate::volumetric::{self, TableSpec, VolumetricData, VolumetricMap};

/// Kind under which the map is kept in the model store.
pub const MODEL_KIND: &str = "volumetric_map";

/// The map stored for `machine`, if any (after checking the machine exists). For other
/// capabilities: the gap diagnosis predicts a part's deviation with
/// [`VolumetricMap::error_at`] or [`volumetric::normal_deviation`].
pub async fn load_map(state: &AppState, machine: &Id) -> ApiResult<Option<VolumetricMap>> {
    require_machine(state, machine).await?;
    match state.store.models().load(machine, None, MODEL_KIND).await? {
        Some(bytes) => Ok(Some(VolumetricMap::from_bytes(&bytes)?)),
        None => Ok(None),
    }
}

async fn require_map(state: &AppState, machine: &Id) -> ApiResult<VolumetricMap> {
    load_map(state, machine).await?.ok_or_else(|| {
        ApiError::not_found(format!(
            "machine '{machine}' has no volumetric map: PUT /v1/machines/{machine}/volumetric-map first"
        ))
    })
}

pub(super) async fn put_map(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
    Query(query): Query<HashMap<String, String>>,
    req: Request,
) -> ApiResult<Response> {
    let is_csv = is_csv_body(
        req.headers(),
        "application/json ({\"nodes\", \"errors\"} or {\"lines\"}) \
                 or text/csv (header x,y,z,dx,dy,dz; options in the query string)",
    )?;
    let body = read_body(req).await?;
    let (request, data) = if is_csv {
        let request = options_from_query(&query)?;
        let text = std::str::from_utf8(&body)
            .map_err(|_| ApiError::bad_request("the CSV body is not UTF-8 text"))?;
        let data = VolumetricData::from_csv(text)?;
        (request, data)
    } else {
        if !query.is_empty() {
            return Err(ApiError::bad_request(
                "with a JSON body put the options in the body, not the query string",
            ));
        }
        let mut request: MapRequest = decode_json(&body)?;
        let data = match (
            request.nodes.take(),
            request.errors.take(),
            request.lines.take(),
        ) {
            (Some(nodes), Some(errors), None) => VolumetricData { nodes, errors },
            (None, None, Some(lines)) => volumetric::additive_grid(&lines)?,
            (Some(_), None, None) => {
                return Err(ApiError::bad_request(
                    "'errors' is missing: send one measured [dx,dy,dz] (mm) per node",
                ));
            }
            (None, Some(_), None) => {
                return Err(ApiError::bad_request(
                    "'nodes' is missing: send the commanded [x,y,z] (mm) of every measured error",
                ));
            }
            (None, None, None) => {
                return Err(ApiError::bad_request(
                    "send either 'nodes' and 'errors' (measured grid) or 'lines' (Wang, Dai & Hong axis lines)",
                ));
            }
            _ => {
                return Err(ApiError::bad_request(
                    "send either 'nodes' and 'errors' or 'lines', not both",
                ));
            }
        };
        (request, data)
    };
    if data.nodes.len() > MAX_NODES {
        return Err(ApiError::payload_too_large(format!(
            "{} nodes: at most {MAX_NODES} per map; thin the grid",
            data.nodes.len()
        )));
    }
    crate::api::ranges::check_coords("nodes", &data.nodes)?;
    crate::api::ranges::check_volumetric_errors("errors", &data.errors)?;
    let options = fit_options(&request)?;
    if let Some(e) = request.epochs
        && e.saturating_mul(data.nodes.len()) > MAX_SAMPLE_PASSES
    {
        return Err(ApiError::bad_request(format!(
            "epochs × nodes = {e} × {} exceeds {MAX_SAMPLE_PASSES} sample passes per network: ask for at most {} epochs",
            data.nodes.len(),
            MAX_SAMPLE_PASSES / data.nodes.len().max(1)
        )));
    }
    require_machine(&state, &machine).await?;
    let existed = state
        .store
        .models()
        .load(&machine, None, MODEL_KIND)
        .await
        .ok()
        .flatten()
        .is_some();
    let mut map = state
        .jobs
        .run(move || volumetric::fit(&data, &options))
        .await??;
    map.truecut_version = Some(crate::version().to_string());
    state
        .store
        .models()
        .save(&machine, None, MODEL_KIND, &map.to_bytes())
        .await?;
    let status = if existed {
        StatusCode::OK
    } else {
        StatusCode::CREATED
    };
    Ok((
        status,
        [(
            header::LOCATION,
            format!("/v1/machines/{machine}/volumetric-map"),
        )],
        ApiJson(summary(&map)),
    )
        .into_response())
}

pub(super) async fn get_map(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    Query(query): Query<HashMap<String, String>>,
) -> ApiResult<ApiJson<serde_json::Value>> {
    let samples: usize = parse_query(&query, "samples")?.unwrap_or(21);
    if !(2..=1001).contains(&samples) {
        return Err(ApiError::bad_request(format!(
            "samples must be between 2 and 1001 positions per axis (default 21), got {samples}"
        )));
    }
    let map = require_map(&state, &machine).await?;
    let mut body = summary(&map);
    let components = state
        .jobs
        .run(move || {
            map.components
                .as_ref()
                .map(|k| volumetric::component_curves(k, samples))
        })
        .await?;
    body["components"] = serde_json::to_value(components).map_err(ApiError::internal)?;
    Ok(ApiJson(body))
}

pub(super) async fn delete_map(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<StatusCode> {
    require_map(&state, &machine).await?;
    state
        .store
        .models()
        .delete(&machine, None, MODEL_KIND)
        .await?;
    Ok(StatusCode::NO_CONTENT)
}

fn map_ref(machine: &Id) -> ModelRef<'_> {
    ModelRef {
        machine,
        surface: None,
        kind: MODEL_KIND,
        path: format!("/v1/machines/{machine}/volumetric-map"),
        made_by: format!("PUT /v1/machines/{machine}/volumetric-map"),
    }
}

pub(super) async fn map_versions(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<ApiJson<serde_json::Value>> {
    require_machine(&state, &machine).await?;
    Ok(ApiJson(
        model_versions::list(&state, &map_ref(&machine)).await?,
    ))
}

pub(super) async fn map_rollback(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
    ApiJson(req): ApiJson<RollbackRequest>,
) -> ApiResult<ApiJson<serde_json::Value>> {
    require_machine(&state, &machine).await?;
    Ok(ApiJson(
        model_versions::rollback(&state, &map_ref(&machine), req).await?,
    ))
}

pub(super) async fn predict(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    ApiJson(req): ApiJson<PredictRequest>,
) -> ApiResult<ApiJson<PredictResponse>> {
    check_points("points", &req.points)?;
    crate::api::ranges::check_coords("points", &req.points)?;
    if req.points.len() > MAX_POINTS {
        return Err(ApiError::payload_too_large(format!(
            "{} points: at most {MAX_POINTS} per request; split them",
            req.points.len()
        )));
    }
    let map = require_map(&state, &machine).await?;
    let model = map.model.kind().name();
    let p = state.jobs.run(move || map.predict(&req.points)).await??;
    Ok(ApiJson(PredictResponse {
        errors: p.errors,
        out_of_box: p.out_of_box,
        model,
    }))
}

pub(super) async fn table(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    Query(query): Query<HashMap<String, String>>,
) -> ApiResult<Response> {
    const KNOWN: [&str; 4] = ["points", "min", "max", "max_points_per_axis"];
    if let Some(k) = query.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown query parameter '{k}': use {}",
            KNOWN.join(", ")
        )));
    }
    let points = query
        .get("points")
        .map(|v| parse_counts(v))
        .transpose()?
        .unwrap_or([11; 3]);
    let min = query
        .get("min")
        .map(|v| parse_triple("min", v))
        .transpose()?;
    let max = query
        .get("max")
        .map(|v| parse_triple("max", v))
        .transpose()?;
    let limit = parse_query::<usize>(&query, "max_points_per_axis")?;
    let map = require_map(&state, &machine).await?;
    let mut spec = TableSpec::over(&map, points);
    spec.min = min.unwrap_or(spec.min);
    spec.max = max.unwrap_or(spec.max);
    spec.max_points_per_axis = limit;
    let csv = state
        .jobs
        .run(move || volumetric::compensation_table_csv(&map, &spec))
        .await??;
    Ok((
        [
            (header::CONTENT_TYPE, "text/csv; charset=utf-8".to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{machine}-volumetric-table.csv\""),
            ),
        ],
        csv,
    )
        .into_response())
}
