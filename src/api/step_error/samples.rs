//! `POST /v1/step-error/samples` and `POST .../step-error-samples`: exactly labelled segments
//! from an analytic height surface or a stored nominal grid (training data for the network).

use axum::extract::State;
use axum::response::Response;
use serde::{Deserialize, Serialize};

use super::MAX_SYNC_SAMPLES;
use super::exact::{check_tool_radius, json_response};
use crate::api::AppState;
use crate::api::error::{ApiError, ApiResult};
use crate::api::extract::ApiJson;
use crate::api::id::PathIds;
use crate::api::lookup::require_surface;
use crate::geometry::{
    self, HeightSurface, PathPlan, StepErrorSegment, grid_segments, height_surface_segments,
};

/// Where samples come from in `POST /v1/step-error/samples`.
#[derive(Debug, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum SampleSurface {
    /// An analytic height function `z = scale * sum(terms) + offset`.
    Height(HeightSurface),
    /// One of the Python study's surfaces 1, 2, 3.
    Reference(u32),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SamplesRequest {
    surface: SampleSurface,
    plan: PathPlan,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SurfaceSamplesRequest {
    plan: PlanWithOptionalRadius,
}

/// A [`PathPlan`] whose radius defaults to the stored surface's `tool_radius`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PlanWithOptionalRadius {
    #[serde(default)]
    tool_radius_mm: Option<f64>,
    #[serde(default)]
    step_over_mm: Option<f64>,
    #[serde(default)]
    cl_spacing_mm: Option<f64>,
    #[serde(default)]
    lines: Option<usize>,
    #[serde(default)]
    points_per_line: Option<usize>,
    #[serde(default)]
    cc_points: Option<usize>,
}

impl PlanWithOptionalRadius {
    pub(super) fn resolve(&self, surface_radius: Option<f64>) -> ApiResult<PathPlan> {
        let r = self.tool_radius_mm.or(surface_radius).ok_or_else(|| {
            ApiError::bad_request(
                "plan.tool_radius_mm is required (the surface has no tool_radius stored)",
            )
        })?;
        check_tool_radius(r)?;
        Ok(PathPlan {
            tool_radius_mm: r,
            step_over_mm: self.step_over_mm,
            cl_spacing_mm: self.cl_spacing_mm,
            lines: self.lines,
            points_per_line: self.points_per_line,
            cc_points: self.cc_points.unwrap_or(20),
        })
    }
}

#[derive(Serialize)]
struct SamplesAnswer<'a> {
    tool_radius: f64,
    segments: &'a [StepErrorSegment],
    step_errors: Vec<f64>,
    convex: Vec<bool>,
    inflections: Vec<usize>,
    unit: &'static str,
}

fn labelled_samples_json(r: f64, segs: Vec<StepErrorSegment>) -> ApiResult<Vec<u8>> {
    if segs.len() > MAX_SYNC_SAMPLES {
        return Err(ApiError::payload_too_large(format!(
            "the plan makes {} segments; this route answers at most {MAX_SYNC_SAMPLES}: raise step_over_mm or cl_spacing_mm",
            segs.len()
        )));
    }
    let errs = geometry::step_errors(r, &segs, 0)?;
    serde_json::to_vec(&SamplesAnswer {
        tool_radius: r,
        segments: &segs,
        step_errors: errs.iter().map(|e| e.error_mm).collect(),
        convex: errs.iter().map(|e| e.convex).collect(),
        inflections: errs
            .iter()
            .enumerate()
            .filter(|(_, e)| e.inflection)
            .map(|(i, _)| i)
            .collect(),
        unit: "mm",
    })
    .map_err(ApiError::internal)
}

pub(super) async fn samples(
    State(state): State<AppState>,
    ApiJson(req): ApiJson<SamplesRequest>,
) -> ApiResult<Response> {
    check_tool_radius(req.plan.tool_radius_mm)?;
    let surface = match req.surface {
        SampleSurface::Height(h) => h,
        SampleSurface::Reference(id) => HeightSurface::reference(id).ok_or_else(|| {
            ApiError::bad_request(format!(
                "surface.reference must be 1, 2 or 3 (the study's surfaces), got {id}"
            ))
        })?,
    };
    let out = state
        .jobs
        .run(move || {
            let segs = height_surface_segments(&surface, &req.plan)?;
            labelled_samples_json(req.plan.tool_radius_mm, segs)
        })
        .await??;
    Ok(json_response(out))
}

pub(super) async fn surface_samples(
    State(state): State<AppState>,
    PathIds([machine, surface]): PathIds<2>,
    ApiJson(req): ApiJson<SurfaceSamplesRequest>,
) -> ApiResult<Response> {
    let s = require_surface(&state, &machine, &surface).await?;
    let plan = req.plan.resolve(s.tool_radius)?;
    let out = state
        .jobs
        .run(move || {
            let segs = grid_segments(s.nu, s.nv, &s.points, &s.normals, &plan)?;
            labelled_samples_json(plan.tool_radius_mm, segs)
        })
        .await??;
    Ok(json_response(out))
}
