//! Volumetric error maps (CONTRACT "Volumetric error map"; seeds 001, 004; ISO 230-1):
//! `PUT/GET/DELETE /v1/machines/{machine}/volumetric-map`, `POST .../predict`,
//! `GET .../table` (compensation table CSV). Also the one `From<volumetric::Error> for
//! ApiError` and [`load_map`] for other capabilities (the gap diagnosis).

use std::collections::HashMap;

use axum::Router;
use axum::extract::{Path, Query, Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::AppState;
use super::auth::RequireAdmin;
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, check_id, check_points, content_type, decode_json, read_body};
use super::lookup::require_machine;
use crate::volumetric::{
    self, AxisLines, FitOptions, ModelKind, NetworkOptions, ResidualKind, TableSpec,
    VolumetricData, VolumetricMap,
};

/// Kind under which the map is kept in the model store.
pub const MODEL_KIND: &str = "volumetric_map";
/// Most nodes fitted synchronously (CONTRACT: sync up to 20,000 nodes).
pub const MAX_NODES: usize = 20_000;
/// Most points predicted in one request (CONTRACT: sync up to 100,000 points).
pub const MAX_POINTS: usize = 100_000;
/// Most training epochs a client may ask for.
pub const MAX_EPOCHS: usize = 20_000;
/// Most epochs × nodes a client may ask for per network (auto trains up to 17 networks
/// in its cross-validation; this keeps a request under about a minute).
pub const MAX_SAMPLE_PASSES: usize = 4_000_000;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v1/machines/{machine}/volumetric-map",
            get(get_map).put(put_map).delete(delete_map),
        )
        .route(
            "/v1/machines/{machine}/volumetric-map/predict",
            post(predict),
        )
        .route("/v1/machines/{machine}/volumetric-map/table", get(table))
}

/// Options that may come in the JSON body or, for CSV uploads, the query string.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct MapRequest {
    nodes: Option<Vec<[f64; 3]>>,
    errors: Option<Vec<[f64; 3]>>,
    lines: Option<AxisLines>,
    model: Option<String>,
    tool_offset_mm: Option<[f64; 3]>,
    degree: Option<usize>,
    residual: Option<String>,
    max_points_per_axis: Option<usize>,
    hidden: Option<usize>,
    epochs: Option<usize>,
    seed: Option<u64>,
    sigmoid_output: Option<bool>,
}

fn parse_triple(field: &str, v: &str) -> ApiResult<[f64; 3]> {
    let parts: Vec<Option<f64>> = v
        .split(',')
        .map(|s| s.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect();
    match parts.as_slice() {
        [Some(a), Some(b), Some(c)] => Ok([*a, *b, *c]),
        _ => Err(ApiError::bad_request(format!(
            "{field} must be three finite numbers separated by commas, e.g. {field}=0,0,-150 (got '{v}')"
        ))),
    }
}

fn parse_query<T: std::str::FromStr>(
    q: &HashMap<String, String>,
    field: &str,
) -> ApiResult<Option<T>> {
    q.get(field)
        .map(|v| {
            v.parse::<T>().map_err(|_| {
                ApiError::bad_request(format!(
                    "query parameter {field}='{v}' is not a valid value"
                ))
            })
        })
        .transpose()
}

fn options_from_query(q: &HashMap<String, String>) -> ApiResult<MapRequest> {
    const KNOWN: [&str; 9] = [
        "model",
        "tool_offset_mm",
        "degree",
        "residual",
        "max_points_per_axis",
        "hidden",
        "epochs",
        "seed",
        "sigmoid_output",
    ];
    if let Some(k) = q.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown query parameter '{k}': use {}",
            KNOWN.join(", ")
        )));
    }
    Ok(MapRequest {
        model: q.get("model").cloned(),
        tool_offset_mm: q
            .get("tool_offset_mm")
            .map(|v| parse_triple("tool_offset_mm", v))
            .transpose()?,
        degree: parse_query(q, "degree")?,
        residual: q.get("residual").cloned(),
        max_points_per_axis: parse_query(q, "max_points_per_axis")?,
        hidden: parse_query(q, "hidden")?,
        epochs: parse_query(q, "epochs")?,
        seed: parse_query(q, "seed")?,
        sigmoid_output: parse_query(q, "sigmoid_output")?,
        ..MapRequest::default()
    })
}

fn fit_options(r: &MapRequest) -> ApiResult<FitOptions> {
    let d = FitOptions::default();
    let model = match &r.model {
        Some(m) => ModelKind::parse(m)?,
        None => ModelKind::Auto,
    };
    if let Some(e) = r.epochs
        && !(1..=MAX_EPOCHS).contains(&e)
    {
        return Err(ApiError::bad_request(format!(
            "epochs must be between 1 and {MAX_EPOCHS} (default: about 40,000 mini-batch steps), got {e}"
        )));
    }
    let residual = match r.residual.as_deref() {
        None => d.residual,
        Some(s) => ResidualKind::parse(s).ok_or_else(|| {
            ApiError::bad_request(format!(
                "residual must be \"spline\" or \"network\" (what the hybrid fits to the kinematic model's residual), got '{s}'"
            ))
        })?,
    };
    Ok(FitOptions {
        model,
        tool_offset_mm: r.tool_offset_mm.unwrap_or(d.tool_offset_mm),
        degree: r.degree.unwrap_or(d.degree),
        residual,
        max_points_per_axis: r.max_points_per_axis,
        network: NetworkOptions {
            hidden: r.hidden.unwrap_or(d.network.hidden),
            sigmoid_output: r.sigmoid_output.unwrap_or(d.network.sigmoid_output),
            epochs: r.epochs,
            seed: r.seed.unwrap_or(d.network.seed),
        },
        ..d
    })
}

