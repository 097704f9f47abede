//! Loading the records a route needs, with the standard 404 sentences.

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::check_id;
use crate::store::{Measurement, Surface};

/// The machine's stored definition, or 404 "machine 'm1' does not exist: PUT /v1/machines/m1 first".
/// Also rejects an invalid id with 400.
pub async fn require_machine(state: &AppState, machine: &str) -> ApiResult<serde_json::Value> {
    check_id("machine", machine)?;
    state.store.get_machine(machine).await?.ok_or_else(|| {
        ApiError::not_found(format!(
            "machine '{machine}' does not exist: PUT /v1/machines/{machine} first"
        ))
    })
}

/// The surface, or 404 naming the missing machine or surface and the PUT that creates it.
pub async fn require_surface(state: &AppState, machine: &str, surface: &str) -> ApiResult<Surface> {
    check_id("machine", machine)?;
    check_id("surface", surface)?;
    if let Some(s) = state.store.get_surface(machine, surface).await? {
        return Ok(s);
    }
    require_machine(state, machine).await?;
    Err(ApiError::not_found(format!(
        "surface '{surface}' of machine '{machine}' does not exist: \
         PUT /v1/machines/{machine}/surfaces/{surface} first"
    )))
}

/// The measurement, or 404 naming what is missing.
pub async fn require_measurement(
    state: &AppState,
    machine: &str,
    surface: &str,
    id: &str,
) -> ApiResult<Measurement> {
    check_id("machine", machine)?;
    check_id("surface", surface)?;
    check_id("measurement", id)?;
    if let Some(m) = state.store.get_measurement(machine, surface, id).await? {
        return Ok(m);
    }
    require_surface(state, machine, surface).await?;
    Err(ApiError::not_found(format!(
        "measurement '{id}' of surface '{surface}' (machine '{machine}') does not exist: \
         POST the probe data to /v1/machines/{machine}/surfaces/{surface}/measurements first"
    )))
}
