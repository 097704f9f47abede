//! Sim-to-real gap diagnosis: `POST /v1/machines/{machine}/gap-diagnosis` (openapi.yaml,
//! motion and part domains). The motion request is the gap
//! core's ([`gap::GapRequest`], [`gap::diagnose_motion_request`]); this file loads what is
//! stored (machine, surface, measurement) and chooses between answering and a job.

use std::sync::Arc;

use axum::Router;
use axum::extract::{Request, State};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use super::AppState;
use super::auth::Role;
use super::contour::{ToolTables, reader_options};
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, decode_json, is_json, read_body};
use super::lookup::{require_machine, require_measurement, require_surface};
use super::version::stamp;
use crate::api::id::{Id, PathIds};
use crate::gap::adopted::EffectSet;
use crate::gap::{
    self, GapRequest, PartBlock, PartGrid, ProgramCommand, diagnose_motion_program,
    diagnose_motion_request, motion_inputs, part_answer,
};
use crate::jobs::{Progress, Runner};
use crate::motion::{
    Effects, Machine, MachineDef, ServoAxes, check_period, interpolate_with,
    machine_for_simulation, parse_modes, servo_axes, stored_definition,
};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/v1/machines/{machine}/gap-diagnosis", post(gap_diagnosis))
}

/// Samples per block answered synchronously (openapi.yaml: sync up to 100,000 samples a block);
/// larger motion blocks run as a job (202 `{"job": id}`).
pub const MAX_SYNC_SAMPLES: usize = 100_000;
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

/// Kind of the stored motion-diagnosis job (input: the machine id and the request body).
pub const JOB_KIND: &str = "gap-diagnosis";

/// Input of a stored motion diagnosis: the machine and the request body as sent.
#[derive(Debug, Serialize, Deserialize)]
struct StoredGap {
    machine: String,
    body: String,
}

/// Runs a stored motion diagnosis on any instance: the machine's servo model is read when
/// the job runs (as the door read it), the request is the body as sent.
pub fn runner(state: AppState) -> Runner {
    let handle = tokio::runtime::Handle::current();
    Arc::new(move |input: &str, p: &Progress| {
        // A database outage (503) puts the job back in the queue instead of failing it.
        let sentence = |e: ApiError| {
            if e.status() == axum::http::StatusCode::SERVICE_UNAVAILABLE {
                p.retry_later();
            }
            e.detail().to_string()
        };
        let job: StoredGap = serde_json::from_str(input)
            .map_err(|e| format!("the stored job input is not a gap diagnosis: {e}"))?;
        let req: GapRequest = serde_json::from_str(&job.body)
            .map_err(|e| format!("the stored request is not a gap diagnosis: {e}"))?;
        let machine = Id::parse("machine", &job.machine).map_err(sentence)?;
        p.set(0.02);
        let def = handle
            .block_on(require_machine(&state, &machine))
            .map_err(sentence)?;
        let mdef = stored_definition(&machine, &def).map_err(|e| sentence(e.into()))?;
        let (m, prior) = handle
            .block_on(motion_axes(&state, &machine, &mdef, &req))
            .map_err(sentence)?;
        p.set(0.05);
        diagnose_motion_request(&m, &req)
            .map(|a| with_accept(a, &m, prior.as_ref()))
            .map_err(|e| sentence(e.into()))
    })
}

