//! Sim-to-real gap diagnosis: `POST /v1/machines/{machine}/gap-diagnosis` (CONTRACT
//! "Sim-to-real gap diagnosis", motion and part domains). Also the one
//! `From<gap::Error> for ApiError`.

use axum::Router;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use serde::Deserialize;
use serde_json::{Map, Value, json};

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, check_id};
use super::lookup::{require_machine, require_measurement, require_surface};
use crate::gap::{
    self, MotionBlock, MotionDiagnosis, MotionOptions, PartBlock, PartDiagnosis, PartGrid,
};
use crate::motion::{Machine, ServoAxis, StructuralMode};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/v1/machines/{machine}/gap-diagnosis", post(gap_diagnosis))
}

/// Samples per block answered synchronously (CONTRACT: sync up to 100,000 samples a block);
/// larger motion blocks run as a job (202 `{"job": id}`).
pub const MAX_SYNC_SAMPLES: usize = 100_000;
/// Samples per block accepted at all.
pub const MAX_SAMPLES: usize = 2_000_000;

/// Body of the route (both domains; fields of the other domain are rejected).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GapRequest {
    /// "motion" or "part".
    pub domain: String,
    /// Motion: sample period, s.
    #[serde(default)]
    pub period_s: Option<f64>,
    /// Motion: command rows `[x, y]` or `[x, y, z]`, mm.
    #[serde(default)]
    pub commanded: Option<Vec<Vec<f64>>>,
    /// Motion: measured rows, mm.
    #[serde(default)]
    pub measured: Option<Vec<Vec<f64>>>,
    /// Part: surface id.
    #[serde(default)]
    pub surface: Option<String>,
    /// Part: measurement id.
    #[serde(default)]
    pub measurement: Option<String>,
    /// Part: simulated deviation per point, mm (default: volumetric map along the normals, else 0).
    #[serde(default)]
    pub predicted: Option<Vec<f64>>,
    /// Part: cutting time per point, s.
    #[serde(default)]
    pub time: Option<Vec<f64>>,
    /// Part: probe approach direction per point.
    #[serde(default)]
    pub approach: Option<Vec<[f64; 3]>>,
    /// Validation block (shape depends on the domain).
    #[serde(default)]
    pub validation: Option<Value>,
    /// Extension: cross-validation folds (default 5, 2..=10).
    #[serde(default)]
    pub folds: Option<usize>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionValidationBody {
    commanded: Vec<Vec<f64>>,
    measured: Vec<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PartValidationBody {
    measurement: String,
    #[serde(default)]
    predicted: Option<Vec<f64>>,
    #[serde(default)]
    time: Option<Vec<f64>>,
    #[serde(default)]
    approach: Option<Vec<[f64; 3]>>,
}

/// Rows `[[x, y(, z)]; n]` → per-axis columns, checking shape, size and finiteness.
pub fn rows_to_columns(field: &str, rows: &[Vec<f64>]) -> ApiResult<Vec<Vec<f64>>> {
    let Some(first) = rows.first() else {
        return Err(ApiError::bad_request(format!(
            "{field} is empty: send one row [x, y] or [x, y, z] (mm) per period"
        )));
    };
    let dims = first.len();
    if !(2..=3).contains(&dims) {
        return Err(ApiError::bad_request(format!(
            "{field}[0] has {dims} values: rows are [x, y] or [x, y, z] in mm"
        )));
    }
    if rows.len() > MAX_SAMPLES {
        return Err(ApiError::payload_too_large(format!(
            "{field} has {} rows: at most {MAX_SAMPLES} samples a block",
            rows.len()
        )));
    }
    let mut cols = vec![Vec::with_capacity(rows.len()); dims];
    for (i, row) in rows.iter().enumerate() {
        if row.len() != dims {
            return Err(ApiError::bad_request(format!(
                "{field}[{i}] has {} values but {field}[0] has {dims}: every row needs the same axes",
                row.len()
            )));
        }
        for (k, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(ApiError::bad_request(format!(
                    "{field}[{i}][{k}] is not a finite number"
                )));
            }
            cols[k].push(*v);
        }
    }
    Ok(cols)
}

