//! Probe measurements: `POST/GET .../surfaces/{surface}/measurements`,
//! `GET/DELETE .../measurements/{id}` (JSON or CSV in; JSON or CSV out).

use std::collections::HashMap;

use axum::Router;
use axum::extract::{Query, Request, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::{Value, json};

use super::AppState;
use super::auth::{RequireAdmin, RequireWrite};
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, is_csv_body};
use super::intake::parse_streaming;
use super::lookup::{
    require_measurement, require_surface, require_surface_grid, require_surface_shared,
};
use super::upload::{ProbeData, read_csv_upload, read_json_upload};
use crate::api::id::{Id, PathIds};
use crate::signal::flyers::{FlyerParams, suspects};
use crate::store::{Inserted, Measurement};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/measurements",
            get(list_measurements).post(post_measurement),
        )
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/measurements/{id}",
            get(get_measurement).delete(delete_measurement),
        )
}

/// True when the client asks for CSV (`Accept: text/csv`).
pub fn wants_csv(headers: &HeaderMap) -> bool {
    headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|a| a.contains("text/csv"))
}

async fn post_measurement(
    State(state): State<AppState>,
    _write: RequireWrite,
    PathIds([machine, surface]): PathIds<2>,
    Query(query): Query<HashMap<String, String>>,
    req: Request,
) -> ApiResult<Response> {
    let is_csv = is_csv_body(
        req.headers(),
        "application/json ({\"points\"} or {\"deviations\"}) \
                 or text/csv (header x,y,z or deviation)",
    )?;
    // Before the body is read: the surface exists (404) and, for CSV, whose id can only
    // come from the query, the id is free (409). A refused upload is never read.
    let n = require_surface_grid(&state, &machine, &surface).await?;
    let query_id = query
        .get("id")
        .map(|id| Id::parse("measurement", id))
        .transpose()?;
    if is_csv && let Some(id) = &query_id {
        refuse_taken(&state, &machine, &surface, id).await?;
    }
    // An upload without an id under an Idempotency-Key takes the key's id: a retry after its
    // first try's instance died meets the first try's record (a replay), not a twin.
    let keyed = req
        .extensions()
        .get::<super::idempotency::KeyedId>()
        .map(|k| k.0.clone());
    // Parsed as it arrives; a CSV with more rows than the grid is refused at the first one.
    let (data, body_id) = parse_streaming(req.into_body(), move |input| {
        if is_csv {
            read_csv_upload(input, Some(n)).map(|d| (d, None))
        } else {
            read_json_upload(input)
        }
    })
    .await?;
    let id = match (body_id, query_id) {
        (Some(id), _) => Id::parse("measurement", &id)?,
        (None, Some(id)) => id,
        (None, None) => Id::parse(
            "measurement",
            &keyed.unwrap_or_else(|| uuid::Uuid::now_v7().to_string()),
        )?,
    };
    let surf = require_surface_shared(&state, &machine, &surface).await?;
    let (nu, nv) = (surf.nu, surf.nv);
    if data.len() != n {
        return Err(ApiError::bad_request(format!(
            "{} has {} entries but surface '{surface}' has {n} grid points (nu*nv = {}*{}); \
             send one per grid point in nominal order (u fastest)",
            data.field(),
            data.len(),
            surf.nu,
            surf.nv
        )));
    }
    // A taken id is decided by the insert below, not by a look before it: uploads of one id
    // that race store one record, and an upload that repeats the stored one (a retry whose
    // answer was lost) is answered as the first was.
    let limits = state.limits;
    // One short blocking task (not a worker-pool slot: an upload is never turned away
    // because decompositions fill the pool): pairing, the flyer search, and the record.
    let record = (id.to_string(), machine.to_string(), surface.to_string());
    let (m, outliers) = tokio::task::spawn_blocking(move || {
        let (deviations, points) = match data {
            ProbeData::Deviations(d) => limits
                .check_deviations("deviations", &d)
                .map(|()| (d, None))?,
            ProbeData::Points(p) => {
                super::ranges::check_coords("points", &p)?;
                let d = limits.pair_points(&p, &surf.points, &surf.normals, surf.nu)?;
                (d, Some(p))
            }
        };
        drop(surf);
        let outliers = suspects(&deviations, Some((nu, nv)), &FlyerParams::default()).0;
        let m = Measurement::new(record.0, record.1, record.2, deviations, points);
        Ok::<_, ApiError>((m, outliers))
    })
    .await
    .map_err(ApiError::internal)??;
    let warnings = flyer_warnings(&outliers, &m.deviations, nu);
    let (id, n, max_abs, mean_abs) = (m.id.clone(), m.deviations.len(), m.max_abs, m.mean_abs);
    // The arrays go into the record's BLOBs and are dropped before the write.
    let replayed = match state.store.insert_measurement_owned(m).await? {
        Inserted::Created => false,
        Inserted::Same => true,
        Inserted::Different => return Err(taken(&surface, &id)),
    };
    let mut resp = (
        StatusCode::CREATED,
        [(
            header::LOCATION,
            format!("/v1/machines/{machine}/surfaces/{surface}/measurements/{id}"),
        )],
        ApiJson(json!({
            "id": id, "n": n, "max_abs": max_abs, "mean_abs": mean_abs,
            "outliers": outliers, "warnings": warnings,
        })),
    )
        .into_response();
    if replayed {
        // The same data under the same id: the first upload's answer, marked as a replay.
        resp.headers_mut().insert(
            super::idempotency::REPLAYED,
            header::HeaderValue::from_static("true"),
        );
    }
    Ok(resp)
}