async fn gap_diagnosis(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    request: Request,
) -> ApiResult<Response> {
    if !is_json(request.headers()) {
        return Err(ApiError::unsupported_media_type(
            "send the body with Content-Type: application/json",
        ));
    }
    let role = request.extensions().get::<Role>().copied();
    let body = read_body(request).await?;
    let req: GapRequest = decode_json(&body)?;
    let def = require_machine(&state, &machine).await?;
    match req.domain.as_str() {
        "motion" => {
            let mdef = stored_definition(&machine, &def)?;
            let (m, prior) = motion_axes(&state, &machine, &mdef, &req).await?;
            if req.gcode.is_some() {
                let sim = machine_for_simulation(&machine, &mdef)?;
                let reference = (mdef.home, mdef.g30);
                return motion_from_program(&state, sim, (m, prior), req, reference).await;
            }
            let n = req.commanded.as_ref().map_or(0, Vec::len);
            if req.measured_t.is_some() {
                // a time-stamped log is aligned and diagnosed while the caller waits
                let rows = n.max(req.measured.as_ref().map_or(0, Vec::len));
                if rows > MAX_SYNC_SAMPLES {
                    return Err(ApiError::bad_request(format!(
                        "a log with measured_t is diagnosed synchronously: at most {MAX_SYNC_SAMPLES} commanded rows and measured samples, got {rows}"
                    )));
                }
            }
            let nv = req
                .validation
                .as_ref()
                .and_then(|v| v.get("commanded"))
                .and_then(Value::as_array)
                .map_or(0, Vec::len);
            if n.max(nv) > MAX_SYNC_SAMPLES {
                super::auth::may_queue_job(
                    role,
                    &format!(
                        "the log has {} rows, more than the {MAX_SYNC_SAMPLES} diagnosed directly",
                        n.max(nv)
                    ),
                )?;
                // validate now so bad input is a 4xx, not a failed job
                motion_inputs(&m, &req)?;
                let input = serde_json::to_string(&StoredGap {
                    machine: machine.to_string(),
                    body: String::from_utf8(body.to_vec())
                        .map_err(|_| ApiError::bad_request("the request body is not UTF-8 JSON"))?,
                })
                .map_err(ApiError::internal)?;
                let id = state.jobs.enqueue(JOB_KIND, input).await?;
                return Ok(super::jobs::accepted(&id));
            }
            let answer = state
                .jobs
                .run(move || {
                    diagnose_motion_request(&m, &req).map(|a| with_accept(a, &m, prior.as_ref()))
                })
                .await??;
            Ok(ApiJson(stamp(answer)).into_response())
        }
        "part" => {
            let answer = diagnose_part_route(&state, &machine, req).await?;
            Ok(ApiJson(stamp(answer)).into_response())
        }
        other => Err(ApiError::bad_request(format!(
            "domain must be \"motion\" or \"part\", got \"{other}\""
        ))),
    }
}

/// The motion diagnosis of a program (CONTRACT v1.1): the program is read with the contour
/// route's lenient reader and options, interpolated on this machine every `period_s`, fitted
/// to the measured rows' length (held at its end or cut, with a warning), and diagnosed with
/// its lines named in `where`.
async fn motion_from_program(
    state: &AppState,
    sim: Machine,
    (m, prior): (ServoAxes, Option<EffectSet>),
    req: GapRequest,
    (home, g30): (Option<[f64; 3]>, Option<[f64; 3]>),
) -> ApiResult<Response> {
    let gcode = req.gcode.clone().unwrap_or_default();
    if gcode.trim().is_empty() {
        return Err(ApiError::bad_request(
            "gcode is empty: send the program text, e.g. \"G1 X10 F600\"",
        ));
    }
    let period_s = req.period_s.ok_or_else(|| {
        ApiError::bad_request("period_s is missing: give the sample period in seconds, e.g. 0.001")
    })?;
    check_period(period_s)?;
    let tools = ToolTables {
        lengths: &req.tool_lengths,
        diameters: &req.tool_diameters,
    };
    let options = reader_options(req.strict, &req.work_offsets, &tools, req.home)?
        .with_reference_points(home, g30);
    let n = req.measured.as_ref().map_or(0, Vec::len);
    if n > MAX_SYNC_SAMPLES {
        return Err(ApiError::bad_request(format!(
            "measured has {n} rows: a diagnosis from gcode takes at most {MAX_SYNC_SAMPLES} (send commanded rows for longer blocks)"
        )));
    }
    let answer = state
        .jobs
        .run(move || -> ApiResult<Value> {
            let (mut program, control, warnings) = parse_modes(&gcode, &options)?;
            let mut warnings: Vec<String> = warnings.iter().map(ToString::to_string).collect();
            if !options.strict {
                let has = |name: &str| sim.axes.iter().any(|a| a.name == name);
                warnings.extend(
                    program
                        .forget_still_rotary_axes(has("A"), has("C"))
                        .iter()
                        .map(ToString::to_string),
                );
            }
            let traj = interpolate_with(&program, &control, &sim, period_s, MAX_PROGRAM_PERIODS)?;
            let have = traj.line.len();
            let mut cmd = ProgramCommand {
                commanded: traj.axes,
                lines: traj.line,
                warnings,
            };
            // a time-stamped log is put on the program's grid by the alignment instead
            if n > 0 && have != n && req.measured_t.is_none() {
                for c in cmd.commanded.iter_mut() {
                    let last = c.last().copied().unwrap_or(0.0);
                    c.resize(n, last);
                }
                let last = cmd.lines.last().copied().unwrap_or(1);
                cmd.lines.resize(n, last);
                cmd.warnings.push(if have < n {
                    format!(
                        "the program's interpolation has {have} samples and measured {n} rows: the command holds the program's end position for the last {} rows",
                        n - have
                    )
                } else {
                    format!(
                        "the program's interpolation has {have} samples and measured {n} rows: the diagnosis covers the program's first {n} samples"
                    )
                });
            }
            let answer = diagnose_motion_program(&m, &req, Some(&cmd))?;
            Ok(with_accept(answer, &m, prior.as_ref()))
        })
        .await??;
    Ok(ApiJson(stamp(answer)).into_response())
}