fn params_json(params: &[(String, f64)]) -> Value {
    Value::Object(
        params
            .iter()
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect::<Map<_, _>>(),
    )
}

fn columns_to_rows(cols: &[Vec<f64>]) -> Value {
    let n = cols.first().map_or(0, Vec::len);
    Value::Array(
        (0..n)
            .map(|i| Value::Array(cols.iter().map(|c| json!(c[i])).collect()))
            .collect(),
    )
}

/// The CONTRACT answer of a motion diagnosis (plus `domain`, `axes`, `noise_mm`).
pub fn motion_answer(axes: &[String], d: &MotionDiagnosis) -> Value {
    let mut out = json!({
        "domain": "motion",
        "axes": axes,
        "gap_before": d.gap_before,
        "where": d.spans,
        "effects": d.effects.iter().map(|e| json!({
            "effect": e.fitted.effect().name(),
            "params": params_json(&e.params),
            "score": e.score,
        })).collect::<Vec<_>>(),
        "verdict": d.verdict.name(),
        "gap_after": d.gap_after,
        "noise_mm": d.noise_mm,
    });
    if let Some(v) = &d.validation {
        out["validation"] = json!({
            "predicted_before": columns_to_rows(&v.predicted_before),
            "predicted_after": columns_to_rows(&v.predicted_after),
            "rms_before": v.rms_before,
            "rms_after": v.rms_after,
        });
    }
    out
}

/// The CONTRACT answer of a part diagnosis (plus `domain`, `predicted_source`).
pub fn part_answer(d: &PartDiagnosis, predicted_source: &str) -> Value {
    let mut out = json!({
        "domain": "part",
        "gap_before": d.gap_before,
        "where": d.regions,
        "effects": d.effects.iter().map(|e| json!({
            "effect": e.effect.name(),
            "params": params_json(&e.params),
            "score": e.score,
        })).collect::<Vec<_>>(),
        "verdict": d.verdict.name(),
        "gap_after": d.gap_after,
        "predicted_source": predicted_source,
    });
    if let Some((before, after, rb, ra)) = &d.validation {
        out["validation"] = json!({
            "predicted_before": before, "predicted_after": after,
            "rms_before": rb, "rms_after": ra,
        });
    }
    out
}

/// The servo models the gap simulation uses, per axis in the order X, Y, Z.
#[derive(Clone, Debug, Default)]
pub struct GapAxes {
    /// Machine id (for messages).
    pub machine: String,
    /// Axis letters.
    pub names: Vec<String>,
    /// CONTRACT cascade per axis.
    pub servo: Vec<ServoAxis>,
    /// Structural mode per axis (from the definition's "physical" parameters), if any.
    pub structure: Vec<Option<StructuralMode>>,
}

/// The X, Y(, Z) servo models of a stored machine definition: the motion core's machine model
/// when the whole definition simulates (physical parameters mapped onto the cascade,
/// structural modes), otherwise the CONTRACT cascade of just the axes present, so a 2-axis
/// diagnosis needs only X and Y. 422 when an axis' servo is invalid.
pub fn gap_axes(id: &str, def: &Value) -> ApiResult<GapAxes> {
    let mut out = GapAxes {
        machine: id.to_string(),
        ..GapAxes::default()
    };
    if let Ok(m) = Machine::from_json(def) {
        for name in ["X", "Y", "Z"] {
            let Some(a) = m.axes.iter().find(|a| a.name == name) else {
                break;
            };
            out.names.push(name.to_string());
            out.servo.push(a.servo.clone());
            out.structure.push(a.structure);
        }
        if !out.names.is_empty() {
            return Ok(out);
        }
    }
    for name in ["X", "Y", "Z"] {
        let Some(v) = def.get("axes").and_then(|a| a.get(name)) else {
            break;
        };
        let servo: ServoAxis = serde_json::from_value(v.clone()).map_err(|e| {
            ApiError::unprocessable(format!(
                "machine '{id}' axes.{name} is not a servo model ({e}): fix it with PUT /v1/machines/{id}"
            ))
        })?;
        servo.validate().map_err(|e| {
            ApiError::unprocessable(format!(
                "machine '{id}' axes.{name}: {e}. Fix it with PUT /v1/machines/{id}"
            ))
        })?;
        out.names.push(name.to_string());
        out.servo.push(servo);
        out.structure.push(None);
    }
    Ok(out)
}

