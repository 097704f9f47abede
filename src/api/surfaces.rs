//! Nominal surfaces: `PUT/GET/DELETE /v1/machines/{machine}/surfaces/{surface}`,
//! `GET /v1/machines/{machine}/surfaces`.

use std::collections::BTreeMap;

use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde::Deserialize;
use serde_json::value::RawValue;
use serde_json::{Map, Value, json};

use super::AppState;
use super::auth::RequireAdmin;
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, check_len, check_points};
use super::lookup::{require_machine, require_surface};
use crate::api::id::PathIds;
use crate::store::Surface;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/machines/{machine}/surfaces", get(list_surfaces))
        .route(
            "/v1/machines/{machine}/surfaces/{surface}",
            get(get_surface).put(put_surface).delete(delete_surface),
        )
}

/// Largest |‖n‖ − 1| accepted for a normal (normals are then rescaled to unit length).
pub const NORMAL_TOLERANCE: f64 = 1e-3;

/// Top-level keys of a surface definition (HTTP contract "Surfaces", openapi.yaml schema `SurfaceDefinition`; `name` as for machines).
pub const SURFACE_KEYS: [&str; 3] = ["nominal", "tool_radius", "name"];

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Nominal {
    grid: Grid,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Grid {
    nu: usize,
    nv: usize,
    points: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
}

/// Parses and validates a surface PUT body into a [`Surface`] plus the extra top-level
/// fields (`name`, kept verbatim unless null). Unknown keys, at the top and in `nominal` and
/// its `grid`, are refused naming the keys allowed (HTTP contract v1.1, docs/REFERENCES.md). Errors name the field.
pub fn parse_surface(machine: &str, surface: &str, body: &[u8]) -> ApiResult<(Surface, Value)> {
    let top: BTreeMap<String, Box<RawValue>> = super::extract::decode_json(body)?;
    if let Some(k) = top.keys().find(|k| !SURFACE_KEYS.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown key '{k}' in the surface definition: the keys allowed are {}",
            SURFACE_KEYS.join(", ")
        )));
    }
    if let Some(name) = top.get("name").map(|r| r.get())
        && name != "null"
        && !name.starts_with('"')
    {
        return Err(ApiError::bad_request("name must be a string"));
    }
    let nominal = top.get("nominal").ok_or_else(|| {
        ApiError::bad_request(
            "nominal is required: {\"nominal\": {\"grid\": {\"nu\", \"nv\", \"points\", \"normals\"}}}",
        )
    })?;
    let nominal: Nominal =
        serde_path_to_error::deserialize(&mut serde_json::Deserializer::from_str(nominal.get()))
            .map_err(|e| {
                let path = e.path().to_string();
                let field = if path == "." {
                    "nominal".to_string()
                } else {
                    format!("nominal.{path}")
                };
                ApiError::bad_request(format!("{field}: {}", e.inner()))
            })?;
    let tool_radius = match top.get("tool_radius").map(|r| r.get()) {
        None | Some("null") => None,
        Some(raw) => {
            let r: f64 = serde_json::from_str(raw)
                .map_err(|_| ApiError::bad_request("tool_radius must be a number (mm)"))?;
            super::ranges::check_tool_radius("tool_radius", r)?;
            Some(r)
        }
    };
    let mut extra = Map::new();
    for (k, v) in &top {
        if k != "nominal" && k != "tool_radius" && v.get() != "null" {
            let v: Value = serde_json::from_str(v.get())
                .map_err(|e| ApiError::bad_request(format!("{k}: {e}")))?;
            extra.insert(k.clone(), v);
        }
    }
    let Grid {
        nu,
        nv,
        points,
        mut normals,
    } = nominal.grid;
    if nu == 0 || nv == 0 {
        return Err(ApiError::bad_request(format!(
            "nominal.grid.nu and nv must be at least 1, got nu={nu}, nv={nv}"
        )));
    }
    let n = nu
        .checked_mul(nv)
        .ok_or_else(|| ApiError::bad_request("nominal.grid.nu*nv is too large"))?;
    check_points("nominal.grid.points", &points)?;
    super::ranges::check_coords("nominal.grid.points", &points)?;
    check_len("nominal.grid.points", points.len(), n)
        .map_err(|e| ApiError::bad_request(format!("{} (nu*nv = {nu}*{nv})", e.detail())))?;
    check_points("nominal.grid.normals", &normals)?;
    check_len("nominal.grid.normals", normals.len(), n)?;
    for (k, nrm) in normals.iter_mut().enumerate() {
        let len = (nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]).sqrt();
        if (len - 1.0).abs() > NORMAL_TOLERANCE {
            return Err(ApiError::bad_request(format!(
                "nominal.grid.normals[{k}] has length {len:.6}; send unit normals pointing out of the material"
            )));
        }
        for c in nrm.iter_mut() {
            *c /= len;
        }
    }
    Ok((
        Surface {
            machine: machine.to_string(),
            surface: surface.to_string(),
            nu,
            nv,
            points,
            normals,
            tool_radius,
        },
        Value::Object(extra),
    ))
}

