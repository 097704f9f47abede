//! Normal-offset compensation (openapi.yaml; Chen et al. 2024 §4.3):
//! `GET /v1/machines/{machine}/surfaces/{surface}/compensation?measurement={id}` as JSON or
//! (`Accept: text/csv`) CSV `x,y,z,i,j,k,offset`. Extensions: `nu=&nv=` resamples the reconstructed
//! compensated surface at that density; `cl=true` adds compensated ball-end cutter-location points
//! (CL' = CL − offset·n) for `tool_radius` (query, else the surface's). Also the one
//! `From<compensation::Error> for ApiError`.

use std::collections::HashMap;

use axum::Router;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::Value;

use super::AppState;
use super::decomposition::DOC_KIND;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::lookup::{require_measurement, require_surface};
use super::measurements::wants_csv;
use crate::api::id::{Id, PathIds};
use crate::compensation::{self, CompensatedGrid, CompensatedSurface, compensate_points};
use crate::signal::{DecomposeParams, Method, decompose};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route(
        "/v1/machines/{machine}/surfaces/{surface}/compensation",
        get(get_compensation),
    )
}

const KNOWN: [&str; 5] = ["measurement", "nu", "nv", "cl", "tool_radius"];

fn parse<T: std::str::FromStr>(
    q: &HashMap<String, String>,
    field: &str,
    what: &str,
) -> ApiResult<Option<T>> {
    q.get(field)
        .map(|v| {
            v.parse::<T>().map_err(|_| {
                ApiError::bad_request(format!("query parameter {field}='{v}' must be {what}"))
            })
        })
        .transpose()
}

/// The systematic error (offsets, mm) of the measurement's stored decomposition, or of a
/// fresh default (coarse-to-fine) one when none was stored.
async fn offsets(
    state: &AppState,
    machine: &Id,
    surface: &Id,
    id: &Id,
    nu: usize,
    nv: usize,
) -> ApiResult<(Vec<f64>, Vec<usize>)> {
    let m = require_measurement(state, machine, surface, id).await?;
    let key = format!("{surface}/{id}");
    if let Some(doc) = state.store.get_doc(machine, DOC_KIND, &key).await? {
        if let Some(arr) = doc.get("systematic").and_then(Value::as_array) {
            let v: Option<Vec<f64>> = arr.iter().map(Value::as_f64).collect();
            if let Some(v) = v.filter(|v| v.len() == nu * nv) {
                // Decompositions stored before the flyer screen have no `outliers`.
                let outliers = doc
                    .get("outliers")
                    .and_then(Value::as_array)
                    .map(|a| {
                        a.iter()
                            .filter_map(Value::as_u64)
                            .map(|k| k as usize)
                            .collect()
                    })
                    .unwrap_or_default();
                return Ok((v, outliers));
            }
        }
    }
    if m.deviations.len() != nu * nv {
        return Err(ApiError::conflict(format!(
            "measurement '{id}' has {} deviations but surface '{surface}' has {nu} x {nv} points; \
             upload the measurement again for the current surface",
            m.deviations.len()
        )));
    }
    let params = DecomposeParams {
        nu: Some(nu),
        nv: Some(nv),
        ..Default::default()
    };
    let devs = m.deviations;
    let d = state
        .jobs
        .run(move || decompose(&devs, Method::CoarseToFine, &params))
        .await??;
    Ok((d.systematic, d.outliers))
}

fn csv(grid: &CompensatedGrid) -> String {
    let mut out = String::with_capacity(grid.points.len() * 96);
    out.push_str("x,y,z,i,j,k,offset");
    if grid.cl.is_some() {
        out.push_str(",cl_x,cl_y,cl_z");
    }
    out.push('\n');
    for k in 0..grid.points.len() {
        let (p, n) = (grid.points[k], grid.normals[k]);
        out.push_str(&format!(
            "{},{},{},{},{},{},{}",
            p[0], p[1], p[2], n[0], n[1], n[2], grid.offsets[k]
        ));
        if let Some(cl) = &grid.cl {
            out.push_str(&format!(",{},{},{}", cl[k][0], cl[k][1], cl[k][2]));
        }
        out.push('\n');
    }
    out
}

async fn get_compensation(
    State(state): State<AppState>,
    PathIds([machine, surface]): PathIds<2>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
) -> ApiResult<Response> {
    if let Some(k) = q.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown query parameter '{k}'; use measurement, nu, nv, cl, tool_radius"
        )));
    }
    let Some(id) = q.get("measurement").cloned() else {
        return Err(ApiError::bad_request(
            "query parameter measurement is required: ?measurement=<measurement id>",
        ));
    };
    let nu2: Option<usize> = parse(&q, "nu", "a whole number of points (2..2000)")?;
    let nv2: Option<usize> = parse(&q, "nv", "a whole number of points (2..2000)")?;
    let cl: bool = parse(&q, "cl", "true or false")?.unwrap_or(false);
    let radius: Option<f64> = parse(&q, "tool_radius", "a tool radius in mm")?;
    if let Some(r) = radius {
        super::ranges::check_tool_radius("query parameter tool_radius", r)?;
    }
    if nu2.is_some() != nv2.is_some() {
        return Err(ApiError::bad_request(
            "give both nu and nv (the resampling density) or neither",
        ));
    }
    let surf = require_surface(&state, &machine, &surface).await?;
    let id = Id::parse("measurement", &id)?;
    let (offs, outliers) = offsets(&state, &machine, &surface, &id, surf.nu, surf.nv).await?;
    let radius = if cl {
        match radius.or(surf.tool_radius) {
            Some(r) => Some(r),
            None => {
                return Err(ApiError::unprocessable(format!(
                    "cl=true needs a tool radius: add &tool_radius=<mm> or PUT surface '{surface}' with \"tool_radius\""
                )));
            }
        }
    } else {
        None
    };
    let (nu, nv) = (surf.nu, surf.nv);
    let grid = state
        .jobs
        .run(move || -> Result<CompensatedGrid, compensation::Error> {
            match (nu2, nv2) {
                (Some(a), Some(b)) => {
                    CompensatedSurface::new(nu, nv, &surf.points, &surf.normals, &offs)?
                        .resample(a, b, radius)
                }
                _ => {
                    let points = compensate_points(&surf.points, &surf.normals, &offs)?;
                    let cl = radius.map(|r| {
                        points
                            .iter()
                            .zip(&surf.normals)
                            .map(|(p, n)| [p[0] + r * n[0], p[1] + r * n[1], p[2] + r * n[2]])
                            .collect()
                    });
                    Ok(CompensatedGrid {
                        nu,
                        nv,
                        points,
                        normals: surf.normals,
                        offsets: offs,
                        cl,
                    })
                }
            }
        })
        .await??;
    if wants_csv(&headers) {
        return Ok((
            [(header::CONTENT_TYPE, "text/csv; charset=utf-8")],
            csv(&grid),
        )
            .into_response());
    }
    // The flyers (grid indices of the measurement) whose offsets came from their neighbours.
    let mut body = serde_json::to_value(&grid).map_err(ApiError::internal)?;
    body["outliers"] = serde_json::json!(outliers);
    Ok(ApiJson(body).into_response())
}