/// The servo axes of a motion diagnosis with the effects its request asks for (stored, the
/// default, or none), and the stored set for the answer's `accept`.
async fn motion_axes(
    state: &AppState,
    machine: &Id,
    mdef: &MachineDef,
    req: &GapRequest,
) -> ApiResult<(ServoAxes, Option<EffectSet>)> {
    let mut m = servo_axes(machine, mdef)?;
    let stored =
        super::effects::for_simulation_set(state, machine, mdef, req.effects.as_deref()).await?;
    Ok(match stored {
        Some((s, set)) => {
            m.effects = Effects(Some(s));
            (m, Some(set))
        }
        None => (m, None),
    })
}

/// A motion answer with `effects_version` (the stored effects the simulation included, or
/// null) and `accept`: the body of `PUT /v1/machines/{machine}/effects` that adopts the
/// steps' effects with their fitted parameters, after those already stored (the steps were
/// fitted on top of them, and stored effects add up as the steps do).
fn with_accept(mut answer: Value, m: &ServoAxes, prior: Option<&EffectSet>) -> Value {
    let mut effects: Vec<Value> = prior
        .map(|p| p.effects.iter().map(|e| json!(e)).collect())
        .unwrap_or_default();
    let steps = answer.get("steps").and_then(Value::as_array);
    for s in steps.into_iter().flatten() {
        effects.push(json!({"effect": s["effect"], "params": s["params"]}));
    }
    let now = time::OffsetDateTime::now_utc()
        .format(&time::format_description::well_known::Rfc3339)
        .unwrap_or_default();
    let source = match m.effects.version() {
        Some(v) => format!("gap diagnosis of {now} on effects version {v}"),
        None => format!("gap diagnosis of {now}"),
    };
    answer["effects_version"] = json!(m.effects.version());
    answer["accept"] = json!({"effects": effects, "source": source});
    answer
}

/// Most interpolation periods read from a program for a motion diagnosis.
pub const MAX_PROGRAM_PERIODS: usize = 1_000_000;

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

async fn diagnose_part_route(state: &AppState, machine: &Id, req: GapRequest) -> ApiResult<Value> {
    for (name, present) in [
        ("period_s", req.period_s.is_some()),
        ("commanded", req.commanded.is_some()),
        ("measured", req.measured.is_some()),
        ("gcode", req.gcode.is_some()),
    ] {
        if present {
            return Err(ApiError::bad_request(format!(
                "{name} belongs to domain \"motion\": a part diagnosis takes surface, measurement, predicted, time, approach and validation"
            )));
        }
    }
    let surface_id = req.surface.as_deref().ok_or_else(|| {
        ApiError::bad_request("surface is missing: give the id of the probed surface")
    })?;
    let surface_id = Id::parse("surface", surface_id)?;
    let measurement_id = req.measurement.as_deref().ok_or_else(|| {
        ApiError::bad_request(
            "measurement is missing: give the id of an uploaded measurement of that surface",
        )
    })?;
    let measurement_id = Id::parse("measurement", measurement_id)?;
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
            let vm_id = Id::parse("validation.measurement", &body.measurement)?;
            let vm = require_measurement(state, machine, &surface_id, &vm_id).await?;
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
mod tests;