/// Runs the motion diagnosis of `req` against the machine's servo models (sync core call;
/// also used by `truecut gap diagnose` and `truecut gap csv`).
pub fn diagnose_motion_request(axes: &GapAxes, req: &GapRequest) -> ApiResult<Value> {
    let (main, validation, period_s, opts) = motion_inputs(axes, req)?;
    let dims = main.commanded.len();
    let d = gap::diagnose_motion_structured(
        &axes.names[..dims],
        &axes.servo[..dims],
        &axes.structure[..dims],
        period_s,
        &main,
        validation.as_ref(),
        &opts,
    )?;
    Ok(motion_answer(&axes.names[..dims], &d))
}

type MotionInputs = (MotionBlock, Option<MotionBlock>, f64, MotionOptions);

fn motion_inputs(axes: &GapAxes, req: &GapRequest) -> ApiResult<MotionInputs> {
    for (name, present) in [
        ("surface", req.surface.is_some()),
        ("measurement", req.measurement.is_some()),
        ("predicted", req.predicted.is_some()),
        ("time", req.time.is_some()),
        ("approach", req.approach.is_some()),
    ] {
        if present {
            return Err(ApiError::bad_request(format!(
                "{name} belongs to domain \"part\": a motion diagnosis takes period_s, commanded, measured and validation"
            )));
        }
    }
    let period_s = req.period_s.ok_or_else(|| {
        ApiError::bad_request("period_s is missing: give the sample period in seconds, e.g. 0.001")
    })?;
    if !(period_s.is_finite() && period_s > 0.0 && period_s <= 10.0) {
        return Err(ApiError::bad_request(format!(
            "period_s must be a positive number of seconds (at most 10), got {period_s}"
        )));
    }
    let need = |field: &str, v: &Option<Vec<Vec<f64>>>| -> ApiResult<Vec<Vec<f64>>> {
        rows_to_columns(
            field,
            v.as_deref().ok_or_else(|| {
                ApiError::bad_request(format!(
                    "{field} is missing: send rows [x, y] or [x, y, z] in mm"
                ))
            })?,
        )
    };
    let commanded = need("commanded", &req.commanded)?;
    let measured = need("measured", &req.measured)?;
    let dims = commanded.len();
    if measured.len() != dims {
        return Err(ApiError::bad_request(format!(
            "measured rows have {} values but commanded rows have {dims}",
            measured.len()
        )));
    }
    if measured[0].len() != commanded[0].len() {
        return Err(ApiError::bad_request(format!(
            "measured has {} rows but commanded has {}: one measured row per commanded row",
            measured[0].len(),
            commanded[0].len()
        )));
    }
    if axes.names.len() < dims {
        let id = &axes.machine;
        return Err(ApiError::unprocessable(format!(
            "machine '{id}' has servo models for [{}] but the rows have {dims} columns: \
             PUT /v1/machines/{id} with axes {}",
            axes.names.join(", "),
            ["X", "Y", "Z"][..dims].join(", ")
        )));
    }
    let validation = match &req.validation {
        None | Some(Value::Null) => None,
        Some(v) => {
            let body: MotionValidationBody = serde_json::from_value(v.clone()).map_err(|e| {
                ApiError::bad_request(format!(
                    "validation must be {{\"commanded\": [...], \"measured\": [...]}}: {e}"
                ))
            })?;
            let c = rows_to_columns("validation.commanded", &body.commanded)?;
            let m = rows_to_columns("validation.measured", &body.measured)?;
            if c.len() != dims || m.len() != dims || c[0].len() != m[0].len() {
                return Err(ApiError::bad_request(format!(
                    "validation.commanded and validation.measured need {dims}-value rows and the same number of rows"
                )));
            }
            Some(MotionBlock {
                commanded: c,
                measured: m,
            })
        }
    };
    let folds = req.folds.unwrap_or(5);
    if !(2..=10).contains(&folds) {
        return Err(ApiError::bad_request(format!(
            "folds must be 2..=10, got {folds}"
        )));
    }
    // small blocks: one thread per request (the pool runs requests side by side); large
    // blocks: the 7 effect fits on 2 threads, so one 100,000-sample request stays near 5 s
    let threads = if commanded[0].len() >= 20_000 { 2 } else { 1 };
    let opts = MotionOptions {
        folds,
        threads,
        ..MotionOptions::default()
    };
    Ok((
        MotionBlock {
            commanded,
            measured,
        },
        validation,
        period_s,
        opts,
    ))
}