fn summary(s: &Surface) -> Value {
    json!({
        "machine": s.machine,
        "surface": s.surface,
        "nu": s.nu,
        "nv": s.nv,
        "n": s.points.len(),
        "tool_radius": s.tool_radius,
    })
}

async fn put_surface(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine, surface]): PathIds<2>,
    req: axum::extract::Request,
) -> ApiResult<Response> {
    if !super::extract::is_json(req.headers()) {
        return Err(ApiError::unsupported_media_type(
            "send the surface with Content-Type: application/json",
        ));
    }
    let body = super::extract::read_body(req).await?;
    let (m, s) = (machine.clone(), surface.clone());
    let (surf, extra) = tokio::task::spawn_blocking(move || parse_surface(&m, &s, &body))
        .await
        .map_err(ApiError::internal)??;
    require_machine(&state, &machine).await?;
    if let Some(old) = state.store.get_surface(&machine, &surface).await?
        && (old.nu, old.nv) != (surf.nu, surf.nv)
    {
        let count = state.store.count_measurements(&machine, &surface).await?;
        if count > 0 {
            return Err(ApiError::conflict(format!(
                "surface '{surface}' has {count} measurement(s) on its {}x{} grid; delete them \
                 (DELETE .../measurements/{{id}}) or use a new surface id before changing the grid to {}x{}",
                old.nu, old.nv, surf.nu, surf.nv
            )));
        }
    }
    let created = state.store.put_surface(&surf, &extra).await?;
    let body = ApiJson(summary(&surf));
    if created {
        Ok((
            StatusCode::CREATED,
            [(
                header::LOCATION,
                format!("/v1/machines/{machine}/surfaces/{surface}"),
            )],
            body,
        )
            .into_response())
    } else {
        Ok((StatusCode::OK, body).into_response())
    }
}

async fn get_surface(
    State(state): State<AppState>,
    PathIds([machine, surface]): PathIds<2>,
) -> ApiResult<ApiJson<Value>> {
    let s = require_surface(&state, &machine, &surface).await?;
    let extra = state
        .store
        .get_surface_extra(&machine, &surface)
        .await?
        .unwrap_or_else(|| json!({}));
    let mut out = match extra {
        Value::Object(m) => m,
        _ => Map::new(),
    };
    out.insert(
        "nominal".into(),
        json!({"grid": {"nu": s.nu, "nv": s.nv, "points": s.points, "normals": s.normals}}),
    );
    out.insert("tool_radius".into(), json!(s.tool_radius));
    Ok(ApiJson(Value::Object(out)))
}

async fn list_surfaces(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<ApiJson<Value>> {
    require_machine(&state, &machine).await?;
    let surfaces = state.store.list_surfaces(&machine).await?;
    Ok(ApiJson(json!({ "surfaces": surfaces })))
}

async fn delete_surface(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine, surface]): PathIds<2>,
) -> ApiResult<StatusCode> {
    require_surface(&state, &machine, &surface).await?;
    state.store.delete_surface(&machine, &surface).await?;
    Ok(StatusCode::NO_CONTENT)
}
