//! ISO 230-2 runs stored per machine axis, to compare the figures before and after
//! compensation: `POST /v1/machines/{machine}/axes/{axis}/iso230-2` evaluates (as
//! `POST /v1/iso230-2`) and stores, `GET` lists the runs oldest first with their figures and
//! the change from the first to the last, `GET .../iso230-2/{id}` answers one run in full.

use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Extension, Router};
use serde_json::{Map, Value, json};

use super::AppState;
use super::auth::RequireWrite;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::id::{Id, PathIds};
use super::idempotency::KeyedId;
use super::iso230::evaluate_2;
use super::lookup::require_machine;
use crate::store::Iso230Run;
use crate::wire::iso230::Iso2302Request;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v1/machines/{machine}/axes/{axis}/iso230-2",
            get(list_runs).post(store_run),
        )
        .route(
            "/v1/machines/{machine}/axes/{axis}/iso230-2/{id}",
            get(get_run),
        )
}

/// Axis letters a run may be stored under.
pub const AXES: [&str; 9] = ["X", "Y", "Z", "A", "B", "C", "U", "V", "W"];

/// The axis figures compared across runs.
const FIGURES: [&str; 12] = [
    "A", "A_fwd", "A_bwd", "E", "E_fwd", "E_bwd", "M", "R", "R_fwd", "R_bwd", "B", "B_avg",
];

/// Refuses an axis letter that is not one of [`AXES`] (400, naming them).
pub(super) fn check_axis(axis: &Id) -> ApiResult<()> {
    if AXES.contains(&axis.as_str()) {
        Ok(())
    } else {
        Err(ApiError::bad_request(format!(
            "axis '{axis}' is not a machine axis; use one of {}",
            AXES.join(", ")
        )))
    }
}

fn rfc3339(ms: i64) -> Value {
    time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(ms) * 1_000_000)
        .ok()
        .and_then(|t| {
            t.format(&time::format_description::well_known::Rfc3339)
                .ok()
        })
        .map_or(Value::Null, Value::String)
}

/// A run as listed: id, label, time and the axis figures (mm).
fn summary(run: &Iso230Run) -> Value {
    let mut m = Map::new();
    m.insert("id".into(), json!(run.id));
    m.insert("label".into(), json!(run.label));
    m.insert("created_at".into(), rfc3339(run.created_at_ms));
    for f in FIGURES {
        m.insert(f.into(), run.answer.get(f).cloned().unwrap_or(Value::Null));
    }
    m.insert(
        "targets".into(),
        json!(
            run.answer
                .get("targets")
                .and_then(Value::as_array)
                .map_or(0, Vec::len)
        ),
    );
    Value::Object(m)
}

/// The whole run: the answer with id, machine, axis, label, time and the table evaluated.
fn full(machine: &Id, run: &Iso230Run) -> Value {
    let mut answer = run.answer.clone();
    if let Value::Object(m) = &mut answer {
        m.insert("id".into(), json!(run.id));
        m.insert("machine".into(), json!(machine.as_str()));
        m.insert("axis".into(), json!(run.axis));
        m.insert("label".into(), json!(run.label));
        m.insert("created_at".into(), rfc3339(run.created_at_ms));
        m.insert("input".into(), run.input.clone());
    }
    answer
}

async fn store_run(
    State(state): State<AppState>,
    _write: RequireWrite,
    keyed: Option<Extension<KeyedId>>,
    PathIds([machine, axis]): PathIds<2>,
    ApiJson(mut req): ApiJson<Iso2302Request>,
) -> ApiResult<Response> {
    check_axis(&axis)?;
    require_machine(&state, &machine).await?;
    let label = req.label.take();
    if let Some(l) = &label {
        if l.chars().count() > 200 {
            return Err(ApiError::bad_request(
                "label is longer than 200 characters; shorten it",
            ));
        }
    }
    let (answer, table) = evaluate_2(&state, req).await?;
    let input = json!({
        "targets": table.targets_mm,
        "forward": table.forward_mm,
        "backward": table.backward_mm,
    });
    let answer = serde_json::to_value(&answer).map_err(ApiError::internal)?;
    let run = state
        .store
        .put_iso230_run(
            &machine,
            &axis,
            keyed.as_ref().map(|k| k.0.0.as_str()),
            label.as_deref(),
            &input,
            &answer,
        )
        .await?;
    let location = format!("/v1/machines/{machine}/axes/{axis}/iso230-2/{}", run.id);
    Ok((
        StatusCode::CREATED,
        [(header::LOCATION, location)],
        ApiJson(full(&machine, &run)),
    )
        .into_response())
}

async fn list_runs(
    State(state): State<AppState>,
    PathIds([machine, axis]): PathIds<2>,
) -> ApiResult<ApiJson<Value>> {
    check_axis(&axis)?;
    require_machine(&state, &machine).await?;
    let runs = state.store.list_iso230_runs(&machine, &axis).await?;
    let change = match (runs.first(), runs.last()) {
        (Some(first), Some(last)) if runs.len() >= 2 => {
            let mut m = Map::new();
            m.insert("from".into(), json!(first.id));
            m.insert("to".into(), json!(last.id));
            for f in FIGURES {
                let d = match (
                    first.answer.get(f).and_then(Value::as_f64),
                    last.answer.get(f).and_then(Value::as_f64),
                ) {
                    (Some(a), Some(b)) => json!(b - a),
                    _ => Value::Null,
                };
                m.insert(f.into(), d);
            }
            Value::Object(m)
        }
        _ => Value::Null,
    };
    Ok(ApiJson(json!({
        "machine": machine.as_str(),
        "axis": axis.as_str(),
        "runs": runs.iter().map(summary).collect::<Vec<_>>(),
        "change": change,
    })))
}

async fn get_run(
    State(state): State<AppState>,
    PathIds([machine, axis, id]): PathIds<3>,
) -> ApiResult<ApiJson<Value>> {
    check_axis(&axis)?;
    match state.store.get_iso230_run(&machine, &axis, &id).await? {
        Some(run) => Ok(ApiJson(full(&machine, &run))),
        None => {
            require_machine(&state, &machine).await?;
            Err(ApiError::not_found(format!(
                "ISO 230-2 run '{id}' of axis {axis} (machine '{machine}') does not exist: \
                 GET /v1/machines/{machine}/axes/{axis}/iso230-2 lists the runs"
            )))
        }
    }
}