async fn gap_diagnosis(
    State(state): State<AppState>,
    Path(machine): Path<String>,
    ApiJson(req): ApiJson<GapRequest>,
) -> ApiResult<Response> {
    let def = require_machine(&state, &machine).await?;
    match req.domain.as_str() {
        "motion" => {
            let m = gap_axes(&machine, &def)?;
            let n = req.commanded.as_ref().map_or(0, Vec::len);
            let nv = req
                .validation
                .as_ref()
                .and_then(|v| v.get("commanded"))
                .and_then(Value::as_array)
                .map_or(0, Vec::len);
            if n.max(nv) > MAX_SYNC_SAMPLES {
                // validate now so bad input is a 4xx, not a failed job
                motion_inputs(&m, &req)?;
                let id = state
                    .jobs
                    .submit("gap-diagnosis", move |p| {
                        p.set(0.05);
                        diagnose_motion_request(&m, &req).map_err(|e| e.detail().to_string())
                    })
                    .await?;
                return Ok((StatusCode::ACCEPTED, ApiJson(json!({"job": id}))).into_response());
            }
            let answer = state
                .jobs
                .run(move || diagnose_motion_request(&m, &req))
                .await??;
            Ok(ApiJson(answer).into_response())
        }
        "part" => Ok(ApiJson(diagnose_part_route(&state, &machine, req).await?).into_response()),
        other => Err(ApiError::bad_request(format!(
            "domain must be \"motion\" or \"part\", got \"{other}\""
        ))),
    }
}

fn check_opt(field: &str, v: &Option<Vec<f64>>, n: usize) -> ApiResult<()> {
    if let Some(xs) = v {
        if xs.len() != n {
            return Err(ApiError::bad_request(format!(
                "{field} has {} values but the surface grid has {n} points: one per point in nominal order",
                xs.len()
            )));
        }
        if let Some(i) = xs.iter().position(|x| !x.is_finite()) {
            return Err(ApiError::bad_request(format!(
                "{field}[{i}] is not a finite number"
            )));
        }
    }
    Ok(())
}

fn part_block(
    field: &str,
    grid: &PartGrid,
    measured: Vec<f64>,
    predicted: Option<Vec<f64>>,
    time: Option<Vec<f64>>,
    approach: Option<Vec<[f64; 3]>>,
) -> ApiResult<PartBlock> {
    let n = grid.nu * grid.nv;
    if measured.len() != n {
        return Err(ApiError::unprocessable(format!(
            "{field} has {} deviations but the surface grid has {n} points: upload it again for this surface",
            measured.len()
        )));
    }
    check_opt(&format!("{field}.predicted"), &predicted, n)?;
    check_opt(&format!("{field}.time"), &time, n)?;
    if let Some(a) = &approach {
        if a.len() != n {
            return Err(ApiError::bad_request(format!(
                "{field}.approach has {} directions but the surface grid has {n} points",
                a.len()
            )));
        }
        if let Some(i) = a.iter().position(|v| {
            !v.iter().all(|x| x.is_finite())
                || (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - 1.0).abs() > 1e-3
        }) {
            return Err(ApiError::bad_request(format!(
                "{field}.approach[{i}] must be a finite unit vector [i, j, k]"
            )));
        }
    }
    Ok(PartBlock {
        measured,
        predicted: predicted.unwrap_or_else(|| vec![0.0; n]),
        time: time.unwrap_or_else(|| (0..n).map(|k| k as f64).collect()),
        approach: approach
            .unwrap_or_else(|| grid.normals.iter().map(|v| [-v[0], -v[1], -v[2]]).collect()),
    })
}

