//! Loading the records a route needs, with the standard 404 sentences. Ids come in parsed
//! ([`Id`]), so nothing unchecked reaches the store.

use axum::extract::{MatchedPath, Request, State};
use axum::http::Method;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::id::Id;
use crate::motion::{MachineDef, stored_definition};
use crate::store::{Measurement, Surface};

/// The machine's stored definition, or 404 "machine 'm1' does not exist: PUT /v1/machines/m1 first".
pub async fn require_machine(state: &AppState, machine: &Id) -> ApiResult<serde_json::Value> {
    state.store.get_machine(machine).await?.ok_or_else(|| {
        ApiError::not_found(format!(
            "machine '{machine}' does not exist: PUT /v1/machines/{machine} first"
        ))
    })
}

/// The machine's stored definition parsed for a simulation: 404 as [`require_machine`], 422
/// naming the PUT that fixes a definition stored before PUT checked everything.
pub async fn require_machine_def(state: &AppState, machine: &Id) -> ApiResult<MachineDef> {
    let def = require_machine(state, machine).await?;
    Ok(stored_definition(machine, &def)?)
}

/// The surface, or 404 naming the missing machine or surface and the PUT that creates it.
pub async fn require_surface(state: &AppState, machine: &Id, surface: &Id) -> ApiResult<Surface> {
    if let Some(s) = state.store.get_surface(machine, surface).await? {
        return Ok(s);
    }
    require_machine(state, machine).await?;
    Err(ApiError::not_found(format!(
        "surface '{surface}' of machine '{machine}' does not exist: \
         PUT /v1/machines/{machine}/surfaces/{surface} first"
    )))
}

/// Like [`require_surface`], the surface shared with other requests (one copy per surface,
/// [`crate::store::Store::get_surface_shared`]): for uploads, which only read it.
pub async fn require_surface_shared(
    state: &AppState,
    machine: &Id,
    surface: &Id,
) -> ApiResult<std::sync::Arc<Surface>> {
    if let Some(s) = state.store.get_surface_shared(machine, surface).await? {
        return Ok(s);
    }
    require_machine(state, machine).await?;
    Err(ApiError::not_found(format!(
        "surface '{surface}' of machine '{machine}' does not exist: \
         PUT /v1/machines/{machine}/surfaces/{surface} first"
    )))
}

/// 404 as [`require_machine`] unless the machine exists; its definition is not read.
pub async fn require_machine_exists(state: &AppState, machine: &Id) -> ApiResult<()> {
    if state.store.machine_exists(machine).await? {
        return Ok(());
    }
    Err(ApiError::not_found(format!(
        "machine '{machine}' does not exist: PUT /v1/machines/{machine} first"
    )))
}

/// The surface's number of grid points `nu * nv`, or 404 as [`require_surface`]; its arrays
/// are not read (the check made before a request body is).
pub async fn require_surface_grid(
    state: &AppState,
    machine: &Id,
    surface: &Id,
) -> ApiResult<usize> {
    if let Some((nu, nv)) = state.store.surface_grid(machine, surface).await? {
        return Ok(nu * nv);
    }
    require_machine_exists(state, machine).await?;
    Err(ApiError::not_found(format!(
        "surface '{surface}' of machine '{machine}' does not exist: \
         PUT /v1/machines/{machine}/surfaces/{surface} first"
    )))
}

/// The measurement, or 404 naming what is missing.
pub async fn require_measurement(
    state: &AppState,
    machine: &Id,
    surface: &Id,
    id: &Id,
) -> ApiResult<Measurement> {
    if let Some(m) = state.store.get_measurement(machine, surface, id).await? {
        return Ok(m);
    }
    require_surface(state, machine, surface).await?;
    Err(ApiError::not_found(format!(
        "measurement '{id}' of surface '{surface}' (machine '{machine}') does not exist: \
         POST the probe data to /v1/machines/{machine}/surfaces/{surface}/measurements first"
    )))
}

/// What must exist before the body of a request to `route` (a matched route pattern) is read:
/// the surface for routes below one, the machine for the other routes below a machine,
/// nothing else. The compensated-program routes are left to their handler (a program can be
/// compensated with a stored map alone).
pub fn parents_of(method: &Method, route: &str) -> Parents {
    if !matches!(*method, Method::POST | Method::PUT | Method::PATCH) {
        return Parents::None;
    }
    if route.starts_with("/v1/machines/{machine}/surfaces/{surface}/") {
        Parents::Surface
    } else if route.starts_with("/v1/machines/{machine}/") && !route.contains("/compensated-") {
        Parents::Machine
    } else {
        Parents::None
    }
}

/// The records a request's path names that [`parents_exist`] checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Parents {
    /// Nothing is checked.
    None,
    /// The machine must exist.
    Machine,
    /// The machine and surface must exist.
    Surface,
}

/// Route middleware: before a body is read, the machine or surface its path names must
/// exist (404 as the handlers word it), with a query that reads no definition or array, so
/// a 120 MiB upload to an unknown surface is answered at once and never read. Ids that do
/// not parse are left to the handler's 400.
pub async fn parents_exist(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map(|m| m.as_str().to_string())
        .unwrap_or_default();
    let parents = parents_of(req.method(), &route);
    if parents != Parents::None {
        let segments: Vec<&str> = req.uri().path().split('/').collect();
        // "", "v1", "machines", machine, "surfaces", surface, ...
        let machine = segments.get(3).and_then(|m| Id::parse("machine", m).ok());
        let surface = segments.get(5).and_then(|s| Id::parse("surface", s).ok());
        let checked = match (parents, machine, surface) {
            (Parents::Machine, Some(m), _) => require_machine_exists(&state, &m).await,
            (Parents::Surface, Some(m), Some(s)) => {
                require_surface_grid(&state, &m, &s).await.map(|_| ())
            }
            _ => Ok(()),
        };
        if let Err(e) = checked {
            return e.into_response();
        }
    }
    next.run(req).await
}
