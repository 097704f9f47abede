//! Loading the records a route needs, with the standard 404 sentences. Ids come in parsed
//! ([`Id`]), so nothing unchecked reaches the store.

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