async fn diagnose_part_route(state: &AppState, machine: &str, req: GapRequest) -> ApiResult<Value> {
    for (name, present) in [
        ("period_s", req.period_s.is_some()),
        ("commanded", req.commanded.is_some()),
        ("measured", req.measured.is_some()),
    ] {
        if present {
            return Err(ApiError::bad_request(format!(
                "{name} belongs to domain \"motion\": a part diagnosis takes surface, measurement, predicted, time, approach and validation"
            )));
        }
    }
    let surface_id = req.surface.clone().ok_or_else(|| {
        ApiError::bad_request("surface is missing: give the id of the probed surface")
    })?;
    let measurement_id = req.measurement.clone().ok_or_else(|| {
        ApiError::bad_request(
            "measurement is missing: give the id of an uploaded measurement of that surface",
        )
    })?;
    check_id("surface", &surface_id)?;
    check_id("measurement", &measurement_id)?;
    let surface = require_surface(state, machine, &surface_id).await?;
    let main_m = require_measurement(state, machine, &surface_id, &measurement_id).await?;
    let grid = PartGrid {
        nu: surface.nu,
        nv: surface.nv,
        points: surface.points,
        normals: surface.normals,
    };
    // The service's own prediction: the machine's volumetric map along the normals, if one is
    // stored (e·n, volumetric::normal_deviation); 0 otherwise.
    let own: Option<Vec<f64>> = super::volumetric::load_map(state, machine)
        .await?
        .map(|map| crate::volumetric::normal_deviation(&map, &grid.points, &grid.normals));
    let source = match (&req.predicted, &own) {
        (Some(_), _) => "caller",
        (None, Some(_)) => "volumetric-map",
        (None, None) => "zero",
    };
    let main_predicted = req.predicted.or_else(|| own.clone());
    let main = part_block(
        "main",
        &grid,
        main_m.deviations,
        main_predicted,
        req.time,
        req.approach,
    )?;
    let validation = match req.validation {
        None | Some(Value::Null) => None,
        Some(v) => {
            let body: PartValidationBody = serde_json::from_value(v).map_err(|e| {
                ApiError::bad_request(format!(
                    "validation must be {{\"measurement\": id, \"predicted\"?: [...], \"time\"?: [...], \"approach\"?: [...]}}: {e}"
                ))
            })?;
            let vm = require_measurement(state, machine, &surface_id, &body.measurement).await?;
            Some(part_block(
                "validation",
                &grid,
                vm.deviations,
                body.predicted.or(own),
                body.time,
                body.approach,
            )?)
        }
    };
    let d = state
        .jobs
        .run(move || gap::diagnose_part(&grid, &main, validation.as_ref(), 0.05))
        .await??;
    Ok(part_answer(&d, source))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::Effect;

    #[test]
    fn rows_are_checked_and_transposed() {
        let c = rows_to_columns("commanded", &[vec![1.0, 2.0], vec![3.0, 4.0]]).unwrap();
        assert_eq!(c, vec![vec![1.0, 3.0], vec![2.0, 4.0]]);
        let e = rows_to_columns("commanded", &[vec![1.0, 2.0], vec![3.0]]).unwrap_err();
        assert!(e.detail().contains("commanded[1]"), "{}", e.detail());
        let e = rows_to_columns("measured", &[]).unwrap_err();
        assert!(e.detail().contains("measured is empty"));
        let e = rows_to_columns("commanded", &[vec![1.0; 4]]).unwrap_err();
        assert_eq!(e.status(), StatusCode::BAD_REQUEST);
    }

    #[test]
    fn gap_errors_map_to_4xx() {
        let e: ApiError = gap::Error::Shape {
            field: "commanded".into(),
            reason: "x".into(),
        }
        .into();
        assert_eq!(e.status(), StatusCode::BAD_REQUEST);
        let e: ApiError = gap::Error::Servo {
            axis: "X".into(),
            source: crate::motion::Error::EmptyCommand,
        }
        .into();
        assert_eq!(e.status(), StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(Effect::None.name(), "none");
    }
}