/// The map stored for `machine`, if any (after checking the machine exists). For other
/// capabilities: the gap diagnosis predicts a part's deviation with
/// [`VolumetricMap::error_at`] or [`volumetric::normal_deviation`].
pub async fn load_map(state: &AppState, machine: &str) -> ApiResult<Option<VolumetricMap>> {
    require_machine(state, machine).await?;
    match state.store.models().load(machine, None, MODEL_KIND).await? {
        Some(bytes) => Ok(Some(VolumetricMap::from_bytes(&bytes)?)),
        None => Ok(None),
    }
}

async fn require_map(state: &AppState, machine: &str) -> ApiResult<VolumetricMap> {
    load_map(state, machine).await?.ok_or_else(|| {
        ApiError::not_found(format!(
            "machine '{machine}' has no volumetric map: PUT /v1/machines/{machine}/volumetric-map first"
        ))
    })
}

fn summary(map: &VolumetricMap) -> serde_json::Value {
    // which residual part a hybrid carries (null for the other models)
    let residual = match &map.model {
        volumetric::Model::Hybrid(h) => match h.residual_kind() {
            ResidualKind::Spline => Some("spline"),
            ResidualKind::Network => Some("network"),
        },
        _ => None,
    };
    // how the ISO 230-1 error motions are represented (the kinematic part, when fitted)
    let error_motions = map.components.as_ref().map(|k| {
        json!({
            "basis": k.basis,
            "terms_per_axis": k.degree.map(|d| d + 1),
            "smoothing": k.smoothing,
            "effective_parameters": k.effective_parameters,
        })
    });
    json!({
        "model": map.model.kind().name(),
        "residual": residual,
        "error_motions": error_motions,
        "requested": map.options.model.name(),
        "parameter_count": map.model.parameter_count(),
        "n_nodes": map.n_nodes,
        "cv_scheme": map.cv_scheme,
        "scores": map.scores,
        "fit_rms_mm": map.fit_rms_mm,
        "bounds": map.bounds,
        "tool_offset_mm": map.options.tool_offset_mm,
        "units": {"lengths": "mm", "errors": "mm", "cv_rms_mm": "mm"},
    })
}

async fn put_map(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    Path(machine): Path<String>,
    Query(query): Query<HashMap<String, String>>,
    req: Request,
) -> ApiResult<Response> {
    check_id("machine", &machine)?;
    let is_csv = match content_type(req.headers()).as_deref() {
        Some("application/json") => false,
        Some(ct) if ct.starts_with("application/") && ct.ends_with("+json") => false,
        Some("text/csv" | "text/plain" | "application/csv") => true,
        _ => {
            return Err(ApiError::unsupported_media_type(
                "send Content-Type: application/json ({\"nodes\", \"errors\"} or {\"lines\"}) \
                 or text/csv (header x,y,z,dx,dy,dz; options in the query string)",
            ));
        }
    };
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
                    "send either 'nodes' and 'errors' (measured grid) or 'lines' (seed 004 axis lines)",
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
    let map = state
        .jobs
        .run(move || volumetric::fit(&data, &options))
        .await??;
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

async fn get_map(
    State(state): State<AppState>,
    Path(machine): Path<String>,
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

async fn delete_map(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    Path(machine): Path<String>,
) -> ApiResult<StatusCode> {
    require_map(&state, &machine).await?;
    state
        .store
        .models()
        .delete(&machine, None, MODEL_KIND)
        .await?;
    Ok(StatusCode::NO_CONTENT)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PredictRequest {
    points: Vec<[f64; 3]>,
}

#[derive(Debug, Serialize)]
struct PredictResponse {
    errors: Vec<[f64; 3]>,
    out_of_box: Vec<bool>,
    model: &'static str,
}

async fn predict(
    State(state): State<AppState>,
    Path(machine): Path<String>,
    ApiJson(req): ApiJson<PredictRequest>,
) -> ApiResult<ApiJson<PredictResponse>> {
    check_id("machine", &machine)?;
    check_points("points", &req.points)?;
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

fn parse_counts(v: &str) -> ApiResult<[usize; 3]> {
    let parts: Vec<Option<usize>> = v.split(',').map(|s| s.trim().parse().ok()).collect();
    match parts.as_slice() {
        [Some(n)] => Ok([*n; 3]),
        [Some(a), Some(b), Some(c)] => Ok([*a, *b, *c]),
        _ => Err(ApiError::bad_request(format!(
            "points must be one count or three counts separated by commas, e.g. points=11,9,7 (got '{v}')"
        ))),
    }
}

async fn table(
    State(state): State<AppState>,
    Path(machine): Path<String>,
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