/// The 409 of a measurement id that holds other data.
fn taken(surface: &Id, id: &str) -> ApiError {
    ApiError::conflict(format!(
        "measurement '{id}' already exists on surface '{surface}' with other data; choose \
         another id or DELETE it first"
    ))
}

/// 409 when measurement `id` is taken on the surface (a CSV upload, whose id comes from the
/// query, is refused before its body is read).
async fn refuse_taken(state: &AppState, machine: &Id, surface: &Id, id: &Id) -> ApiResult<()> {
    if state.store.measurement_exists(machine, surface, id).await? {
        return Err(ApiError::conflict(format!(
            "measurement '{id}' already exists on surface '{surface}'; choose another id or \
             DELETE it first (a retry of a CSV upload is answered as the first only with an \
             Idempotency-Key header)"
        )));
    }
    Ok(())
}

/// The upload's warning about suspected probe flyers (none when `outliers` is empty).
fn flyer_warnings(outliers: &[usize], deviations: &[f64], nu: usize) -> Vec<String> {
    if outliers.is_empty() {
        return Vec::new();
    }
    const SHOWN: usize = 10;
    let mut list: Vec<String> = outliers
        .iter()
        .take(SHOWN)
        .map(|&k| {
            format!(
                "k={k} (iu {}, iv {}) {:+.4} mm",
                k % nu,
                k / nu,
                deviations[k]
            )
        })
        .collect();
    if outliers.len() > SHOWN {
        list.push(format!("and {} more", outliers.len() - SHOWN));
    }
    vec![format!(
        "{} point(s) look like probe flyers (a chip, a coolant drop, a missed trigger): they \
         stand far off their neighbours: {}. The decomposition leaves them out of the \
         systematic part and fills their compensation from their neighbours; re-probe them \
         if they are real.",
        outliers.len(),
        list.join(", ")
    )]
}

async fn get_measurement(
    State(state): State<AppState>,
    PathIds([machine, surface, id]): PathIds<3>,
    headers: HeaderMap,
) -> ApiResult<Response> {
    let m = require_measurement(&state, &machine, &surface, &id).await?;
    if wants_csv(&headers) {
        let mut out = String::with_capacity(m.deviations.len() * 48);
        match &m.points {
            Some(points) => {
                out.push_str("x,y,z,deviation\n");
                for (p, d) in points.iter().zip(&m.deviations) {
                    out.push_str(&format!("{},{},{},{}\n", p[0], p[1], p[2], d));
                }
            }
            None => {
                out.push_str("deviation\n");
                for d in &m.deviations {
                    out.push_str(&format!("{d}\n"));
                }
            }
        }
        return Ok(([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], out).into_response());
    }
    let mut body = json!({
        "id": m.id,
        "n": m.deviations.len(),
        "max_abs": m.max_abs,
        "mean_abs": m.mean_abs,
        "deviations": m.deviations,
    });
    if let Some(points) = m.points {
        body["points"] = json!(points);
    }
    Ok(ApiJson(body).into_response())
}

async fn list_measurements(
    State(state): State<AppState>,
    PathIds([machine, surface]): PathIds<2>,
) -> ApiResult<ApiJson<Value>> {
    require_surface(&state, &machine, &surface).await?;
    let list = state.store.list_measurements(&machine, &surface).await?;
    Ok(ApiJson(json!({ "measurements": list })))
}

async fn delete_measurement(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine, surface, id]): PathIds<3>,
) -> ApiResult<StatusCode> {
    require_measurement(&state, &machine, &surface, &id).await?;
    state
        .store
        .delete_measurement(&machine, &surface, &id)
        .await?;
    Ok(StatusCode::NO_CONTENT)
}
