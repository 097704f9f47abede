//! Effects stored with a machine (openapi.yaml `/v1/machines/{machine}/effects`):
//! `PUT/GET/DELETE`, `GET .../versions` and `POST .../rollback`, versioned like the models
//! (every PUT keeps the previous sets). Also [`for_simulation`]: the stored effects every
//! route that simulates the machine adds, unless its request says `"effects": "none"`.

use axum::Router;
use axum::extract::State;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde_json::{Value, json};
use std::sync::Arc;

use super::AppState;
use super::auth::RequireAdmin;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::id::{Id, PathIds};
use super::lookup::{require_machine, require_machine_def};
use super::model_versions::{self, ModelRef, RollbackRequest};
use crate::gap::adopted::{AxisInfo, EffectSet, StoredEffects, check};
use crate::motion::{Effects, MachineDef};

/// Model kind of the stored effects in the model store.
pub const MODEL_KIND: &str = "effects";

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v1/machines/{machine}/effects",
            get(get_effects).put(put_effects).delete(delete_effects),
        )
        .route("/v1/machines/{machine}/effects/versions", get(versions))
        .route("/v1/machines/{machine}/effects/rollback", post(rollback))
}

/// The machine's axes an effect may name: those of its kinematics that have a servo model.
pub fn axis_infos(def: &MachineDef) -> Vec<AxisInfo> {
    def.kinematics
        .axis_names()
        .iter()
        .enumerate()
        .filter_map(|(i, name)| {
            let a = def.axes.as_ref()?.get(name)?;
            let built = a.build(name, i >= 3).ok()?;
            Some(AxisInfo {
                name: (*name).to_string(),
                velocity_loop: built.servo.kp_v.is_some(),
            })
        })
        .collect()
}

fn effects_ref(machine: &Id) -> ModelRef<'_> {
    ModelRef {
        machine,
        surface: None,
        kind: MODEL_KIND,
        path: format!("/v1/machines/{machine}/effects"),
        made_by: format!("PUT /v1/machines/{machine}/effects"),
    }
}

/// The served set and its version, or `None` when the machine has none.
async fn load(state: &AppState, machine: &Id) -> ApiResult<Option<(i64, EffectSet)>> {
    let Some((version, bytes)) = state
        .store
        .models()
        .load_versioned(machine, None, MODEL_KIND)
        .await?
    else {
        return Ok(None);
    };
    let set: EffectSet = serde_json::from_slice(&bytes).map_err(ApiError::internal)?;
    Ok(Some((version, set)))
}

/// How a simulating request asks for the stored effects: its `effects` field, `"stored"`
/// (the default) or `"none"`.
pub fn wants_stored(field: Option<&str>) -> ApiResult<bool> {
    match field {
        None | Some("stored") => Ok(true),
        Some("none") => Ok(false),
        Some(other) => Err(ApiError::bad_request(format!(
            "effects must be \"stored\" (the default: the effects stored with the machine) or \
             \"none\" (the machine's servo model alone), got \"{other}\""
        ))),
    }
}

/// The effects a simulation of `machine` adds: the stored set, unless `field` is `"none"`
/// (400 for another value), read against the machine's axes (422 when they no longer fit it).
pub async fn for_simulation(
    state: &AppState,
    machine: &Id,
    def: &MachineDef,
    field: Option<&str>,
) -> ApiResult<Effects> {
    Ok(Effects(
        for_simulation_set(state, machine, def, field)
            .await?
            .map(|(s, _)| s as Arc<dyn crate::motion::AddedEffects>),
    ))
}

/// [`for_simulation`] with the set as stored (for a diagnosis' `accept`).
pub async fn for_simulation_set(
    state: &AppState,
    machine: &Id,
    def: &MachineDef,
    field: Option<&str>,
) -> ApiResult<Option<(Arc<StoredEffects>, EffectSet)>> {
    if !wants_stored(field)? {
        return Ok(None);
    }
    let Some((version, set)) = load(state, machine).await? else {
        return Ok(None);
    };
    let stored = StoredEffects::new(&set, &axis_infos(def), version).map_err(|e| {
        ApiError::unprocessable(format!(
            "the effects stored with machine '{machine}' (version {version}) no longer fit its \
             definition: {e}. PUT /v1/machines/{machine}/effects again, or send \"effects\": \
             \"none\""
        ))
    })?;
    Ok(Some((Arc::new(stored), set)))
}

fn answer(machine: &Id, version: i64, set: &EffectSet) -> Value {
    json!({
        "machine": machine.to_string(),
        "version": version,
        "effects": set.effects,
        "source": set.source,
    })
}

async fn put_effects(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
    ApiJson(set): ApiJson<EffectSet>,
) -> ApiResult<Response> {
    let def = require_machine_def(&state, &machine).await?;
    check(&set, &axis_infos(&def)).map_err(|e| ApiError::bad_request(e.to_string()))?;
    if set.source.as_ref().is_some_and(|s| s.len() > 1000) {
        return Err(ApiError::bad_request(
            "source: at most 1,000 characters (say where the effects come from)",
        ));
    }
    let payload = serde_json::to_vec(&set).map_err(ApiError::internal)?;
    let version = state
        .store
        .models()
        .save(&machine, None, MODEL_KIND, &payload)
        .await?;
    let status = if version == 1 {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, ApiJson(answer(&machine, version, &set))).into_response())
}

async fn get_effects(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<ApiJson<Value>> {
    require_machine(&state, &machine).await?;
    let (version, set) = load(&state, &machine).await?.ok_or_else(|| {
        ApiError::not_found(format!(
            "machine '{machine}' has no stored effects: PUT /v1/machines/{machine}/effects, \
             e.g. with the accept body of a gap diagnosis"
        ))
    })?;
    Ok(ApiJson(answer(&machine, version, &set)))
}

async fn delete_effects(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<StatusCode> {
    require_machine(&state, &machine).await?;
    if state
        .store
        .models()
        .delete(&machine, None, MODEL_KIND)
        .await?
    {
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(ApiError::not_found(format!(
            "machine '{machine}' has no stored effects to delete"
        )))
    }
}

async fn versions(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<ApiJson<Value>> {
    require_machine(&state, &machine).await?;
    Ok(ApiJson(
        model_versions::list(&state, &effects_ref(&machine)).await?,
    ))
}

async fn rollback(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
    ApiJson(req): ApiJson<RollbackRequest>,
) -> ApiResult<ApiJson<Value>> {
    require_machine(&state, &machine).await?;
    Ok(ApiJson(
        model_versions::rollback(&state, &effects_ref(&machine), req).await?,
    ))
}
