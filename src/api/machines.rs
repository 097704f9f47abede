//! Machines: `PUT/GET/DELETE /v1/machines/{machine}`, `GET /v1/machines`.

use axum::Router;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::{Map, Value, json};

use super::AppState;
use super::auth::RequireAdmin;
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, check_id};
use super::lookup::require_machine;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/machines", get(list_machines))
        .route(
            "/v1/machines/{machine}",
            get(get_machine).put(put_machine).delete(delete_machine),
        )
}

/// Kinematic chains the service knows.
pub const KINEMATICS: [&str; 2] = ["xyz", "xyzac_table"];

fn number(field: &str, v: &Value) -> ApiResult<f64> {
    v.as_f64()
        .filter(|x| x.is_finite())
        .ok_or_else(|| ApiError::bad_request(format!("{field} must be a finite number")))
}

/// Validates a machine definition (CONTRACT "Machines" and "Servo model"); unknown extra
/// fields are allowed and kept.
pub fn validate_machine(def: &Value) -> ApiResult<()> {
    let obj = def
        .as_object()
        .ok_or_else(|| ApiError::bad_request("the machine definition must be a JSON object"))?;
    if let Some(name) = obj.get("name")
        && !name.is_string()
        && !name.is_null()
    {
        return Err(ApiError::bad_request("name must be a string"));
    }
    let kin = obj.get("kinematics").and_then(Value::as_str).ok_or_else(|| {
        ApiError::bad_request(
            "kinematics is required: \"xyz\" (3-axis) or \"xyzac_table\" (5-axis, A and C on the table)",
        )
    })?;
    if !KINEMATICS.contains(&kin) {
        return Err(ApiError::bad_request(format!(
            "kinematics '{kin}' is not supported; use \"xyz\" or \"xyzac_table\""
        )));
    }
    let allowed: &[&str] = if kin == "xyz" {
        &["X", "Y", "Z"]
    } else {
        &["X", "Y", "Z", "A", "C"]
    };
    match obj.get("axes") {
        None | Some(Value::Null) => {}
        Some(Value::Object(axes)) => {
            for (axis, servo) in axes {
                if !allowed.contains(&axis.as_str()) {
                    return Err(ApiError::bad_request(format!(
                        "axes.{axis}: kinematics '{kin}' has axes {}",
                        allowed.join(", ")
                    )));
                }
                validate_servo(axis, servo)?;
            }
        }
        Some(_) => {
            return Err(ApiError::bad_request(
                "axes must be an object mapping an axis letter (X, Y, Z, A, C) to its servo model",
            ));
        }
    }
    Ok(())
}

fn validate_servo(axis: &str, servo: &Value) -> ApiResult<()> {
    let s: &Map<String, Value> = servo.as_object().ok_or_else(|| {
        ApiError::bad_request(format!(
            "axes.{axis} must be an object like {{\"kv\": 30.0}} (kv in 1/s)"
        ))
    })?;
    let kv = s.get("kv").ok_or_else(|| {
        ApiError::bad_request(format!(
            "axes.{axis}.kv (position loop gain, 1/s) is required"
        ))
    })?;
    let kv = number(&format!("axes.{axis}.kv"), kv)?;
    if kv <= 0.0 {
        return Err(ApiError::bad_request(format!(
            "axes.{axis}.kv must be > 0 (position loop gain in 1/s), got {kv}"
        )));
    }
    if let Some(v) = s.get("kff").filter(|v| !v.is_null()) {
        let kff = number(&format!("axes.{axis}.kff"), v)?;
        if !(0.0..=1.0).contains(&kff) {
            return Err(ApiError::bad_request(format!(
                "axes.{axis}.kff (velocity feed-forward) must be in 0..1, got {kff}"
            )));
        }
    }
    for (key, unit) in [("kp_v", "1/s"), ("ti_v", "s"), ("tc", "s")] {
        if let Some(v) = s.get(key).filter(|v| !v.is_null()) {
            let x = number(&format!("axes.{axis}.{key}"), v)?;
            if x <= 0.0 {
                return Err(ApiError::bad_request(format!(
                    "axes.{axis}.{key} must be > 0 ({unit}) or omitted, got {x}"
                )));
            }
        }
    }
    Ok(())
}

async fn put_machine(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    Path(machine): Path<String>,
    ApiJson(def): ApiJson<Value>,
) -> ApiResult<Response> {
    check_id("machine", &machine)?;
    validate_machine(&def)?;
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
    Path(machine): Path<String>,
) -> ApiResult<ApiJson<Value>> {
    require_machine(&state, &machine).await.map(ApiJson)
}

async fn list_machines(State(state): State<AppState>) -> ApiResult<ApiJson<Value>> {
    let machines: Vec<Value> = state
        .store
        .list_machines()
        .await?
        .into_iter()
        .map(|m| {
            json!({
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
    Path(machine): Path<String>,
) -> ApiResult<StatusCode> {
    check_id("machine", &machine)?;
    if state.store.delete_machine(&machine).await? {
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(ApiError::not_found(format!(
            "machine '{machine}' does not exist"
        )))
    }
}
