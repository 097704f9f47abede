//! Machines: `PUT/GET/DELETE /v1/machines/{machine}`, `GET /v1/machines`. A PUT body is parsed
//! into the motion core's [`MachineDef`], whose one `validate()` every simulation relies on.

use axum::Router;
use axum::extract::{Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::{Map, Value, json};

use super::AppState;
use super::auth::RequireAdmin;
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, decode_json, is_json, read_body};
use super::id::PathIds;
use super::lookup::require_machine;
use crate::motion::MachineDef;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/machines", get(list_machines))
        .route(
            "/v1/machines/{machine}",
            get(get_machine).put(put_machine).delete(delete_machine),
        )
}

/// Parses a machine definition (PUT body) with the one rule set every simulation uses
/// ([`MachineDef`]); returns the JSON to store and echo: the body without null-valued keys
/// (an optional key sent as `null` is absent, and echoing the null would break the schema).
pub fn parse_machine(body: &[u8]) -> ApiResult<(MachineDef, Value)> {
    if body.is_empty() {
        return Err(ApiError::bad_request(
            "the request body is empty; send a JSON machine definition",
        ));
    }
    let def = MachineDef::from_slice(body)?;
    let json: Value = decode_json(body)?;
    Ok((def, without_nulls(json)))
}

fn without_nulls(v: Value) -> Value {
    match v {
        Value::Object(m) => Value::Object(
            m.into_iter()
                .filter(|(_, v)| !v.is_null())
                .map(|(k, v)| (k, without_nulls(v)))
                .collect::<Map<String, Value>>(),
        ),
        other => other,
    }
}

async fn put_machine(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
    req: Request,
) -> ApiResult<Response> {
    if !is_json(req.headers()) {
        return Err(ApiError::unsupported_media_type(
            "send the body with Content-Type: application/json",
        ));
    }
    let body = read_body(req).await?;
    let (_, def) = parse_machine(&body)?;
    let created = state.store.put_machine(&machine, &def).await?;
    if created {
        Ok((
            StatusCode::CREATED,
            [(header::LOCATION, format!("/v1/machines/{machine}"))],
            ApiJson(def),
        )
            .into_response())
    } else {
        Ok((StatusCode::OK, ApiJson(def)).into_response())
    }
}

async fn get_machine(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<ApiJson<Value>> {
    require_machine(&state, &machine).await.map(ApiJson)
}

/// Every machine with its definition and what it has (`volumetric_map`: whether
/// `GET .../volumetric-map` answers a map; `effects`: whether `GET .../effects` answers
/// stored effects), so that a client asks only for what exists.
async fn list_machines(State(state): State<AppState>) -> ApiResult<ApiJson<Value>> {
    let with_map = state
        .store
        .models()
        .machines_with(crate::api::volumetric::MODEL_KIND)
        .await?;
    let with_effects = state
        .store
        .models()
        .machines_with(crate::api::effects::MODEL_KIND)
        .await?;
    let machines: Vec<Value> = state
        .store
        .list_machines()
        .await?
        .into_iter()
        .map(|m| {
            json!({
                "volumetric_map": with_map.contains(&m.id),
                "effects": with_effects.contains(&m.id),
                "id": m.id,
                "name": m.definition.get("name"),
                "kinematics": m.definition.get("kinematics"),
                "definition": m.definition,
            })
        })
        .collect();
    Ok(ApiJson(json!({ "machines": machines })))
}

async fn delete_machine(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine]): PathIds<1>,
) -> ApiResult<StatusCode> {
    if state.store.delete_machine(&machine).await? {
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(ApiError::not_found(format!(
            "machine '{machine}' does not exist"
        )))
    }
}
